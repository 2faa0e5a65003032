"""Coverage of the diagnosis' standard errors, and accuracy on noise-free data.

    python -m benchmarks error_coverage --cases 24                 # noisy cases, as many as 24 (resumable)
    python -m benchmarks error_coverage --cases 4 --noise 0 --kinds rectangle --rows R0.jsonl
    python -m benchmarks error_coverage --merge benchmarks/results/error_coverage_rows.jsonl   # summary only
    python -m benchmarks error_coverage --cases 20 --seed 9000 --spacing 10 --frames 1   # small cases, ~1-2 min each


Each case draws a hidden effect (place, size, ratio) under its own seed from
:func:`refine.demo_data.random_truth` (kinds: a stiff circle, a soft ellipse, a hole, a
rectangle whose ratio is drawn in 3-10), generates its data from an independent finer solve on
quadratic triangles of a larger sheet plus Gaussian noise, and fits the TRUE hypothesis kind, as
the diagnosis fits it: linear triangles on a mesh that follows the shape, started off the truth
(centre 0.3 spacing, axes 10-15 %, ratio x1.5 or /1.5, 0.1 rad), then refitted on every guide
point at the fitted shape with quadratic triangles (:func:`refine.diagnosis.fitted.refit`),
which gives the covariance. The search for the kind is not measured here (``diagnose.py`` does);
what is measured is whether the reported standard errors (:mod:`refine.diagnosis.uncertainty`)
cover the truth: ``|estimate - truth| <= 2 std`` for every quantity (centre x and y, axes or
half sides, angle where the truth is not a circle, area, ratio), which should hold for about 95 %
of them. Noise-free cases (``--noise 0``) measure the accuracy where data allow it: the ratio
within 1 % of the truth (their rows in a rows file of their own, merged into the summary with the
noisy rows: ``--merge NOISY.jsonl NOISE_FREE.jsonl``).

The errors scored per quantity (:data:`benchmarks._error_coverage_summary.VARIANTS`): ``gauss_newton``, the fit's points
alone (the errors before the drive's noise was counted), ``standard_error``, that plus the noise
of the boundary points driving the model (:func:`refine.diagnosis.uncertainty.drive_covariance`;
report.json's ``std``), and ``reported``, that plus the discretisation error (the change on a
sqrt(2) coarser mesh, :func:`refine.diagnosis.uncertainty.discretisation_bias`) in quadrature:
report.json's ``total_std``, what the targets use, with the drive's discretisation error (a
refit driven by every other boundary point, :func:`refine.diagnosis.uncertainty.drive_bias`;
``mesh_only`` leaves it out; ``linear_total`` is that total with the standard error to first order,
the delta method, before the draws through the map to shapes). Rows written before the drive's term was measured (no ``drive``)
are scored apart (``before_the_drive_term``: the mesh's term alone), rows written before any
discretisation term (no ``bias``) not at all (``rows_without_discretisation``), so that every
variant is scored on the same cases. Coverage comes with exact binomial 95 % intervals (quantities as independent
trials) and intervals from resampling whole cases (a case's quantities are correlated), per
quantity and per kind; the errors' median sizes per variant show how much each widens them.

Small cases (``--spacing 10 --frames 1``: a quarter of the points, the last frame alone, a
coarser model mesh, which follows the spacing) cost a fraction of the default ones (5 mm, two
frames), so that 30+ cases fit a shared machine; coverage is also given per case size
(``per_size``: spacing and frames), since fewer points make the fit less linear in its noise.

Rows go to a JSONL file (resumable); the summary to benchmarks/results/error_coverage.json (with
``targets``) and error_coverage.png. Seconds are wall seconds per case, with the load average.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from benchmarks._error_coverage_summary import KINDS, QUANTITIES, _plot, summarise
from benchmarks._cli import QUICK, quick  # noqa: E402

OUT = Path(__file__).parent / "results"


def truth_of(kind: str, seed: int):
    """The hidden effect of a case: :func:`random_truth`'s, a rectangle's ratio drawn in 3-10."""
    import jaxfem as jf  # noqa: F401
    from refine.demo_data import Inclusion, Truth, random_truth

    rng = np.random.default_rng(seed)
    truth = random_truth(rng, kind)
    if kind == "rectangle":
        truth = Truth(inclusions=(Inclusion(truth.inclusions[0].shape, float(rng.uniform(3.0, 10.0))),))
    return truth


def true_quantities(truth) -> np.ndarray:
    """``(cx, cy, a, b, angle, area, ratio)`` of the case's one shape (a hole's ratio 0)."""
    if truth.holes:
        shape, ratio = truth.holes[0], 0.0
    else:
        shape, ratio = truth.inclusions[0].shape, truth.inclusions[0].ratio
    return np.array([*shape.params, shape.area, ratio], float)


def started(q: np.ndarray, kind: str, spacing: float, rng):
    """The start of the fit: the truth moved off by about a third of a grid spacing, the axes
    10-15 % off, the angle 0.1 rad, the ratio x1.5 or /1.5."""
    from refine.diagnosis.shapes import Hole, RegionShape

    centre = tuple(q[:2] + rng.choice([-1, 1], 2) * 0.3 * spacing)
    axes = tuple(q[2:4] * rng.choice([0.87, 1.13], 2))
    angle = float(q[4] + rng.choice([-0.1, 0.1]))
    if kind == "hole":
        return Hole(centre, axes, angle)
    shape_kind = "rectangle" if kind == "rectangle" else "ellipse"
    return RegionShape(centre, axes, angle, shape_kind, float(q[6] * rng.choice([1.5, 1 / 1.5])))


def fit_true_kind(bundle, kind: str, start, sigma: float):
    """The true hypothesis kind fitted from ``start`` as the diagnosis fits it, also from its
    restarts at the fitted centre (:func:`refine.diagnosis.restarts.best_of_restarts`, as
    :func:`refine.diagnosis.regions.fit_regions` does; a hole's since 26 Nov, branch h-coverage,
    :func:`refine.diagnosis.holes.fit_hole` with ``restarts``; rows before it fitted a hole from
    its start alone; a region's also along the size-ratio valley since 26 Nov, branch
    h-coverage, rows ``error_coverage_rows_valley*.jsonl``) and refitted on every guide point with quadratic triangles; returns the
    refit (its ``z_cov`` set) and the linear triangles' misfits (the fitting points' chi2) from
    ``start`` and after the restarts (the same where none did better)."""
    from refine.diagnosis.fitted import fit, refit
    from refine.diagnosis.holes import hole_hypothesis
    from refine.diagnosis.regions import regions_hypothesis
    from refine.diagnosis.restarts import RESTARTS, best_of_restarts
    from refine.model.measured import MeasuredModel

    obs = bundle.observations
    model = MeasuredModel(bundle.experiment, obs)
    guide, hold = obs.mask("guide"), obs.mask("validate")
    if kind == "hole":  # fit_hole's steps, its first fit kept apart to record its misfit
        first = fit(hole_hypothesis(model, start), guide, hold, sigma)
    else:
        first = fit(regions_hypothesis(model, [start], [1 if start.ratio > 1 else -1]), guide, hold, sigma)
    f = best_of_restarts(first, [start], guide, hold, RESTARTS)
    return refit(f, guide, hold, sigma, element="tri6"), (first.chi2_fit, f.chi2_fit)


def matched(q_fit: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """The fitted quantities with their axes in the truth's order (an ellipse's or a
    rectangle's first axis may be the truth's second one, turned a quarter) and its angle within
    a quarter turn of the truth's (an orientation is defined modulo half a turn)."""
    q = q_fit.copy()
    turn = np.angle(np.exp(2j * (q[4] - q_true[4]))) / 2
    if abs(turn) > np.pi / 4:
        q[2], q[3], q[4] = q[3], q[2], q[4] - np.sign(turn) * np.pi / 2
    q[4] = q_true[4] + np.angle(np.exp(2j * (q[4] - q_true[4]))) / 2
    return q


