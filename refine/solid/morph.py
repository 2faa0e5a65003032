"""A 2D morph of a plate's plan extruded through its thickness: the differentiable geometry of a
through-thickness hole in an extruded ``tet4``/``tet10`` mesh (:mod:`jaxfem.wall`).

Each vertex moves in (x, y) as the plan node under it does (:func:`jaxfem.morph` on the plan,
whose hole curve is on its boundary) and keeps its z; each mid-edge node stays at its edge's
middle, so cells keep straight edges and :func:`refine.solid.loaded.moved_probe` is exact.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfem as jf
from jaxfem.wall import ExtrudedWall
from jaxfem.shapes import Morph

from refine.solid.loaded import straight_tet10_pairs


def midpoint_pairs(mesh: jf.Mesh) -> np.ndarray:
    """``(n_nodes - n_vertices, 2)``: the two vertices each mid-edge node of a ``tet10`` mesh lies
    between (nodes numbered vertices first, as :func:`jaxfem.to_quadratic` does); empty for tet4."""
    if mesh.element != "tet10":
        return np.zeros((0, 2), np.int64)
    n_v = int(mesh.cells[:, :4].max()) + 1
    pairs = straight_tet10_pairs(mesh)
    out = np.zeros((mesh.n_nodes - n_v, 2), np.int64)
    for j, (a, b) in enumerate(pairs):
        out[mesh.cells[:, 4 + j] - n_v] = np.stack([mesh.cells[:, a], mesh.cells[:, b]], 1)
    return out


class ExtrudedMorph(eqx.Module):
    """The morph of an extruded mesh (see the module): ``morph(params)`` and ``morph.affine(centres,
    maps)`` as :class:`jaxfem.shapes.Morph`, returning the 3D nodes ``(n_nodes, 3)``."""

    plan: Morph
    column: np.ndarray  # (n_vertices,) plan node under each vertex
    z: np.ndarray  # (n_vertices,)
    mids: np.ndarray  # (n_mid, 2)

    @classmethod
    def of(cls, slab: ExtrudedWall) -> ExtrudedMorph:
        """The morph of the hole of ``slab`` (a disc wall, or a disc wall with a rim, with a hole;
        the plan's regions keep the rim's feet where they are)."""
        n_v = len(slab.column)
        return cls(jf.morph(slab.plan, [slab.hole]), slab.column, slab.mesh.nodes[:n_v, 2], midpoint_pairs(slab.mesh))

    @property
    def params0(self) -> np.ndarray:
        return self.plan.params0

    def _lift(self, xy):
        V = jnp.concatenate([jnp.asarray(xy)[self.column], jnp.asarray(self.z)[:, None]], 1)
        if not len(self.mids):
            return V
        return jnp.concatenate([V, 0.5 * (V[self.mids[:, 0]] + V[self.mids[:, 1]])], 0)

    def __call__(self, params):
        return self._lift(self.plan(params))

    def affine(self, centres, maps):
        return self._lift(self.plan.affine(centres, maps))
