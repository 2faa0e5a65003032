"""Standard errors of every fitted quantity of a shape (centre, axes or half sides, angle, area,
relative elasticity), propagated from the covariance of the fitted unknowns.

A fit's unknowns z are not the quantities a report gives: a region's are its log ratio and the
changes of its shape (for an ellipse the entries of a symmetric matrix, for a rectangle its half
sides and a scaled angle; :class:`~refine.model.parametrize.ShapeGeometry`). The covariance of z
(Gauss-Newton, :func:`~refine.diagnosis.fitted.covariance`) is carried to the reported
quantities through the hypothesis' own map from z to shapes (``shapes_at``, cheap: no solve):
by draws of z (:func:`sampled_variance`), since the map is not linear where it matters (an
ellipse's axes near a circle, a ratio ``exp(z)`` with a wide log error); the delta method,
``C_q = G C_z G^T`` with ``G = dq/dz`` by central differences (:func:`quantity_jacobian`), is
its first order and stands in where the covariance is not finite. An ellipse's or a hole's
orientation error is taken at the unbiased estimate of its elongation
(:func:`orientation_variance`): noise makes a fitted near-circle more elongated than the truth.

The model is driven by the measured boundary points, which carry the same noise as the points it is
fitted to: errors in the variables, which the Gauss-Newton covariance ``(J^T J)^-1`` of the fitting
points alone leaves out. :func:`drive_covariance` adds what the drive's noise does to the fitted
unknowns, to first order: ``dz = -(J^T J)^-1 J^T (dr/dB) dB`` with ``Cov(dB) = sigma_B^2 I``, so
``C_drive = sigma_B^2 M M^T``, ``M = (J^T J)^-1 J^T dr/dB``; ``dr/dB`` exactly, by forward-mode
derivatives of the prediction with respect to the boundary motion (one back-substitution per
boundary value and frame at the converged state).

Noise is not the only error: the model is discretised twice, by its mesh and by its drive (the
boundary motion between the boundary points is interpolated along the outline).
:func:`with_discretisation` refits the chosen hypothesis from its fitted shapes on a mesh sqrt(2)
times coarser (:func:`discretisation_bias`) and driven by every other boundary point
(:func:`drive_bias`); each change is Richardson's estimate of the final model's error (both of
order h^2 or spacing^2). Their quadrature is reported beside the standard error and added to it
in quadrature (:func:`total_errors`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from jaxtyping import Bool, Float

from refine.diagnosis.valley import ratio_draws
from refine.measures import Residuals

QUANTITIES = ("cx", "cy", "a", "b", "angle", "area", "ratio")
"""What :func:`shape_quantities` gives per shape, in this order (lengths in the bundle's unit,
the angle in radians, the area in length squared, the ratio dimensionless)."""


@dataclass(frozen=True)
class ShapeErrors:
    """Standard errors of one fitted shape's reported quantities (None: not fitted, e.g. a hole's
    ratio, which is 0 by definition).

    Attributes:
        centroid: ``(x, y)``; axes: semi-axes or half sides ``(a, b)``; angle: radians; area:
        length squared; relative_elasticity: the ratio's (dimensionless).
    """

    centroid: tuple[float, float]
    axes: tuple[float, float]
    angle: float
    area: float
    relative_elasticity: float | None

    def to_json(self, digits: int = 4) -> dict:
        """report.json's ``std`` entry of a finding (rounded to ``digits`` decimals)."""
        r = lambda v: None if v is None or not np.isfinite(v) else round(float(v), digits)  # noqa: E731
        return {"centroid": [r(v) for v in self.centroid], "axes": [r(v) for v in self.axes],
                "angle": r(self.angle), "area": r(self.area), "relative_elasticity": r(self.relative_elasticity)}


