"""Where a solid's model is wrong: a regularised modulus field on the 3D mesh (a log-modulus per
cell, total-variation smoothing, fitted by L-BFGS-B with exact adjoint gradients:
:func:`refine.diagnosis.localize.fit_field`, the 2D diagnosis's own), segmented into connected
regions of abnormal stiffness (:func:`refine.diagnosis.localize.segment`), each summarised by the
ellipsoid of its second moments: the starting places of the 3D shape hypotheses
(:mod:`refine.solid.inclusion`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from jaxtyping import Bool, Float

from refine.diagnosis.localize import fit_field, segment
from refine.model.measured import MeasuredModel

FIELD_WEIGHT = 2.0
"""The field's smoothing weight, times the number of residuals per cell (the 2D diagnosis's
default ``field_weight``)."""


@dataclass(frozen=True)
class Blob:
    """A connected region of abnormal modulus in a 3D field.

    Attributes:
        sign: +1 stiffer, -1 softer than the background.
        cells: ``(m,)`` indices of its cells.
        centroid: ``(3,)`` its centroid weighted by volume x deviation (length unit).
        axes: ``(3,)`` semi-axes of the uniform ellipsoid with its second moments, larger first.
        rotation: ``(3, 3)`` the directions of ``axes`` as columns.
        volume: its cells' volume (length unit cubed).
        strength: integrated |log modulus deviation| x volume (ranks blobs).
        peak: its largest |log modulus deviation|; ratio: exp(sign x peak), a starting ratio.
        source: what proposed it (``"field"``: the modulus field; ``"gap"``: a gap in the points
            inside the volume).
    """

    sign: int
    cells: np.ndarray
    centroid: np.ndarray
    axes: np.ndarray
    rotation: np.ndarray
    volume: float
    strength: float
    peak: float
    source: str = "field"

    @property
    def ratio(self) -> float:
        return float(np.exp(self.sign * self.peak))


def moment_ellipsoid(cent: Float[np.ndarray, "n 3"], vol: Float[np.ndarray, "n"]
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The uniform ellipsoid with the second moments of cells (centroids ``(n, 3)``, volumes
    ``(n,)``): its centre ``(3,)``, semi-axes ``(3,)`` larger first (a uniform ellipsoid's variance
    along an axis is a^2 / 5) and their directions as the columns of ``(3, 3)``. A cell counts as
    a ball of its volume, not a point."""
    centre = (vol[:, None] * cent).sum(0) / vol.sum()
    d = cent - centre
    cov = np.einsum("n,ni,nj->ij", vol, d, d) / vol.sum()
    cov += np.eye(3) * 0.2 * (3.0 * vol.mean() / (4.0 * np.pi)) ** (2.0 / 3.0)
    ev, evec = np.linalg.eigh(cov)
    return centre, np.sqrt(5.0 * np.maximum(ev[::-1], 1e-12)), evec[:, ::-1]


def blobs(mesh, z: Float[np.ndarray, "cells"], min_volume: float = 0.0, max_regions: int = 3) -> list[Blob]:
    """The connected regions of the log-modulus field ``z`` (per cell of ``mesh``) departing from
    its median (:func:`refine.diagnosis.localize.segment`: a cell is abnormal beyond half the
    largest deviation of its sign, and at least 0.1), of at least ``min_volume``, strongest first."""
    vol, cent = mesh.volumes(), mesh.centroids()
    out = []
    for c in segment(mesh, np.asarray(z, float), min_area=min_volume, max_regions=max_regions):
        w = vol[c.cells] * np.abs(z[c.cells] - np.median(z))
        centre = (w[:, None] * cent[c.cells]).sum(0) / w.sum()
        _, axes, rot = moment_ellipsoid(cent[c.cells], vol[c.cells])
        out.append(Blob(c.sign, c.cells, centre, axes, rot, float(vol[c.cells].sum()), c.strength, c.peak))
    return out


@dataclass(frozen=True)
class Field:
    """A fitted 3D modulus field: ``z (n_cells,)`` log(E / E_initial) per cell, the regions it
    shows (``blobs``), the gradients the fit took and its seconds."""

    z: np.ndarray
    blobs: list
    gradients: int
    seconds: float


def modulus_field(model: MeasuredModel, sigma: float, points: Bool[np.ndarray, "n_points"],
                  weight: float = FIELD_WEIGHT, maxiter: int = 60, max_regions: int = 3) -> Field:
    """The regularised modulus field of ``model`` fitted to ``points`` (noise ``sigma``, length
    unit) and its regions (:func:`blobs`, each at least four cells' mean volume).

    ``weight`` multiplies the number of residuals per cell, so the smoothing keeps its balance
    with the misfit as meshes and point sets change size. Each iteration costs one forward and one
    adjoint solve per frame."""
    n_res = 3 * model.obs.n_frames * int(np.asarray(points).sum())
    z, res = fit_field(model, weight=weight * n_res / model.mesh.n_cells, sigma=sigma, points=points, maxiter=maxiter)
    found = blobs(model.mesh, z, min_volume=4.0 * model.mesh.volumes().mean(), max_regions=max_regions)
    return Field(z, found, int(res.n_gradient), float(res.seconds))
