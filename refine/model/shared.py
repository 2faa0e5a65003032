"""Functions compiled once per traced program, not once per object: the arrays a function closes
over (a parametrisation's masks or morph, a model's base parameters) are arguments of the
compiled program, not constants in it.

``Shared(fn)`` called on arguments traces ``fn`` to a jaxpr (in Python, no XLA), hoists the
arrays it closes over out as arguments, and runs the jaxpr on :func:`_run`, one module-level
``jax.jit`` whose static argument is the jaxpr keyed by its text (operations, shapes, dtypes,
scalar literals) and its argument and result structures. Two objects whose functions trace to
the same text (two hypotheses' parametrisations of the same shapes, masks or morph weights
aside) run on one compiled program, and JAX's persistent cache (:mod:`jaxfem.cache`) finds it
by the same lowered program in a later process. The values are those of ``jax.jit(fn)`` with the
closed-over arrays as arguments (no constant folding of them into the program).
"""

from __future__ import annotations

import threading
from functools import partial

import jax
import numpy as np
from jax.core import eval_jaxpr

#: closed-over arrays of at most this many elements stay constants of the program (in its key)
SMALL = 64


def _small(c) -> bool:
    return np.size(c) <= SMALL and not isinstance(c, jax.core.Tracer)


class _Program:
    """A traced program, equal to another with the same text, argument and result structures and
    small constants (:data:`SMALL`: kept in the program, so that it computes with them as
    ``jax.jit`` of the function does)."""

    __slots__ = ("jaxpr", "out_tree", "small", "key", "_hash")

    def __init__(self, closed, in_tree, out_tree):
        self.jaxpr, self.out_tree = closed.jaxpr, out_tree
        self.small = {i: np.asarray(c) for i, c in enumerate(closed.consts) if _small(c)}
        values = tuple((i, c.dtype.str, c.shape, c.tobytes()) for i, c in self.small.items())
        self.key = (str(closed.jaxpr), str(in_tree), str(out_tree), values)
        self._hash = hash(self.key)

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other) -> bool:
        return isinstance(other, _Program) and self.key == other.key


@partial(jax.jit, static_argnums=0)
def _run(program: _Program, consts, leaves):
    given = iter(consts)
    every = [program.small[i] if i in program.small else next(given) for i in range(len(program.jaxpr.constvars))]
    return jax.tree.unflatten(program.out_tree, eval_jaxpr(program.jaxpr, every, *leaves))


class Shared:
    """``fn`` (positional arguments, pytrees of arrays) on the program :func:`_run` shares among
    every function that traces to the same jaxpr; traced once per argument structure and shapes."""

    def __init__(self, fn):
        self.fn = fn
        self._traced: dict = {}
        self._lock = threading.Lock()

    def _program(self, leaves, tree):
        sig = (tree, tuple((jax.numpy.shape(v), jax.numpy.result_type(v), getattr(v, "weak_type", False))
                           for v in leaves))
        with self._lock:
            got = self._traced.get(sig)
            if got is None:
                def flat(*xs):
                    return self.fn(*jax.tree.unflatten(tree, xs))

                closed, shape = jax.make_jaxpr(flat, return_shape=True)(*leaves)
                program = _Program(closed, tree, jax.tree.structure(shape))
                got = (program, [c for i, c in enumerate(closed.consts) if i not in program.small])
                self._traced[sig] = got
            return got

    def __call__(self, *args):
        leaves, tree = jax.tree.flatten(args)
        program, consts = self._program(leaves, tree)
        return _run(program, consts, leaves)