def shape_quantities(shapes) -> Float[np.ndarray, "shapes 7"]:
    """The reported quantities of ``shapes`` (:class:`~refine.diagnosis.shapes.RegionShape` or
    ``Hole``), one row of :data:`QUANTITIES` each (a hole's ratio is 0). A shape with an axis
    that is not positive (a draw of :func:`sampled_variance` past a vanishing axis: no fit
    reaches one) has the signed area of the same formula, ``pi a b`` (``4 a b`` for a
    rectangle): the map from the fitted unknowns carried on smoothly, not an error."""
    rows = []
    for s in shapes:
        if min(s.axes) > 0:
            area, _ = s.outline()
        else:
            area = (4.0 if s.kind == "rectangle" else np.pi) * s.axes[0] * s.axes[1]
        rows.append([*s.centre, *s.axes, s.angle, area, float(s.ratio)])
    return np.asarray(rows, float)


def quantity_jacobian(fitted, step: float = 1e-6) -> Float[np.ndarray, "q k"]:
    """``d quantities / dz`` ``(7 n_shapes, k)`` at the fitted unknowns, by central differences
    of ``fitted.hypothesis.shapes_at`` (angle differences wrapped to half a turn, so a step never
    reads as a flip of the orientation)."""
    h, compiled, z = fitted.hypothesis, fitted.compiled, np.asarray(fitted.z, float)
    G = np.zeros((len(QUANTITIES) * len(fitted.shapes), z.size))
    for j in range(z.size):
        dz = np.zeros_like(z)
        dz[j] = step * max(1.0, abs(z[j]))
        hi, lo = (shape_quantities(h.shapes_at(compiled, z + s * dz)) for s in (1, -1))
        d = hi - lo
        d[:, 4] = np.angle(np.exp(1j * d[:, 4] * 2)) / 2  # an orientation is defined modulo pi
        G[:, j] = d.ravel() / (2 * dz[j])
    return G


def shape_errors(fitted) -> list[ShapeErrors] | None:
    """Standard errors of every fitted shape's quantities (:class:`ShapeErrors`, in the order of
    ``fitted.shapes``), or None where the fit has no covariance (``fitted.z_cov``, set by
    :func:`~refine.diagnosis.fitted.refit`) or no shapes."""
    cov = getattr(fitted, "z_cov", None)
    if cov is None or not getattr(fitted, "shapes", ()) or getattr(fitted, "compiled", None) is None:
        return None
    G = quantity_jacobian(fitted)
    var = np.einsum("qk,kl,ql->q", G, cov, G).reshape(len(fitted.shapes), len(QUANTITIES))
    sampled = sampled_variance(fitted, cov, G=G)
    if sampled is not None:
        var = np.where(np.isnan(sampled), var, sampled)  # inf: a ratio the data bound from below only
    std = np.sqrt(np.clip(var, 0, None))
    return [errors_of(s, shape) for s, shape in zip(std, fitted.shapes)]


SAMPLES = 1000
"""Draws of the fitted unknowns in :func:`sampled_variance` (a relative error of about 2 % in a
standard error; fixed seed, so a report is reproducible)."""


def sampled_variance(fitted, cov: Float[np.ndarray, "k k"], draws: int = SAMPLES, seed: int = 0,
                     G: Float[np.ndarray, "q k"] | None = None) -> Float[np.ndarray, "shapes 7"] | None:
    """The mean square change of every reported quantity (:data:`QUANTITIES`, one row per shape)
    when the fitted unknowns z are drawn from ``N(z, cov)`` and carried through the hypothesis'
    own map to shapes (``shapes_at``: no solve): the delta method without its linearisation.

    The map is far from linear where it matters: an ellipse's semi-axes are the eigenvalues of
    the fitted matrix M (:class:`~refine.model.parametrize.ShapeGeometry`), and near a circle (a
    stiff circle, a round hole) noise on M splits them in every direction, while the delta
    method sees only the split along the fitted axes (on a noisy circle it covered 90 % of the
    truths within 2 errors, the draws 97 %); a region's ratio trades against its size along a
    bent valley, so its draws take the region's strength as drawn (:func:`~refine.diagnosis.valley.
    ratio_draws`) and its error is half the change that 95.45 % of them stay within, as 2
    errors of a Gaussian (infinite where more than 4.55 % reach a rigid region: the data then
    bound the ratio from below only). Angle changes wrapped to half a turn; an ellipse's or a hole's orientation's
    spread taken at the unbiased estimate of its elongation (:func:`orientation_variance`).
    None where ``cov`` is not finite. ``G``: :func:`quantity_jacobian` of ``fitted`` where the
    caller has it."""
    cov = np.asarray(cov, float)
    z = np.asarray(fitted.z, float)
    if not np.all(np.isfinite(cov)):
        return None
    w, V = np.linalg.eigh((cov + cov.T) / 2)
    root = V * np.sqrt(np.clip(w, 0, None))
    dz = np.random.default_rng(seed).standard_normal((draws, z.size)) @ root.T
    q0 = shape_quantities(fitted.shapes)
    q = np.stack([shape_quantities(fitted.hypothesis.shapes_at(fitted.compiled, z + e)) for e in dz])
    G = quantity_jacobian(fitted) if G is None else G
    q[..., 6] = ratio_draws(q0, q, G, dz)  # along the size-ratio valley
    d = q - q0
    d[..., 4] = np.angle(np.exp(2j * d[..., 4])) / 2  # an orientation is defined modulo pi
    var = np.mean(d**2, axis=0)
    var[:, 6] = (np.quantile(np.abs(d[..., 6]), 0.9545, axis=0, method="higher") / 2) ** 2  # skewed: 2 errors hold 95.45 %
    oval = np.array([s.kind != "rectangle" for s in fitted.shapes])
    var[oval, 4] = orientation_variance(q0[oval], q[:, oval])
    return var


