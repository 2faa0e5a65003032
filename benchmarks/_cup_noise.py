"""Is the cup holder's area error on one seed the noise's or the model's? (issue 23 item 4;
benchmarks/README.md's diagnose3d section, session 25.)

From a seed's noise-free data (``diagnose3d.py --noise 0 --data-only``, the same points: the
generator draws the points before the noise) this writes bundles beside it: ``clean`` (the
noise-free displacements, weighted at the noisy bundle's noise), ``orig`` (the noisy bundle's own
displacements, to check that they are clean + noise) and ``draw<k>`` (clean + new Gaussian noise of
the same standard deviation, seeds 1000 + k). ``_cup_area.py --name ...`` then refits the
diagnosis's hole on each at h 1.2 and sqrt(2) x 1.2; ``--summary`` gives per bundle the fitted
ellipse's and the extrapolated cut area's errors.

    python benchmarks/_cup_noise.py --make --seed 2 --clean B/cup_seed2_hdata0.8_s0.6_n0_f1-2-3-4 \
        --noisy B2/cup_seed2_hdata0.8_s0.6_n0.005_f1-2-3-4 --draws 4
    python benchmarks/_cup_noise.py --summary benchmarks/results/cup_noise_s25.jsonl
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np


def read_u(root: Path) -> tuple[list[str], np.ndarray]:
    lines = (root / "displacements.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    return [f"{r[0]},{r[1]}" for r in rows], np.array([[float(v) for v in r[2:]] for r in rows])


def write_like(src_noisy: Path, dst: Path, keys: list[str], U: np.ndarray) -> None:
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(src_noisy, dst)
    body = "\n".join(f"{k},{float(u[0])!r},{float(u[1])!r},{float(u[2])!r}" for k, u in zip(keys, U))
    (dst / "displacements.csv").write_text("frame,id,ux,uy,uz\n" + body + "\n")


def make(args) -> None:
    if (args.clean / "points.csv").read_text() != (args.noisy / "points.csv").read_text():
        raise SystemExit("the clean and noisy bundles' points differ: not the same seed and grid")
    keys, clean = read_u(args.clean)
    keys2, noisy = read_u(args.noisy)
    assert keys == keys2
    r = noisy - clean
    sigma = float(args.sigma)
    print(json.dumps({"orig_noise_std": float(r.std()), "orig_noise_mean": float(r.mean()),
                      "max_abs": float(np.abs(r).max()), "sigma": sigma, "n": int(r.size)}))
    out = args.clean.parent
    stem = f"cup_seed{args.seed}_"
    write_like(args.noisy, out / f"{stem}clean", keys, clean)
    write_like(args.noisy, out / f"{stem}orig", keys, noisy)
    for k in range(1, args.draws + 1):
        rng = np.random.default_rng(1000 + k)
        write_like(args.noisy, out / f"{stem}draw{k}", keys, clean + rng.normal(0.0, sigma, clean.shape))


def summary(path: Path, out: Path | None) -> None:
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    table = []
    for name in dict.fromkeys(r.get("bundle") for r in rows):
        at = {round(r["h"], 3): r for r in rows if r.get("bundle") == name and "area_error_pct" in r}
        f, c = at.get(1.2), at.get(1.697)
        if f is None or c is None:
            continue
        cut = 2 * f["cut_area_error_pct"] - c["cut_area_error_pct"]  # Richardson, order 2, factor sqrt(2)
        table.append({"bundle": name, "seed": f["seed"], "ellipse_pct": f["area_error_pct"],
                      "cut_richardson_pct": 100 * ((1 + cut / 100) * f["data_cut_fraction"] - 1),
                      "modulus_fine": f["modulus"], "modulus_coarse": c["modulus"],
                      "chi2_per_fine": f["chi2_per"], "cpu_seconds": f["cpu_seconds"] + c["cpu_seconds"]})
    for t in table:
        print(" ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in t.items()))
    draws = [t["cut_richardson_pct"] for t in table if str(t["bundle"]).startswith("draw")]
    if draws:
        print(json.dumps({"draws": len(draws), "mean": float(np.mean(draws)),
                          "std": float(np.std(draws, ddof=1)) if len(draws) > 1 else None}))
    if out:
        out.write_text(json.dumps(table, indent=1) + "\n")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--make", action="store_true")
    p.add_argument("--seed", type=int, default=2)
    p.add_argument("--clean", type=Path)
    p.add_argument("--noisy", type=Path)
    p.add_argument("--sigma", type=float, default=0.005)
    p.add_argument("--draws", type=int, default=4)
    p.add_argument("--summary", type=Path)
    p.add_argument("--out", type=Path)
    args = p.parse_args()
    if args.make:
        make(args)
    if args.summary:
        summary(args.summary, args.out)


if __name__ == "__main__":
    main()
