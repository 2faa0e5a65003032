"""Benchmark of the tracking package: accuracy and speed of the grid and speckle trackers.

Sweeps noise and strain on synthetic images (ground truth known analytically), compares the grid
refiners (symmetric line fitting, Hessian extremum, snake crossings alone) and the line fit's
centre-line shapes on fields with creases (straight, curved, adaptive), and both trackers with
OpenCV's pyramidal Lucas-Kanade and scikit-image's upsampled phase correlation on the same 8-bit
images and points, measures points per second, and runs the DIC Challenge Sample 3 images when
../shared/ holds them. The large-motion rows (motion of several pitches per frame, a 20 % pair,
holes, edges, glare, a speckle jump; against OpenCV's pyramidal LK and ECC) and Sample 12 against
DICe are in ``_tracking_large``. Writes benchmarks/results/trackers.json (with ``targets``:
pass/fail per target), trackers.png and trackers_large_motion.png.

    python -m benchmarks trackers            # a few minutes on 2 cores
    python -m benchmarks trackers --quick    # fewer sweep points, for a smoke test
    python -m benchmarks trackers --only large   # the large-motion rows and Sample 12, kept with
                                                 # the other rows of an existing trackers.json

The competitors get an oracle start (each point's true motion rounded to whole pixels) and track
the true reference points, so their numbers measure sub-pixel estimation alone; ours include
detection and frame-to-frame tracking from no prior knowledge.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from scipy.spatial import cKDTree  # noqa: E402

from tracking import (GridTracker, SpeckleTracker, creased_displacement, deformed_points, grid_truth,  # noqa: E402
                      load_images, render_grid, render_speckle, scaled, smooth_displacement)

from benchmarks import _tracking_large as large  # noqa: E402
from benchmarks._tracker_competitors import lucas_kanade, phase_correlation  # noqa: E402
from benchmarks._cli import QUICK, quick  # noqa: E402

SHAPE = (256, 256)
ROI = (16, 16, 240, 240)
PITCH = 12.0
FRAMES = 3            # frames from rest to the full deformation (ours track the sequence)
TARGET_RMS_PX = 0.05  # the test suite's bound on generated images (tests/test_tracking_*.py)
TARGET_NOISE = 2.0    # ... at the test suite's image noise (grey levels)
OURS = {"grid": "lines", "speckle": "dic_icgn"}   # the default grid refiner, the speckle tracker


def _rms(error):
    error = error[np.isfinite(error)]
    return float(np.sqrt(np.mean(error ** 2))) if error.size else float("nan")


def _sequence(render, field, noise, seed):
    steps = np.linspace(0.0, 1.0, FRAMES)
    return [render(scaled(field, s), noise, seed * 100 + k) for k, s in enumerate(steps)]


def _grid_image(displacement, noise, seed, pitch=PITCH, shape=SHAPE):
    return render_grid(shape, pitch, 2.0 if pitch < 15 else 3.0, displacement, noise_sigma=noise,
                       blur_sigma=1.0, seed=seed, quantize=True, lighting_gradient=0.2)


def _speckle_image(displacement, noise, seed):
    return render_speckle(SHAPE, displacement=displacement, noise_sigma=noise, seed=seed, quantize=True)


def _grid_case(field, noise, seed, refiners=("lines", "hessian", "snake"), pitch=PITCH, competitors=True):
    images = _sequence(lambda u, n, k: _grid_image(u, n, k, pitch), field, noise, seed)
    truth_ref, _, _ = grid_truth(SHAPE, pitch, margin=-120)
    result = {}
    for refiner in refiners:
        start = time.perf_counter()
        tracks = GridTracker(refiner=refiner).track(images, roi=ROI)
        seconds = time.perf_counter() - start
        distance, match = cKDTree(truth_ref).query(tracks.reference)
        reference = truth_ref[match]
        truth = deformed_points(reference, field)
        result[refiner] = {
            "reference_rms_px": _rms(np.linalg.norm(tracks.reference - reference, axis=1)),
            "deformed_rms_px": _rms(np.linalg.norm(tracks.positions[-1] - truth, axis=1)),
            "deformed_max_px": float(np.nanmax(np.linalg.norm(tracks.positions[-1] - truth, axis=1))),
            "lost_last_frame": int(tracks.lost[-1].sum()), "points": tracks.n_points,
            "points_per_second": tracks.n_points * len(images) / seconds}
    if not competitors:
        return result
    # competitors: the true reference crossings inside the ROI, oracle integer start
    x0, y0, x1, y1 = ROI
    inside = ((truth_ref[:, 0] > x0) & (truth_ref[:, 0] < x1)
              & (truth_ref[:, 1] > y0) & (truth_ref[:, 1] < y1))
    points = truth_ref[inside]
    truth = deformed_points(points, field)
    visible = np.all((truth > 20) & (truth < np.array(SHAPE[::-1]) - 20), axis=1)
    points, truth = points[visible], truth[visible]
    start = np.rint(truth)
    grid_lk = lambda *a: lucas_kanade(*a, window=15)  # noqa: E731 - LK's best window on the grid
    result.update(_baselines((("opencv_lk", grid_lk), ("phase_correlation", phase_correlation)),
                             images, points, truth, start))
    return result


def _baselines(methods, images, points, truth, start) -> dict:
    """Each of ``methods`` (name, function of (first image, last image, points, start)) from the
    first image to the last: its error against ``truth`` (px), points lost and points per second."""
    out = {}
    for name, method in methods:
        t0 = time.perf_counter()
        found = method(images[0], images[-1], points, start)
        seconds = time.perf_counter() - t0
        error = np.linalg.norm(found - truth, axis=1)
        out[name] = {"deformed_rms_px": _rms(error), "deformed_max_px": float(np.nanmax(error)),
                     "lost_last_frame": int(np.isnan(error).sum()), "points": len(points),
                     "points_per_second": len(points) / seconds}
    return out


def _crease_case(jump, seed, shapes=("straight", "curved", "adaptive")):
    """Grid crossings on a field with creases (the strain jumps by ``jump``, as at a stiff
    inclusion's edge): RMS error within 4 px of a crease and elsewhere, per centre-line shape."""
    field, distance = creased_displacement(SHAPE, jump=jump, seed=seed)
    images = _sequence(lambda u, n, k: _grid_image(u, n, k), field, 2.0, seed)
    truth_ref, _, _ = grid_truth(SHAPE, PITCH, margin=-120)
    result = {}
    for shape in shapes:
        tracks = GridTracker(line_shape=shape).track(images, roi=ROI)
        reference = truth_ref[cKDTree(truth_ref).query(tracks.reference)[1]]
        error = np.linalg.norm(tracks.positions[-1] - deformed_points(reference, field), axis=1)
        near = distance(reference) < 4.0
        result[shape] = {"near_crease_rms_px": _rms(error[near]), "elsewhere_rms_px": _rms(error[~near]),
                         "reference_rms_px": _rms(np.linalg.norm(tracks.reference - reference, axis=1)),
                         "near_points": int(near.sum()), "lost_last_frame": int(tracks.lost[-1].sum())}
    return result


def _speckle_case(field, noise, seed):
    images = _sequence(_speckle_image, field, noise, seed)
    start_time = time.perf_counter()
    tracks = SpeckleTracker(spacing=10, subset=21).track(images, roi=ROI)
    seconds = time.perf_counter() - start_time
    truth = deformed_points(tracks.reference, field)
    error = np.linalg.norm(tracks.positions[-1] - truth, axis=1)
    result = {"dic_icgn": {"deformed_rms_px": _rms(error), "deformed_max_px": float(np.nanmax(error)),
                           "lost_last_frame": int(tracks.lost[-1].sum()), "points": tracks.n_points,
                           "points_per_second": tracks.n_points * (len(images) - 1) / seconds}}
    points = tracks.reference
    visible = np.all((truth > 20) & (truth < np.array(SHAPE[::-1]) - 20), axis=1)
    points, truth = points[visible], truth[visible]
    result.update(_baselines((("opencv_lk", lucas_kanade), ("phase_correlation", phase_correlation)),
                             images, points, truth, np.rint(truth)))
    return result


def _speed():
    """Points per second on 384 x 384 images, 3 frames (ours) or one pair (competitors)."""
    shape = (384, 384)
    field = smooth_displacement(shape, 0.05, seed=4)
    out = {}
    for pattern in ("grid", "speckle"):
        if pattern == "grid":
            images = [_grid_image(scaled(field, s), 2.0, k, shape=shape) for k, s in enumerate([0, 0.5, 1])]
            tracker = GridTracker()
        else:
            images = [render_speckle(shape, displacement=scaled(field, s), noise_sigma=2.0, seed=k,
                                     quantize=True) for k, s in enumerate([0, 0.5, 1])]
            tracker = SpeckleTracker(spacing=10, subset=21)
        t0 = time.perf_counter()
        tracks = tracker.track(images, roi=(16, 16, shape[1] - 16, shape[0] - 16))
        seconds = time.perf_counter() - t0
        frames = len(images) if pattern == "grid" else len(images) - 1
        entry = {"points": tracks.n_points, "ours_points_per_second": tracks.n_points * frames / seconds}
        truth = deformed_points(tracks.reference, field)
        for name, method in (("opencv_lk", lucas_kanade), ("phase_correlation", phase_correlation)):
            t0 = time.perf_counter()
            method(images[0], images[-1], tracks.reference, np.rint(truth))
            entry[f"{name}_points_per_second"] = tracks.n_points / (time.perf_counter() - t0)
        out[pattern] = entry
    return out


def dic_challenge(folder: Path):
    """Sample 3 of the DIC Challenge: mean and std of the error per frame, per method."""
    with open(folder / "truth.csv") as handle:
        rows = list(csv.DictReader(handle))
    paths = [folder / "reference.tif"] + [folder / r["file"] for r in rows]
    shifts = np.array([[0.0, 0.0]] + [[float(r["shift_x_px"]), float(r["shift_y_px"])] for r in rows])
    images = load_images(paths)
    roi = load_images([folder / "roi.tif"])[0] > 0
    t0 = time.perf_counter()
    tracks = SpeckleTracker(spacing=10, subset=21).track(images, roi=roi)
    seconds = time.perf_counter() - t0
    out = {"points": tracks.n_points,
           "dic_icgn_points_per_second": tracks.n_points * (len(images) - 1) / seconds,
           "competitor_points": "every 8th point of the same lattice, started at zero motion"}
    few = tracks.reference[::8]
    methods = {"dic_icgn": lambda k: tracks.positions[k],
               "opencv_lk": lambda k: lucas_kanade(images[0], images[k], few, few),
               "phase_correlation": lambda k: phase_correlation(images[0], images[k], few, few)}
    for name, method in methods.items():
        frames = []
        for k in range(1, len(images)):
            points = tracks.reference if name == "dic_icgn" else few
            error = method(k) - points - shifts[k]
            frames.append({"shift_px": float(shifts[k, 0]),
                           "mean_error_px": [float(v) for v in np.nanmean(error, axis=0)],
                           "std_error_px": [float(v) for v in np.nanstd(error, axis=0)],
                           "lost": int(np.isnan(error[:, 0]).sum())})
        out[name] = {"frames": frames,
                     "worst_abs_mean_px": max(max(abs(v) for v in f["mean_error_px"]) for f in frames),
                     "worst_std_px": max(max(f["std_error_px"]) for f in frames)}
    return out


def main(argv=None) -> int:
    argv = quick(argv, ["--quick", "--out", str(QUICK)])
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer sweep points")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    parser.add_argument("--only", choices=("all", "large"), default="all",
                        help="large: only the large-motion rows and Sample 12 (other rows kept from --out)")
    args = parser.parse_args(argv)
    shared = Path(os.environ.get("NONRIGID_SHARED", ROOT.parent / "shared"))
    if args.only == "large":
        return _large_only(args, shared)
    noises = [0.0, 2.0, 8.0] if args.quick else [0.0, 1.0, 2.0, 4.0, 8.0]
    strains = [0.0, 0.2] if args.quick else [0.0, 0.05, 0.1, 0.15, 0.2]
    report = {"shape": SHAPE, "pitch_px": PITCH, "frames_per_sequence": FRAMES, "quick": args.quick,
              "noise_vs": {}, "strain_vs": {}}
    t_start = time.perf_counter()
    for pattern, case in (("grid", _grid_case), ("speckle", _speckle_case)):
        report["noise_vs"][pattern] = [
            {"noise_sigma": n, **case(smooth_displacement(SHAPE, 0.1, seed=1), n, seed=7)} for n in noises]
        report["strain_vs"][pattern] = [
            {"stretch": s, **case(smooth_displacement(SHAPE, s, seed=2), 2.0, seed=8)} for s in strains]
        print(f"{pattern}: done at {time.perf_counter() - t_start:.0f} s", flush=True)
    report["pitch_vs"] = [{"pitch_px": p, **_grid_case(smooth_displacement(SHAPE, 0.2, seed=3), 2.0, seed=9,
                                                       pitch=p, competitors=False)}
                          for p in ([10.0, 20.0] if args.quick else [10.0, 15.0, 20.0])]
    report["crease_vs"] = [{"jump": j, **_crease_case(j, seed=5)}
                           for j in ([0.0, 0.15] if args.quick else [0.0, 0.05, 0.1, 0.15, 0.2])]
    report["speed"] = _speed()
    print(f"pitch and speed: done at {time.perf_counter() - t_start:.0f} s", flush=True)
    folder = shared / "data" / "dic-challenge-sample3"
    report["dic_challenge_sample3"] = dic_challenge(folder) if folder.is_dir() else None
    report["large_motion"] = large.run(args.quick, shared, lambda m: print(m, flush=True))
    report["seconds"] = time.perf_counter() - t_start
    report["load_average_1_5_15min"] = os.getloadavg()
    report["targets"] = {**targets(report), **large.targets(report["large_motion"])}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "trackers.json").write_text(json.dumps(report, indent=1))
    _plot(report, args.out / "trackers.png")
    large.plot(report["large_motion"], args.out / "trackers_large_motion.png")
    _summary(report)
    return 0


