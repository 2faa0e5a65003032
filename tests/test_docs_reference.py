"""The documentation site's API reference (docs/_reference.py, an mkdocs hook) shows every public
name of ``jaxfem``, ``tracking`` and ``refine`` with its docstring; no mkdocs needed here.

Public here means: the ``__all__`` of every package and public subpackage found by walking the
packages (not the generator's own list), and what a public top-level module of ``refine`` defines
(``refine`` itself exports nothing: its rooms and modules are the API). The build itself
(``mkdocs build --strict``) runs in .ci/run.
"""

from __future__ import annotations

import importlib
import importlib.util
import inspect
import pkgutil
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("jaxfem", "tracking", "refine")


@pytest.fixture(scope="module")
def reference():
    spec = importlib.util.spec_from_file_location("_docs_reference", ROOT / "docs" / "_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _public_packages():
    """Every package and subpackage of the three whose dotted path has no ``_`` part."""
    for name in PACKAGES:
        package = importlib.import_module(name)
        yield package
        for info in pkgutil.walk_packages(package.__path__, prefix=f"{name}."):
            if info.ispkg and not any(part.startswith("_") for part in info.name.split(".")):
                yield importlib.import_module(info.name)


def _expected() -> set[str]:
    names = {f"{p.__name__}.{n}" for p in _public_packages() for n in getattr(p, "__all__", ())}
    refine = importlib.import_module("refine")
    for info in pkgutil.iter_modules(refine.__path__):
        if not info.ispkg and not info.name.startswith("_"):
            module = importlib.import_module(f"refine.{info.name}")
            names |= {f"{module.__name__}.{n}" for n, obj in vars(module).items() if not n.startswith("_")
                      and (inspect.isfunction(obj) or inspect.isclass(obj)) and obj.__module__ == module.__name__}
    return names


def test_every_public_name_is_in_the_reference_with_a_docstring(reference):
    pages = reference.pages()
    directives = {m for text in pages.values() for m in re.findall(r"^::: (\S+)$", text, re.M)}
    # a public name is shown when its page has a directive for it (its own path, or the object's
    # where a submodule of that name would be documented instead: reference.target)
    shown = {f"{m}.{n}" for p in PACKAGES for m in reference.documented_modules(p)
             for n in reference.public_names(importlib.import_module(m)) if reference.target(m, n) in directives}
    expected = _expected()
    assert len(expected) > 200  # the three packages' exports (259 once the paper's bodies left for examples/), not an empty walk
    missing = sorted(expected - shown)
    assert not missing, f"public names missing from the API reference: {missing}"
    undocumented = []
    for dotted in sorted(shown & expected):
        module, name = dotted.rsplit(".", 1)
        obj = getattr(importlib.import_module(module), name)
        doc = (obj.__doc__ or "").strip() if inspect.isfunction(obj) or inspect.isclass(obj) else "constant"
        if not doc or doc.startswith(f"{getattr(obj, '__name__', '')}("):  # a dataclass' generated signature
            undocumented.append(dotted)
    assert not undocumented, f"public functions or classes without a docstring: {undocumented}"


def test_every_reference_page_is_in_the_nav_and_every_command_page_has_its_help(reference):
    pages = reference.pages()
    modules = [m for p in PACKAGES for m in reference.documented_modules(p)]
    assert sorted(pages) == sorted([f"reference/{m}.md" for m in modules] + ["reference/index.md"])
    for page in sorted((ROOT / "docs" / "commands").glob("*.md")):
        for argv in re.findall(r"^<!-- nonrigid-help:([^>]*)-->$", page.read_text(), re.M):
            assert reference.command_help(argv.split()).startswith("usage: nonrigid"), (page.name, argv)
