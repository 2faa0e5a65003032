"""Many parameter sets on one mesh: batched equilibria that share the pattern and the compilation.

:meth:`Solver.displacement <jaxfem.solver.Solver.displacement>` is a pure function of ``theta``,
so ``jax.vmap`` applies to it directly, and so do ``jax.grad``/``jax.jvp`` of the batched map.
What happens under ``vmap``:

- the element assembly (residuals, tangents) runs once per Newton iteration for the whole batch,
  vectorised over it;
- the Newton and load-step ``while_loop`` runs until every member has converged; members that are
  done are carried along unchanged (each keeps its own load steps and cut-backs, the batch takes
  as many iterations as its slowest member);
- the sparse direct solvers behind a host callback (``"pardiso"``, ``"superlu"``) are called with
  ``vmap_method="sequential"``: one factorisation per member and iteration, one after the other;
  ``"cg"`` and ``"dense"`` are pure JAX and batch for real.

``method="map"`` runs the members one after the other with ``lax.map`` instead: no iteration is
wasted on members that have converged and memory does not grow with the batch, but nothing is
vectorised. ``benchmarks/gradients.py`` compares the two with separate solves.
"""

from __future__ import annotations

from typing import Callable, Sequence

import jax
import jax.numpy as jnp

from . import _config  # noqa: F401
from .exceptions import OptionError, UnknownParameterError
from .solver import Solver


def stack_params(thetas: Sequence[dict]) -> dict:
    """One parameter pytree with a leading batch axis from a list of pytrees of equal shapes."""
    return jax.tree.map(lambda *leaves: jnp.stack(leaves), *thetas)


def batch_displacement(solver: Solver, batched: Sequence[str] | None = None,
                       method: str = "vmap") -> Callable[[dict], jax.Array]:
    """A compiled, differentiable ``thetas -> u`` for a batch of parameter sets.

    Build it once and call it for every batch (each call of this function compiles anew).

    Args:
        solver: the solver (its mesh, pattern and linear solver are shared by the batch).
        batched: the keys of ``theta`` that carry a leading batch axis ``(B, ...)``; the others are
            shared by every member. Default: all keys (e.g. from :func:`stack_params`).
        method: ``"vmap"`` (vectorised, see the module notes) or ``"map"`` (one member after the
            other with ``lax.map``).
    Returns:
        A jitted function of ``thetas`` returning displacements ``(B, n_nodes, dim)``; a member
        whose solve failed is NaN (solve it alone with :meth:`Solver.solve` for the reason).
    """
    if method not in ("vmap", "map"):
        raise OptionError(f"method must be 'vmap' or 'map', not {method!r}")

    def axes(thetas):
        keys = thetas.keys() if batched is None else batched
        unknown = set(keys) - set(thetas)
        if unknown:
            raise UnknownParameterError(f"batched keys {sorted(unknown)} are not parameters; name only keys of "
                                        f"theta: {sorted(thetas)}")
        return {k: 0 if k in keys else None for k in thetas}

    def run(thetas):
        in_axes = axes(thetas)
        if method == "vmap":
            return jax.vmap(solver.displacement, in_axes=(in_axes,))(thetas)
        shared = {k: v for k, v in thetas.items() if in_axes[k] is None}
        members = {k: v for k, v in thetas.items() if in_axes[k] == 0}
        return jax.lax.map(lambda m: solver.displacement({**shared, **m}), members)

    return jax.jit(run)
