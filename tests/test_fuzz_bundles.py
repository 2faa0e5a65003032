"""Fuzz the reading of measurement bundles: every mutated bundle either reads and validates or
raises a RefineError with a one-line message; through ``nonrigid diagnose`` / ``simulate`` it exits
2 with one line on stderr and no traceback; the bundle's files are never changed.

The mutations start from a small valid bundle (the first points of
/work/shared/examples' sheet-stiff-inclusion layout, rewritten here): truncated, dropped,
duplicated and reordered rows, NaN / inf / 1e300 / 5000-digit cells, missing and duplicated ids,
wrong headers and cell counts, BOM, CRLF, bytes that are not UTF-8, NUL bytes, empty and missing
files, wrong TOML values and units, frames that do not match, unicode folder names. The default
suite runs a fast subset; ``-m slow`` runs >= 1,500 bundles and prints the tally.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import given, strategies as st

from refine.exceptions import RefineError
from tests._fuzz_util import Tally, fixed, one_line, run_cli, snapshot

EXPERIMENT = """[experiment]
name = "fuzz"
units = { length = "mm", stress = "kPa", force = "mN" }

[model]
kind = "plane-stress"
thickness = 1.0
domain = { rectangle = [0.0, 0.0, 40.0, 20.0] }

[material]
law = "neo-hookean"
E = 80.0
nu = 0.3

