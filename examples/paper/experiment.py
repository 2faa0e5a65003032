"""The paper's Section 3.1 experiment: an unknown material embedded in a known one, reproduced.

A sheet of background modulus 83.76 kPa carries a rectangle of a second material of 837.61 kPa
(Tsap, Goldgof & Sarkar 2000, Sec. 3.1). It is stretched; a grid of points is tracked, the grid's
boundary points drive the model (the set P) and its interior points guide the search (the set Q).
The model knows where the rectangle is (the first, uniform model located it, Fig. 7) and searches
its modulus over the bracket 41.88-1591.44 kPa, half to twenty times the background:

- :meth:`PaperExperiment.brent`: Brent's method on the paper's error eq. (1) from the middle
  point b = 118.80 or b = 1256.40 kPa at tolerance 0.01 (Tables 1-3);
- :meth:`PaperExperiment.cubic`: the cubic fit over the bracket, then Brent at tolerance 0.001;
- :meth:`PaperExperiment.least_squares` and :meth:`PaperExperiment.lbfgsb`: the same unknown by
  exact gradients (Levenberg-Marquardt / Gauss-Newton on the log ratio, bounded L-BFGS);
- :meth:`PaperExperiment.error_curve` and :meth:`PaperExperiment.strain_figure`: Figs. 9 and 8.

The data are synthetic (:func:`refine.demo_data.synthetic_bundle`): a larger sheet, clamped and
pulled, solved on a conforming mesh of quadratic triangles, sampled on the grid with Gaussian
noise; the inversion uses linear triangles of another size, so no method can hit the truth
exactly and each converges to the minimiser of its own error measure.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import jax
import numpy as np

import jaxfem as jf

from refine import optimize
from refine.model.objective import Objective
from refine.bundle.io import Bundle
from refine.model.measured import MeasuredModel, domain_mesh
from refine.model.parametrize import RegionModuli
from refine.optimize.result import RefineResult
from refine.optimize import brent_search, cubic_brent_search
from refine.demo_data import Inclusion, Truth, synthetic_bundle

BACKGROUND = 83.76
"""Modulus of the first (background) material, kPa."""
INCLUSION = 837.61
"""Modulus of the embedded rectangle, kPa (the ground truth of eq. 6)."""
BRACKET = (41.88, 1591.44)
"""Bounding interval of the search, kPa: half to twenty times the background."""
MIDDLE_POINTS = (118.80, 1256.40)
"""The paper's deliberately bad middle points b, close to either end (Tables 1 and 2)."""
TOLERANCE = 0.01
"""The paper's tolerance of Brent's method (relative to the parameter)."""
CUBIC_TOLERANCE = 0.001
"""The tolerance of the Brent stage after the cubic fit (the paper: four steps, 838.38 kPa)."""
NAME = "E_inclusion"


@dataclass(frozen=True)
class EmbeddedRectangle:
    """Configuration of the experiment (lengths mm, moduli kPa).

    Attributes:
        roi: the tracked region and the model's domain ``[xmin, ymin, xmax, ymax]``.
        rectangle: the embedded rectangle ``[xmin, ymin, xmax, ymax]``, on grid lines.
        spacing: grid spacing of the tracked points.
        noise: standard deviation of the noise on each displacement component (0: none).
        fractions: frames, as fractions of the final pull.
        pull: final stretch of the sheet.
        data_h: element size of the data-generating quadratic mesh.
        model_h: element size of the inversion's mesh.
        model_element: element type of the inversion's mesh (quadratic triangles make the model's
            discretisation error, ~0.3 % on the modulus at h = 4 mm, much smaller than the noise's).
        seed: seeds the noise and the validation points.
        forces: also write the force across the ROI's right side.
    """

    roi: tuple = (20.0, 10.0, 120.0, 70.0)
    rectangle: tuple = (50.0, 30.0, 80.0, 50.0)
    spacing: float = 10.0
    noise: float = 0.02
    fractions: tuple = (0.5, 1.0)
    pull: float = 0.15
    data_h: float = 3.0
    model_h: float = 4.0
    model_element: str = "tri6"
    seed: int = 0
    forces: bool = False

    @property
    def shape(self) -> jf.Rect:
        return jf.Rect(*self.rectangle)

    def truth(self) -> Truth:
        """What the synthetic data hide: the rectangle at the paper's modulus ratio."""
        return Truth(inclusions=(Inclusion(self.shape, INCLUSION / BACKGROUND),), E=BACKGROUND)

    def bundle(self) -> Bundle:
        """The measurement bundle, generated on a finer, different mesh than the inversion's."""
        return synthetic_bundle(self.truth(), seed=self.seed, roi=self.roi, spacing=self.spacing,
                                noise=self.noise, pull=self.pull, fractions=self.fractions, h=self.data_h,
                                forces=self.forces, name="paper-section-3.1")


