"""A motion of the hand, frame by frame, and the strain of its skin (the paper's Sec. 5 analysis).

A :class:`Motion` takes joint angles from 0 to their full range in ``frames`` equal steps; each
frame is solved by Newton (with its own load stepping and cut-backs) from the last frame's
equilibrium. Per frame, the skin strain: the cell under each skin facet, its Green-Lagrange strain
projected on the facet's tangent plane, the larger of its two principal values (how far the skin is
stretched there); the frame's maximum over the skin; the displacement of the motion's marked point.
The curve max strain vs displacement is what the paper plots (its threshold, where the strain's
growth rate changes at 80-90 % of the motion, is found by a detector passed as ``detector``: see
:func:`run_motion`).

An *area of interest* (a mask of skin facets, :func:`skin_area`: e.g. the wrist's skin or a
region around a scar) gives a second maximum, ``area_max_strain``, taken over that skin only: the
paper "ignored strains other than in the area of interest". The box-like hand's re-entrant edges
(the palm overhanging the wrist) concentrate strain in a mesh-dependent way, so the full-skin
maximum (``max_strain``, kept) sits there and barely feels a scar. The strain limit and the
threshold detector use the area's curve where an area is given.

A motion is *restricted* when it cannot reach its full range: Newton fails at every cut-back (the
reachable fraction is where the last load step converged), or the maximum strain (over the area of
interest, if given) passes a stated ``strain_limit`` (the fraction where the curve crosses it,
linearly between frames).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from jaxfem.exceptions import ProblemError, SolverError
from jaxfem.postprocess import green_lagrange_strain
from jaxfem.shapes import Ellipse
from .body import Box
from .model import HandModel, Scar


@dataclass(frozen=True)
class Motion:
    """Joint ``angles`` at the motion's full range ``{angle name: degrees}``, the ``mark`` whose
    displacement is the curve's abscissa (a name of the body's marks) and the number of ``frames``.
    ``schedule``: the share of the full range at frames ``1..frames`` (increasing, ending at 1; a
    motion that speeds up or slows down); ``None``: equal steps ``k / frames``."""

    name: str
    angles: dict
    mark: str
    frames: int = 10
    schedule: tuple | None = None

    def __post_init__(self):
        if self.frames < 1 or not self.angles:
            raise ProblemError(f"motion {self.name!r} needs at least one frame and one joint angle")
        if self.schedule is not None:
            s = np.asarray(self.schedule, float)
            if s.shape != (self.frames,) or not (np.all(np.diff(np.r_[0.0, s]) > 0) and np.isclose(s[-1], 1.0)):
                raise ProblemError(f"motion {self.name!r}: the schedule needs {self.frames} shares of the full range "
                                   f"(one per frame), increasing from above 0 to 1; got {self.schedule}")
            object.__setattr__(self, "schedule", tuple(s.tolist()))

    def share(self, k: int) -> float:
        """The share of the full range at frame ``k`` (0: rest)."""
        if k == 0:
            return 0.0
        return self.schedule[k - 1] if self.schedule is not None else k / self.frames


def standard_motions(body, frames: int = 10) -> dict:
    """The paper's three motions for a :func:`~examples.hand.default_body` hand: thumb flexion (base
    45 and tip 60 degrees towards the palm), the wrist bent to the side (30 degrees, towards the
    little finger) and up (45 degrees, the back of the hand up); the wrist's marked point is the
    first finger's tip."""
    tip = next(n for n in body.marks if n != "thumb tip")
    return {m.name: m for m in (
        Motion("thumb flexion", {"thumb_1": 45.0, "thumb_2": 60.0}, "thumb tip", frames),
        Motion("wrist side-to-side", {"wrist_deviation": 30.0}, tip, frames),
        Motion("wrist up-down", {"wrist_flexion": 45.0}, tip, frames))}