def orientation_variance(q0: Float[np.ndarray, "shapes 7"], q: Float[np.ndarray, "draws shapes 7"]
                         ) -> Float[np.ndarray, "shapes"]:
    """The mean square change of an ellipse's orientation (radians^2) over draws ``q`` of its
    quantities (:data:`QUANTITIES`) about the fit ``q0``, taken at the unbiased estimate of its
    elongation rather than at the fitted one.

    The orientation is half the direction of the ellipse's deviator ``v = (a - b) / 2 (cos 2t,
    sin 2t)`` (``M``'s ``((M11 - M22) / 2, M12)``), and noise lengthens a deviator on average:
    ``E|v_fit|^2 = |v|^2 + tr C_v``. Near a circle a fit is therefore more elongated than the
    truth, and draws about it turn its orientation less than the data allow (on a Gaussian
    deviator of true length 0.7 / 1 / 1.5 noise stds, draws about the fit covered the angle
    within 2 errors 83 / 88 / 92 % of the time; about the unbiased length ``sqrt(|v_fit|^2 -
    tr C_v)`` 95 / 95 / 97 %, and 86 % at a circle, where the orientation has no truth). So each
    draw's change of the deviator, ``v_draw - v_fit``, is added to the fitted deviator shortened
    to that length (to zero where ``tr C_v`` exceeds ``|v_fit|^2``: an orientation the data do
    not fix, whose draws then spread over every direction, an error of about pi / sqrt(12));
    far from a circle it is the draws' own spread."""
    def deviator(x):
        return 0.5 * (x[..., 2] - x[..., 3])[..., None] * np.stack([np.cos(2 * x[..., 4]), np.sin(2 * x[..., 4])], -1)

    v0 = deviator(q0)
    e = deviator(q) - v0
    length2 = np.sum(v0**2, axis=-1)
    shorter = np.sqrt(np.clip(length2 - np.mean(np.sum(e**2, axis=-1), axis=0), 0, None) / np.where(length2 > 0, length2, 1))
    c = v0 * shorter[:, None] + e
    # turns from the fitted deviator's direction: 2t, or 2t + pi where b > a
    fitted = np.where(length2 > 0, (v0[:, 0] + 1j * v0[:, 1]) / np.sqrt(np.where(length2 > 0, length2, 1)),
                      np.exp(2j * q0[:, 4]))
    turn = np.angle((c[..., 0] + 1j * c[..., 1]) * np.conj(fitted)) / 2
    return np.mean(turn**2, axis=0)


def errors_of(row: Float[np.ndarray, "7"], shape) -> ShapeErrors:
    """``row`` (one value per :data:`QUANTITIES`) as the :class:`ShapeErrors` of ``shape`` (a
    hole's ratio error None)."""
    return _from_row(row, shape.kind != "hole")


