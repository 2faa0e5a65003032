"""How much of a noise-free fit's offset is the drive's linear interpolation along the outline, on
``error_coverage.py``'s cases (``--kind``, ``--seeds``): an experiment, not the library's drive.

    PYTHONPATH=. python benchmarks/error_coverage_drive_order.py --kind hole --seeds 9506

1. *The interpolation error along each side*: the case's noise-free displacements on a 5 mm grid
   (the fine solve's, last frame); the 10 mm points' linear interpolation (the model's drive,
   :func:`jaxfem.boundary_interpolation`) and a 4-point Lagrange cubic along the side, both at
   the 5 mm midpoints, against the truth there: rms per side and component (mm).
2. *The fit's offset with either drive*: the case fitted on its noise-free 10 mm data as
   ``error_coverage.py`` fits it, once with the library's linear drive and once with
   :func:`cubic_drive` put in its place for this process (``jaxfem.boundary_interpolation``
   patched: a cubic along each side of the rectangular ROI through the boundary points on it,
   its stencil kept inside the side, so no cubic spans a corner). The offsets from the truth of
   the centre, axes, angle, area and ratio.

Rows appended to ``results/error_coverage_drive_order_rows.jsonl``; ``--summary`` writes
``results/error_coverage_drive_order.json`` with ``targets``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from error_coverage import FRACTIONS, _code_version, fit_true_kind, matched, started, true_quantities, truth_of

OUT = Path(__file__).parent / "results"
ROI = (20.0, 10.0, 120.0, 70.0)
"""The synthetic bundles' tracked region ``[xmin, ymin, xmax, ymax]`` (mm)."""


def _sides(roi=ROI):
    """The ROI's sides: ``(name, on(P) -> mask, axis along the side)``."""
    x0, y0, x1, y1 = roi
    return [("bottom", lambda P: np.isclose(P[:, 1], y0), 0), ("top", lambda P: np.isclose(P[:, 1], y1), 0),
            ("left", lambda P: np.isclose(P[:, 0], x0), 1), ("right", lambda P: np.isclose(P[:, 0], x1), 1)]