[measurement]
noise_std = 0.02
"""
_GRID = [(i * 10.0, j * 10.0) for j in range(3) for i in range(5)]
POINTS = "id,x,y,role\n" + "".join(
    f"{k + 1},{x:.6f},{y:.6f},{'boundary' if x in (0.0, 40.0) else 'guide'}\n" for k, (x, y) in enumerate(_GRID))
DISPLACEMENTS = "frame,id,ux,uy\n" + "".join(
    f"{f},{k + 1},{0.01 * f * x:.6f},{-0.003 * f * y:.6f}\n" for f in (1, 2) for k, (x, y) in enumerate(_GRID))
FORCES = "frame,edge,fx,fy\n1,right,12.5,0.0\n2,right,25.0,0.0\n"
FILES = {"experiment.toml": EXPERIMENT, "points.csv": POINTS, "displacements.csv": DISPLACEMENTS,
         "forces.csv": FORCES}

CELLS = ["nan", "NaN", "inf", "-inf", "1e300", "-1e300", "1e309", "", "abc", "1e", "0", "-1", "-0", "99999",
         "9" * 30, "9" * 5000, "é", "0x10", "1_000", " 3 ", "boundary", "guide", "validate", "interior", "1.5", '"', "right",
         "3", "2", "1"]
HEADERS = ["id,x,y", "id,x,y,z,role", "frame,id,ux", "x,y,id,role", "", "ID,X,Y,ROLE", "frame,id,ux,uy,uz",
           "frame,edge,fx", "id;x;y;role"]
VALUES = ["nan", "inf", "-inf", "1e300", "-1.0", "0", '"abc"', "[]", "{}", "true", '"é✓"', "[1.0, 2.0]",
          "{ rectangle = [0.0, 0.0, 0.0, 0.0] }", "{ rectangle = [40.0, 20.0, 0.0, 0.0] }",
          '{ mesh = "missing.msh" }', '{ length = "furlong" }', '{ length = "mm" }', "1e-300", "9" * 30,
          '"solid"', '"plane-strain"', '"unknown-law"', "-0.5", "0.5", "0.49999"]
LINES = ['mesh = "missing.msh"', "[diagnose]", "[diagnose]\nunknown_setting = 1", "[model]", "E = 1e300",
         'units = "mm"', "[[model.sides]]", "x = [", "noise_std = -1"]
BAD_BYTES = [b"\xff\xfe", b"\x00", b"\xef\xbb\xbf", b"\r", b"\x80abc", b'"', b",,,", b"\n\n"]

_name = st.text(st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters="/\\"), min_size=1,
                max_size=10).filter(lambda s: s not in (".", "..") and len(s.encode()) < 200)
_csv_op = st.one_of(
    st.tuples(st.just("truncate"), st.floats(0, 1)),
    st.tuples(st.just("drop"), st.integers(0, 40)),
    st.tuples(st.just("duplicate"), st.integers(0, 40)),
    st.tuples(st.just("swap"), st.integers(0, 40), st.integers(0, 40)),
    st.tuples(st.just("reverse")),
    st.tuples(st.just("cell"), st.integers(0, 40), st.integers(0, 4), st.sampled_from(CELLS)),
    st.tuples(st.just("cells"), st.integers(0, 40), st.integers(-2, 2)),
    st.tuples(st.just("header"), st.sampled_from(HEADERS)))
_toml_op = st.one_of(
    st.tuples(st.just("truncate"), st.floats(0, 1)),
    st.tuples(st.just("drop"), st.integers(0, 20)),
    st.tuples(st.just("value"), st.integers(0, 20), st.sampled_from(VALUES)),
    st.tuples(st.just("insert"), st.integers(0, 20), st.sampled_from(LINES)))
_any_op = st.one_of(st.tuples(st.just("bytes"), st.floats(0, 1), st.sampled_from(BAD_BYTES)),
                    st.tuples(st.just("bom")), st.tuples(st.just("crlf")), st.tuples(st.just("empty")),
                    st.tuples(st.just("delete")))
_mutation = st.one_of(
    st.tuples(st.sampled_from(["points.csv", "displacements.csv", "forces.csv"]), _csv_op),
    st.tuples(st.just("experiment.toml"), _toml_op),
    st.tuples(st.sampled_from(sorted(FILES)), _any_op))
cases = st.tuples(_name, st.lists(_mutation, min_size=0, max_size=4), st.booleans())


def mutate(text: bytes, op: tuple) -> bytes | None:
    """``text`` changed by one mutation ``op``; None deletes the file."""
    kind, *a = op
    lines = text.split(b"\n")
    if kind == "truncate":
        return text[:int(a[0] * len(text))]
    if kind == "drop" and lines:
        del lines[a[0] % len(lines)]
    elif kind == "duplicate" and lines:
        lines.insert(a[0] % len(lines), lines[a[0] % len(lines)])
    elif kind == "swap" and lines:
        i, j = a[0] % len(lines), a[1] % len(lines)
        lines[i], lines[j] = lines[j], lines[i]
    elif kind == "reverse":
        lines = lines[:1] + lines[1:][::-1]
    elif kind == "cell" and len(lines) > 1:
        i = 1 + a[0] % (len(lines) - 1)
        cells = lines[i].split(b",")
        cells[a[1] % len(cells)] = a[2].encode()
        lines[i] = b",".join(cells)
    elif kind == "cells" and len(lines) > 1:
        i = 1 + a[0] % (len(lines) - 1)
        cells = lines[i].split(b",")
        lines[i] = b",".join(cells[:a[1]] if a[1] < 0 else cells + [b"1"] * a[1])
    elif kind == "header":
        lines[0] = a[0].encode()
    elif kind == "value" and lines:
        i = a[0] % len(lines)
        if b"=" in lines[i]:
            lines[i] = lines[i].split(b"=")[0] + b"= " + a[1].encode()
    elif kind == "insert":
        lines.insert(a[0] % (len(lines) + 1), a[1].encode())
    elif kind == "bytes":
        k = int(a[0] * len(text))
        return text[:k] + a[1] + text[k:]
    elif kind == "bom":
        return b"\xef\xbb\xbf" + text
    elif kind == "crlf":
        return text.replace(b"\n", b"\r\n")
    elif kind == "empty":
        return b""
    elif kind == "delete":
        return None
    return b"\n".join(lines)


def make_bundle(root: Path, name: str, mutations, forces: bool) -> Path:
    bundle = root / "in" / name
    bundle.mkdir(parents=True)
    content = {f: t.encode() for f, t in FILES.items() if forces or f != "forces.csv"}
    for file, op in mutations:
        if content.get(file) is not None:
            content[file] = mutate(content[file], op)
    for file, data in content.items():
        if data is not None:
            (bundle / file).write_bytes(data)
    return bundle


def validate(path: Path):
    """What ``nonrigid diagnose`` does before any solve: read the bundle and its settings."""
    from refine.bundle.io import read_bundle
    from refine.cli.diagnose import settings_of

    bundle = read_bundle(path)
    if bundle.observations is not None:
        settings_of(bundle)
    return bundle


def _unreadable(path: Path) -> bool:
    """Whether the bundle itself is refused (not only its ``[diagnose]`` settings)."""
    from refine.bundle.io import read_bundle

    try:
        read_bundle(path)
    except RefineError:
        return True
    return False


def check_case(name, mutations, forces, tally: Tally, cli: bool):
    root = Path(tempfile.mkdtemp(prefix="fuzz-bundle-"))
    try:
        bundle = make_bundle(root, name, mutations, forces)
        before = snapshot(root / "in")
        outcome = "ok"
        try:
            validate(bundle)
        except RefineError as e:
            outcome = "error" if one_line(str(e)) else "traceback"
            message = str(e)
        except Exception as e:  # noqa: BLE001 - the failure this suite looks for
            outcome, message = "traceback", f"{type(e).__name__}: {e}"
        if outcome == "error" and cli:
            # simulate reads no [diagnose] table: it must refuse only what read_bundle refuses
            for command in ("diagnose", "simulate") if _unreadable(bundle) else ("diagnose",):
                rc, err = run_cli([command, str(bundle), "--out", str(root / "out" / command)])
                if rc != 2 or not one_line(err) or not err.startswith(f"nonrigid {command}: error: "):
                    outcome, message = "traceback", f"{command}: exit {rc}: {err!r}"
        if snapshot(root / "in") != before:
            outcome = "modified"
        tally[outcome] += 1
        assert outcome in ("ok", "error"), (mutations, message if outcome != "modified" else "files changed")
    finally:
        shutil.rmtree(root, ignore_errors=True)


def test_base_bundle_reads():
    """The unmutated bundle is valid: the fuzz starts from something that works."""
    tally = Tally()
    check_case("base", [], True, tally, cli=False)
    assert tally["ok"] == 1


FAST, SLOW = Tally(), Tally()


@fixed(120)
@given(cases)
def test_fuzz_bundles_fast(case):
    check_case(*case, FAST, cli=len(case[1]) % 3 == 1)


@pytest.mark.slow
def test_fuzz_bundles_slow():
    """>= 1,500 generated bundles (with test_fuzz_images' slow test, >= 2,000 inputs); prints the tally."""
    @fixed(1500)
    @given(cases)
    def run(case):
        check_case(*case, SLOW, cli=len(case[1]) % 3 == 1)

    run()
    print(SLOW.line("bundles"))
    assert sum(SLOW.values()) >= 1500 and SLOW["traceback"] == SLOW["modified"] == 0
