"""Every notebook in notebooks/ executes headless from top to bottom without an error.

Not marked slow on purpose: CI runs it, so notebooks must stay fast (each well under the 600 s
timeout; the paper's Sec. 3.1 walk-through takes about two minutes on 2 cores).
"""

from __future__ import annotations

from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))
SLOW = {"real_cfrp.ipynb",  # real data in ../shared and two diagnoses of 2,800 points: minutes (tests/test_cfrp.py)
        "hand.ipynb",  # two scarred wrist motions and a tracked range sequence (a finer solve, two compiles): minutes
        "cup_holder.ipynb"}  # a 3D data solve and the 3D diagnosis (local and global fits): minutes


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.name in SLOW else p for p in NOTEBOOKS],
                         ids=[p.name for p in NOTEBOOKS])
def test_notebook_executes(path, tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(path.parent)}})
    client.execute()  # raises CellExecutionError naming the failing cell
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"]
    assert not errors
