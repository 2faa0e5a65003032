"""Candidate places of the 3D engine where points lie inside the volume (a DVC export): the gaps
among them, where a cavity or a soft region may hide (:func:`gap_candidates`)."""

from __future__ import annotations

import numpy as np

from refine.model.measured import MeasuredModel
from refine.solid.field import Blob, moment_ellipsoid


def interior_points(model: MeasuredModel, tol: float | None = None) -> np.ndarray:
    """``(n_points,)`` bool: the points lying inside the volume, farther than ``tol`` (default a
    tenth of a cell) from every boundary facet of the model's mesh (sampled densely)."""
    from scipy.spatial import cKDTree

    from refine.solid.inclusion import cell_size

    mesh = model.mesh
    f = mesh.boundary_facets()[:, :3]
    n = 6
    lam = np.array([(i, j, n - i - j) for i in range(n + 1) for j in range(n + 1 - i)], float) / n
    samples = np.einsum("qc,fcd->fqd", lam, mesh.nodes[f]).reshape(-1, 3)
    h = cell_size(mesh)
    d, _ = cKDTree(samples).query(model.obs.reference)
    return d > (tol if tol is not None else 0.25 * h)


def gap_candidates(model: MeasuredModel, factor: float = 1.5, max_regions: int = 2) -> list[Blob]:
    """Softer candidates where points lie inside the volume: the connected groups of cells (at
    least four) whose centroid lies farther than ``factor`` times the interior points' median
    spacing from every point and inside their bounding box, not on the surface; none with fewer
    than 20 interior points."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    inside = interior_points(model)
    X = model.obs.reference
    if inside.sum() < 20:
        return []
    P = X[inside]
    tree = cKDTree(P)
    spacing = float(np.median(tree.query(P, k=2)[0][:, 1]))
    mesh = model.mesh
    cent, vol = mesh.centroids(), mesh.volumes()
    d, _ = cKDTree(X).query(cent)
    surface = np.zeros(mesh.n_nodes, bool)
    surface[mesh.boundary_nodes()] = True
    corners = mesh.cells[:, :4]
    gap = (d > factor * spacing) & (cent >= P.min(0)).all(1) & (cent <= P.max(0)).all(1) & ~surface[corners].any(1)
    idx = np.flatnonzero(gap)
    if idx.size < 4:
        return []
    # cells sharing a corner node are neighbours
    rows = np.repeat(np.arange(idx.size), 4)
    A = coo_matrix((np.ones(rows.size), (rows, corners[idx].ravel())), shape=(idx.size, mesh.n_nodes)).tocsr()
    _, labels = connected_components(A @ A.T, directed=False)
    out = []
    for k in np.unique(labels):
        cells = idx[labels == k]
        if cells.size < 4:
            continue
        c, axes, rot = moment_ellipsoid(cent[cells], vol[cells])
        out.append(Blob(-1, cells, c, axes, rot, float(vol[cells].sum()), float(vol[cells].sum()), 1.6, "gap"))
    return sorted(out, key=lambda b: -b.volume)[:max_regions]
