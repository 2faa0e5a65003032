"""Benchmark: the paper's derivative-free searches against exact-gradient fits.

Three cases, each over ``--seeds`` random seeds with noise 0.02 mm (data from
:func:`refine.demo_data.synthetic_bundle`: quadratic triangles on a larger sheet; the inversions
use other meshes):

1. ``paper``: the Sec. 3.1 experiment with one unknown, the embedded rectangle's modulus (the paper's
   moduli, a random rectangle per seed). Brent from b = 118.80 and b = 1256.40 kPa at tolerance
   0.01, the cubic fit + Brent at 0.001; Levenberg-Marquardt, Gauss-Newton, the third-order
   tensor method and Pade steps on the equilibrium's order-16 series (refine.optimize.pade) on the log
   ratio, each from the uniform model and from Brent's two middle points; L-BFGS-B.
2. ``two_regions``: a stiffer and a softer ellipse. Coordinate-wise Brent against LM and GN.
3. ``field``: a modulus per element (at least 2,000), TV-regularised, by L-BFGS-B. Brent cannot do
   this: one 1-D search per element and sweep.

Counting. A forward solve is one evaluation of the model over all frames (one Newton solve per
frame). A gradient evaluation is a Jacobian (LM/GN: one tangent solve per unknown and frame, with
the tangent matrix of the converged state), an adjoint gradient (L-BFGS-B: one adjoint solve per
frame), the derivative tensors of the tensor method (k + k^2 + k^3 tangent solves per frame) or
the equilibrium's series (Pade: 16 tangent solves and Taylor evaluations per frame), each from
one factorisation. Seconds are warm: each gradient method runs twice and the second run is timed, and
Brent runs after a reference search has compiled its solve. The compilation is reported apart
as ``compile_seconds``.

"Solves to 0.1 %" is the number of forward solves until the best point so far stays within 0.1 %
of the method's own converged value, in every modulus. Each method minimises its own objective
(Brent the paper's eq. (1), the gradient methods the noise-weighted sum of squares), and with
noise the two minimisers differ. Brent's count comes from a run to a tight tolerance, from the
same start, because at the paper's 0.01 it may stop short of 0.1 %.

    python -m benchmarks brent_vs_gradient              # 5 seeds; about an hour on 2 quiet cores
    python -m benchmarks brent_vs_gradient --seeds 1 --quick

Writes benchmarks/results/brent_vs_gradient.json (rewritten after every seed) and .png.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from benchmarks._subprocess import command, environment  # noqa: E402
from refine import optimize  # noqa: E402
from refine.model import MeasuredModel, ModulusField, Objective, RegionModuli, domain_mesh  # noqa: E402
from refine.optimize import coordinate_brent_search  # noqa: E402
from examples.paper import (BACKGROUND, INCLUSION, MIDDLE_POINTS, NAME, EmbeddedRectangle,  # noqa: E402
                          PaperExperiment, solves_to_reach)
from examples.paper.experiment import displacement_error_function, evaluations_to_reach  # noqa: E402
from refine.demo_data import random_truth, synthetic_bundle  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
DATA = dict(spacing=10.0, noise=0.02, fractions=(0.5, 1.0), h=3.0)
REL = 1e-3  # the 0.1 % target


def _record(method, r, truth, reference, n_to, *, compile_seconds=None, curve=None, **extra):
    """One row of the results: counts, warm seconds, errors, solves to 0.1 %."""
    values = np.atleast_1d(np.asarray(reference["estimate"], float))
    true = np.atleast_1d(np.asarray(truth, float))
    return {"method": method, "n_forward": int(r.n_forward), "n_gradient": int(r.n_gradient),
            "seconds": float(r.seconds), "compile_seconds": compile_seconds, "converged": bool(r.converged),
            "estimate": values.tolist(), "truth": true.tolist(),
            "relative_error": float(np.max(np.abs(values / true - 1.0))),
            "reference": np.atleast_1d(reference["value"]).tolist(), "solves_to_0.1%": n_to,
            "curve": curve, **extra}


def _curve(errors, estimates, reference, seconds):
    """Best-so-far distance to ``reference`` after each evaluation, and the seconds it took
    (evaluations spread evenly over the run's warm seconds)."""
    ref = np.asarray(reference, float)
    best, best_err, dist = None, np.inf, []
    for err, est in zip(errors, estimates):
        if err < best_err:
            best, best_err = np.asarray(est, float), err
        dist.append(float(np.max(np.abs(best / ref - 1.0))))
    n = len(dist)
    return {"solves": list(range(1, n + 1)), "seconds": [seconds * k / n for k in range(1, n + 1)], "distance": dist}


def _twice(run):
    """Run a compiled method twice: (warm result, compile seconds = cold - warm)."""
    cold = run()
    warm = run()
    return warm, max(0.0, cold.seconds - warm.seconds)


def paper_case(seed: int) -> list[dict]:
    rng = np.random.default_rng(seed)
    shape = random_truth(rng, "rectangle").inclusions[0].shape
    config = EmbeddedRectangle(rectangle=(shape.x0, shape.y0, shape.x1, shape.y1), seed=seed)
    ex = PaperExperiment(config)
    t = time.perf_counter()
    ex.error(BACKGROUND)
    cold = time.perf_counter() - t
    t = time.perf_counter()
    ex.error(BACKGROUND)
    brent_compile = cold - (time.perf_counter() - t)
    eq1_min = ex.brent(MIDDLE_POINTS[1], tol=1e-7).values[NAME]
    rows = []

    def searched(method, r, tight):
        n_to = solves_to_reach(tight, eq1_min, REL)
        h = tight.history
        curve = _curve([x["error"] for x in h], [[x[NAME]] for x in h], [eq1_min], tight.seconds)
        rows.append(_record(method, r, INCLUSION, {"estimate": r.values[NAME], "value": eq1_min}, n_to,
                            compile_seconds=brent_compile, curve=curve, objective="eq. (1)"))

    for b in MIDDLE_POINTS:
        searched(f"brent b={b:g}", ex.brent(b), ex.brent(b, tol=1e-6))
    searched("cubic+brent", ex.cubic(), ex.cubic(tol=1e-6))
    starts = {"": None, **{f" b={b:g}": b for b in MIDDLE_POINTS}}  # the uniform model, then Brent's middle points
    runs = [(f"{name}{tag}", (lambda k=key, s=start: ex.least_squares(k, start=s)))
            for name, key in (("levenberg-marquardt", "lm"), ("gauss-newton", "gn"), ("tensor (3rd order)", "tensor"),
                              ("pade (order 16)", "pade"))
            for tag, start in starts.items()]
    runs.append(("l-bfgs-b", lambda: ex.lbfgsb()))
    for method, run in runs:
        r, compile_s = _twice(run)
        ref = r.values[NAME]
        h = r.history
        curve = _curve([x["error"] for x in h], [[x[NAME]] for x in h], [ref], r.seconds)
        rows.append(_record(method, r, INCLUSION, {"estimate": ref, "value": ref}, solves_to_reach(r, ref, REL),
                            compile_seconds=compile_s, curve=curve, objective="least squares"))
    return rows


def two_region_case(seed: int) -> list[dict]:
    truth = random_truth(np.random.default_rng(100 + seed), "two-regions")
    bundle = synthetic_bundle(truth, seed=seed, **DATA)
    shapes = [inc.shape for inc in truth.inclusions]
    mesh = domain_mesh(bundle.experiment, 4.0, "tri6", inclusions=shapes)
    model = MeasuredModel(bundle.experiment, bundle.observations, mesh=mesh)
    E0 = bundle.experiment.E
    masks = np.stack([mesh.regions == k for k in (1, 2)])
    objective = Objective(model, RegionModuli(masks=masks, E0=E0, names=("a", "b")))
    true = [E0 * inc.ratio for inc in truth.inclusions]
    eq1 = displacement_error_function(objective)

    def error(moduli):
        return eq1(np.log(np.asarray(moduli, float) / E0))

    t = time.perf_counter()
    error([E0, E0])
    cold = time.perf_counter() - t
    t = time.perf_counter()
    error([E0 * 1.01, E0])
    brent_compile = cold - (time.perf_counter() - t)
    brackets = [(E0 / 20, E0, 20 * E0)] * 2  # from the uniform model, as wide as the paper's

    def search(tol):
        return coordinate_brent_search(error, brackets, names=("a", "b"), tol=tol)

    tight = search(1e-5)
    ref = [tight.values["a"], tight.values["b"]]
    r = search(0.01)
    h = tight.history
    est = [[x["a"], x["b"]] for x in h]
    n_to = evaluations_to_reach([x["error"] for x in h], est, ref, REL)
    rows = [_record("coordinate brent", r, true, {"estimate": [r.values["a"], r.values["b"]], "value": ref}, n_to,
                    compile_seconds=brent_compile, curve=_curve([x["error"] for x in h], est, ref, tight.seconds),
                    objective="eq. (1)", sweeps=int(max(x["sweep"] for x in r.history)))]
    for method, key in (("levenberg-marquardt", "lm"), ("gauss-newton", "gn")):
        r, compile_s = _twice(lambda: optimize.least_squares(objective, method=key, rtol=1e-5, atol=1e-4))
        moduli = [E0 * np.exp(np.asarray(x["z"])) for x in r.history]
        value = E0 * np.exp(np.asarray(r.values["z"]))
        errors = [x["misfit"] for x in r.history]
        rows.append(_record(method, r, true, {"estimate": value, "value": value},
                            evaluations_to_reach(errors, moduli, value, REL), compile_seconds=compile_s,
                            curve=_curve(errors, moduli, value, r.seconds), objective="least squares"))
    return rows


def field_case(seed: int, maxiter: int, warm: bool) -> list[dict]:
    truth = random_truth(np.random.default_rng(200 + seed), "stiffer-region")
    bundle = synthetic_bundle(truth, seed=seed, **DATA)
    mesh = domain_mesh(bundle.experiment, 2.35)
    assert mesh.n_cells >= 2000, mesh.n_cells
    model = MeasuredModel(bundle.experiment, bundle.observations, mesh=mesh)
    E0 = bundle.experiment.E
    objective = Objective(model, ModulusField(mesh, E0, weight=1.0, kind="tv"))
    run = lambda: optimize.lbfgsb(objective, bounds=(-3.0, 3.0), maxiter=maxiter)  # noqa: E731
    if warm:
        r, compile_s = _twice(run)
    else:
        r, compile_s = run(), None
    z = np.asarray(r.values["z"])
    inc = truth.inclusions[0]
    inside = inc.shape.contains(mesh.centroids())
    true_field = np.where(inside, E0 * inc.ratio, E0)
    field = E0 * np.exp(z)
    values = [x["value"] for x in r.history]
    curve = {"solves": list(range(1, len(values) + 1)),
             "seconds": [r.seconds * k / len(values) for k in range(1, len(values) + 1)],
             "distance": [v / values[0] for v in values]}  # objective value relative to the first iterate
    row = {"method": "l-bfgs-b (TV field)", "n_unknowns": int(mesh.n_cells), "n_forward": int(r.n_forward),
           "n_gradient": int(r.n_gradient), "seconds": float(r.seconds), "compile_seconds": compile_s,
           "converged": bool(r.converged),
           "median_cell_relative_error": float(np.median(np.abs(field / true_field - 1.0))),
           "relative_error": float(abs(np.exp(np.mean(z[inside])) / inc.ratio - 1.0)),
           "inside_mean_ratio": float(np.exp(np.mean(z[inside]))), "truth_ratio": float(inc.ratio),
           "outside_mean_ratio": float(np.exp(np.mean(z[~inside]))),
           "peak_inside_region": bool(inside[np.argmax(z)]), "solves_to_0.1%": None, "curve": curve}
    brent = {"method": "brent (coordinate-wise)", "possible": False,
             "why": f"{mesh.n_cells} unknowns: one 1-D search (~10 solves) per element and sweep, "
                    f"~{10 * mesh.n_cells} solves per sweep, and no regularisation"}
    return [row, brent]


def _median(rows, method, key):
    vals = [r[key] for r in rows if r["method"] == method and r.get(key) is not None]
    return float(np.median(vals)) if vals else None


def summarise(cases: dict) -> dict:
    summary, targets = {}, []
    for name, rows in cases.items():
        methods = list(dict.fromkeys(r["method"] for r in rows if r.get("possible", True)))
        summary[name] = {m: {k: _median(rows, m, k) for k in ("n_forward", "n_gradient", "seconds",
                                                             "compile_seconds", "relative_error", "solves_to_0.1%")}
                         for m in methods}
        for m in methods:
            reached = [r["solves_to_0.1%"] is not None for r in rows if r["method"] == m]
            summary[name][m]["reached_0.1%"] = f"{sum(reached)}/{len(reached)}"
    p = summary.get("paper")
    if p:
        best = min(p[m]["solves_to_0.1%"] for m in p if m.startswith("brent"))
        for m in p:
            if m.startswith(("brent", "cubic")):
                continue
            # from one of Brent's middle points: against Brent from the same point; from the
            # uniform model: against the best Brent
            same = next((f"brent {tag}" for tag in (f"b={b:g}" for b in MIDDLE_POINTS) if m.endswith(tag)), None)
            brent = p[same]["solves_to_0.1%"] if same else best
            n = p[m]["solves_to_0.1%"]
            start = f"from {same[6:]} as Brent" if same else "from the uniform model, against the best Brent"
            targets.append({"target": f"paper case: {m} ({start}) reaches 0.1 % with at most a third of "
                                      "Brent's forward solves",
                            "gradient_solves": n, "brent_solves": brent, "threshold": brent / 3.0,
                            "ratio": n / brent, "pass": bool(n <= brent / 3.0)})
    t = summary.get("two_regions")
    if t:
        brent = t["coordinate brent"]["solves_to_0.1%"]
        for m in ("levenberg-marquardt", "gauss-newton"):
            n = t[m]["solves_to_0.1%"]
            targets.append({"target": f"two regions: {m} needs fewer forward solves than coordinate-wise Brent",
                            "gradient_solves": n, "brent_solves": brent, "ratio": n / brent,
                            "pass": bool(n < brent)})
    rows = cases.get("field")
    if rows:
        fields = [r for r in rows if r["method"].startswith("l-bfgs-b")]
        ok = all(r["peak_inside_region"] and r["inside_mean_ratio"] > 1.5 * r["outside_mean_ratio"] for r in fields)
        targets.append({"target": "field: L-BFGS-B recovers a per-element field (peak inside the true region, "
                                  "stiffer inside than around) that Brent cannot give at all",
                        "n_unknowns": min(r["n_unknowns"] for r in fields), "pass": bool(ok)})
    return {"summary": summary, "targets": targets}


def plot(cases: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    titles = {"paper": "paper case (1 unknown)", "two_regions": "two regions", "field": "per-element field"}
    fig, axes = plt.subplots(2, 3, figsize=(15, 8))
    for col, (name, rows) in enumerate(cases.items()):
        colors = {}
        for r in rows:
            if not r.get("curve"):
                continue
            label = None if r["method"] in colors else r["method"]  # one legend entry per method
            c = colors.setdefault(r["method"], f"C{len(colors)}")
            d = np.maximum(r["curve"]["distance"], 1e-7)
            axes[0, col].semilogy(r["curve"]["solves"], d, "-", color=c, alpha=0.7, label=label)
            axes[1, col].semilogy(r["curve"]["seconds"], d, "-", color=c, alpha=0.7, label=label)
        ylabel = ("objective / first objective" if name == "field"
                  else "distance to own converged value (max over moduli)")
        for row, xlabel in ((0, "forward solves"), (1, "seconds (warm)")):
            ax = axes[row, col]
            if name != "field":
                ax.axhline(REL, color="k", ls=":", lw=1)
            ax.set(xlabel=xlabel, ylabel=ylabel, title=titles.get(name, name))
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def run_case(name: str, seed: int, quick: bool) -> list[dict]:
    if name == "paper":
        return paper_case(seed)
    if name == "two_regions":
        return two_region_case(seed)
    return field_case(seed, maxiter=60 if quick else 150, warm=not quick)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="shorter field run, no warm re-run of it")
    ap.add_argument("--cases", default="paper,two_regions,field")
    ap.add_argument("--one", nargs=3, metavar=("CASE", "SEED", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:  # child process: one case and seed, rows to a JSON file
        name, seed, out = args.one
        rows = run_case(name, int(seed), args.quick)
        Path(out).write_text(json.dumps([{**r, "seed": int(seed)} for r in rows]))
        return 0
    RESULTS.mkdir(parents=True, exist_ok=True)
    out_json, out_png = RESULTS / "brent_vs_gradient.json", RESULTS / "brent_vs_gradient.png"
    wanted = args.cases.split(",")
    cases = {name: [] for name in wanted}
    kept = {}
    if out_json.exists():  # a run of some cases keeps the others' rows from the last full run
        old = json.loads(out_json.read_text())
        kept = {k: v for k, v in old.get("cases", {}).items() if k not in wanted}
    started = time.perf_counter()
    for seed in range(args.seeds):
        for name in wanted:
            # Each case in its own process: every model compiles its own solves, and the compiled
            # code of earlier models piles up in one process (it reached 18 GB and was killed).
            t = time.perf_counter()
            tmp = RESULTS / f"brent_vs_gradient.{name}.{seed}.tmp"
            cmd = command("brent_vs_gradient", "--one", name, seed, tmp) + (["--quick"] if args.quick else [])
            done = subprocess.run(cmd, env=environment()).returncode == 0 and tmp.exists()
            if not done:
                print(f"seed {seed} {name}: FAILED (see the output above)", flush=True)
                continue
            cases[name].extend(json.loads(tmp.read_text()))
            tmp.unlink()
            print(f"seed {seed} {name}: {time.perf_counter() - t:.0f} s", flush=True)
            result = {"benchmark": "brent_vs_gradient", "seeds": seed + 1, "noise_mm": DATA["noise"],
                      "grid_spacing_mm": DATA["spacing"], "frames": len(DATA["fractions"]),
                      "load_average": os.getloadavg(), "cpu_count": os.cpu_count(),
                      "wall_seconds": time.perf_counter() - started, "kept_from_earlier_run": sorted(kept),
                      **summarise({**kept, **cases}), "cases": {**kept, **cases}}
            out_json.write_text(json.dumps(result, indent=1))  # after every case: a long run may be cut
            plot({**kept, **cases}, out_png)
    for t in result["targets"]:
        print(("PASS " if t["pass"] else "FAIL ") + t["target"], {k: v for k, v in t.items() if k not in ("target", "pass")})
    print(f"wrote {out_json} and {out_png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
