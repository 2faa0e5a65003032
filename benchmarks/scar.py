"""Skin with a burn scar (the paper's Secs. 3.2 and 5.1), diagnosed over seeds.

Skin with a burn scar (issue 25 item 1; the paper's Secs. 3.2 and 5.1), diagnosed over seeds.

    python -m benchmarks scar --seeds 6             # cases 0..5 (resumable rows)
    python -m benchmarks scar --merge               # summary and plot from the rows only
    python -m benchmarks scar --locking             # also the plane-stress locking check

Each case draws a scar under its own seed (:func:`examples.skin.synthetic.random_scar`: normal
skin of modulus 10-100 kPa, nu 0.49, 1-2 mm thick; an ellipse at any angle or a rectangle of
relative elasticity 2-6, placed at random), generates its bundle from the finer quadratic solve
of the larger stretched skin plus noise (:func:`examples.skin.synthetic.skin_bundle`), and runs
the diagnosis as ``nonrigid diagnose`` runs it (:func:`refine.diagnosis.diagnose`, default
settings but one worker). Targets (the issue's): a stiffer region named; its relative elasticity
within 5 % of the truth (each seed); its centroid within 2 % of the field of view (its diagonal;
each seed); the ratio "within its reported uncertainty" judged over the seeds
(:func:`within_reported_uncertainty`: the share within 2 total reported errors, standard error
and discretisation error in quadrature, consistent with 95 %, and sum z^2 with its chi-square;
a per-seed limit of 2 errors fails 4.6 % of seeds where the errors are right). The paper's own
reading is checked beside it: the scar is the pocket of lowest strain in the measured grid's strain map
(:mod:`refine.diagnosis.measured_strain`): the median strain inside the scar below that
outside, and most of the lowest-strain decile of triangles on the scar.

``--locking`` compares a coarse linear and a fine quadratic mesh of a skin patch with a stiff
inclusion in plane stress and plane strain at nu 0.3 and 0.49: plane stress keeps its
discretisation error at nu 0.49 (no locking), plane strain's grows (shown for contrast).

Rows go to benchmarks/results/scar_rows.jsonl; the summary to scar.json (with ``targets``) and
scar.png. Seconds are wall seconds with the load average.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from benchmarks._cli import QUICK, quick  # noqa: E402

OUT = Path(__file__).parent / "results"
RATIO_TOL, CENTROID_TOL = 0.05, 0.02


def run_case(seed: int) -> dict:
    """One scar: generate, diagnose, score against the truth; the measured strain pocket."""
    from refine.diagnosis import DiagnoseConfig, diagnose
    from examples.skin.synthetic import SKIN, random_scar, skin_bundle

    t0 = time.perf_counter()
    truth = random_scar(np.random.default_rng(seed))
    inc = truth.inclusions[0]
    bundle = skin_bundle(truth, seed=seed)
    row = {"seed": seed, "truth": {"shape": type(inc.shape).__name__, "params": list(map(float, inc.shape.params)),
                                   "ratio": inc.ratio, "E": truth.E, "thickness": truth.thickness, "nu": truth.nu},
           "pocket": strain_pocket(bundle, inc.shape)}
    t1 = time.perf_counter()
    lines = []
    d = diagnose(bundle, DiagnoseConfig(workers=1), log=lines.append)  # one worker: a shared machine
    cost = [m for m in lines if "discretisation error estimated" in m]
    row.update(generate_seconds=t1 - t0, diagnose_seconds=time.perf_counter() - t1,
               discretisation_seconds=float(cost[0].split("(")[-1].split(" s")[0]) if cost else None,
               load_average=[round(x, 2) for x in os.getloadavg()], chosen=d.chosen.describe(),
               **score(d.findings, inc, SKIN.field_of_view))
    return row


def score(findings: list[dict], inclusion, field_of_view: float) -> dict:
    """The finding against the hidden scar: named, ratio error and its z, centroid error as a
    fraction of the field of view, and whether each target holds. The ratio is checked against
    its total reported error (standard error and discretisation error in quadrature,
    ``relative_elasticity_total_std``; the standard error alone where a report has no total);
    ``ratio_z_std`` is the z of the standard error alone, as before the discretisation term."""
    stiff = [f for f in findings if f["cause"] == "stiffer-region"]
    if len(findings) != 1 or not stiff:
        return {"named": False, "causes": [f["cause"] for f in findings], "pass": False}
    f = stiff[0]
    ratio, std = f["relative_elasticity"], f.get("relative_elasticity_std")
    total = f.get("relative_elasticity_total_std") or std
    disc = (f.get("discretisation") or {}).get("relative_elasticity")
    err = ratio / inclusion.ratio - 1
    z = (ratio - inclusion.ratio) / total if total else float("inf")
    z_std = (ratio - inclusion.ratio) / std if std else float("inf")
    c = np.asarray(f["region"]["centroid"]) - np.asarray(inclusion.shape.params[:2])
    centroid = float(np.hypot(*c) / field_of_view)
    ok = {"ratio_within_5_percent": abs(err) <= RATIO_TOL, "ratio_within_2_std": abs(z) <= 2,
          "centroid_within_2_percent": centroid <= CENTROID_TOL}
    return {"named": True, "ratio": ratio, "ratio_std": std, "ratio_discretisation": disc, "ratio_total_std": total,
            "ratio_error": float(err), "ratio_z": float(z), "ratio_z_std": float(z_std),
            "centroid_error": centroid, "shape": f["region"]["shape"], **ok, "pass": all(ok.values())}


def coverage(z: list[float], k: float = 2.0) -> dict:
    """Whether the ratio's z values over seeds (error / total reported error) are what standard
    normal errors give, the reading of "within its reported uncertainty" that holds over many
    seeds (a per-seed limit of 2 errors fails 4.6 % of seeds where the errors are exactly right):
    ``outside`` of ``n`` beyond ``k`` errors and the binomial probability of at least that many
    (errors too small: few such); the chi-square probability of ``sum z^2`` on ``n`` degrees of
    freedom, both tails (too small and too large errors). Passes where both are 0.05 or more.
    Beside them (not in the pass): the mean z and its two-sided probability under no bias. A
    few seeds tell only errors far off: the chi-square test catches errors short by 1.82, 1.64,
    1.48 times half the time with 4, 6, 10 seeds."""
    from scipy.stats import binom, chi2, norm

    z = np.asarray(z, float)
    n, outside, s = len(z), int(np.sum(np.abs(z) > k)), float(np.sum(z**2))
    p_out = float(binom.sf(outside - 1, n, 2 * norm.sf(k)))
    p_chi2 = float(2 * min(chi2.sf(s, n), chi2.cdf(s, n)))
    mean = float(np.mean(z)) if n else None  # informational: a bias shows as mean z off 0 by more than 2 / sqrt(n)
    return {"n": n, "outside": outside, "expected_outside": float(n * 2 * norm.sf(k)), "p_outside": p_out,
            "sum_z2": s, "p_sum_z2": p_chi2, "mean_z": mean, "p_mean_z": float(2 * norm.sf(abs(mean) * np.sqrt(n)))
            if n else None, "pass": bool(n and p_out >= 0.05 and p_chi2 >= 0.05)}


def within_reported_uncertainty(rows: list[dict], k: float = 2.0) -> dict:
    """The issue's "within its reported uncertainty" judged over the seeds' ``rows`` (each with
    its ``seed`` and ``ratio_z``, the ratio's error over its total reported error): ``value`` the
    share within ``k`` errors, about 95 % where the errors are right (every one of n seeds within
    2 errors happens only 0.954^n of the time: 52 % for 14 seeds, so that is no target); passes
    where :func:`coverage` does (the count beyond ``k`` errors ordinary for a binomial of 4.6 %,
    and ``sum z^2`` ordinary for its chi-square). The per-seed figures are kept: ``z`` per seed
    and the seeds beyond ``k``."""
    from scipy.stats import norm

    z = {int(r["seed"]): float(r["ratio_z"]) for r in rows}
    share = float(np.mean([abs(v) <= k for v in z.values()])) if z else None
    return {"value": share,
            "target": (f"share within {k:g} total errors consistent with {1 - 2 * norm.sf(k):.1%} (binomial, "
                       "p >= 0.05) and sum z^2 with its chi-square (p >= 0.05, both tails)"),
            "errors": ("total reported error: the standard error and the discretisation error (mesh and drive) "
                       "in quadrature"),
            "z": {str(s): round(v, 3) for s, v in sorted(z.items())},
            "seeds_outside": sorted(s for s, v in z.items() if abs(v) > k), **coverage(list(z.values()), k)}


def strain_pocket(bundle, shape) -> dict:
    """The measured grid's strain map at the last frame (von Mises equivalent of the in-plane
    Green-Lagrange strain per Delaunay triangle of the points): median strain inside the scar
    and outside, and the share of the lowest-strain decile of triangles whose centroid lies on
    the scar (within half a grid spacing of it)."""
    from refine.diagnosis.measured_strain import equivalent, measured_strain, point_spacing

    obs = bundle.observations
    X = obs.reference
    tri, E = measured_strain(X, obs.displacements[-1])
    eq = equivalent(E)
    centre = X[tri].mean(axis=1)
    near = shape.contains(centre) | (np.linalg.norm(centre - shape.to_curve(centre), axis=1) < 0.5 * point_spacing(X))
    inside = shape.contains(centre)
    low = eq <= np.quantile(eq, 0.1)
    return {"median_inside": float(np.median(eq[inside])), "median_outside": float(np.median(eq[~near])),
            "lowest_decile_on_scar": float(np.mean(near[low])), "triangles": int(len(tri))}


def locking() -> dict:
    """Relative L2 difference of a coarse linear (h 4 mm) and a fine quadratic (h 1 mm) solution
    of a 40 x 30 mm skin patch with a stiff elliptic inclusion stretched 10 %, per kind and nu."""
    import jaxfem as jf

    X, Y = np.meshgrid(np.linspace(1, 39, 20), np.linspace(1, 29, 15))
    pts = np.stack([X.ravel(), Y.ravel()], 1)

    def solve(h, element, nu, kind):
        mesh = jf.plate(0, 0, 40, 30, h, inclusions=[jf.Ellipse(20, 15, 6, 4, 0.5)], element=element)
        fixed = np.concatenate([jf.dofs(mesh, mesh.side("left")), jf.dofs(mesh, mesh.side("right"))])
        problem = jf.Problem(mesh, "neo-hookean", kind, fixed=fixed)
        u_D = problem.prescribe(lambda P: np.stack([np.where(P[:, 0] > 20, 4.0, 0.0), 0 * P[:, 1]], 1))
        theta = problem.params(E=np.where(mesh.regions == 1, 250.0, 50.0), nu=nu, thickness=1.5, u_D=u_D)
        return np.asarray(jf.locate(mesh, pts)(jf.Solver(problem).solve(theta).u))

    out = {}
    for kind in ("plane-stress", "plane-strain"):
        for nu in (0.3, 0.49):
            fine, coarse = solve(1.0, "tri6", nu, kind), solve(4.0, "tri3", nu, kind)
            out[f"{kind} nu {nu}"] = float(np.linalg.norm(coarse - fine) / np.linalg.norm(fine))
    return out


def summarise(rows: list[dict], lock: dict | None) -> dict:
    ok = [r for r in rows if "named" in r]
    share = lambda key: float(np.mean([bool(r.get(key)) for r in ok])) if ok else None  # noqa: E731
    pockets = [r["pocket"] for r in rows if "pocket" in r]
    targets = {k: {"value": share(k), "target": 1.0, "pass": share(k) == 1.0}
               for k in ("named", "ratio_within_5_percent", "centroid_within_2_percent")}
    targets["ratio_within_2_std"] = within_reported_uncertainty(ok)
    targets["scar_is_the_lowest_strain_pocket"] = {
        "value": float(np.mean([p["median_inside"] < p["median_outside"] and p["lowest_decile_on_scar"] >= 0.5
                                for p in pockets])) if pockets else None, "target": 1.0}
    targets["scar_is_the_lowest_strain_pocket"]["pass"] = targets["scar_is_the_lowest_strain_pocket"]["value"] == 1.0
    if lock:
        ps = lock["plane-stress nu 0.49"] / lock["plane-stress nu 0.3"]
        targets["plane_stress_does_not_lock"] = {"value": ps, "target": "error at nu 0.49 under 2x that at nu 0.3",
                                                 "plane_strain_for_contrast":
                                                     lock["plane-strain nu 0.49"] / lock["plane-strain nu 0.3"],
                                                 "pass": ps < 2.0}
    return {"cases": len(rows), "failed": len(rows) - len(ok), "locking": lock, "targets": targets,
            "ratio_errors": [r.get("ratio_error") for r in ok], "ratio_z": [r.get("ratio_z") for r in ok],
            "ratio_z_std_alone": [r.get("ratio_z_std") for r in ok],
            "centroid_errors": [r.get("centroid_error") for r in ok],
            "median_diagnose_seconds": float(np.median([r["diagnose_seconds"] for r in ok])) if ok else None}


def _plot(rows, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r.get("named")]
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(13, 3.8))
    seeds = [r["seed"] for r in ok]
    a.errorbar(seeds, [100 * r["ratio_error"] for r in ok],
               yerr=[200 * r.get("ratio_total_std", r["ratio_std"]) / r["truth"]["ratio"] for r in ok], fmt="o",
               capsize=3, label="+- 2 total errors (noise and mesh)")
    a.axhspan(-100 * RATIO_TOL, 100 * RATIO_TOL, color="g", alpha=0.15, label="5 %")
    a.set(xlabel="seed", ylabel="relative elasticity error, %", title="scar rating")
    a.legend()
    b.bar([str(s) for s in seeds], [100 * r["centroid_error"] for r in ok])
    b.axhline(100 * CENTROID_TOL, color="r", lw=0.8)
    b.set(xlabel="seed", ylabel="centroid error, % of the field of view", title="scar place")
    pk = [r["pocket"] for r in rows]
    c.plot([r["seed"] for r in rows], [p["median_inside"] / p["median_outside"] for p in pk], "o",
           label="median strain inside / outside")
    c.plot([r["seed"] for r in rows], [p["lowest_decile_on_scar"] for p in pk], "s",
           label="lowest-strain decile on the scar")
    c.set(xlabel="seed", ylim=(0, 1.05), title="measured strain: the scar is the low pocket")
    c.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110, bbox_inches="tight")


def main(argv=None) -> int:
    argv = quick(argv, ["--seeds", "1", "--rows", str(QUICK / "scar_rows.jsonl")])
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=6, help="cases 0..N-1 (seeds)")
    p.add_argument("--first", type=int, default=0, help="first seed")
    p.add_argument("--rows", type=Path, default=OUT / "scar_rows.jsonl")
    p.add_argument("--merge", action="store_true", help="only summarise the rows")
    p.add_argument("--rerun", action="store_true", help="run the seeds again (their old rows are dropped)")
    p.add_argument("--locking", action="store_true", help="also run the locking check")
    args = p.parse_args(argv)
    seeds = range(args.first, args.first + args.seeds)
    if args.rerun and not args.merge:  # e.g. after a change of the diagnosis: keep only the other seeds' rows
        kept = [r for r in _read(args.rows) if r["seed"] not in seeds]
        args.rows.write_text("".join(json.dumps(r) + "\n" for r in kept))
    done = {r["seed"] for r in _read(args.rows)}
    for seed in seeds:
        if args.merge or seed in done:
            continue
        try:
            row = run_case(seed)
        except Exception as e:  # noqa: BLE001 - a failed case is a row
            row = {"seed": seed, "error": f"{type(e).__name__}: {e}"}
        with open(args.rows, "a") as out:
            out.write(json.dumps(row) + "\n")
        print({k: row.get(k) for k in ("seed", "chosen", "ratio_error", "ratio_z", "centroid_error", "pass",
                                       "diagnose_seconds", "error")}, flush=True)
    previous = json.loads((OUT / "scar.json").read_text()) if (OUT / "scar.json").exists() else {}
    lock = locking() if args.locking else previous.get("locking")
    rows = _read(args.rows)
    summary = summarise(rows, lock)
    (OUT / "scar.json").write_text(json.dumps({**summary, "rows": rows}, indent=1))
    _plot(rows, OUT / "scar.png")
    print(json.dumps(summary["targets"], indent=1))
    return 0


def _read(path: Path) -> list[dict]:
    return [json.loads(line) for line in open(path)] if Path(path).exists() else []


if __name__ == "__main__":
    raise SystemExit(main())