@dataclass(frozen=True, eq=False)
class MotionResult:
    """What a motion did, per frame ``k = 0..K`` (frame 0 is the rest state; only frames reached).

    Attributes:
        motion: the :class:`Motion`; scar: the :class:`Scar` or ``None``.
        fraction: share of the full range per frame ``(K + 1,)``; time: share of the motion's
            frames ``k / frames`` (its duration; equals ``fraction`` without a schedule).
        displacement: the marked point's displacement magnitude, mm ``(K + 1,)``.
        max_strain: the skin's largest principal Green-Lagrange strain, over all the skin ``(K + 1,)``.
        area_max_strain: that maximum over the area of interest (``max_strain`` without one) ``(K + 1,)``;
            area: the area's skin-facet mask ``(n_skin,)`` or ``None``.
        skin_strain: that strain per skin facet ``(K + 1, n_skin)``; equivalent: the cells' von Mises
            equivalent strain ``(K + 1, n_cells)``; u: displacements ``(K + 1, n_nodes, 3)``, mm.
        seconds, iterations: wall seconds and Newton iterations per solved frame ``(K,)``.
        reached: the share of the full range reached (1: all of it); limited_by: ``None``,
            ``"solver"`` or ``"strain limit"``; strain_limit: the limit applied to ``area_max_strain``
            (or ``None``).
        threshold: what the ``detector`` of :func:`run_motion` returned (``None`` without one).
    """

    motion: Motion
    scar: Scar | None
    fraction: np.ndarray
    time: np.ndarray
    displacement: np.ndarray
    max_strain: np.ndarray
    area_max_strain: np.ndarray
    area: np.ndarray | None
    skin_strain: np.ndarray
    equivalent: np.ndarray
    u: np.ndarray
    seconds: np.ndarray
    iterations: np.ndarray
    reached: float = 1.0
    limited_by: str | None = None
    strain_limit: float | None = None
    threshold: object = field(default=None)

    @property
    def restricted(self) -> bool:
        return self.reached < 1.0


def skin_strain_function(model: HandModel):
    """A jitted ``(u, theta) -> (skin strain (n_skin,), equivalent strain (n_cells,))``."""
    hand = model.hand
    n = hand.skin_normals()
    X = hand.mesh.nodes[hand.skin_facets[:, :2]]
    t1 = X[:, 1] - X[:, 0]
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    T = jnp.asarray(np.stack([t1, np.cross(n, t1)], -1))  # (n_skin, 3, 2)
    owner = jnp.asarray(hand.skin_cells)

    @jax.jit
    def strains(u, theta):
        E = green_lagrange_strain(model.solver, u, theta)
        Es = jnp.einsum("fia,fij,fjb->fab", T, E[owner], T)
        dev = E - jnp.trace(E, axis1=1, axis2=2)[:, None, None] * jnp.eye(3) / 3.0
        return jnp.linalg.eigvalsh(Es)[:, -1], jnp.sqrt(2.0 / 3.0 * jnp.sum(dev * dev, axis=(1, 2)))

    return strains


def skin_area(hand, region) -> np.ndarray:
    """The skin facets whose centre lies in ``region``, ``(n_skin,)`` bool: a :class:`~examples.hand.Box`
    (mm, 3D) or an :class:`~jaxfem.Ellipse` in the (x, y) plane (any z: both sides of the hand).

    Raises:
        ProblemError: a region of another kind, or one that holds no skin facet's centre.
    """
    c = hand.mesh.nodes[hand.skin_facets[:, :3]].mean(axis=1)
    if isinstance(region, Box):
        mask = region.contains(c)
    elif isinstance(region, Ellipse):
        mask = np.asarray(region.contains(c[:, :2]), bool)
    else:
        raise ProblemError(f"an area of interest is a examples.hand.Box or a jaxfem.Ellipse, got {type(region).__name__}")
    if not mask.any():
        raise ProblemError(f"the area of interest {region} holds no skin facet's centre at h = {hand.h:g} mm; "
                           "enlarge it or move it onto the skin")
    return mask


def reachable(fraction, max_strain, limit: float) -> float:
    """The share of the motion reached before ``max_strain`` first passes ``limit`` (linear between
    frames; the last frame's share if it never does). ``fraction``, ``max_strain``: ``(K + 1,)``."""
    over = np.flatnonzero(np.asarray(max_strain) > limit)
    if over.size == 0:
        return float(fraction[-1])
    k = int(over[0])
    if k == 0:
        return 0.0
    s0, s1, e0, e1 = fraction[k - 1], fraction[k], max_strain[k - 1], max_strain[k]
    return float(s0 + (limit - e0) / (e1 - e0) * (s1 - s0))


