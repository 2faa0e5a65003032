"""Executables kept whole on disk (jaxfem.executables): a second instance (as a later process
would) loads instead of compiling and gives the same bits; another dependency, another shape or
an edit of what a function closes over is another key; what JAX's persistent cache gives is not
written; no stable key, a traced argument or no cache folder: plain jax.jit; a damaged file is
dropped and compiled again."""

import numpy as np
import pytest

import jax
import jax.numpy as jnp
import jaxfem as jf
from jaxfem import cache
from jaxfem.executables import FOLDER, Kept, stable_key


@pytest.fixture
def folder(tmp_path):
    before = cache.cache_dir()
    jf.compilation_cache(tmp_path / "c")
    yield tmp_path / "c" / FOLDER
    jf.compilation_cache(before)


def _fn(c):
    def f(theta, x, s):
        return jnp.sin(theta["a"] * x) * c + s, jnp.sum(x)

    return f


def _args(rng, n):
    return {"a": rng.uniform(1, 2, n)}, rng.normal(size=n), float(rng.uniform())


def test_a_second_instance_loads_the_same_executable(folder):
    rng = np.random.default_rng(7)
    c = float(rng.uniform(1, 2))
    args = _args(rng, 5)
    before = jf.compile_counts()
    first = Kept(_fn(c), "t", ("x", 1))(*args)
    assert len(list(folder.iterdir())) == 1 and jf.compiles_since(before)["kept"] == 0
    before = jf.compile_counts()
    second = Kept(_fn(c), "t", ("x", 1))(*args)  # a new instance: as in a new process
    got = jf.compiles_since(before)
    assert got["kept"] == 1 and got["compiled"] == 0 and got["cached"] == 0
    for a, b, ref in zip(first, second, jax.jit(_fn(c))(*args)):
        assert np.array_equal(a, b) and np.array_equal(a, ref)
    Kept(_fn(c), "t", ("x", 1))(*_args(rng, 6))  # another shape
    Kept(_fn(c + 1.0), "t", ("x", 1))(*args)  # another closed-over constant
    assert len(list(folder.iterdir())) == 3
    before = jf.compile_counts()
    Kept(_fn(c), "t", ("x", 2))(*args)  # another dependency, the same program: JAX's cache gives it,
    got = jf.compiles_since(before)     # which is not written (it would serialize without its code)
    assert got["cached"] == 1 and got["kept"] == 0 and len(list(folder.iterdir())) == 3


def test_no_key_a_tracer_or_no_folder_is_plain_jit(folder, tmp_path):
    rng = np.random.default_rng(8)
    args = _args(rng, 4)
    assert stable_key(object()) is stable_key([1, object()]) and stable_key(("a", 1.5)) == stable_key(("a", 1.5))
    Kept(_fn(1.0), "t", object())(*args)  # no stable key
    k = Kept(_fn(1.0), "t")
    g = jax.grad(lambda a: k({"a": a}, args[1], 0.0)[0].sum())(args[0]["a"])  # traced: jit's path
    assert np.allclose(g, jax.grad(lambda a: _fn(1.0)({"a": a}, args[1], 0.0)[0].sum())(args[0]["a"]))
    assert not folder.exists() or not any(folder.iterdir())
    jf.compilation_cache(None)
    Kept(_fn(1.0), "t")(*args)
    assert not folder.exists() or not any(folder.iterdir())


def test_a_damaged_file_is_compiled_again(folder):
    args = _args(np.random.default_rng(9), 3)
    ref = Kept(_fn(2.0), "t")(*args)
    (path,) = folder.iterdir()
    path.write_bytes(b"not an executable")
    before = jf.compile_counts()
    got = Kept(_fn(2.0), "t")(*args)
    assert jf.compiles_since(before)["kept"] == 0 and np.array_equal(got[0], ref[0])
    assert not path.exists()  # dropped (JAX's cache gave the program again: not written)
    Kept(_fn(3.0), "t")(*args)
    assert jf.cache_info(folder.parent)["entries"] >= 1
    jf.clear_cache(folder.parent)
    assert not any(folder.iterdir())
