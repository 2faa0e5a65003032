"""Dynamic refinement while tracking (the paper's title) on unlabelled clouds.

Frame by frame: the model refined on frames <= k predicts frame k+1 (its grips fitted to the
frame's training points, its parameters kept); the prediction error is the RMS distance of the
frame's held-out boundary points to the predicted boundary (outline in 2D, surface in 3D).
Where it exceeds its null level (the same error at frame 0, where the model is the reference
shape and only noise and sampling remain, times ``null_factor``), the model is refined: a modulus
field (total variation) is fitted jointly with the grips of the last ``window`` frames, and the
error is measured again. At the end the field's regions are refitted as balls of their own
modulus over every frame, each kept only where the BIC accepts it
(:mod:`refine.correspond.region`). Every node's position in every frame (the dense
correspondences) comes from the refitted model where it kept a region, else from the fit of its
frame.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field

import numpy as np

from refine.correspond.fit import FitConfig, Fitter, compiled_settings, held_error, split_frames, with_labelled
from refine.correspond.model import CloudModel, Grips
from refine.exceptions import CorrespondenceError
from refine.model.parametrize import ModulusField


@dataclass(frozen=True)
class FollowConfig:
    """Settings of following a sequence (data).

    Attributes:
        fit: the fit's settings (noise, robust scale, hold-out share, seed).
        grips: clamped and gripped sides.
        h: element size of the model (length).
        null_factor: refine when the prediction error exceeds this times the null level.
        refine: False: predict and track only (the comparison without refinement).
        window: frames in a refinement's joint fit (the last ones up to the current).
        field_weight: total-variation weight of the modulus field, times residuals per cell.
        track_iterations, refine_iterations: L-BFGS-B iterations of a frame's grips fit and of a
            refinement.
        reference_tol: how far (length) the reference cloud may lie from the model's boundary.
        refit: refit the final field's regions as balls (centre, radius, ratio with standard
            errors; a region kept only where the BIC accepts it); refit_iterations its L-BFGS-B
            iterations per hypothesis.
    """

    fit: FitConfig = field(default_factory=FitConfig)
    grips: Grips = field(default_factory=Grips)
    h: float = 5.0
    null_factor: float = 1.5
    refine: bool = True
    window: int = 3
    field_weight: float = 0.5
    track_iterations: int = 60
    refine_iterations: int = 60
    reference_tol: float | None = None
    refit: bool = True
    refit_iterations: int = 80


@dataclass(frozen=True)
class FrameRecord:
    """One frame of a followed sequence: its prediction error before and after a refinement
    (length; equal where none happened), whether one happened and what it changed."""

    frame: int
    error_before: float
    error_after: float
    refined: bool
    change: dict | None
    seconds: float


@dataclass(frozen=True, eq=False)
class FollowResult:
    """The followed sequence.

    Attributes:
        records: one :class:`FrameRecord` per deformed frame.
        null_level: the refinement threshold (length); noise_level the frame-0 error it came from.
        nodes: ``(n_nodes, dim)`` the model's reference nodes.
        positions: ``(n_frames + 1, n_nodes, dim)`` every node in every frame (dense correspondences).
        grips: ``(n_frames, n_grips, grip_dof)`` the fitted grip motions.
        log_modulus: ``(n_cells,)`` the final field, log(E / E initial) per cell.
        findings: the regions found: those of the parametric refit the BIC kept (cause, centroid,
            radius, ``relative_elasticity``, each with its standard error) where a refit ran, else
            those of the final field.
        field_findings: the abnormal regions of the final field (cause, centroid, area, and as
            ``relative_elasticity`` the field's peak ratio: smeared by the total variation, well
            below a region's true ratio).
        refit: the refit's record (:func:`refine.correspond.region.refit_regions`) or None.
    """

    records: list
    null_level: float
    noise_level: float
    nodes: np.ndarray
    positions: np.ndarray
    grips: np.ndarray
    log_modulus: np.ndarray
    findings: list
    seconds: float
    field_findings: list = field(default_factory=list)
    refit: dict | None = None

    def summary(self) -> dict:
        """A JSON-ready summary (no arrays but the findings')."""
        return {"null_level": self.null_level, "noise_level": self.noise_level, "seconds": self.seconds,
                "frames": [asdict(r) for r in self.records], "findings": self.findings,
                "field_findings": self.field_findings,
                "refit": None if self.refit is None else {k: v for k, v in self.refit.items()
                                                          if k not in ("grips", "positions")},
                "refinements": [r.frame for r in self.records if r.refined]}


def follow_clouds(experiment, clouds, config: FollowConfig = FollowConfig(), model: CloudModel | None = None,
                  progress=None, observations=None) -> FollowResult:
    """Follow a sequence of unlabelled clouds ``[frame 0, frame 1, ...]`` (``(n_k, dim)`` each).

    Args:
        experiment: the bundle's experiment (domain, law, E, nu; ``noise_std`` if ``config.fit``
            leaves the noise at its default).
        clouds: the clouds, frame 0 the reference shape.
        config: :class:`FollowConfig`.
        model: a :class:`CloudModel` to reuse (its compilation); default one from the config (2D;
            a 3D model is built from its mesh, ``CloudModel(..., mesh=...)``).
        progress: optional callable ``(FrameRecord) -> None`` after every frame.
        observations: tracked points of the same frames (:class:`refine.bundle.Observations`,
            e.g. a bundle's points.csv beside its clouds), fitted as extra data; the prediction
            error stays that of the clouds' held-out points.
    """
    t0 = time.perf_counter()
    clouds = [np.asarray(c, float) for c in clouds]
    if len(clouds) < 2:
        raise CorrespondenceError("a sequence needs frame 0 (the reference shape) and at least one more frame")
    model = model or CloudModel(experiment, config.grips, config.h)
    cfg = config.fit
    train, held = split_frames(clouds, cfg)
    model.check_reference(clouds[0], cfg.noise, config.reference_tol or max(10 * cfg.noise, 0.02 * model.size))
    if model.dim == 3:  # a range camera sees part of the surface: only the nodes it saw are pulled to the cloud
        train = train.seen_by(model, clouds[0], 2.0 * train.spacing + 3.0 * cfg.noise)
    if observations is not None:
        train = with_labelled(train, model, observations.reference, observations.displacements)
    cap = 20.0 * cfg.noise
    noise_level = float(held_error(model, model.mesh.nodes[None], held.frames([0]), cap)[0])
    level = config.null_factor * max(noise_level, cfg.noise)
    n_res = float(train.w_boundary[1:].sum(axis=1).mean())
    weight = config.field_weight * n_res / model.mesh.n_cells
    fitter = field_fitter(model, cfg)
    param = fitter.param
    n = len(clouds) - 1
    Q = np.zeros((n + 1, model.n_grips, model.grip_dof))  # Q[k]: frame k's grips (frame 0: none)
    zp = np.zeros(param.size)
    positions = [model.mesh.nodes.copy()] + [None] * n
    states = [None] + [None] * n  # (u, q) of each frame's equilibrium, where the next solve starts
    records = []
    for k in range(1, n + 1):
        t1 = time.perf_counter()
        guess = Q[k - 1] + (Q[k - 1] - Q[k - 2] if k >= 2 else 0.0)
        Qk, _, _ = fitter.fit(train.frames([k]), guess[None], zp, states[k - 1], maxiter=config.track_iterations,
                              reg_weight=weight)
        x = np.asarray(fitter._positions(Qk, zp, model.start(states[k - 1])))
        _check_frame(model, x[0], train.frames([k]), k, config.reference_tol or 0.05 * model.size)
        before = float(held_error(model, x, held.frames([k]), cap)[0])
        after, change = before, None
        if config.refine and before > level:
            first = max(1, k - config.window + 1)
            frames = list(range(first, k + 1))
            Q0 = np.concatenate([Q[first:k], Qk])
            Qw, zp_new, res = fitter.fit(train.frames(frames), Q0, zp, states[first - 1], joint=True,
                                         maxiter=config.refine_iterations, reg_weight=weight)
            xw = np.asarray(fitter._positions(Qw, zp_new, model.start(states[first - 1])))
            after = float(held_error(model, xw[-1:], held.frames([k]), cap)[0])
            change = _change(model, zp, zp_new, res, frames)
            zp, Qk, x = zp_new, Qw[-1:], xw[-1:]
            for j, f in enumerate(frames[:-1]):  # the window's earlier frames follow the refined model
                Q[f], positions[f] = Qw[j], xw[j]
        Q[k], positions[k] = Qk[0], x[0]
        states[k] = (positions[k] - model.mesh.nodes, Q[k])
        records.append(FrameRecord(k, before, after, change is not None, change, time.perf_counter() - t1))
        if progress is not None:
            progress(records[-1])
    found = _findings(model, zp)
    refit = None
    if config.refit and found:
        from refine.correspond.region import refit_regions

        refit = refit_regions(model, cfg, train.frames(list(range(1, n + 1))), Q[1:], found,
                              maxiter=config.refit_iterations)
        if refit["regions"]:  # the refitted model's motion of every frame: the dense correspondences
            positions[1:], Q[1:] = list(refit.pop("positions")), np.asarray(refit["grips"])
    return FollowResult(records, level, noise_level, model.mesh.nodes.copy(), np.stack(positions), Q[1:], zp,
                        found if refit is None else refit["regions"], time.perf_counter() - t0, found, refit)


def _check_frame(model: CloudModel, x, data, k: int, tol: float) -> None:
    """Raise :class:`CorrespondenceError` when most of frame k's boundary points lie farther than
    ``tol`` from the model fitted to them: the cloud is not of this object, or the object jumped
    farther between frames than its grips can follow."""
    w = data.w_boundary[0] > 0
    far = float(np.median(model.boundary_distances(data.boundary[0][w], x)))
    if far > tol:
        raise CorrespondenceError(f"frame {k}'s cloud lies {far:.3g} from the model fitted to it (median; allowed "
                                  f"{tol:.3g}): it does not show this object, or the object moved too far since "
                                  f"frame {k - 1}; check the frame's coordinates or add the frames between")


def field_fitter(model: CloudModel, config: FitConfig) -> Fitter:
    """The :class:`Fitter` of a total-variation modulus field on ``model`` (kept on the model, so a
    second sequence on the same model compiles nothing)."""
    cache = model.__dict__.setdefault("_field_fitters", {})
    config = compiled_settings(config)
    if config not in cache:
        cache[config] = Fitter(model, config, ModulusField(model.mesh, model.experiment.E, weight=1.0, kind="tv",
                                                           eps=0.05))
    return cache[config]


def _change(model, zp_old, zp_new, res, frames) -> dict:
    """What a refinement changed: the field's extremes, the strongest region, the fit's counts."""
    found = _findings(model, zp_new)
    return {"frames": frames, "max_relative_modulus": float(np.exp(zp_new.max())),
            "min_relative_modulus": float(np.exp(zp_new.min())),
            "largest_change": float(np.abs(zp_new - zp_old).max()), "regions": found,
            "iterations": len(res.history), "misfit": res.error}


def _findings(model, zp) -> list:
    """Abnormal regions of a log-modulus field (:func:`refine.diagnosis.localize.segment`)."""
    from refine.diagnosis.localize import segment

    if np.abs(zp).max(initial=0.0) < 0.1:
        return []
    out = []
    for c in segment(model.mesh, np.asarray(zp), max_regions=2):
        out.append({"cause": "stiffer-region" if c.sign > 0 else "softer-region",
                    "centroid": [float(v) for v in c.centroid],
                    "relative_elasticity": float(np.exp(c.sign * c.peak)),
                    "area": float(model.mesh.volumes()[c.cells].sum())})
    return out
