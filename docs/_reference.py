"""The API reference's pages, generated from the packages' public exports (an mkdocs hook).

Every public name of ``jaxfem``, ``tracking`` and ``refine`` gets a ``::: module.name`` block
(mkdocstrings renders its signature and docstring), so a new export appears in the site without
editing a page. The public names of a module are its ``__all__``; a module without one (``refine``'s
``threshold``, ``measures``, ``exceptions``) contributes the functions and classes it defines and its
upper-case constants. The modules documented: each package, its public subpackages (recursively),
and a plain public module where the package's ``__init__`` imports it by name (``from . import plot``)
or where the package exports nothing itself (``refine``, whose rooms are its API).

``pages()`` needs no mkdocs (tests/test_docs_reference.py checks the reference with it); the hooks
below add the pages and the notebooks to the build, the pages to the nav, and each command's
``--help`` to its page. (The docstrings' Sphinx roles are read by docs/_griffe_roles.py.)
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
import pkgutil
import re
import sys
from pathlib import Path

PACKAGES = ("jaxfem", "tracking", "refine")
ROOT = "reference"
REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:  # document this checkout, whichever copy of the packages is installed
    sys.path.insert(0, str(REPO))


def public_names(module) -> list[str]:
    """The public names of ``module``: its ``__all__``, or what it defines (see the module docstring)."""
    names = getattr(module, "__all__", None)
    if names is not None:
        return list(names)
    out = []
    for name, obj in vars(module).items():
        if name.startswith("_") or inspect.ismodule(obj):
            continue
        if inspect.isfunction(obj) or inspect.isclass(obj):
            if getattr(obj, "__module__", None) == module.__name__:
                out.append(name)
        elif name.isupper():
            out.append(name)
    return out


def _imported_by_name(package) -> set[str]:
    """Submodules the package's ``__init__`` imports as ``from . import NAME``."""
    tree = ast.parse(Path(package.__file__).read_text(encoding="utf-8"))
    return {alias.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
            and node.level == 1 and node.module is None for alias in node.names}


def documented_modules(package_name: str) -> list[str]:
    """The dotted names of the modules whose public names the reference shows, package first."""
    package = importlib.import_module(package_name)
    out = [package_name] if public_names(package) else []
    exports_nothing = not getattr(package, "__all__", None)
    by_name = _imported_by_name(package)
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        child = f"{package_name}.{info.name}"
        if info.ispkg:
            out += documented_modules(child)
        elif exports_nothing or info.name in by_name:
            if public_names(importlib.import_module(child)):
                out.append(child)
    return out


def target(module_name: str, name: str) -> str:
    """The dotted path mkdocstrings documents ``module_name.name`` by: that path, or the object's own
    where a submodule of the same name would be taken instead (``refine.cli.track`` is the command's
    function, ``refine.cli.track.track``, not its module)."""
    module = importlib.import_module(module_name)
    obj = getattr(module, name)
    if (not inspect.ismodule(obj) and hasattr(module, "__path__")
            and importlib.util.find_spec(f"{module_name}.{name}") is not None):
        return f"{obj.__module__}.{obj.__qualname__}"
    return f"{module_name}.{name}"


def page(module_name: str) -> str:
    """The markdown of one module's reference page: its docstring, then every public name."""
    module = importlib.import_module(module_name)
    lines = [f"# `{module_name}`", "", f"::: {module_name}", "    options:", "      members: false",
             "      show_root_heading: false", "      show_root_toc_entry: false", ""]
    for name in public_names(module):
        lines += [f"::: {target(module_name, name)}", ""]
    return "\n".join(lines)


def pages() -> dict[str, str]:
    """``{path under docs/: markdown}`` for the whole reference, its index included."""
    out, index = {}, ["# API reference", "",
                      "Generated from the public exports of each package (`__all__`); every name links "
                      "to its signature and docstring.", ""]
    for package in PACKAGES:
        index += [f"## `{package}`", ""]
        for module_name in documented_modules(package):
            path = f"{ROOT}/{module_name}.md"
            out[path] = page(module_name)
            names = ", ".join(f"[`{n}`]({module_name}.md#{target(module_name, n)})"
                              for n in public_names(importlib.import_module(module_name)))
            index += [f"- [`{module_name}`]({module_name}.md): {names}", ""]
    out[f"{ROOT}/index.md"] = "\n".join(index)
    return out


# --- mkdocs hooks (mkdocs.yml: hooks) ---------------------------------------------------------

try:  # the hooks need mkdocs; pages() does not
    from mkdocs.plugins import event_priority
except ImportError:  # pragma: no cover - imported by the test without mkdocs
    def event_priority(priority):
        return lambda f: f



NAV_TITLE = "API reference"
BENCHMARKS = "Benchmarks"


def benchmark_files() -> list[str]:
    """The files of benchmarks/ the site shows, as they are in the repository: its README (the page),
    its other Markdown pages, and the results (``results/*.json``, ``*.png``) they link to."""
    root = REPO / "benchmarks"
    found = [*root.glob("*.md"), *(root / "results").glob("*.json"), *(root / "results").glob("*.png")]
    return sorted(str(f.relative_to(REPO)) for f in found)


def on_config(config):
    """Replace the nav's ``API reference: reference/index.md`` by the index and a page per module,
    and ``Benchmarks: benchmarks/README.md`` by the README and benchmarks/'s other pages."""
    modules = [m for package in PACKAGES for m in documented_modules(package)]
    reference = [f"{ROOT}/index.md"] + [{m: f"{ROOT}/{m}.md"} for m in modules]
    benchmarks = ["benchmarks/README.md"] + [f for f in benchmark_files()
                                             if f.endswith(".md") and f != "benchmarks/README.md"]
    for k, entry in enumerate(config.nav or []):
        if isinstance(entry, dict) and NAV_TITLE in entry:
            config.nav[k] = {NAV_TITLE: reference}
        elif isinstance(entry, dict) and BENCHMARKS in entry:
            config.nav[k] = {BENCHMARKS: benchmarks}
    return config


@event_priority(100)  # before mkdocs-jupyter's on_files, which turns the notebooks into pages
def on_files(files, config):
    """Add the generated reference pages, the notebooks (``notebooks/*.ipynb``, as stored: executed
    by their ``_make_*.py``, never at build time) and :func:`benchmark_files` to the build."""
    from mkdocs.structure.files import File

    for path, content in pages().items():
        files.append(File.generated(config, path, content=content))
    shown = [f"notebooks/{nb.name}" for nb in sorted((REPO / "notebooks").glob("*.ipynb"))] + benchmark_files()
    for path in shown:
        files.append(File(path, src_dir=str(REPO), dest_dir=config.site_dir,
                          use_directory_urls=config.use_directory_urls))
    return files


_HELP = re.compile(r"^<!-- nonrigid-help:(?P<argv>[^>]*)-->$", re.M)


def command_help(argv: list[str]) -> str:
    """What ``nonrigid ARGV... --help`` prints (80 columns), from this checkout's parser."""
    import contextlib
    import io
    import os

    from refine.cli.main import build_parser

    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "80"  # argparse wraps to the terminal's width: the same page everywhere
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            build_parser().parse_args([*argv, "--help"])
    finally:
        if previous is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = previous
    return out.getvalue().rstrip()


def on_page_markdown(markdown, page, config, files):
    """``<!-- nonrigid-help: batch diagnose -->`` on a line of its own -> that command's ``--help``."""
    return _HELP.sub(lambda m: "```text\n" + command_help(m["argv"].split()) + "\n```", markdown)
