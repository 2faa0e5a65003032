"""Shared by the notebook generators: cells (kind, source) -> a notebook file, optionally executed.

Edit the cells in each ``_make_*.py``, not in the notebooks, so that the two never drift apart.
"""

import os
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook


def build(cells) -> nbformat.NotebookNode:
    """A notebook from ``[("md" | "code", source), ...]`` with a python3 kernel."""
    nb = new_notebook()
    nb.cells = [new_markdown_cell(src) if kind == "md" else new_code_cell(src) for kind, src in cells]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    return nb


INLINE = "module://matplotlib_inline.backend_inline"
REPO = Path(__file__).resolve().parents[1]


def write(cells, path: Path, execute: bool = False, cwd: Path | None = None, timeout: int = 600) -> None:
    """Write the notebook to ``path``; with ``execute``, run it first (in ``cwd``) to store outputs.

    The kernel draws figures inline whatever ``MPLBACKEND`` the shell has (``Agg`` there would run
    every plotting cell and store no figure) and imports this checkout's packages first (not an
    installed copy elsewhere); ``timeout`` is nbclient's limit per cell, in seconds.
    """
    nb = build(cells)
    if execute:
        from nbclient import NotebookClient

        previous = {k: os.environ.get(k) for k in ("MPLBACKEND", "PYTHONPATH")}
        os.environ["MPLBACKEND"] = INLINE  # the kernel inherits this process's environment
        os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), previous["PYTHONPATH"]) if p)
        try:
            NotebookClient(nb, timeout=timeout, kernel_name="python3",
                           resources={"metadata": {"path": str(cwd or path.parent)}}).execute()
        finally:
            for key, value in previous.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value
    nbformat.write(nb, path)
    figures = sum("image/png" in o.get("data", {}) for c in nb.cells for o in c.get("outputs", []))
    print(f"wrote {path}" + (f" ({figures} figures)" if execute else ""))