def _from_row(row: Float[np.ndarray, "7"], with_ratio: bool) -> ShapeErrors:
    """``row`` (one value per :data:`QUANTITIES`) as a :class:`ShapeErrors` (the ratio's error
    None unless ``with_ratio``)."""
    return ShapeErrors((row[0], row[1]), (row[2], row[3]), row[4], row[5], row[6] if with_ratio else None)


def as_row(e: ShapeErrors) -> Float[np.ndarray, "7"]:
    """A :class:`ShapeErrors` as one value per :data:`QUANTITIES` (NaN where None)."""
    return np.array([*e.centroid, *e.axes, e.angle, e.area,
                     np.nan if e.relative_elasticity is None else e.relative_elasticity], float)


def drive_sensitivity(fitted, points: Bool[np.ndarray, "n_points"], sigma: float
                      ) -> Float[np.ndarray, "k frames_x_boundary"]:
    """``M = (J^T J)^-1 J^T dr/dB`` ``(k, n_frames * n_boundary * dim)``: the fitted unknowns z
    move by ``-M dB`` when the driving boundary displacements (:meth:`MeasuredModel.measured_boundary`,
    flattened frame by frame) move by ``dB``, to first order, for a fit on ``points`` weighted
    by ``sigma`` (length unit). ``J^T dr/dB`` by reverse mode, one pull-back per unknown (an
    adjoint solve per frame each; forward mode would take a tangent solve per boundary value,
    ~450 per frame for 3,000 points, a thousand and more for a 3D model): on the solver's shared
    programs where the model shares them (:meth:`MeasuredModel.boundary_vjp`), else through the
    model's own solve; NaN where ``J^T J`` is singular."""
    model = fitted.compiled.model
    res = Residuals.at(model.obs.displacements, points, sigma)
    J = res.jacobian(np.asarray(fitted.compiled.jacobian(fitted.z)))
    if model.shares_programs:
        JtJB = _pulled_shared(model, res, fitted.theta, J)
    else:
        JtJB = _pulled_boundary(model, res, fitted.theta, J)
    try:
        return np.linalg.solve(J.T @ J, JtJB)
    except np.linalg.LinAlgError:
        return np.full(JtJB.shape, np.nan)


def _pulled_shared(model, res, theta, J) -> np.ndarray:
    """``J^T dr/dB`` ``(k, n_frames * n_boundary * dim)`` on the solver's shared programs: the
    residuals' cotangents ``J (n, k)`` (rows frame after frame over the tracked matched points,
    weighted by ``res.sigma``) pulled back to the drive by :meth:`MeasuredModel.boundary_vjp`
    (one adjoint solve per unknown and frame, not a tangent solve per boundary value)."""
    obs = model.obs.displacements
    k, dim = J.shape[1], obs.shape[-1]
    at = np.zeros((k,) + res.valid.shape + (dim,))
    at[:, res.valid] = J.T.reshape(k, -1, dim) / res.sigma
    C = np.zeros((k,) + obs.shape)
    C[:, :, res.points] = at
    return model.boundary_vjp(theta, C).reshape(k, -1)


def _pulled_boundary(model, res, theta, J) -> np.ndarray:
    """``J^T dr/dB`` ``(k, n_frames * n_boundary * dim)`` by reverse mode through the model's own
    solve: one pull-back per column of ``J (n, k)``."""
    import jax
    import jax.numpy as jnp

    def pulled(b, cotangents):  # (k, n) -> (k, *b.shape): the rows of J^T dr/dB
        _, pull = jax.vjp(lambda bb: res.weighted(model.predict(theta, boundary=bb)), b)
        return jax.vmap(lambda c: pull(c)[0])(cotangents)

    JtJB = np.asarray(jax.jit(pulled)(jnp.asarray(model.measured_boundary()), jnp.asarray(J.T)))
    return JtJB.reshape(J.shape[1], -1)