def run_case(case: dict) -> dict:
    """Generate one case's bundle, fit the true kind, score every quantity against its error."""
    from dataclasses import replace

    from refine.diagnosis.fitted import covariance
    from refine.diagnosis.uncertainty import (discretisation_bias, drive_bias, quantity_jacobian, shape_errors,
                                              shape_quantities)
    from refine.demo_data import synthetic_bundle

    t0 = time.perf_counter()
    kind, seed, noise, spacing = case["kind"], case["seed"], case["noise"], case["spacing"]
    truth = truth_of(kind, seed)
    q_true = true_quantities(truth)
    bundle = synthetic_bundle(truth, seed=seed, spacing=spacing, noise=noise, fractions=FRACTIONS[case.get("frames", 2)])
    start = started(q_true, kind, spacing, np.random.default_rng(seed + 1))
    row = {**case, "truth": q_true.tolist()}
    try:
        f, chi2_first = fit_true_kind(bundle, kind, start, sigma=noise if noise > 0 else 1e-3)
    except Exception as e:  # noqa: BLE001 - a failed fit is recorded as such
        return {**row, "error": f"{type(e).__name__}: {e}", "seconds": time.perf_counter() - t0}
    q_raw = shape_quantities(f.shapes)[0]
    q_fit = matched(q_raw, q_true)
    order = [0, 1, 3, 2, 4, 5, 6] if q_fit[2] != q_raw[2] else list(range(7))  # errors follow matched axes
    guide = bundle.observations.mask("guide")
    std = _std(shape_errors(f)[0])
    std_gn = _std(shape_errors(replace(f, z_cov=covariance(f, guide, f.sigma)))[0])  # before: the fit's points only
    G = quantity_jacobian(f)  # the first-order (delta method) errors, before the draws through the map
    std_lin = np.sqrt(np.clip(np.einsum("qk,kl,ql->q", G, f.z_cov, G), 0, None))[: len(QUANTITIES)]
    t1 = time.perf_counter()
    bias = discretisation_bias(f, guide, bundle.observations.mask("validate"), f.sigma)
    bias = np.full(len(QUANTITIES), np.nan) if bias is None else bias[0]
    t2 = time.perf_counter()
    drive = drive_bias(f, guide, bundle.observations.mask("validate"), f.sigma)
    drive = np.full(len(QUANTITIES), np.nan) if drive is None else drive[0]
    std, std_gn, std_lin, bias, drive = std[order], std_gn[order], std_lin[order], bias[order], drive[order]
    row.update(std_linear=std_lin.tolist(), bias=bias.tolist(), bias_seconds=t2 - t1, drive=drive.tolist(), drive_seconds=time.perf_counter() - t2)
    use = np.ones(len(QUANTITIES), bool)
    use[4] = abs(q_true[2] - q_true[3]) > 0.05 * max(q_true[2:4])  # a circle's angle is not a quantity
    use[6] = kind != "hole"
    z, z_gn = (q_fit - q_true) / std, (q_fit - q_true) / std_gn
    row.update(estimate=q_fit.tolist(), std=std.tolist(), z=[float(v) if u else None for v, u in zip(z, use)],
               std_gauss_newton=std_gn.tolist(), z_gauss_newton=[float(v) if u else None for v, u in zip(z_gn, use)],
               ratio_error=None if kind == "hole" else float(q_fit[6] / q_true[6] - 1),
               area_error=float(q_fit[5] / q_true[5] - 1), chi2=f.chi2_fit, chi2_first_and_restarted=list(chi2_first), k=f.k,
               seconds=time.perf_counter() - t0, load_average=[round(x, 2) for x in os.getloadavg()],
               fitted=f.describe(), code=_code_version())
    return row