def run_motion(model: HandModel, motion: Motion, scar: Scar | None = None, strain_limit: float | None = None,
               detector=None, strains=None, area=None, against: str = "displacement") -> MotionResult:
    """Move the hand through ``motion`` (with ``scar``, if given) and measure its skin.

    Args:
        strain_limit: the largest skin strain allowed (over ``area``, if given); the motion is
            restricted where it passes.
        detector: the strain-threshold detector, ``(abscissa (K + 1,), area_max_strain (K + 1,)) ->
            anything`` (e.g. the threshold with its uncertainty); its result is ``threshold``. This
            is the hook for refine's detector (``refine.threshold.ThresholdRule.find``): jaxfem has
            none of its own. The abscissa is the marked point's ``"displacement"`` (the paper's
            curve), or ``"time"`` (the share of the motion's frames) or ``"fraction"`` (of the
            joint angles' range), as ``against`` says.
        strains: a :func:`skin_strain_function` of ``model`` to reuse (made here otherwise).
        area: the area of interest, a skin-facet mask ``(n_skin,)`` (:func:`skin_area`) or ``None``
            (all the skin).
    """
    if against not in ("displacement", "time", "fraction"):
        raise ProblemError(f"against must be 'displacement', 'time' or 'fraction', got {against!r}")
    if area is not None and np.shape(area) != (len(model.hand.skin_facets),):
        raise ProblemError(f"the area of interest must be a mask of the {len(model.hand.skin_facets)} skin facets "
                           f"(examples.hand.skin_area), got shape {np.shape(area)}")
    unknown = set(motion.angles) - set(model.hand.body.angle_names)
    if unknown or motion.mark not in model.hand.marks:
        raise ProblemError(f"motion {motion.name!r} names angles {sorted(unknown)} or a mark {motion.mark!r} the "
                           f"hand lacks; angles: {model.hand.body.angle_names}, marks: {sorted(model.hand.marks)}")
    strains = strains or skin_strain_function(model)
    solver, mark = model.solver, model.hand.marks[motion.mark]
    full = {k: np.radians(v) for k, v in motion.angles.items()}
    theta = model.params({}, scar)
    u = jnp.zeros(model.problem.n_dofs)
    rows = [(0.0, np.zeros((model.hand.mesh.n_nodes, 3)), *map(np.asarray, strains(u, theta)))]
    seconds, iterations, reached, why = [], [], 1.0, None
    for k in range(1, motion.frames + 1):
        s = motion.share(k)
        loads0 = {"u_D": theta["u_D"], "f": theta["f"], "traction": theta["traction"]}
        new = model.params({n: s * a for n, a in full.items()}, scar)
        t0 = time.perf_counter()
        try:
            sol = solver.solve(new, start=(u, loads0))
        except SolverError as e:
            s0 = motion.share(k - 1)
            reached, why = s0 + e.load_factor * (s - s0), "solver"
            break
        seconds.append(time.perf_counter() - t0)
        iterations.append(int(sol.info["iterations"]))
        theta, u = new, sol.u.reshape(-1)
        rows.append((s, np.asarray(sol.u), *map(np.asarray, strains(sol.u, theta))))
    frac, U, skin, eq = (np.array([r[i] for r in rows]) for i in range(4))
    peak = skin.max(axis=1)
    area = None if area is None else np.asarray(area, bool)
    local = peak if area is None else skin[:, area].max(axis=1)
    if strain_limit is not None and reachable(frac, local, strain_limit) < reached:
        reached, why = reachable(frac, local, strain_limit), "strain limit"
    disp = np.linalg.norm(U[:, mark], axis=1)
    time_ = np.arange(len(frac)) / motion.frames
    x = {"displacement": disp, "time": time_, "fraction": frac}[against]
    return MotionResult(motion, scar, frac, time_, disp, peak, local, area, skin, eq, U, np.array(seconds),
                        np.array(iterations), float(reached), why, strain_limit,
                        None if detector is None else detector(x, local))
