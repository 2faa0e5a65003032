"""Shared by the notebook generators: cells (kind, source) -> a notebook file, optionally executed.

Edit the cells in each ``_make_*.py``, not in the notebooks, so that the two never drift apart.
"""

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook


def build(cells) -> nbformat.NotebookNode:
    """A notebook from ``[("md" | "code", source), ...]`` with a python3 kernel."""
    nb = new_notebook()
    nb.cells = [new_markdown_cell(src) if kind == "md" else new_code_cell(src) for kind, src in cells]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    return nb


def write(cells, path: Path, execute: bool = False, cwd: Path | None = None) -> None:
    """Write the notebook to ``path``; with ``execute``, run it first (in ``cwd``) to store outputs."""
    nb = build(cells)
    if execute:
        from nbclient import NotebookClient

        NotebookClient(nb, timeout=600, kernel_name="python3",
                       resources={"metadata": {"path": str(cwd or path.parent)}}).execute()
    nbformat.write(nb, path)
    print(f"wrote {path}")
