"""The mesh an inclusion is fitted on: the body's box graded fine around the field's regions.

A coarse model biases a fitted inclusion along its volume-ratio valley (its volume low, about as
h^2; benchmarks/inclusion3d_mesh.py). Refining the whole block costs the fits
and the profile in proportion to its cells; refining where the inclusion is costs far less: a
:func:`jaxfem.graded.graded_box` whose ticks are at most ``fine`` apart over the regions' extent
plus a ``margin`` (along each axis; the body's cross-section is often all of it) and grow by
``growth`` per cell to ``coarse`` away from it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from types import SimpleNamespace

import numpy as np
from jaxtyping import Float

import jaxfem as jf
from jaxfem.graded import graded_box, graded_ticks
from refine.diagnosis.fitted import baseline, fit_compiled
from refine.model.measured import MeasuredModel


@dataclass(frozen=True)
class FocusedMesh:
    """How the fit mesh is graded (length unit): spacing ``fine`` over the regions' extent plus
    ``margin``, growing by ``growth`` per cell up to ``coarse`` elsewhere; ``element``; the refit's
    Levenberg-Marquardt evaluations at most ``max_steps`` (its start is the coarse fit; along the
    flat valley the profile goes on). The defaults
    mesh issue 23's 40 x 20 x 20 mm block around a 9-13 mm inclusion with ~3200 cells (a uniform
    3 mm box has 3822, a 4 mm one 1500)."""

    fine: float = 2.5
    coarse: float = 5.0
    margin: float = 0.0
    growth: float = 1.6
    element: str = "tet10"
    max_steps: int = 10


def extent(centre: Float[np.ndarray, "3"], axes: Float[np.ndarray, "3"], rotation: Float[np.ndarray, "3 3"]
           ) -> tuple[np.ndarray, np.ndarray]:
    """The axis-aligned bounding box ``(lo (3,), hi (3,))`` of the ellipsoid with ``centre``,
    semi-axes ``axes`` along the columns of ``rotation``."""
    half = np.sqrt(((np.asarray(rotation, float) * np.asarray(axes, float)) ** 2).sum(axis=1))
    return np.asarray(centre, float) - half, np.asarray(centre, float) + half


def is_box(mesh: jf.Mesh, tol: float = 1e-3) -> bool:
    """Whether a 3D mesh fills its axis-aligned bounding box (to ``tol`` of its volume)."""
    lo, hi = mesh.bounds()
    return bool(abs(mesh.volumes().sum() / np.prod(hi - lo) - 1.0) <= tol)


def focused_mesh(body: jf.Mesh, regions, cfg: FocusedMesh = FocusedMesh()) -> jf.Mesh | None:
    """The box of ``body`` graded fine (``cfg``) over the union of the ``regions``' extents
    (anything with ``centroid``, ``axes`` and ``rotation``: :class:`refine.solid.field.Blob`);
    None where ``body`` is no box (its own mesh then serves) or there is no region."""
    if not regions or body.dim != 3 or not is_box(body):
        return None
    boxes = [extent(r.centroid, r.axes, r.rotation) for r in regions]
    a = np.min([b[0] for b in boxes], axis=0) - cfg.margin
    b = np.max([b[1] for b in boxes], axis=0) + cfg.margin
    lo, hi = body.bounds()
    ticks = [graded_ticks(lo[d], hi[d], (a[d], b[d]), cfg.fine, cfg.coarse, cfg.growth) for d in range(3)]
    return graded_box(ticks, cfg.element)


def focus_of(shape, pad: float = 1.25) -> SimpleNamespace:
    """The region to mesh fine for a fitted :class:`~refine.solid.inclusion.EllipsoidShape`: its
    ellipsoid with the semi-axes grown by ``pad`` (a coarse model's fit comes out small along the
    volume-ratio valley)."""
    return SimpleNamespace(centroid=np.asarray(shape.centre), axes=pad * np.asarray(shape.axes),
                           rotation=np.asarray(shape.rotation))


def refit_focused(f, fit_mask, hold_mask, sigma: float, cfg: FocusedMesh = FocusedMesh(), region=None,
                  with_base: bool = True):
    """A coarse model's inclusion fit ``f`` (a :class:`~refine.diagnosis.fitted.Fitted`) refitted on
    the body's box graded fine around ``region`` (default :func:`focus_of` its shape;
    :func:`focused_mesh`), started from its shape and ratio; returns the initial model's fit on
    that mesh (None without ``with_base``: one solve saved) and the refit (both None where the
    body is no box)."""
    coarse = f.model
    mesh = focused_mesh(coarse.mesh, [focus_of(f.shapes[0]) if region is None else region], cfg)
    if mesh is None:
        return None, None
    model = MeasuredModel(coarse.experiment, coarse.obs, mesh=mesh, linear_solver=coarse.linear_solver)
    hyp = f.hypothesis.on(model, f.shapes)  # the same kind of region, started at the fit
    compiled, z0 = hyp.build()
    g = fit_compiled(hyp, compiled, fit_mask, hold_mask, sigma, z0=z0, max_steps=cfg.max_steps)
    return (baseline(model, fit_mask, hold_mask, sigma) if with_base else None), g


def coarser(cfg: FocusedMesh, factor: float) -> FocusedMesh:
    """``cfg`` with its ``fine`` and ``coarse`` spacings ``factor`` times larger (the same grading
    and region): the mesh a discretisation error is estimated on
    (:func:`refine.solid.inclusion_total.discretisation_refit`)."""
    return replace(cfg, fine=factor * cfg.fine, coarse=factor * cfg.coarse)
