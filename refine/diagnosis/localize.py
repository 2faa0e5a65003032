"""Where is the model wrong? A regularised modulus field fitted by adjoint gradients, segmented
into connected regions of abnormal stiffness, each summarised by the ellipse of its moments.

The region's shape comes from the data (the field), not from a grid cell the points bound; the
parametric refit that follows (``refine.diagnosis.regions``, ``refine.diagnosis.holes``) then sharpens it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from refine.model.objective import Objective
from refine.optimize.lbfgsb import lbfgsb
from refine.model.parametrize import ModulusField, cell_adjacency, make_shape


@dataclass(frozen=True)
class Candidate:
    """A connected region of abnormal modulus in the field.

    Attributes:
        sign: +1 stiffer, -1 softer than the background.
        cells: indices of its cells.
        centroid, axes, angle: the ellipse with the region's weighted second moments (length units,
            semi-axes, radians).
        strength: integrated |log modulus deviation| x area (ranks candidates).
        peak: largest |log modulus deviation| in it.
        source: what proposed it: ``"field"`` (the fitted modulus field), ``"strain"`` (the
            measured strain map) or ``"missing-points"`` (a gap in the tracked points).
    """

    sign: int
    cells: np.ndarray
    centroid: np.ndarray
    axes: np.ndarray
    angle: float
    strength: float
    peak: float
    source: str = "field"


def fit_field(model, weight: float, sigma: float, points=None, maxiter: int = 80, kind: str = "tv"):
    """Fit a per-cell log-modulus field to the matched points (bounded L-BFGS, adjoint gradients:
    each iteration costs one forward and one adjoint solve per frame).

    Returns ``(z (n_cells,), RefineResult)``: z is log(E / E_initial) per cell.
    """
    param = ModulusField(model.mesh, model.experiment.E, weight=weight, kind=kind, eps=0.05)
    res = lbfgsb(Objective(model, param, points=points, noise_std=sigma), bounds=(-4.0, 4.0), maxiter=maxiter)
    return np.asarray(res.values["z"]), res


def segment(mesh, z: np.ndarray, threshold: float | None = None, min_area: float = 0.0,
            max_regions: int = 3) -> list[Candidate]:
    """Connected regions where the log-modulus field departs from its background (median).

    A cell is abnormal when its deviation exceeds ``threshold`` (default: half the largest
    deviation of that sign, and at least 0.1, i.e. 10 %); connected abnormal cells of one sign
    form a candidate; the ``max_regions`` strongest of at least ``min_area`` are returned (up to
    rounding: four triangles of a 5 mm mesh sum to 49.99999999999999, not 50).
    """
    return segment_cells(z - np.median(z), mesh.volumes(), mesh.centroids(), cell_adjacency(mesh), threshold,
                         min_area, max_regions)


def segment_cells(d: np.ndarray, area: np.ndarray, cent: np.ndarray, pairs: np.ndarray,
                  threshold: float | None = None, min_area: float = 0.0, max_regions: int = 3,
                  source: str = "field") -> list[Candidate]:
    """:func:`segment` on any cells: deviations ``d (n,)`` (positive: stiffer), cell areas
    ``(n,)``, centroids ``(n, 2)`` and neighbouring pairs ``(m, 2)``."""
    out = []
    n = len(d)
    for sign in (1, -1):
        ds = sign * d
        if ds.max() <= 0:
            continue
        thr = max(0.5 * ds.max(), 0.1) if threshold is None else threshold
        on = ds > thr
        keep = on[pairs[:, 0]] & on[pairs[:, 1]]
        g = coo_matrix((np.ones(keep.sum()), (pairs[keep, 0], pairs[keep, 1])), shape=(n, n))
        _, label = connected_components(g, directed=False)
        for lab in np.unique(label[on]):
            cells = np.flatnonzero(on & (label == lab))
            if area[cells].sum() < min_area * (1.0 - 1e-9):
                continue
            w = area[cells] * ds[cells]
            c = (w[:, None] * cent[cells]).sum(0) / w.sum()
            centre, axes, angle = moment_ellipse(cent[cells], area[cells])
            out.append(Candidate(sign, cells, c, axes, angle, float(w.sum()), float(ds[cells].max()), source))
    out.sort(key=lambda c: -c.strength)
    return out[:max_regions]


def moment_ellipse(cent: np.ndarray, area: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The uniform ellipse with the second moments of cells (centroids ``(n, 2)``, areas ``(n,)``):
    its centre, semi-axes (larger first) and angle (radians)."""
    a = area
    centre = (a[:, None] * cent).sum(0) / a.sum()
    dx = cent - centre
    cov = (a[:, None, None] * dx[:, :, None] * dx[:, None, :]).sum(0) / a.sum()
    cov += np.eye(len(centre)) * a.mean() / (4 * np.pi)  # a single cell is a disc of its area, not a point
    ev, evec = np.linalg.eigh(cov)
    axes = 2.0 * np.sqrt(np.maximum(ev[::-1], 1e-12))  # uniform ellipse: second moment = a^2/4
    return centre, axes, float(np.arctan2(evec[1, -1], evec[0, -1]))


def ellipse_polygon(cx, cy, a, b, angle, n: int = 48) -> list[list[float]]:
    """Outline of an ellipse as a counter-clockwise polygon ``[[x, y], ...]``."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    c, s = np.cos(angle), np.sin(angle)
    x = cx + a * np.cos(t) * c - b * np.sin(t) * s
    y = cy + a * np.cos(t) * s + b * np.sin(t) * c
    return np.stack([x, y], 1).round(4).tolist()


def rectangle_polygon(cx, cy, a, b, angle) -> list[list[float]]:
    """Corners of a rectangle of half sides ``a, b`` turned ``angle``, counter-clockwise."""
    return make_shape("rectangle", (cx, cy, a, b, angle)).corners.round(4).tolist()


def shape_outline(kind: str, cx, cy, a, b, angle) -> tuple[float, list[list[float]]]:
    """Area and outline polygon of a fitted shape (``"rectangle"``; otherwise an ellipse)."""
    rect = kind == "rectangle"
    shape = make_shape("rectangle" if rect else "ellipse", (cx, cy, a, b, angle))
    polygon = shape.corners.round(4).tolist() if rect else ellipse_polygon(cx, cy, a, b, angle)
    return shape.area, polygon