def drive_covariance(fitted, points: Bool[np.ndarray, "n_points"], sigma: float,
                     sigma_drive: float | None = None) -> Float[np.ndarray, "k k"]:
    """Covariance ``(k, k)`` of the fitted unknowns z due to noise on the boundary points that
    drive the model, ``sigma_drive^2 M M^T`` (:func:`drive_sensitivity`; see the module's
    docstring), for a fit on ``points`` weighted by ``sigma`` (length unit). ``sigma_drive``: the
    boundary points' noise std (length unit; default the bundle's ``noise_std``, else
    ``sigma``); 0 gives zeros."""
    k = len(fitted.z)
    if sigma_drive is None:
        given = fitted.compiled.model.experiment.noise_std
        sigma_drive = sigma if given is None else given
    if not sigma_drive > 0:
        return np.zeros((k, k))
    M = drive_sensitivity(fitted, points, sigma)
    return sigma_drive**2 * (M @ M.T)


def discretisation_bias(fitted, points: Bool[np.ndarray, "n_points"], hold: Bool[np.ndarray, "n_points"],
                        sigma: float, factor: float = np.sqrt(2.0), order: float = 2.0, signed: bool = False
                        ) -> Float[np.ndarray, "shapes 7"] | None:
    """An estimate of the discretisation error of every reported quantity (:data:`QUANTITIES`,
    one row per shape, absolute values): Richardson's, the change of the quantity when the same
    hypothesis is refitted from its fitted shapes on a mesh ``factor`` times coarser, over
    ``factor^order - 1``: with ``factor = sqrt(2)`` and the rate ``order = 2`` of the energy norm
    of quadratic triangles, the change itself. None where the hypothesis has no shapes to remesh
    at, or the coarse refit fails. Costs one more fit (on the coarser, cheaper mesh). ``signed``:
    the estimate with its sign (fine less the extrapolated value: the fit's own error)."""
    from dataclasses import replace

    from refine.diagnosis.fitted import fit

    if not getattr(fitted, "shapes", ()) or not fitted.hypothesis.remeshable:
        return None
    try:
        coarse = replace(fitted.hypothesis.at(fitted.shapes, fitted.model.mesh.element), h=factor * fitted.model.h)
        g = fit(coarse, points, hold, sigma)
    except Exception:  # noqa: BLE001 - a coarse mesh that cannot hold the shapes gives no estimate
        return None
    return _richardson(fitted.shapes, g.shapes, factor, order, signed)


def _richardson(fine, coarse, factor: float, order: float, signed: bool = False) -> Float[np.ndarray, "shapes 7"]:
    """Richardson's estimate of the error of the ``fine`` fit's shapes' quantities
    (:data:`QUANTITIES`, absolute values) from the same shapes fitted with a discretisation
    ``factor`` times coarser (``coarse``), for errors of ``order``: the change over
    ``factor^order - 1``; ``signed``: with its sign, as the fine fit's error (fine less the
    extrapolated value), so ``fine - estimate`` is Richardson's extrapolation."""
    d = shape_quantities(coarse) - shape_quantities(fine)
    d[:, 4] = np.angle(np.exp(2j * d[:, 4])) / 2  # an orientation is defined modulo pi
    return (d if signed else np.abs(d)) / (factor**order - 1.0)


def with_discretisation(fitted, points: Bool[np.ndarray, "n_points"], hold: Bool[np.ndarray, "n_points"],
                        sigma: float, pool=None):
    """``fitted`` (a :class:`~refine.diagnosis.fitted.Fitted` with its shapes' standard errors)
    with ``q_disc``, the discretisation error of every shape's quantities, set: the mesh's
    (:func:`discretisation_bias`) and the drive's (:func:`drive_bias`) in quadrature, two more
    fits; ``q_disc_parts`` ``{"mesh": rows, "drive": rows}``; and ``q_disc_signed``, the mesh's
    estimate with its sign (the coarser refit's change over ``factor^order - 1``: a hole's area
    extrapolated from it, :func:`refine.solid.hole_area.extrapolated_area`). Unchanged where there is none
    to give (no shapes, or both refits fail). ``pool``: an executor (e.g. the diagnosis's
    threads) that fits the coarser mesh while this thread fits the sparser drive (their solves
    take the shared program's lock in turn; what overlaps is the rest: meshing, the fits' host
    side; the same figures as one after the other); None: one after the other."""
    from dataclasses import replace

    mesh = pool.submit(discretisation_bias, fitted, points, hold, sigma, signed=True) if pool is not None else None
    drive = drive_bias(fitted, points, hold, sigma)
    signed = mesh.result() if mesh is not None else discretisation_bias(fitted, points, hold, sigma, signed=True)
    parts = {"mesh": None if signed is None else np.abs(signed), "drive": drive}
    given = [d for d in parts.values() if d is not None]
    if not given:
        return fitted
    total = np.sqrt(sum(np.nan_to_num(d) ** 2 for d in given))
    total[np.all([np.isnan(d) for d in given], axis=0)] = np.nan
    return replace(fitted, q_disc=total, q_disc_parts={k: d for k, d in parts.items() if d is not None},
                   q_disc_signed=signed)


