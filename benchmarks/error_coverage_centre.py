"""Why a region's centre is covered less well across the pull (y) than along it (x): one
``error_coverage.py`` case at a time (``--kind``, ``--seeds``), two measurements.

    PYTHONPATH=. python benchmarks/error_coverage_centre.py --kind softer-region --seeds 9533 9525

1. *The misfit's shape along each centre coordinate*: from the final fit (quadratic triangles,
   every guide point), the unknowns moved along the linearised profile path of ``cx`` and ``cy``
   (``dz = t C g / sqrt(g^T C g)``, ``C = (J^T J)^-1``, ``g = d q / dz``), ``t = -2, -1, 1, 2``
   errors; a quadratic misfit rises by ``t^2`` there (4 at 2 errors). Less: the misfit is flatter
   than the Gauss-Newton covariance says, the error too small (the true profile re-optimises the
   other unknowns, so it lies lower still); more: inconclusive. No fits, one solve per point.
   ``--quantities`` picks other quantities (e.g. a hole's ``angle``).
2. *A bias*: the same case fitted on its noise-free data (same truth, points and start): the
   centre's offset from the truth, in the noisy fit's reported errors.

3. *The drive's noise* (``--drive-draws``): the boundary points' displacements drawn with the
   noise (``sigma`` on each component), the model solved with them at the fitted unknowns, and
   the unknowns' linear response ``(J^T J)^-1 J^T dr`` carried to ``cx`` and ``cy``: its scatter
   beside what :func:`refine.diagnosis.uncertainty.drive_covariance` (first order, by adjoints)
   gives. A check of that term's code, one solve per draw.

Rows (one per seed) appended to ``results/error_coverage_centre_rows.jsonl``; ``--summary``
writes ``results/error_coverage_centre.json`` with ``targets``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from error_coverage import FRACTIONS, _code_version, fit_true_kind, matched, started, true_quantities, truth_of
from error_coverage_summary import QUANTITIES

OUT = Path(__file__).parent / "results"
STEPS = (-2.0, -1.0, 1.0, 2.0)
"""Where the misfit is evaluated along a quantity's linearised profile path (its errors)."""


def profile_path(f, guide, quantity: int, steps=STEPS) -> dict:
    """The misfit's rise (chi2 on ``guide``) and the quantity's change when the fitted unknowns
    move ``t`` Gauss-Newton errors of ``quantity`` (index into ``QUANTITIES``) along its
    linearised profile path, for each ``t`` of ``steps``."""
    from refine.diagnosis.uncertainty import quantity_jacobian, shape_quantities
    from refine.measures import Residuals

    res = Residuals.at(f.compiled.model.obs.displacements, guide, f.sigma)
    J = res.jacobian(f.compiled.jacobian(f.z))
    C = np.linalg.inv(J.T @ J)
    g = quantity_jacobian(f)[quantity]
    std = float(np.sqrt(g @ C @ g))
    d = C @ g / std
    chi0 = res.chi2(f.compiled.predict(f.z))
    q0 = shape_quantities(f.shapes)[0, quantity]
    rise, moved = [], []
    for t in steps:
        z = f.z + t * d
        rise.append(float(res.chi2(f.compiled.predict(z)) - chi0))
        moved.append(float(shape_quantities(f.hypothesis.shapes_at(f.compiled, z))[0, quantity] - q0))
    return {"std_gauss_newton_unscaled": std, "steps": list(steps), "chi2_rise": rise, "moved": moved}


def drive_check(f, guide, draws: int, seed: int = 0) -> dict:
    """The scatter of ``cx`` and ``cy`` due to the drive's noise alone, from ``draws`` draws of
    the boundary points' displacements (one solve each, linear response of the unknowns),
    beside the first-order ``drive_covariance``'s errors."""
    from refine.diagnosis.uncertainty import drive_covariance, quantity_jacobian
    from refine.measures import Residuals

    model = f.compiled.model
    res = Residuals.at(model.obs.displacements, guide, f.sigma)
    J = res.jacobian(f.compiled.jacobian(f.z))
    B = np.asarray(model.measured_boundary())
    p0 = np.asarray(model.predict(f.theta))
    rng = np.random.default_rng(seed)
    sigma_drive = model.experiment.noise_std or f.sigma
    dz = []
    for _ in range(draws):
        dp = np.asarray(model.predict(f.theta, boundary=B + rng.normal(0.0, sigma_drive, B.shape))) - p0
        dz.append(np.linalg.solve(J.T @ J, J.T @ res.weighted(dp)))
    G = quantity_jacobian(f)[:2]
    drawn = np.std(np.asarray(dz) @ G.T, axis=0, ddof=1)
    formula = np.sqrt(np.einsum("qk,kl,ql->q", G, drive_covariance(f, guide, f.sigma), G))
    return {"draws": draws, "std_drawn": drawn.tolist(), "std_first_order": formula.tolist()}