def _std(err) -> np.ndarray:
    """A shape's standard errors in the order of :data:`QUANTITIES` (NaN: not fitted)."""
    return np.array([*err.centroid, *err.axes, err.angle, err.area,
                     np.nan if err.relative_elasticity is None else err.relative_elasticity], float)


def _code_version() -> str:
    """The commit of this run's code (\"+dirty\" when the tree differs from it)."""
    import subprocess

    git = lambda *a: subprocess.run(["git", *a], capture_output=True, text=True,  # noqa: E731
                                    cwd=Path(__file__).parent).stdout.strip()
    return git("rev-parse", "--short", "HEAD") + ("+dirty" if git("status", "--porcelain", "refine") else "")


FRACTIONS = {1: (1.0,), 2: (0.5, 1.0)}
"""The frames of a case (fractions of the final stretch) by their number (rows without
``frames`` are the two-frame cases of the first runs)."""


def main(argv=None) -> int:
    argv = quick(argv, ["--cases", "1", "--spacing", "10", "--frames", "1", "--rows", str(QUICK / "error_coverage_rows.jsonl")])
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=24, help="cases (kinds in turn)")
    p.add_argument("--kinds", nargs="+", default=list(KINDS), choices=KINDS)
    p.add_argument("--noise", type=float, default=0.02, help="noise std, mm (0: noise-free cases)")
    p.add_argument("--spacing", type=float, default=5.0, help="grid spacing of the tracked points, mm")
    p.add_argument("--seed", type=int, default=7000, help="first case's seed")
    p.add_argument("--frames", type=int, default=2, choices=sorted(FRACTIONS), help="frames per case (1: the last alone)")
    p.add_argument("--rows", type=Path, default=OUT / "error_coverage_rows.jsonl", help="rows file (appended, resumable)")
    p.add_argument("--merge", type=Path, nargs="*", help="only summarise these rows files")
    p.add_argument("--minutes", type=float, default=None, help="stop starting new cases after this many minutes")
    args = p.parse_args(argv)
    paths = args.merge if args.merge is not None else [args.rows]
    if args.merge is None:
        done = {(r["kind"], r["seed"], r["noise"], r["spacing"], r.get("frames", 2)) for r in _read(args.rows)}
        t0 = time.time()
        for k in range(args.cases):
            kind = args.kinds[k % len(args.kinds)]
            case = {"kind": kind, "seed": args.seed + k, "noise": args.noise, "spacing": args.spacing,
                    "frames": args.frames}
            if (kind, case["seed"], args.noise, args.spacing, args.frames) in done:
                continue
            if args.minutes is not None and time.time() - t0 > 60 * args.minutes:
                break
            row = run_case(case)
            with open(args.rows, "a") as out:
                out.write(json.dumps(row) + "\n")
            zs = ", ".join("-" if v is None else f"{v:+.1f}" for v in row.get("z", []))
            print(f"{kind:15s} seed {case['seed']} ratio error {row.get('ratio_error')} z [{zs}] "
                  f"{row['seconds']:.0f} s {row.get('error', '')}", flush=True)
    rows = [r for path in paths for r in _read(path)]
    summary = summarise(rows)
    OUT.mkdir(exist_ok=True)
    (OUT / "error_coverage.json").write_text(json.dumps({**summary, "rows": rows}, indent=1))
    _plot(rows, summary, OUT / "error_coverage.png")
    print(json.dumps(summary["targets"], indent=1))
    return 0


def _read(path: Path) -> list[dict]:
    return [json.loads(line) for line in open(path)] if Path(path).exists() else []


if __name__ == "__main__":
    raise SystemExit(main())
