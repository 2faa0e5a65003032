"""Offline check (issue 23, session 23): would a discretisation allowance from the move between two
fit meshes hold the truths of inclusion3d's rows, and how wide would it make the intervals?

No solve: it reads rows already in benchmarks/results/ that hold one inclusion fitted on two meshes
of the same data, takes Richardson's estimate of the finer fit's error, |q_coarse - q_fine| /
(factor^2 - 1) (the log ratio's, the volume's, the strength's; ``factor`` the ratio of the meshes'
cell sizes), and widens the finer fit's profile intervals by it as the diagnosis now does
(refine.solid.inclusion_total.total_interval: each side and 2 discretisation errors in quadrature).
The pairs (no row holds the refit the diagnosis now makes, on the graded box sqrt 2 coarser):

- s22 seeds 12, 21: the 4 mm model's fit (report.json's coarse_fit) and the graded fit (2.5 mm over
  the inclusion, 5 mm away), data 2.0 mm; factor 4 / 2.5 = 1.6 (over the inclusion);
- seeds 11, 13 on the older 2.5 mm data: the 4 mm model's fit (inclusion3d_4mm.json) and a uniform
  3 mm fit mesh (inclusion3d_hfit3*.json); factor 4 / 3.

    python benchmarks/_inclusion3d_allowance.py     # writes results/inclusion3d_allowance.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

import numpy as np  # noqa: E402

RESULTS = HERE / "results"


def row_of(name: str, seed: int) -> dict:
    return next(r for r in json.loads((RESULTS / name).read_text())["rows"] if r["seed"] == seed)


def fit_values(f: dict) -> dict:
    return {"ratio": f["relative_elasticity"], "volume": f["volume"], "strength": f["strength"]}


def check(label: str, fine: dict, coarse: dict, factor: float) -> dict:
    from refine.solid.inclusion_profile import strength
    from refine.solid.inclusion_total import Discretisation, errors_between, total_intervals

    f = fine["report"]["findings"][0]
    fit = fit_values(f)
    errors = errors_between(fit, coarse, factor, 2.0)
    total = total_intervals(fit, f["profile"], Discretisation(factor, 2.0, 0, coarse, errors, 0, 0.0))
    t = fine["truth"]
    truth = {"ratio": t["ratio"], "volume": t["volume"], "strength": float(strength(t["volume"], t["ratio"], 0.3))}
    out = {"case": label, "factor": factor, "truth": truth, "fit": fit, "coarse": coarse, "errors": errors,
           "profile": {k: f["profile"][k] for k in ("ratio", "volume", "strength")}, "total": total}
    for k in ("ratio", "volume", "strength"):
        out[f"{k}_in_profile"] = bool(f["profile"][k][0] <= truth[k] <= f["profile"][k][1])
        out[f"{k}_in_total"] = bool(total[k][0] <= truth[k] <= total[k][1])
    out["ratio_total_span"] = total["ratio"][1] / total["ratio"][0]  # high / low
    out["volume_total_width_pct"] = 100 * (total["volume"][1] - total["volume"][0]) / fit["volume"]
    out["strength_total_width_pct"] = 100 * abs(total["strength"][1] - total["strength"][0]) / abs(fit["strength"])
    return out


def main() -> None:
    cases = []
    for seed in (12, 21):
        r = row_of(f"inclusion3d_s22_seed{seed}.json", seed)
        c = r["report"]["findings"][0]["coarse_fit"]
        cases.append(check(f"s22 seed {seed}: 4 mm -> graded 2.5 mm", r, fit_values(c), 4.0 / 2.5))
    for seed, name in ((11, "inclusion3d_hfit3.json"), (13, "inclusion3d_hfit3_seed13.json")):
        coarse = fit_values(row_of("inclusion3d_4mm.json", seed)["report"]["findings"][0])
        cases.append(check(f"2.5 mm data seed {seed}: 4 mm -> uniform 3 mm", row_of(name, seed), coarse, 4.0 / 3.0))
    for c in cases:
        print(f"{c['case']}: truth r {c['truth']['ratio']:.3g} V {c['truth']['volume']:.0f} "
              f"S {c['truth']['strength']:.0f}; fit r {c['fit']['ratio']:.3g} V {c['fit']['volume']:.0f} "
              f"S {c['fit']['strength']:.0f}; errors dlogr {c['errors']['log_ratio']:.2f} "
              f"dV {c['errors']['volume']:.0f} dS {c['errors']['strength']:.1f}")
        for k in ("ratio", "volume", "strength"):
            p, t = c["profile"][k], c["total"][k]
            print(f"    {k}: profile {p[0]:.4g}-{p[1]:.4g} ({'in' if c[k + '_in_profile'] else 'OUT'}), "
                  f"total {t[0]:.4g}-{t[1]:.4g} ({'in' if c[k + '_in_total'] else 'OUT'})")
    out = RESULTS / "inclusion3d_allowance.json"
    out.write_text(json.dumps({"cases": cases}, indent=1, default=float), encoding="utf-8")
    print(f"wrote {out}")


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
