"""The figure of benchmarks/diagnose.py (split from it: the runner and its summary stay there)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from benchmarks._diagnose_oracle import GAIN_MIN, RATIO_TOL


def plot(results, path: Path):
    """The diagnosis benchmark's figure at ``path``: rates per cell (right cause, every criterion,
    false alarms) and, where the oracle's rows cover cases with an effect, the diagnosis's gain
    against the true model's and the ratio errors against their Cramer-Rao bounds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = results["groups"]
    if not groups:
        return
    rows = [r for g in groups for r in g["rows"]]
    gains = [(r["oracle_gain"], r["gain"]) for r in rows if r["truth"] and r.get("oracle_gain") and r["gain"]]
    ratios = [(s, e) for r in rows for e, s in zip(r["ratio_error"], r.get("oracle_ratio_std", []))]
    oracle = bool(gains)  # panels against the oracle where its rows cover cases with an effect
    fig = plt.figure(figsize=(11, 8 if oracle else 4))
    ax = fig.add_subplot(2, 1, 1) if oracle else fig.add_subplot(1, 1, 1)
    labels = [f"{g['cause']}\n{g['spacing']:.0f}mm/{g['noise']} (n={g['cases']})" for g in groups]
    x = np.arange(len(groups))
    bars = [("right cause", "right_cause_rate"), ("all criteria", "pass_rate")]
    if oracle:
        bars.append(("all criteria, over the cases where the data allow them (no bar: none do)",
                     "pass_rate_where_attainable"))
    bars.append(("false alarm", "false_alarm_rate"))
    w = 0.8 / len(bars)
    for i, (label, key) in enumerate(bars):
        ax.bar(x + (i - (len(bars) - 1) / 2) * w, [g.get(key) or 0 for g in groups], w, label=label)
    ax.set_xticks(x, labels, fontsize=6, rotation=90)
    ax.set_ylabel("rate")
    ax.legend(fontsize=7)
    if oracle:
        ax = fig.add_subplot(2, 2, 3)
        a, b = np.array(gains).T
        ax.loglog(a, b, ".", ms=4)
        lim = [min(a.min(), b.min()) * 0.9, max(a.max(), b.max()) * 1.1]
        ax.plot(lim, lim, "k-", lw=0.6, label="gain of the true model")
        ax.axhline(GAIN_MIN, color="r", lw=0.6, label=f"{GAIN_MIN:g}x")
        ax.axvline(GAIN_MIN, color="r", lw=0.6, ls=":")
        ax.set(xlabel="gain of the true model (oracle)", ylabel="gain of the diagnosis")
        ax.legend(fontsize=7)
    if oracle and ratios:
        ax = fig.add_subplot(2, 2, 4)
        a, b = np.array(ratios).T
        ax.loglog(a, np.maximum(b, 1e-4), ".", ms=4)
        ax.axhline(RATIO_TOL, color="r", lw=0.6, label="10 %")
        ax.axvline(RATIO_TOL / 2, color="r", lw=0.6, ls=":", label="bound 5 %: 10 % is 2 std")
        t = np.array([a.min(), a.max()])
        ax.plot(t, 2 * t, "k-", lw=0.6, label="2 x bound")
        ax.set(xlabel="Cramer-Rao bound of the ratio (relative, shape unknown)", ylabel="ratio error (relative)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")
