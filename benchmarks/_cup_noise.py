"""Is the cup holder's area error on one seed the noise's or the model's? (issue 23 item 4;
benchmarks/README.md's diagnose3d section, session 25.)

From a seed's noise-free data (``diagnose3d.py --noise 0 --data-only``, the same points: the
generator draws the points before the noise) this writes bundles beside it: ``clean`` (the
noise-free displacements, weighted at the noisy bundle's noise), ``orig`` (the noisy bundle's own
displacements, to check that they are clean + noise) and ``draw<k>`` (clean + new Gaussian noise of
the same standard deviation, seeds 1000 + k). ``_cup_area.py --name ... [--layers L]`` then refits
the diagnosis's hole on each at h 1.2 and sqrt(2) x 1.2; ``--summary`` gives per bundle the fitted
ellipse's error and the cut area's extrapolations (the plan's alone, and the grid's with one
layer more: the diagnosis's, :mod:`refine.solid.hole_area`).

    python benchmarks/_cup_noise.py --make --seed 2 --clean B/cup_seed2_hdata0.8_s0.6_n0_f1-2-3-4 \
        --noisy B2/cup_seed2_hdata0.8_s0.6_n0.005_f1-2-3-4 --draws 4
    python benchmarks/_cup_noise.py --summary benchmarks/results/cup_noise_s25.jsonl benchmarks/results/cup_area_s24.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from refine.bundle.io import read_bundle, write_bundle  # noqa: E402


def write_like(noisy, dst: Path, U: np.ndarray) -> None:
    """The bundle ``noisy`` (its experiment: the noise it is weighted with, the mesh) with the
    displacements ``U`` written to ``dst``."""
    write_bundle(dst, replace(noisy, observations=replace(noisy.observations, displacements=U)))


def make(args) -> None:
    clean, noisy = read_bundle(args.clean), read_bundle(args.noisy)
    a, b = clean.observations, noisy.observations
    if not (np.array_equal(a.ids, b.ids) and np.array_equal(a.reference, b.reference)
            and np.array_equal(a.roles, b.roles)):
        raise SystemExit("the clean and noisy bundles' points differ: not the same seed and grid")
    r = b.displacements - a.displacements
    print(json.dumps({"orig_noise_std": float(r.std()), "orig_noise_mean": float(r.mean()),
                      "max_abs": float(np.abs(r).max()), "sigma": args.sigma, "n": int(r.size)}))
    out, stem = args.clean.parent, f"cup_seed{args.seed}_"
    write_like(noisy, out / f"{stem}clean", a.displacements)
    write_like(noisy, out / f"{stem}orig", b.displacements)
    for k in range(1, args.draws + 1):
        rng = np.random.default_rng(1000 + k)
        write_like(noisy, out / f"{stem}draw{k}", a.displacements + rng.normal(0.0, args.sigma, a.displacements.shape))


def summary(paths: list[Path], out: Path | None) -> None:
    """Per bundle of ``_cup_area.py``'s rows: the cut area's extrapolation from the grid's corners
    (h 1.2 and 1.697, the rows' layers L and L + 1; :func:`refine.solid.hole_area.weights`, as the
    diagnosis makes it) and the plan's alone, as errors (%) of the drawn ellipse."""
    from refine.solid.hole_area import weights

    rows = [json.loads(line) for p in paths for line in p.read_text().splitlines() if line.strip()]
    name_of = lambda r: (r["seed"], r.get("bundle", "hdata0.8_s0.6_n0.005_f1-2-3-4"))  # noqa: E731 - s24's rows
    table = []
    for name in dict.fromkeys(map(name_of, rows)):
        at = {(round(r["h"], 3), r.get("layers") or 2): r for r in rows
              if name_of(r) == name and "cut_area_error_pct" in r}
        L = min((k[1] for k in at), default=2)
        corner = {"fine": (1.2, L), "plan": (1.697, L), "layers": (1.2, L + 1), "both": (1.697, L + 1)}
        if any(at.get(c) is None for k, c in corner.items() if k in ("fine", "plan")):
            continue
        f = at[corner["fine"]]
        cut = {k: 1 + at[c]["cut_area_error_pct"] / 100 for k, c in corner.items() if c in at}  # over the data's cut
        of_ellipse = lambda w: 100 * (sum(v * cut[k] for k, v in w.items()) * f["data_cut_fraction"] - 1)  # noqa: E731
        row = {"bundle": name[1], "seed": f["seed"], "layers": L, "ellipse_pct": f["area_error_pct"],
               "plan_only_pct": of_ellipse(weights(L, both=False)), "modulus_fine": f["modulus"]}
        if "layers" in cut and "both" in cut:
            row["grid_pct"] = of_ellipse(weights(L))
        table.append(row)
    for t in table:
        print(" ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in t.items()))
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
    p.add_argument("--summary", type=Path, nargs="+", help="_cup_area.py's rows (JSONL), e.g. session 24's too")
    p.add_argument("--out", type=Path)
    args = p.parse_args()
    if args.make:
        make(args)
    if args.summary:
        summary(args.summary, args.out)


if __name__ == "__main__":
    main()
