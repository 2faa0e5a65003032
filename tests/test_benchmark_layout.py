"""benchmarks/ as a product (read, not imported: the suite depends on no benchmark): every
benchmark is a module with ``main(argv=None)`` that takes ``--quick``, the results are one
NAME.json (with targets that say pass or fail) and its figures per benchmark, the README's table
is the one ``python -m benchmarks --table`` writes, and no test imports a benchmark."""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
RESULTS = BENCH / "results"


def _benchmarks() -> dict[str, ast.FunctionDef]:
    found = {}
    for path in sorted(BENCH.glob("[!_]*.py")):
        tree = ast.parse(path.read_text(), str(path))
        main = next((n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "main"), None)
        if main is not None:
            found[path.stem] = main
    return found


def test_every_benchmark_has_main_of_argv_and_takes_quick():
    found = _benchmarks()
    assert len(found) >= 10
    for name, main in found.items():
        args = main.args
        assert [a.arg for a in args.args] == ["argv"] and isinstance(args.defaults[0], ast.Constant), name
        assert args.defaults[0].value is None, name
        source = (BENCH / f"{name}.py").read_text()
        delegates = re.search(r"return \w+\.main\(", source)  # another benchmark's main, with its options
        assert "--quick" in source or "quick(argv" in source or delegates, name


def test_results_are_one_json_per_benchmark_with_pass_or_fail_targets():
    names = set(_benchmarks())
    for path in sorted(p for p in RESULTS.iterdir() if p.is_file() and p.suffix in (".json", ".png")):
        stem = path.stem
        owner = stem if path.suffix == ".json" else next((n for n in names if stem == n or stem.startswith(n + "_")), None)
        assert owner in names, f"{path.name}: results are benchmarks/results/NAME.json and NAME.png of a benchmark"
        assert not re.search(r"_s\d\d|after_fix|before|seed\d|quiet|_h[a-z]+\d", stem), \
            f"{path.name} is named after a run: the canonical file is NAME.json"
        if path.suffix == ".json":
            targets = json.loads(path.read_text()).get("targets")
            assert isinstance(targets, dict) and targets, f"{path.name} has no targets section"
            judged = []
            for target, entry in targets.items():  # an entry without a verdict is informational
                assert isinstance(entry, dict), (path.name, target)
                verdicts = [entry["pass"]] if "pass" in entry else [v["pass"] for v in entry.values()
                                                                    if isinstance(v, dict) and "pass" in v]
                assert all(v in (True, False, None) for v in verdicts), (path.name, target)
                judged += [v for v in verdicts if v is not None]
            assert judged, f"{path.name}: no target says pass or fail"


def test_the_readme_is_short_and_its_table_is_the_generated_one():
    readme = (BENCH / "README.md").read_text()
    assert len(readme.splitlines()) < 400
    table = subprocess.run([sys.executable, "-m", "benchmarks", "--table"], cwd=ROOT, capture_output=True,
                           text=True, check=True).stdout
    assert table in readme, "the results table is stale: python -m benchmarks --table --write"
    listing = subprocess.run([sys.executable, "-m", "benchmarks"], cwd=ROOT, capture_output=True, text=True,
                             check=True).stdout
    assert all(name in listing for name in _benchmarks())


def test_no_test_imports_a_benchmark():
    bad = []
    for path in sorted((ROOT / "tests").glob("*.py")):
        text = path.read_text()
        for node in ast.walk(ast.parse(text, str(path))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            bad += [f"{path.name}:{node.lineno} imports {n}" for n in names if n.split(".")[0] == "benchmarks"]
        if re.search(r"sys\.path\.\w+\(.*benchmarks|spec_from_file_location\([^)]*benchmarks", text):
            bad.append(f"{path.name} loads a benchmark by path")
    assert not bad, "\n".join(bad)
