"""Shared test set-up: free compiled programs between test modules.

Every model compiles its own solve (one XLA executable per mesh and parametrisation); a pytest
worker that runs many modules otherwise keeps them all. (The worker that once grew past 11 GB
was mostly SciPy's SuperLU leaking factorisations freed on another thread, fixed in
jaxfem.linsolve; the executables are still worth freeing once a module is done with them.)
"""

import gc

import jax
import pytest


@pytest.fixture(autouse=True, scope="module")
def _free_compiled_programs():
    yield
    jax.clear_caches()
    gc.collect()