def run(kind: str, seed: int, noise: float, spacing: float, drive_draws: int = 0, noisy: bool = True,
        quantities=("cx", "cy")) -> dict:
    """One case: the noisy fit's profile paths of ``cx`` and ``cy`` (not with ``noisy`` False)
    and the noise-free fit's centre (see the module's docstring)."""
    from refine.diagnosis.uncertainty import shape_errors, shape_quantities
    from refine.synthetic.sheet import synthetic_bundle

    t0 = time.perf_counter()
    truth = truth_of(kind, seed)
    q_true = true_quantities(truth)
    row = {"kind": kind, "seed": seed, "noise": noise, "spacing": spacing, "truth": q_true.tolist()}
    for name, level in (("noisy", noise), ("noise_free", 0.0))[0 if noisy else 1:]:
        bundle = synthetic_bundle(truth, seed=seed, spacing=spacing, noise=level, fractions=FRACTIONS[1])
        start = started(q_true, kind, spacing, np.random.default_rng(seed + 1))
        f, _ = fit_true_kind(bundle, kind, start, sigma=noise)  # the noise-free fit weighted as the noisy one
        q = matched(shape_quantities(f.shapes)[0], q_true)
        err = shape_errors(f)[0]
        row[name] = {"estimate": q.tolist(), "std_centre": list(err.centroid), "chi2": f.chi2_fit,
                     "fitted": f.describe()}
        if name == "noisy":
            guide = bundle.observations.mask("guide")
            row[name]["profile"] = {q: profile_path(f, guide, QUANTITIES.index(q)) for q in quantities}
            if drive_draws:
                row[name]["drive_check"] = drive_check(f, guide, drive_draws)
                print("drive", row[name]["drive_check"], flush=True)
        print(name, json.dumps(row[name]), flush=True)
    std = np.array(row["noisy" if noisy else "noise_free"]["std_centre"])  # the noise-free fit's, weighted as noisy
    row["bias_in_errors"] = ((np.array(row["noise_free"]["estimate"][:2]) - q_true[:2]) / std).tolist()
    if noisy:
        row["z_noisy"] = ((np.array(row["noisy"]["estimate"][:2]) - q_true[:2]) / std).tolist()
    row.update(seconds=time.perf_counter() - t0, load_average=[round(x, 2) for x in os.getloadavg()],
               code=_code_version())
    return row


def summary(rows: list[dict]) -> dict:
    """The rows' measurements side by side, x against y; targets: the misfit quadratic along both
    centre coordinates (rise at 2 errors within 10 % of 4), the drive term within the chi-square
    95 % interval of its draws, the noise-free offsets under half an error."""
    from scipy.stats import chi2

    prof = [r["noisy"]["profile"] for r in rows if "noisy" in r]
    rise = {c: [v for p in prof for t, v in zip(p[c]["steps"], p[c]["chi2_rise"]) if abs(t) == 2] for c in ("cx", "cy")}
    checks = [r["noisy"]["drive_check"] for r in rows if "drive_check" in r.get("noisy", {})]
    ratio = [np.array(c["std_first_order"]) / np.array(c["std_drawn"]) for c in checks]
    # the drawn std over the true one lies in [a, b] 95 % of the time: first order / drawn in [1/b, 1/a]
    lo, hi = [float(np.sqrt((c["draws"] - 1) / chi2.ppf(q, c["draws"] - 1))) for q in (0.975, 0.025) for c in checks[:1]]
    bias = np.array([r["bias_in_errors"] for r in rows])
    worst = {c: float(np.max(np.abs(bias[:, i]))) for i, c in enumerate(("cx", "cy"))}
    return {"cases": [(r["kind"], r["seed"]) for r in rows],
            "chi2_rise_at_2_errors": rise,
            "drive_first_order_over_drawn": [x.tolist() for x in ratio], "drawn_interval_95": [lo, hi],
            "noise_free_offset_in_errors": {f"{r['kind']} {r['seed']}": r["bias_in_errors"] for r in rows},
            "targets": {
                "misfit_quadratic_along_the_centre": {
                    "value": {c: [min(v), max(v)] for c, v in rise.items()}, "range": [3.6, 4.4],
                    "pass": bool(all(3.6 <= x <= 4.4 for v in rise.values() for x in v))},
                "drive_term_as_its_draws": {
                    "value": [x.tolist() for x in ratio], "range": [lo, hi],
                    "pass": bool(all(lo <= v <= hi for x in ratio for v in x))},
                "noise_free_centre_offset_under_half_an_error": {
                    "value": worst, "target": 0.5, "pass": bool(max(worst.values()) < 0.5)}}}


