"""Strain and field maps with matplotlib (per-cell values on the reference or deformed mesh)."""

from __future__ import annotations

import numpy as np

from .exceptions import MeshError
from .mesh import Mesh

from .surface import FACE_TRIANGLES as _TRI_SPLIT  # a 2D cell is split as a 3D face of its type


def _triangles(mesh: Mesh):
    split = np.asarray(_TRI_SPLIT[mesh.element])
    tri = mesh.cells[:, split].reshape(-1, 3)
    owner = np.repeat(np.arange(mesh.n_cells), len(split))
    return tri, owner


def cell_map(mesh: Mesh, values, u=None, ax=None, cmap="viridis", label=None, points=None,
             vmin=None, vmax=None, title=None):
    """Draw per-cell ``values (n_cells,)`` over a 2D mesh, on the deformed shape if ``u (n_nodes, 2)``
    is given; ``points (n, 2)`` are overlaid (e.g. tracked points). Returns the matplotlib axes."""
    import matplotlib.pyplot as plt

    if mesh.dim != 2:
        raise MeshError("cell_map() draws 2D meshes; write a 3D mesh with jaxfem.write_vtu and view it in ParaView")
    ax = ax or plt.subplots(figsize=(7, 4.5))[1]
    xy = mesh.nodes + (0.0 if u is None else np.asarray(u))
    tri, owner = _triangles(mesh)
    pc = ax.tripcolor(xy[:, 0], xy[:, 1], tri, facecolors=np.asarray(values)[owner], cmap=cmap,
                      vmin=vmin, vmax=vmax, shading="flat")
    ax.figure.colorbar(pc, ax=ax, label=label)
    if points is not None:
        ax.plot(np.asarray(points)[:, 0], np.asarray(points)[:, 1], "k.", ms=2)
    ax.set_aspect("equal")
    if title:
        ax.set_title(title)
    return ax


def strain_map(solver, u, theta, ax=None, deformed=True, **kw):
    """Map of the equivalent (von Mises) Green-Lagrange strain of an equilibrium."""
    from .postprocess import equivalent_strain

    eq = np.asarray(equivalent_strain(solver, u, theta))
    return cell_map(solver.problem.mesh, eq, u=np.asarray(u) if deformed else None, ax=ax,
                    label=kw.pop("label", "equivalent strain"), **kw)
