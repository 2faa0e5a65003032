"""Geometry as a parameter: holes and inclusions moved by a smooth mesh morph, never remeshed.

A plate is meshed once around its holes and inclusions (:func:`~jaxfem.mesher.plate`), and
:func:`~jaxfem.shapes.morph` turns the mesh into a pure JAX map from shape parameters
``(n_shapes, 5)`` = ``(cx, cy, a, b, angle)`` per shape to node coordinates. Putting those nodes
into ``theta["X"]`` makes the geometry one more differentiable parameter of
:meth:`Solver.displacement <jaxfem.solver.Solver.displacement>`: the derivative of the equilibrium
with respect to a hole's centre or semi-axes is the derivative with respect to the nodal
coordinates (implicit, one linear solve) chained with the morph's (explicit, by JAX).

Nothing is remeshed inside an optimisation, so the topology, the sparsity pattern and the compiled
solver stay the same and the objective is smooth in the shape parameters. The price is that a
morph can only take the shapes so far: once a cell would turn inside out the mesh no longer
describes the body. :func:`check_geometry` says so (with how much of the change is still valid);
call it on the host between optimisation steps, and remesh from the current shapes (outside the
optimisation) when a fit needs to move further.

Usage::

    mesh = jf.plate(0, 0, 40, 30, 2.0, holes=[hole], inclusions=[inclusion])
    morph = jf.morph(mesh, [hole, inclusion])
    def misfit(shape_params):                       # (2, 5): hole, then inclusion
        theta_g = with_geometry(theta, morph, shape_params)
        return 0.5 * jnp.sum((probe(solver.displacement(theta_g)) - measured) ** 2)
    g = jax.grad(misfit)(morph.params0)             # (2, 5): d misfit / d (cx, cy, a, b, angle)
    check_geometry(mesh, morph(new_params))         # before accepting a step
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401
from .mesh import Mesh
from .shapes import Morph, check_morph


def with_geometry(theta: dict, morph: Morph, shape_params) -> dict:
    """The parameters ``theta`` with the reference coordinates of the morphed mesh.

    Args:
        theta: parameter pytree (:meth:`Problem.params <jaxfem.problem.Problem.params>`) of a
            problem on the mesh that ``morph`` was made for.
        morph: the :class:`~jaxfem.shapes.Morph` of that mesh.
        shape_params: ``(n_shapes, 5)`` = ``(cx, cy, a, b, angle)`` per shape, in the order the
            shapes were given to :func:`~jaxfem.shapes.morph` (length units, radians).
    Returns:
        A new dict, ``theta`` with ``"X"`` = ``morph(shape_params)`` ``(n_nodes, 2)``;
        differentiable in ``shape_params`` (and in the other entries of ``theta``).
    """
    return {**theta, "X": morph(jnp.asarray(shape_params, jnp.float64))}


def check_geometry(mesh: Mesh, nodes) -> float:
    """Check that moved nodes still make a valid mesh; host side, not inside ``jit``.

    Args:
        mesh: the reference mesh.
        nodes: moved coordinates ``(n_nodes, dim)``, e.g. ``morph(shape_params)``.
    Returns:
        The smallest ratio of moved to reference Jacobian determinant (1 for an unchanged mesh;
        values near 0 mean badly squeezed cells: remesh soon).
    Raises:
        InvertedElementError: a cell turns inside out; the message says which, and by how much
            to scale the change back.
    """
    return check_morph(mesh, np.asarray(jax.device_get(nodes), np.float64))
