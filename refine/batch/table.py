"""The results table of a batch: ``results.jsonl`` in the output directory, one JSON row per bundle,
appended as each bundle finishes (so an interrupted batch keeps what finished); read back with the
last row of each bundle winning, summarised as text and drawn.

A row holds:

- ``bundle``: the bundle directory (absolute path); ``name``: its report's folder in the output
  directory (``out/<name>/``: report.json, figures, log.txt; error.txt when it failed).
- ``cause``: the causes found, joined by ``+`` (``"none"`` when the initial model explains the data);
  ``findings``: per finding its ``cause``, ``centroid`` (length unit of the bundle),
  ``relative_elasticity`` (x the background) and ``law`` (a material-law finding).
- ``centroid``, ``relative_elasticity``: those of the first finding (None without one).
- ``gain``: validation error of the initial model / of the refined one (None without a finding);
  ``p_value``: the null test's.
- ``seconds``: wall seconds of the whole task on its worker (reading, diagnosis, report);
  ``diagnosis_seconds``: the diagnosis' own, from report.json.
- ``worker``, ``host``: where it ran.
- ``error``: None, or ``{"type": ..., "message": ...}`` of what stopped the bundle.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

RESULTS = "results.jsonl"


def row_from_report(report: dict) -> dict:
    """The table's columns taken from a diagnosis' report.json content (any schema: read as
    schema 2, :func:`refine.reports.upgrade`; a 3D finding's centroid has three coordinates)."""
    from refine.reports import upgrade

    report = upgrade(report)
    findings = [{"cause": f["cause"],
                 "centroid": f["centroid"],
                 "relative_elasticity": f.get("relative_elasticity"),
                 "law": f.get("law")} for f in report["findings"]]
    first = findings[0] if findings else {}
    return {"cause": "+".join(f["cause"] for f in findings) or "none", "findings": findings,
            "centroid": first.get("centroid"), "relative_elasticity": first.get("relative_elasticity"),
            "gain": report["gain"]["validation_error"], "p_value": report["decision"]["p_value"],
            "diagnosis_seconds": report["seconds"]}


def append_row(path: Path, row: dict) -> None:
    """Append ``row`` to the JSONL file ``path`` and flush it to disk at once."""
    with open(path, "a") as f:
        f.write(json.dumps(row) + "\n")
        f.flush()


def read_rows(path: Path) -> list[dict]:
    """Every row of the JSONL file ``path`` in file order; none when it does not exist. A line cut
    short by a killed run is skipped (its bundle runs again)."""
    if not Path(path).is_file():
        return []
    rows = []
    for line in Path(path).read_text().splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(row, dict) and "bundle" in row:
            rows.append(row)
    return rows


@dataclass(frozen=True)
class Table:
    """Rows of a batch, one per bundle (see the module docstring for the columns)."""

    rows: tuple[dict, ...]

    @classmethod
    def read(cls, out: str | Path, bundles=None) -> Table:
        """The table of output directory ``out``: the last row of each bundle, in the order of
        ``bundles`` (paths; only those) or else of the file."""
        latest = {}
        for row in read_rows(Path(out) / RESULTS):
            latest[row["bundle"]] = row
        if bundles is None:
            return cls(tuple(latest.values()))
        return cls(tuple(latest[k] for k in (str(Path(b).resolve()) for b in bundles) if k in latest))

    @property
    def failed(self) -> tuple[dict, ...]:
        """Rows of the bundles that stopped with an error."""
        return tuple(r for r in self.rows if r.get("error"))

    def by_bundle(self) -> dict[str, dict]:
        """``{bundle path: row}``."""
        return {r["bundle"]: r for r in self.rows}

    def summary(self) -> str:
        """A text table of the bundles, then counts per cause and the seconds."""
        lines = [f"{'bundle':28s} {'cause':28s} {'centroid':>15s} {'ratio':>7s} {'gain':>6s} {'s':>6s}"]
        for r in self.rows:
            if r.get("error"):
                lines.append(f"{r['name'][:28]:28s} ERROR {r['error']['type']}: {r['error']['message'][:80]}")
                continue
            c = r.get("centroid")
            centroid = f"({c[0]:.1f}, {c[1]:.1f})" if c else "-"
            ratio = f"{r['relative_elasticity']:.3g}" if r.get("relative_elasticity") is not None else "-"
            gain = f"{r['gain']:.2f}" if r.get("gain") else "-"
            lines.append(f"{r['name'][:28]:28s} {r['cause'][:28]:28s} {centroid:>15s} {ratio:>7s} {gain:>6s} "
                         f"{r['seconds']:6.1f}")
        ok = [r for r in self.rows if not r.get("error")]
        counts = Counter(r["cause"] for r in ok)
        lines.append("")
        lines.append(f"{len(self.rows)} bundles: {len(ok)} diagnosed, {len(self.failed)} failed"
                     + ("; " + ", ".join(f"{k} {n}" for k, n in sorted(counts.items())) if counts else ""))
        if ok:
            s = sorted(r["seconds"] for r in ok)
            lines.append(f"seconds per bundle: median {s[len(s) // 2]:.1f}, max {s[-1]:.1f}, sum {sum(s):.0f}")
        return "\n".join(lines)

    def plot(self, path: str | Path) -> Path:
        """Draw the counts per cause (failures as ``error``) and the seconds per bundle by cause
        into the image ``path``; return it."""
        from matplotlib.figure import Figure

        causes = [("error" if r.get("error") else r["cause"]) for r in self.rows]
        kinds = sorted(set(causes))
        fig = Figure(figsize=(11, 4))
        a, b = fig.subplots(1, 2)
        a.bar(kinds, [causes.count(k) for k in kinds], color="tab:blue")
        a.set_ylabel("bundles")
        a.set_title("causes found")
        a.tick_params(axis="x", rotation=30)
        seconds = [[r["seconds"] for r, c in zip(self.rows, causes) if c == k and r.get("seconds") is not None]
                   for k in kinds]
        if any(seconds):
            b.hist(seconds, bins=min(20, max(3, len(self.rows))), stacked=True, label=kinds)
            b.legend(fontsize=8)
        b.set_xlabel("seconds per bundle (on its worker)")
        b.set_ylabel("bundles")
        b.set_title("time")
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        return Path(path)