def _large_only(args, shared):
    """Run the large-motion rows alone; the other rows of an existing trackers.json are kept."""
    path = args.out / "trackers.json"
    report = json.loads(path.read_text()) if path.exists() else {}
    t_start = time.perf_counter()
    report["large_motion"] = large.run(args.quick, shared, lambda m: print(m, flush=True))
    report["large_motion"]["seconds"] = time.perf_counter() - t_start
    report["large_motion"]["load_average_1_5_15min"] = os.getloadavg()
    report["large_motion"]["quick"] = args.quick
    report["large_motion"]["note"] = "--only large: the rows outside large_motion are the earlier run's, judged again"
    old_rows = targets(report) if "noise_vs" in report else {}   # the kept rows judged again
    report["targets"] = {**report.get("targets", {}), **old_rows, **large.targets(report["large_motion"])}
    args.out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(report, indent=1))
    large.plot(report["large_motion"], args.out / "trackers_large_motion.png")
    large.summary(report)


def targets(report):
    """Pass or fail per target, from the noise and strain sweeps: our trackers within TARGET_RMS_PX
    RMS in the last frame at noise up to TARGET_NOISE (every stretch of the strain sweep, which
    runs at that noise), and more accurate than both competitors in every row of both sweeps."""
    out = {}
    for pattern, ours in OURS.items():
        rows = ([("noise_sigma", r["noise_sigma"], r) for r in report["noise_vs"][pattern]
                 if r["noise_sigma"] <= TARGET_NOISE]
                + [("stretch", r["stretch"], r) for r in report["strain_vs"][pattern]])
        accuracy = [{key: value, "rms_px": r[ours]["deformed_rms_px"],
                     "pass": bool(r[ours]["deformed_rms_px"] <= TARGET_RMS_PX)} for key, value, r in rows]
        out[f"{pattern}_{ours}_rms_within_{TARGET_RMS_PX:g}_px"] = {
            "threshold_px": TARGET_RMS_PX, "noise_up_to": TARGET_NOISE, "rows": accuracy,
            "pass": bool(accuracy) and all(a["pass"] for a in accuracy)}
        rows = ([("noise_sigma", r["noise_sigma"], r) for r in report["noise_vs"][pattern]]
                + [("stretch", r["stretch"], r) for r in report["strain_vs"][pattern]])
        compared = [{key: value, "rms_px": r[ours]["deformed_rms_px"],
                     **{f"{m}_rms_px": r[m]["deformed_rms_px"] for m in ("opencv_lk", "phase_correlation")},
                     "pass": bool(r[ours]["deformed_rms_px"] < min(r["opencv_lk"]["deformed_rms_px"],
                                                                   r["phase_correlation"]["deformed_rms_px"]))}
                    for key, value, r in rows]
        out[f"{pattern}_{ours}_more_accurate_than_opencv_lk_and_phase_correlation"] = {
            "rows": compared, "pass": bool(compared) and all(c["pass"] for c in compared)}
    return out