def before_after(before: list[dict], after: list[dict]) -> dict:
    """Per quantity the reported total errors' coverage (within 2, exact binomial 95 % interval)
    on two sets of ``error_coverage.py`` rows, side by side, and the centre's y target: its
    coverage on ``after`` with 95 % inside its binomial interval."""
    from error_coverage_summary import summarise

    per = {}
    for name, rows in (("before", before), ("after", after)):
        q = summarise(rows)["variants"]["reported"]["per_quantity"]
        per[name] = {k: {"within_2": v.get("within_2_std"), "n": v["n"], "binomial_95": v.get("binomial_95")} for k, v in q.items()}
    cy = per["after"]["cy"]
    seeds = {name: [min(r["seed"] for r in rows), max(r["seed"] for r in rows)] for name, rows in (("before", before), ("after", after))}
    return {"seeds": seeds, "per_quantity": per,
            "target": {"cy_covered_as_about_95_percent": {"value": cy["within_2"], "binomial_95": cy["binomial_95"], "n": cy["n"],
                                                          "pass": bool(cy["binomial_95"][0] <= 0.95 <= cy["binomial_95"][1])}}}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kind", choices=("stiffer-region", "softer-region", "hole", "rectangle"))
    p.add_argument("--seeds", type=int, nargs="*", default=[])
    p.add_argument("--noise", type=float, default=0.02)
    p.add_argument("--spacing", type=float, default=10.0)
    p.add_argument("--drive-draws", type=int, default=0, help="draws of the drive's noise (0: no drive check)")
    p.add_argument("--quantities", nargs="+", default=["cx", "cy"], help="profile paths of these quantities")
    p.add_argument("--noise-free-only", action="store_true", help="measurement 2 alone")
    p.add_argument("--rows", type=Path, default=OUT / "error_coverage_centre_rows.jsonl")
    p.add_argument("--summary", action="store_true", help="only summarise the rows")
    p.add_argument("--before", type=Path, help="with --summary: error_coverage.py rows before (coverage side by side)")
    p.add_argument("--after", type=Path, help="with --summary: error_coverage.py rows after")
    args = p.parse_args()
    if args.summary:
        rows = [json.loads(line) for line in open(args.rows)]
        out = summary(rows)
        if args.before and args.after:
            read = lambda path: [r for r in map(json.loads, open(path)) if "error" not in r]  # noqa: E731
            out["coverage_before_after"] = ba = before_after(read(args.before), read(args.after))
            out["targets"].update(ba.pop("target"))
        (OUT / "error_coverage_centre.json").write_text(json.dumps({**out, "rows": rows}, indent=1))
        print(json.dumps(out["targets"], indent=1))
        return
    for seed in args.seeds:
        row = run(args.kind, seed, args.noise, args.spacing, args.drive_draws, not args.noise_free_only,
                  args.quantities)
        with open(args.rows, "a") as out:
            out.write(json.dumps(row) + "\n")
        print(f"{args.kind} {seed}: bias {row['bias_in_errors']} {row['seconds']:.0f} s", flush=True)


if __name__ == "__main__":
    main()
