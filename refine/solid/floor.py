"""A solid body's initial model's discretisation error, part of the null level its misfit is
compared with (as the 2D diagnosis's, :mod:`refine.diagnosis.discretisation`): the change of its
predictions when each of its cells is split in eight (:func:`split_mesh`: the body's own mesh,
whatever its shape, no remeshing), scaled by 4/3 (second-order Richardson).

Without it, a sound body whose model mesh is coarser than the truth's fails its null test (its
misfit is the noise plus the mesh's own error), and any hypothesis with a free parameter (another
law's Poisson's ratio) absorbs part of that error and is taken for a finding.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Bool

import jaxfem as jf

from refine.model.measured import MeasuredModel

_CHILDREN = np.array([[0, 4, 6, 7], [1, 4, 5, 8], [2, 6, 5, 9], [3, 7, 8, 9],  # the corners' tets
                      [6, 8, 4, 5], [6, 8, 5, 9], [6, 8, 9, 7], [6, 8, 7, 4]])  # the octahedron cut along 6-8
"""The eight tetrahedra of a tet10 cell's nodes (jaxfem's order: corners 0-3, then the edges'
mid nodes 01, 12, 20, 03, 13, 23): its red refinement."""


def split_mesh(mesh: jf.Mesh) -> jf.Mesh:
    """``mesh`` (tet10 or tet4) with every cell split in eight (regions kept): a tet10 mesh on its
    nodes (a tet4 mesh first made quadratic), its new mid nodes straight between them."""
    if mesh.element == "tet4":
        mesh = jf.to_quadratic(mesh)
    if mesh.element != "tet10":
        raise ValueError(f"split_mesh() takes a tet4 or tet10 mesh, not {mesh.element!r}")
    cells = mesh.cells[:, _CHILDREN].reshape(-1, 4)
    regions = None if mesh.regions is None else np.repeat(mesh.regions, len(_CHILDREN))
    tet4 = jf.Mesh(mesh.nodes, cells, "tet4", regions, dict(mesh.region_names))
    return jf.to_quadratic(jf.fix_orientation(tet4))


def discretisation_floor(model: MeasuredModel, points: Bool[np.ndarray, "n_points"]) -> float:
    """Std (length unit) of the initial ``model``'s discretisation error at ``points``: 4/3 times
    the RMS change of its predictions on its mesh split in eight (:func:`split_mesh`), over every
    frame and component; NaN where either model cannot be solved. Costs the split model's compile
    and one solve per frame (eight times the cells)."""
    fine = MeasuredModel(model.experiment, model.obs, mesh=split_mesh(model.mesh), linear_solver=model.linear_solver)
    d = np.asarray(fine.predict(fine.params())) - np.asarray(model.predict(model.params()))
    d = d[:, np.asarray(points)]
    if not np.isfinite(d).all():
        return float("nan")
    return float(4.0 / 3.0 * np.sqrt(np.mean(d**2)))
