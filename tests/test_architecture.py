"""The house rules of docs/architecture.md, checked on the source: imports run one way and modules
stay small. Static (the modules are parsed, not imported), so it runs in a second."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("jaxfem", "refine", "tracking")

# refine's rooms, lowest first: a room imports only from rooms of a lower or equal layer
REFINE_LAYERS = {
    "refine": 0, "refine.exceptions": 0, "refine.measures": 0, "refine.threshold": 0,
    "refine.bundle": 1,
    "refine.model": 2,
    "refine.optimize": 3,
    "refine.diagnosis": 4, "refine.causes": 4, "refine.demo_data": 4, "refine.correspond": 4, "refine.solid": 4,
    "refine.reports": 0,
    "refine.api": 4,  # the entry point: refine.diagnose, over refine.diagnosis and refine.solid
    "refine.batch": 5,
    "refine.cli": 6,
}
MAX_LINES = 420  # "about 400 lines"


def _modules():
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            yield path, ".".join(path.relative_to(ROOT).with_suffix("").parts)


def _imports(path: Path, module: str):
    """Absolute names of the modules ``path`` imports (relative imports resolved)."""
    tree = ast.parse(path.read_text(), str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module
            yield node.lineno, name
            for alias in node.names:  # `from refine import optimize` imports refine.optimize
                yield node.lineno, f"{name}.{alias.name}"


def _room(name: str) -> str | None:
    parts = name.split(".")
    for k in (2, 1):
        if ".".join(parts[:k]) in REFINE_LAYERS:
            return ".".join(parts[:k])
    return None


def test_jaxfem_and_tracking_know_nothing_of_the_layers_above():
    bad = []
    for path, module in _modules():
        top = module.split(".")[0]
        forbidden = {"jaxfem": ("refine", "tracking"), "tracking": ("refine", "jaxfem")}.get(top, ())
        for line, name in _imports(path, module):
            if name.split(".")[0] in forbidden:
                bad.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert not bad, "\n".join(bad)


def test_refine_rooms_import_only_from_lower_rooms():
    bad = []
    for path, module in _modules():
        if not module.startswith("refine"):
            continue
        own = _room(module)
        for line, name in _imports(path, module):
            if not name.startswith("refine"):
                continue
            other = _room(name)
            if other is None:
                # a name imported from a room's package (``from refine.bundle import Bundle``) has no room of its own
                continue
            if REFINE_LAYERS[other] > REFINE_LAYERS[own]:
                bad.append(f"{path.relative_to(ROOT)}:{line} ({own}) imports {name} ({other}, a higher layer)")
    assert not bad, "\n".join(bad)


def test_every_refine_module_belongs_to_a_room():
    loose = [module for _, module in _modules() if module.startswith("refine") and _room(module) is None]
    assert not loose


def test_the_library_imports_no_example_and_no_test():
    """jaxfem, refine and tracking run after ``pip install .`` from a clone without examples/ or tests/."""
    bad = [f"{path.relative_to(ROOT)}:{line} imports {name}" for path, module in _modules()
           for line, name in _imports(path, module) if name.split(".")[0] in ("examples", "tests", "benchmarks")]
    assert not bad, "\n".join(bad)


def test_jaxfem_defines_no_particular_body():
    """A body is data: no module or package of jaxfem is named after one of the paper's bodies."""
    bodies = ("hand", "cup", "cup_holder", "skin", "block", "paper")
    named = [module for _, module in _modules() if module.startswith("jaxfem")
             and any(part in bodies for part in module.split(".")[1:])]
    assert not named, f"move these bodies to examples/: {named}"


@pytest.mark.parametrize("pkg", PACKAGES + ("benchmarks", "examples"))
def test_no_module_is_much_over_400_lines(pkg):
    long = {str(p.relative_to(ROOT)): n for p in sorted((ROOT / pkg).rglob("*.py"))
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"split these modules by concern: {long}"