class PaperExperiment:
    """The inversion of Sec. 3.1: a model over the ROI with the rectangle as its only unknown.

    Args:
        config: the experiment (default: the paper's moduli, 10 mm grid, 2 frames, noise 0.02 mm).
        bundle: measured data to use instead of generating them from ``config``.

    Attributes:
        model: the :class:`~refine.model.MeasuredModel` (mesh edges follow the rectangle).
        objective: the least-squares :class:`~refine.Objective` on the guide points.
        n_error: number of evaluations of eq. (1) so far (each one forward solve of all frames).
    """

    def __init__(self, config: EmbeddedRectangle | None = None, bundle: Bundle | None = None):
        self.config = config or EmbeddedRectangle()
        self.bundle = bundle if bundle is not None else self.config.bundle()
        ex, obs = self.bundle.experiment, self.bundle.observations
        mesh = domain_mesh(ex, self.config.model_h, self.config.model_element, inclusions=[self.config.shape])
        self.model = MeasuredModel(ex, obs, mesh=mesh)
        self.E0 = ex.E
        self.param = RegionModuli(masks=(mesh.regions == 1)[None], E0=self.E0, names=("inclusion",))
        self.objective = Objective(self.model, self.param)
        self._error = displacement_error_function(self.objective)
        self.n_error = 0

    # ------------------------------------------------------------------ the unknown
    def z(self, modulus: float) -> np.ndarray:
        """Log ratio ``(1,)`` of a region modulus (kPa) to the background."""
        return np.array([np.log(modulus / self.E0)])

    def modulus(self, z) -> float:
        """Region modulus (kPa) of a log ratio."""
        return float(self.E0 * np.exp(np.asarray(z).reshape(-1)[0]))

    def theta(self, modulus: float) -> dict:
        """Solver parameters with the rectangle at ``modulus`` kPa."""
        return self.param.apply(self.objective.theta, self.z(modulus))

    # ------------------------------------------------------------------ the paper's search
    def error(self, modulus: float) -> float:
        """The paper's eq. (1): sum over guide points and frames of |q~ - q| (mm) with the
        rectangle at ``modulus`` kPa. One forward solve of every frame."""
        self.n_error += 1
        return self._error(self.z(modulus))

    def brent(self, middle: float, tol: float = TOLERANCE, bracket=BRACKET, progress: bool = False) -> RefineResult:
        """Brent's method over ``bracket`` from the middle point ``middle`` (kPa) on eq. (1).

        The history is the paper's Table 3: one row per evaluation with the modulus, the error and
        whether the step was golden-section or parabolic.
        """
        return brent_search(self.error, (bracket[0], middle, bracket[1]), tol=tol, name=NAME, progress=progress)

    def cubic(self, tol: float = CUBIC_TOLERANCE, points=4, progress: bool = False) -> RefineResult:
        """The paper's speed-up: a cubic through ``points`` spread over the bracket, then Brent in
        [b - E0, b + E0] around its minimum b."""
        return cubic_brent_search(self.error, BRACKET, self.E0, points=points, tol=tol, name=NAME,
                                  progress=progress)

    def tolerance_table(self, middle: float, tolerances=(0.1, 0.01, 0.001)) -> list[dict]:
        """Like the paper's Tables 1 and 2: for each tolerance, the recovered modulus, the number of
        steps (forward solves) and the distance to the ground truth, %."""
        rows = []
        for tol in tolerances:
            r = self.brent(middle, tol)
            E = r.values[NAME]
            rows.append({"tolerance": tol, NAME: E, "steps": r.n_forward,
                         "off_truth_percent": 100.0 * (E - INCLUSION) / INCLUSION})
        return rows

    # ------------------------------------------------------------------ gradients
    def least_squares(self, method: str = "lm", start: float | None = None, rtol: float = 1e-5,
                      atol: float = 1e-4, progress: bool = False) -> RefineResult:
        """Levenberg-Marquardt (``"lm"``), Gauss-Newton (``"gn"``), the third-order tensor method
        (``"tensor"``, :func:`~refine.optimize.tensor_least_squares`) or Pade steps on the
        equilibrium's series (``"pade"``, :func:`~refine.optimize.pade.pade_least_squares`, order 16) on
        the log ratio, exact derivatives, started from ``start`` kPa (default: the uniform model).
        ``values`` and every history row carry the modulus under ``E_inclusion`` and the misfit
        under ``error``."""
        z0 = self.z(self.E0 if start is None else start)
        if method == "tensor":
            r = optimize.tensor_least_squares(self.objective, z0, order=3, rtol=rtol, progress=progress)
        elif method == "pade":
            bounds = tuple(float(v) for v in np.log(np.asarray(BRACKET) / self.E0))
            r = optimize.pade_least_squares(self.objective, z0, order=16, bounds=bounds, progress=progress)
        else:
            r = optimize.least_squares(self.objective, z0, method=method, rtol=rtol, atol=atol, progress=progress)
        return self._in_kpa(r, "misfit")

    def lbfgsb(self, start: float | None = None, tol: float = 1e-6, maxiter: int = 60,
               progress: bool = False) -> RefineResult:
        """Bounded L-BFGS on the same least-squares objective, the log ratio bounded by the bracket."""
        z0 = self.z(self.E0 if start is None else start)
        bounds = tuple(float(v) for v in np.log(np.asarray(BRACKET) / self.E0))
        r = optimize.lbfgsb(self.objective, z0, bounds=bounds, tol=tol, maxiter=maxiter, progress=progress)
        return self._in_kpa(r, "value")

    def _in_kpa(self, r: RefineResult, misfit_key: str) -> RefineResult:
        rows = []
        for h in r.history:
            row = {"gradient_norm": h["error"], **h} if "value" in h else dict(h)  # L-BFGS-B's "error"
            rows.append({**row, NAME: self.modulus(h["z"]), "error": h[misfit_key]})
        return dataclasses.replace(r, values={NAME: self.modulus(r.values["z"]), **r.values}, history=rows)

    # ------------------------------------------------------------------ figures
    def error_curve(self, moduli) -> np.ndarray:
        """Eq. (1) at each modulus (kPa), ``(n,)`` mm: the paper's Fig. 9."""
        return np.array([self.error(E) for E in np.asarray(moduli, float)])

    def equilibrium(self, modulus: float, frame: int = -1):
        """``(theta, u)``: parameters and nodal displacements ``(n_nodes, 2)`` of one frame."""
        theta = self.theta(modulus)
        U = self.model.solve_frames(theta)
        return theta, np.asarray(U[frame])

    def strain_figure(self, moduli, titles=None, frame: int = -1, ncols: int = 3):
        """Strain maps of the model as the rectangle's modulus changes (the paper's Fig. 8), on a
        common colour scale; returns the matplotlib figure."""
        import matplotlib.pyplot as plt

        from jaxfem.postprocess import equivalent_strain

        moduli = list(moduli)
        strain = jax.jit(lambda u, theta: equivalent_strain(self.model.solver, u, theta))  # op by op: slow
        maps = []
        for E in moduli:
            theta, u = self.equilibrium(E, frame)
            maps.append((u, np.asarray(strain(u, theta))))
        vmax = max(float(m.max()) for _, m in maps)
        nrows = -(-len(moduli) // ncols)
        fig, axes = plt.subplots(nrows, ncols, figsize=(4.6 * ncols, 2.9 * nrows), squeeze=False)
        for k, (ax, E, (u, m)) in enumerate(zip(axes.flat, moduli, maps)):
            title = titles[k] if titles else f"E = {E:.1f} kPa"
            jf.plot.cell_map(self.model.mesh, m, u=u, ax=ax, vmin=0.0, vmax=vmax, title=title,
                             label="equivalent strain")
        for ax in list(axes.flat)[len(moduli):]:
            ax.axis("off")
        fig.tight_layout()
        return fig


def displacement_error_function(objective: Objective):
    """The paper's eq. (1) as a function of the unknowns z of ``objective``: the sum over its
    points and all frames of |q~ - q| (length unit); lost points are skipped. One compiled
    forward solve of every frame per call (the prediction is jitted once)."""
    predict = jax.jit(objective.predict)
    measured = np.where(objective.valid[..., None], np.asarray(objective.measured), np.nan)

    def error(z) -> float:
        pred = np.asarray(predict(np.asarray(z, float)))[:, objective.points]
        return float(np.nansum(np.linalg.norm(pred - measured, axis=-1)))

    return error


def solves_to_reach(result: RefineResult, reference: float, rel: float = 1e-3, key: str = NAME):
    """Forward solves a method needed until its best estimate of ``key`` stayed within ``rel`` of
    ``reference`` for good; None if it never did. See :func:`evaluations_to_reach`."""
    rows = result.history
    return evaluations_to_reach([r["error"] for r in rows], [[r[key]] for r in rows], [reference], rel)


def evaluations_to_reach(errors, estimates, reference, rel: float = 1e-3):
    """Number of evaluations after which the best point so far stays within ``rel`` (relative, in
    every component) of ``reference``; None if it never does.

    Args:
        errors: ``(n,)`` objective value of each evaluation, in order.
        estimates: ``(n, k)`` the parameters evaluated (moduli, say).
        reference: ``(k,)`` the converged parameters.

    The best point after k evaluations is the one with the lowest error among the first k (for
    Brent the current x, for least squares the last accepted step); fit points of the cubic
    count like any other evaluation.
    """
    ref = np.asarray(reference, float)
    best, best_err, inside_since = None, np.inf, None
    for k, (err, est) in enumerate(zip(errors, estimates), start=1):
        if err < best_err:
            best, best_err = np.asarray(est, float), err
        close = best is not None and bool(np.all(np.abs(best - ref) <= rel * np.abs(ref)))
        inside_since = (inside_since or k) if close else None
    return inside_since


def format_rows(rows: list[dict]) -> str:
    """A list of dicts as a fixed-width table (the tolerance tables)."""
    return RefineResult(values={}, error=0.0, n_forward=0, history=rows).format_table()


def report(experiment: PaperExperiment | None = None, file=None) -> dict:
    """Run the whole Sec. 3.1 reproduction and print its tables; returns the results by name."""
    ex = experiment or PaperExperiment()
    out = {}
    for k, b in enumerate(MIDDLE_POINTS, start=1):
        print(f"\nTable {k}: b = {b:.2f} kPa (ground truth {INCLUSION} kPa)", file=file)
        out[f"table{k}"] = rows = ex.tolerance_table(b)
        print(format_rows(rows), file=file)
    for b in MIDDLE_POINTS:
        out[f"brent_{b:g}"] = r = ex.brent(b)
        print(f"\nIterations for b = {b:.2f} kPa, tolerance {TOLERANCE} (Table 3 is b = 1256.40)", file=file)
        r.table(file=file)
    out["cubic"] = r = ex.cubic()
    print("\nCubic fit, then Brent at tolerance 0.001", file=file)
    r.table(file=file)
    for method in ("lm", "gn"):
        out[method] = r = ex.least_squares(method)
        print(f"\n{r}", file=file)
    return out