def _lagrange(xs: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    """The 4-point Lagrange stencil (indices into sorted ``xs``, kept inside) and weights at ``s``."""
    k = int(np.clip(np.searchsorted(xs, s, side="right") - 2, 0, len(xs) - 4))
    st = np.arange(k, k + 4)
    w = np.array([np.prod((s - np.delete(xs[st], j)) / (xs[st[j]] - np.delete(xs[st], j))) for j in range(4)])
    return st, w


def cubic_drive(mesh, points, tol=None, names=None, roi=ROI):
    """:func:`jaxfem.boundary_interpolation`'s signature and ``(loop nodes, W)``, with a 4-point
    Lagrange cubic along each side of the rectangle ``roi`` through the points on that side
    (corners belong to both) instead of linear interpolation in arc length."""
    import jaxfem as jf

    pts = np.asarray(points, float)
    loop, _ = _LINEAR[0](mesh, pts, tol=np.inf)
    X = np.asarray(mesh.nodes)[loop]
    W = np.zeros((len(loop), len(pts)))
    done = np.zeros(len(loop), bool)
    for _, on, ax in _sides(roi):
        ip = np.flatnonzero(on(pts))
        if ip.size < 4:
            raise jf.MeshError("a side with fewer than 4 boundary points: no cubic")
        ip = ip[np.argsort(pts[ip, ax])]
        for r in np.flatnonzero(on(X) & ~done):
            st, w = _lagrange(pts[ip, ax], X[r, ax])
            W[r, ip[st]] = w
            done[r] = True
    if not done.all():
        raise jf.MeshError("boundary nodes off the rectangle's sides")
    return loop, W


_LINEAR = []
"""The library's ``jaxfem.boundary_interpolation``, kept while it is patched."""


def side_errors(kind: str, seed: int) -> dict:
    """Rms interpolation errors (mm) of the 10 mm points' linear and cubic drives at the 5 mm
    midpoints, per side and component (noise-free, last frame)."""
    from refine.synthetic.sheet import synthetic_bundle

    b = synthetic_bundle(truth_of(kind, seed), seed=seed, spacing=5.0, noise=0.0, fractions=FRACTIONS[1])
    X, U = np.asarray(b.observations.reference), np.asarray(b.observations.displacements)[-1]
    out = {}
    for name, on, ax in _sides():
        idx = np.flatnonzero(on(X))
        idx = idx[np.argsort(X[idx, ax])]
        u, c = U[idx], U[idx][::2]
        mid = u[3:-3:2]  # midpoints with a full cubic stencil of 10 mm points about them
        lin = 0.5 * (c[1:-2] + c[2:-1]) - mid
        cub = (-c[:-3] + 9 * c[1:-2] + 9 * c[2:-1] - c[3:]) / 16 - mid
        out[name] = {"linear_rms": np.sqrt(np.mean(lin**2, 0)).tolist(), "cubic_rms": np.sqrt(np.mean(cub**2, 0)).tolist()}
    return out


def offsets(kind: str, seed: int, sigma: float = 0.02) -> dict:
    """The noise-free fit's offsets from the truth (:data:`error_coverage_summary.QUANTITIES`) with
    the linear and with the cubic drive."""
    import jaxfem as jf
    from refine.diagnosis.uncertainty import shape_quantities
    from refine.synthetic.sheet import synthetic_bundle

    truth = truth_of(kind, seed)
    q_true = true_quantities(truth)
    bundle = synthetic_bundle(truth, seed=seed, spacing=10.0, noise=0.0, fractions=FRACTIONS[1])
    if not _LINEAR:
        _LINEAR.append(jf.boundary_interpolation)
    out = {}
    try:
        for name, interp in (("linear", _LINEAR[0]), ("cubic", cubic_drive)):
            jf.boundary_interpolation = interp
            start = started(q_true, kind, 10.0, np.random.default_rng(seed + 1))
            f, _ = fit_true_kind(bundle, kind, start, sigma=sigma)
            d = matched(shape_quantities(f.shapes)[0], q_true) - q_true
            out[name] = {"offset": d.tolist(), "chi2": f.chi2_fit}
            print(f"{kind} {seed} {name} drive: offset {np.round(d, 4)} chi2 {f.chi2_fit:.2f}", flush=True)
    finally:
        jf.boundary_interpolation = _LINEAR[0]
    return out


def summary(rows: list[dict]) -> dict:
    """Per quantity the noise-free offsets' rms with either drive; targets: the cubic drive lowers
    the centre's y offset (rms over the rows) by at least half."""
    q = ("cx", "cy", "a", "b", "angle", "area", "ratio")
    rms = {name: {k: float(np.sqrt(np.mean([r["fits"][name]["offset"][i] ** 2 for r in rows]))) for i, k in enumerate(q)}
           for name in ("linear", "cubic")}
    cy = rms["cubic"]["cy"] / rms["linear"]["cy"]
    return {"cases": [(r["kind"], r["seed"]) for r in rows], "offset_rms": rms,
            "targets": {"cubic_drive_halves_the_cy_offset": {"value": cy, "target": 0.5, "pass": bool(cy <= 0.5)}}}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kind", choices=("stiffer-region", "softer-region", "hole", "rectangle"))
    p.add_argument("--seeds", type=int, nargs="*", default=[])
    p.add_argument("--rows", type=Path, default=OUT / "error_coverage_drive_order_rows.jsonl")
    p.add_argument("--summary", action="store_true", help="only summarise the rows")
    args = p.parse_args()
    for seed in args.seeds:
        t0 = time.perf_counter()
        row = {"kind": args.kind, "seed": seed, "sides": side_errors(args.kind, seed), "fits": offsets(args.kind, seed)}
        row.update(seconds=time.perf_counter() - t0, load_average=[round(x, 2) for x in os.getloadavg()],
                   code=_code_version())
        with open(args.rows, "a") as out:
            out.write(json.dumps(row) + "\n")
    if args.summary:
        rows = [json.loads(line) for line in open(args.rows)]
        (OUT / "error_coverage_drive_order.json").write_text(json.dumps({**summary(rows), "rows": rows}, indent=1))
        print(json.dumps(summary(rows)["targets"], indent=1))


if __name__ == "__main__":
    main()