def _plot(report, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 5, figsize=(25, 4.5))
    panels = [("noise_vs", "grid", "noise_sigma", "noise sigma (grey levels)"),
              ("strain_vs", "grid", "stretch", "stretch"),
              ("noise_vs", "speckle", "noise_sigma", "noise sigma (grey levels)"),
              ("strain_vs", "speckle", "stretch", "stretch")]
    for ax, (sweep, pattern, key, label) in zip(axes, panels):
        rows = report[sweep][pattern]
        methods = [m for m in rows[0] if isinstance(rows[0][m], dict)]
        for method in methods:
            ax.plot([r[key] for r in rows], [r[method]["deformed_rms_px"] for r in rows], "o-",
                    label=method)
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("RMS error in the last frame (px)")
        ax.set_title(f"{pattern}: error vs {key}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    ax, rows = axes[-1], report["crease_vs"]
    for shape in [m for m in rows[0] if isinstance(rows[0][m], dict)]:
        for key, style in (("near_crease_rms_px", "o-"), ("elsewhere_rms_px", "s--")):
            ax.plot([r["jump"] for r in rows], [r[shape][key] for r in rows], style,
                    label=f"{shape}, {key.replace('_rms_px', '').replace('_', ' ')}")
    ax.set_yscale("log")
    ax.set_xlabel("jump of the strain across a crease")
    ax.set_ylabel("RMS error in the last frame (px)")
    ax.set_title("grid line shapes at creases")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _summary(report):
    for sweep in ("noise_vs", "strain_vs"):
        for pattern, rows in report[sweep].items():
            for r in rows:
                key = "noise_sigma" if sweep == "noise_vs" else "stretch"
                parts = [f"{m}={v['deformed_rms_px']:.4f}" for m, v in r.items() if isinstance(v, dict)]
                print(f"{pattern:8s} {key}={r[key]:<5} " + " ".join(parts))
    for r in report["crease_vs"]:
        parts = [f"{m}: near {v['near_crease_rms_px']:.4f} elsewhere {v['elsewhere_rms_px']:.4f}"
                 for m, v in r.items() if isinstance(v, dict)]
        print(f"creases jump={r['jump']:<5} " + " | ".join(parts))
    dic = report["dic_challenge_sample3"]
    if dic:
        for m in ("dic_icgn", "opencv_lk", "phase_correlation"):
            print(f"DIC challenge {m}: worst |mean| {dic[m]['worst_abs_mean_px']:.4f} px, "
                  f"worst std {dic[m]['worst_std_px']:.4f} px")
    large.summary(report)
    print(f"total {report['seconds']:.0f} s")


if __name__ == "__main__":
    raise SystemExit(main())