def discretisation_errors(fitted) -> list[ShapeErrors] | None:
    """The discretisation errors ``fitted.q_disc`` as one :class:`ShapeErrors` per shape (None
    where not estimated, :func:`with_discretisation`)."""
    d = getattr(fitted, "q_disc", None)
    if d is None:
        return None
    return [errors_of(row, shape) for row, shape in zip(d, fitted.shapes)]


def total_errors(std: ShapeErrors | None, disc: ShapeErrors | None) -> ShapeErrors | None:
    """The total error of each quantity: its standard error (noise of the fitted points and of
    the drive) and its discretisation error in quadrature (one kind missing: the other alone).
    Both are read as standard deviations, so about 95 % of truths lie within 2 total errors
    where the discretisation error is estimated as well as its size suggests."""
    if std is None or disc is None:
        return std if disc is None else disc
    a, b = as_row(std), as_row(disc)
    row = np.where(np.isnan(b), a, np.hypot(a, np.nan_to_num(b)))
    return _from_row(row, std.relative_elasticity is not None)


def sparser_drive(obs, step: int = 2):
    """``obs`` with only every ``step``-th boundary point along the outline still driving (the
    others become validation points, not fitted): the drive of a model whose boundary points are
    ``step`` times further apart. Boundary points ordered by their angle about their centroid (a
    sheet's outline; 2D only)."""
    from dataclasses import replace

    idx = np.flatnonzero(obs.roles == "boundary")
    X = np.asarray(obs.reference)[idx]
    c = X.mean(axis=0)
    order = idx[np.argsort(np.arctan2(X[:, 1] - c[1], X[:, 0] - c[0]))]
    roles = np.array(obs.roles, dtype=object)
    roles[order[np.arange(order.size) % step != 0]] = "validate"
    return replace(obs, roles=roles.astype(str))


def drive_bias(fitted, points: Bool[np.ndarray, "n_points"], hold: Bool[np.ndarray, "n_points"], sigma: float,
               step: int = 2, order: float = 2.0, signed: bool = False) -> Float[np.ndarray, "shapes 7"] | None:
    """An estimate of the error the drive's discretisation leaves in every reported quantity
    (:data:`QUANTITIES`, one row per shape, absolute values): the model is driven between the
    boundary points by interpolating them along the outline, which misses the boundary motion's
    curvature between them (an error of order spacing^2, however fine the mesh). Richardson's
    estimate from a refit, at the fitted shapes on the same mesh size, driven by every
    ``step``-th boundary point: the change over ``step^order - 1``. None where the hypothesis
    has no shapes, the model is not 2D or the refit fails. Costs one more fit. ``signed``: with its
    sign (:func:`_richardson`)."""
    from dataclasses import replace

    from refine.diagnosis.fitted import fit
    from refine.model.measured import MeasuredModel

    h = fitted.hypothesis
    if not getattr(fitted, "shapes", ()) or not h.remeshable or np.asarray(fitted.model.obs.reference).shape[1] != 2:
        return None
    try:
        base = h.base
        sparse = MeasuredModel(base.experiment, sparser_drive(base.obs, step), h=base.h,
                               linear_solver=base.linear_solver)
        g = fit(replace(h.at(fitted.shapes, fitted.model.mesh.element), base=sparse, h=fitted.model.h),
                points, hold, sigma)
    except Exception:  # noqa: BLE001 - too few boundary points left, or a refit that fails: no estimate
        return None
    return _richardson(fitted.shapes, g.shapes, step, order, signed)
