"""The persistent compilation cache (jaxfem.cache): on by default in a folder the environment can
move or turn off, programs loaded by a later process instead of compiled, the process's compile
counts telling the two apart, and ``nonrigid cache info | clear`` on a folder of its own."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem as jf
from jaxfem.cache import CACHE_DIR_ENV, CACHE_ENV, default_cache_dir
from refine.cli.main import main

ROOT = Path(__file__).resolve().parent.parent

# a program of its own per run (a random constant in it), compiled in a fresh process; prints
# the cache folder in use and the process's counts
PROGRAM = """
import sys, jax, jax.numpy as jnp, jaxfem as jf
c = float(sys.argv[1])
print(jax.jit(lambda x: jnp.sin(x) * c + jnp.cos(x) ** 2)(jnp.arange(5.0)).sum())
n = jf.compile_counts()
print(jf.cache.cache_dir(), n["compiled"], n["cached"], n["by_name"].get("jit(<lambda>)"))
"""


def _run(env_extra: dict, constant: float) -> tuple[str, int, int, list]:
    env = {k: v for k, v in os.environ.items() if k not in (CACHE_ENV, CACHE_DIR_ENV, "JAX_COMPILATION_CACHE_DIR")}
    out = subprocess.run([sys.executable, "-c", PROGRAM, repr(constant)], cwd=ROOT, env={**env, **env_extra},
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    where, compiled, cached, row = out.stdout.strip().splitlines()[-1].split(" ", 3)
    return where, int(compiled), int(cached), ast.literal_eval(row)


@pytest.fixture
def constant():
    return float(np.random.default_rng(int.from_bytes(os.urandom(4), "little")).uniform(1, 2))


def test_a_second_process_loads_the_programs_from_the_folder_given(tmp_path, constant):
    folder = tmp_path / "programs"
    where, compiled, cached, row = _run({CACHE_DIR_ENV: str(folder)}, constant)
    assert Path(where) == folder and compiled >= 1 and row[0] == 1 and row[2] == 0  # compiled, not loaded
    assert jf.cache_info(folder)["entries"] >= compiled  # every program written, however quick
    where, compiled, cached, row = _run({CACHE_DIR_ENV: str(folder)}, constant)
    assert row[0] == 0 and row[2] == 1 and cached >= 1  # loaded, not compiled
    _, _, _, row = _run({CACHE_DIR_ENV: str(folder)}, constant + 1.0)  # another program: compiled
    assert row[0] == 1 and row[2] == 0


def test_the_cache_can_be_turned_off(tmp_path, constant):
    folder = tmp_path / "programs"
    where, compiled, cached, row = _run({CACHE_ENV: "0", CACHE_DIR_ENV: str(folder)}, constant)
    assert where == "None" and row[0] == 1 and cached == 0 and not folder.exists()


def test_the_default_folder_follows_xdg_cache_home(monkeypatch, tmp_path):
    for var in (CACHE_ENV, CACHE_DIR_ENV, "JAX_COMPILATION_CACHE_DIR"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / "nonrigid" / "jax"
    monkeypatch.setenv(CACHE_DIR_ENV, str(tmp_path / "elsewhere"))
    assert default_cache_dir() == tmp_path / "elsewhere"
    monkeypatch.setenv(CACHE_ENV, "off")
    assert default_cache_dir() is None


@pytest.fixture
def own_cache(tmp_path):
    """This process's cache moved to a folder of its own, and back afterwards."""
    before = jf.cache.cache_dir()
    jf.compilation_cache(tmp_path / "programs")
    yield tmp_path / "programs"
    jf.compilation_cache(before)


def test_compile_counts_and_cache_info_and_clear(own_cache, constant, capsys):
    before = jf.compile_counts()
    jax.jit(lambda x: jnp.tanh(x) * constant)(jnp.ones(3)).block_until_ready()
    grew = jf.compiles_since(before)
    assert grew["compiled"] >= 1 and grew["cached"] == 0 and grew["compile_seconds"] > 0
    assert any(name == "jit(<lambda>)" and n == 1 for name, n, _ in grew["slowest"])
    (own_cache / "notes.txt").write_text("not the cache's")
    assert main(["cache", "info", "--dir", str(own_cache)]) == 0
    info = capsys.readouterr().out
    n = jf.cache_info(own_cache)["entries"]
    assert n >= 1 and str(own_cache) in info and f": {n} compiled programs" in info and "used by runs now" in info
    assert main(["cache", "clear", "--dir", str(own_cache)]) == 0
    assert f"deleted {n} compiled programs" in capsys.readouterr().out
    assert jf.cache_info(own_cache)["entries"] == 0 and (own_cache / "notes.txt").exists()  # only the cache's files
