"""The benchmarks' runner.

    python -m benchmarks                  # the benchmarks, one line each
    python -m benchmarks NAME [--quick]   # run one (its own options after the name: NAME --help)
    python -m benchmarks --table          # the results table, from benchmarks/results/*.json
    python -m benchmarks --table --write  # ... written into benchmarks/README.md between its markers
    python -m benchmarks --check          # the benchmarks' own tests (benchmarks/tests: their scoring)

A benchmark is every ``benchmarks/NAME.py`` without a leading underscore that defines ``main``
(found by reading the files, nothing imported until one is run); its canonical results are
``benchmarks/results/NAME.json`` (a ``targets`` section: ``{name: {"target": ..., "value": ...,
"pass": bool}}``) and ``NAME.png``.
"""

from __future__ import annotations

import ast
import importlib
import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
README = HERE / "README.md"
BEGIN, END = "<!-- results table: python -m benchmarks --table --write -->", "<!-- end of results table -->"


def benchmarks() -> dict[str, str]:
    """``{NAME: one-line description}`` of every benchmark module, sorted by name."""
    found = {}
    for path in sorted(HERE.glob("[!_]*.py")):
        tree = ast.parse(path.read_text(), str(path))
        if any(isinstance(n, ast.FunctionDef) and n.name == "main" for n in tree.body):
            found[path.stem] = _first_sentence(ast.get_docstring(tree) or "")
    return found


def _first_sentence(doc: str) -> str:
    """The docstring's summary line (its first line, a trailing colon left off)."""
    return doc.strip().split("\n")[0].rstrip(":")


def _passed(entry) -> bool | None:
    """A target's verdict: its ``pass`` (or ``passed``); for an entry made of sub-targets, all of theirs."""
    if not isinstance(entry, dict):
        return entry if isinstance(entry, bool) else None
    for key in ("pass", "passed"):
        if key in entry:
            return entry[key]
    subs = [_passed(v) for v in entry.values() if isinstance(v, dict)]
    subs = [s for s in subs if s is not None]
    return all(subs) if subs else None


def _figure(entry) -> str:
    """A target's measured figure, short: its ``value`` (or ``measured``), rounded."""
    if not isinstance(entry, dict):
        return ""
    for key in ("value", "measured", "worst_percent", "seconds"):
        if key in entry and isinstance(entry[key], (int, float)) and not isinstance(entry[key], bool):
            return f"{entry[key]:.3g}"
    return ""


def _commit(name: str, result: dict) -> str:
    """The code that produced ``result``: its own ``commit`` (or ``code``) key, else the commit
    that last wrote the results file."""
    for key in ("commit", "code"):
        if isinstance(result.get(key), str):
            return result[key]
    try:
        out = subprocess.run(["git", "log", "-1", "--format=%h", "--", f"results/{name}.json"], cwd=HERE,
                             capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        out = ""
    return out or "uncommitted"


def table() -> str:
    """The markdown table of every benchmark: what it measures, its targets passed, the failing
    ones with their figures, and the commit of its results (read from ``results/NAME.json``)."""
    lines = ["| benchmark | what it measures | targets passed | failing (figure) | written at |",
             "| --- | --- | --- | --- | --- |"]
    for name, what in benchmarks().items():
        path = RESULTS / f"{name}.json"
        if not path.exists():
            lines.append(f"| `{name}` | {what} | no results yet | | |")
            continue
        result = json.loads(path.read_text())
        targets = result.get("targets") or {}
        verdicts = {t: _passed(e) for t, e in targets.items()}
        failing = [t[:60] + (f" ({_figure(targets[t])})" if _figure(targets[t]) else "")
                   for t, v in verdicts.items() if v is False]
        shown = "; ".join(failing[:3]) + (f"; and {len(failing) - 3} more" if len(failing) > 3 else "")
        judged = [v for v in verdicts.values() if v is not None]
        lines.append(f"| [`{name}`](results/{name}.json) | {what} | {sum(judged)}/{len(judged)} | "
                     f"{shown or '-'} | {_commit(name, result)} |")
    return "\n".join(lines) + "\n"


def write_table(readme: Path = README) -> None:
    """Replace the table between the README's markers with :func:`table`."""
    text = readme.read_text()
    head, found, rest = text.partition(BEGIN)
    _, found_end, tail = rest.partition(END)
    if not (found and found_end):
        raise SystemExit(f"{readme} has no {BEGIN!r} ... {END!r} markers: add them where the table goes")
    readme.write_text(f"{head}{BEGIN}\n{table()}{END}{tail}")


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "--list"):
        found = benchmarks()
        width = max(map(len, found), default=0)
        print(__doc__.split("\n\n")[1] if argv[:1] in (["-h"], ["--help"]) else "benchmarks (python -m benchmarks NAME [--quick]):")
        for name, what in found.items():
            print(f"  {name:<{width}}  {what}")
        return 0
    if argv[0] == "--table":
        if argv[1:] == ["--write"]:
            write_table()
        else:
            print(table(), end="")
        return 0
    if argv[0] == "--check":  # their scoring on made-up rows: not the library's suite (tests/)
        return subprocess.run([sys.executable, "-m", "pytest", "-q", str(HERE / "tests"), *argv[1:]]).returncode
    name, rest = argv[0], argv[1:]
    if name not in benchmarks():
        print(f"no benchmark named {name!r}: `python -m benchmarks` lists them", file=sys.stderr)
        return 2
    code = importlib.import_module(f"benchmarks.{name}").main(rest)
    return 0 if code is None else int(code)


if __name__ == "__main__":
    raise SystemExit(main())
