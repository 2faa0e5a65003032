"""Large motion and things in view (issue 21): our trackers against OpenCV's pyramidal
Lucas-Kanade and ECC on the same images, and the DIC Challenge Sample 12 against DICe.

Grid cases (generated, random under seeds; lighting gradient 0.3, noise 2 grey levels, pitch
10 px): a sheet clamped off the image's left side and stretched towards its far end (in view,
dark background beyond) so that the far end moves 0.9, 1.5 or 3 pitches per frame; a before/after
pair at 20 % stretch; a hole, the specimen's edge on dark background, a glare patch at 0.9 pitch
per frame. Speckle: a jump of a tenth of the ROI with a small strain.

Every method gets the same images and no prior knowledge of the motion. The competitors track
the true reference crossings on material (ours detect their own and are matched to the truth),
used as documented: LK with its image pyramid (3 levels, 21 px window), frame to frame as KLT is
used; ECC global + local: an affine ECC of the whole image coarse to fine (3 levels, each frame
started from the previous frame's map), then an affine ECC of a 21 px subset around each point
started from that map. A crossing more than half a pitch from its true position is a slip (not
counted in the RMS); a point the method reports as failed is lost.
"""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np
from scipy.interpolate import LinearNDInterpolator
from scipy.spatial import cKDTree

from tracking import (GridTracker, SpeckleTracker, deformed_points, grid_truth, load_images, read_dice,
                      render_grid, render_speckle)
from tracking._synthetic import Scene, clamped_displacement

SHAPE = (180, 260)
PITCH = 10.0
CLAMP, FAR_END = -10.0, 190.0
TARGET_RMS_PX = 0.05
SAMPLE12 = {"median_px": 0.02, "p95_px": 0.05}
SAMPLE12_HOLE = (np.array([194.0, 543.0]), 51.0, 27.0)   # DICe's excluded circle (centre, radius) and subset, px


def _grid_case(strains, seed, scene):
    """Images, displacement fields and the true reference crossings on material."""
    rng = np.random.default_rng(seed)
    centre_y = rng.uniform(80, 100)
    fields = [clamped_displacement(CLAMP, e, rng.uniform(0.2, 0.4), centre_y) for e in strains]
    images = [render_grid(SHAPE, PITCH, 2.0, f, noise_sigma=2.0, lighting_gradient=0.3, scene=scene,
                          seed=100 * seed + k, quantize=True) for k, f in enumerate(fields)]
    reference, _, _ = grid_truth(SHAPE, PITCH, margin=-100)
    return images, fields, reference


def grid_cases(quick: bool) -> dict:
    """{name: (strains per frame, seed, scene)} of the grid rows."""
    sheet = Scene(specimen=(-100.0, 30.0, FAR_END, 150.0))
    per_pitch = PITCH / (FAR_END - CLAMP)
    rng = np.random.default_rng(21)
    hole = Scene(specimen=sheet.specimen, holes=((rng.uniform(90, 140), rng.uniform(80, 100), rng.uniform(14, 20)),))
    cases = {f"motion_{m:g}_pitch": ([0.0, m * per_pitch, 2 * m * per_pitch], k, sheet)
             for k, m in enumerate((0.9, 1.5, 3.0))}
    cases["pair_20_percent"] = ([0.0, 0.2], 3, sheet)
    step = 0.9 * per_pitch
    cases["hole"] = ([0.0, step, 2 * step], 10, hole)
    cases["edge_on_dark_background"] = ([0.0, 0.03, 0.06], 20, Scene(specimen=(25.0, 30.0, FAR_END, 150.0)))
    cases["glare"] = ([0.0, step, 2 * step], 30, Scene(specimen=sheet.specimen, glare=(110.0, 95.0, 10.0, 170.0)))
    if quick:
        cases = {k: v for k, v in cases.items() if k not in ("motion_1.5_pitch", "edge_on_dark_background")}
    return cases


def _score(found, truth, slip):
    """RMS px of the measured, unslipped points over all frames; slips and lost point-frames."""
    error = np.linalg.norm(found - truth, axis=-1)
    lost = ~np.isfinite(error)
    slipped = np.isfinite(error) & (error > slip)
    good = error[np.isfinite(error) & ~slipped]
    return {"rms_px": float(np.sqrt(np.mean(good ** 2))) if good.size else float("nan"),
            "max_px": float(good.max()) if good.size else float("nan"),
            "slips": int(slipped.sum()), "lost": int(lost.sum()), "point_frames": int(error.size)}


def lucas_kanade_pyramid(images, points):
    """KLT: pyramidal LK (3 levels, 21 px window) frame to frame; (frames, n, 2), NaN when lost."""
    out = np.full((len(images), len(points), 2), np.nan)
    out[0] = points
    alive = np.ones(len(points), bool)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-3)
    for k in range(1, len(images)):
        prev = np.clip(images[k - 1], 0, 255).astype(np.uint8)
        cur = np.clip(images[k], 0, 255).astype(np.uint8)
        p0 = np.nan_to_num(out[k - 1]).astype(np.float32).reshape(-1, 1, 2)
        p1, status, _ = cv2.calcOpticalFlowPyrLK(prev, cur, p0, None, winSize=(21, 21), maxLevel=3, criteria=criteria)
        alive &= status.ravel() == 1
        out[k] = np.where(alive[:, None], p1.reshape(-1, 2), np.nan)
    return out


def _ecc(template, image, warp, levels, iterations=100):
    """Affine ECC of ``image`` to ``template`` from ``warp`` (2, 3), coarse to fine (a level
    that does not converge passes its start on); None if the finest level fails."""
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, iterations, 1e-5)
    warp = warp.astype(np.float32)
    for level in range(levels - 1, -1, -1):
        f = 2 ** level
        t = cv2.resize(template, None, fx=1 / f, fy=1 / f, interpolation=cv2.INTER_AREA) if f > 1 else template
        i = cv2.resize(image, None, fx=1 / f, fy=1 / f, interpolation=cv2.INTER_AREA) if f > 1 else image
        w = warp.copy()
        w[:, 2] /= f
        try:
            _, w = cv2.findTransformECC(t, i, w, cv2.MOTION_AFFINE, criteria, None, 3)
        except cv2.error:
            if level == 0:
                return None
            continue
        warp = w.copy()
        warp[:, 2] *= f
    return warp.astype(np.float64)


def ecc_global_local(images, points, half=10):
    """Global affine ECC per frame (against frame 0, from the previous frame's map), then an affine
    ECC of each point's (2 half + 1)^2 subset from it; (frames, n, 2), NaN where ECC failed."""
    ref = np.asarray(images[0], np.float32)
    out = np.full((len(images), len(points), 2), np.nan)
    out[0] = points
    warp = np.hstack([np.eye(2), np.zeros((2, 1))])
    rows, cols = ref.shape
    for k in range(1, len(images)):
        image = np.asarray(images[k], np.float32)
        found = _ecc(ref, image, warp, 3)
        if found is None:
            continue
        warp = found
        for n, (x, y) in enumerate(points):
            x0, y0 = int(round(x)) - half, int(round(y)) - half
            if x0 < 0 or y0 < 0 or x0 + 2 * half >= cols or y0 + 2 * half >= rows:
                continue
            template = np.ascontiguousarray(ref[y0:y0 + 2 * half + 1, x0:x0 + 2 * half + 1])
            if float(template.std()) < 1.0:
                continue
            # patch pixel (u, v) is image pixel (x0 + u, y0 + v) of the reference
            start = np.hstack([warp[:, :2], (warp[:, :2] @ (x0, y0) + warp[:, 2]).reshape(2, 1)])
            local = _ecc(template, image, start, 1, 50)
            if local is not None:
                out[k, n] = local[:, :2] @ (x - x0, y - y0) + local[:, 2]
    return out


def _competitors(images, points, truth, slip):
    rows = {}
    for name, method in (("opencv_lk_pyramid", lucas_kanade_pyramid), ("opencv_ecc_global_local", ecc_global_local)):
        t0 = time.perf_counter()
        found = method(images, points)
        rows[name] = {**_score(found[1:], truth[1:], slip), "seconds": time.perf_counter() - t0}
    return rows


def grid_row(strains, seed, scene) -> dict:
    """One grid case: ours (GridTracker, no ROI) and both competitors."""
    images, fields, reference = _grid_case(strains, seed, scene)
    t0 = time.perf_counter()
    tracks = GridTracker().track(images)
    seconds = time.perf_counter() - t0
    ref = reference[cKDTree(reference).query(tracks.reference)[1]]
    truth = np.stack([deformed_points(ref, f) for f in fields])
    row = {"ours_grid": {**_score(tracks.positions[1:], truth[1:], 0.5 * PITCH), "seconds": seconds,
                         "points": tracks.n_points, "lost_reasons": _reasons(tracks)}}
    # the competitors: true crossings on material, a pitch inside the image in every frame
    on = scene.material(reference[:, 0], reference[:, 1], margin=0.5 * PITCH)
    truth = np.stack([deformed_points(reference[on], f) for f in fields])
    inside = np.all((truth > 12) & (truth < np.array(SHAPE[::-1]) - 12), axis=(0, 2))
    points, truth = reference[on][inside], truth[:, inside]
    row.update(_competitors(images, points, truth, 0.5 * PITCH))
    row["competitor_points"] = len(points)
    row["max_motion_per_frame_px"] = float(max(np.linalg.norm(b - a, axis=1).max() for a, b in zip(truth, truth[1:])))
    return row


def _reasons(tracks) -> dict:
    from tracking._lost import reason_counts
    return reason_counts(tracks.meta["lost_reasons"])


def speckle_row(seed=0) -> dict:
    """A jump of a tenth of the ROI (140 px) in a random direction, with a strain of up to 2 %."""
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi)
    jump = 0.1 * 140 * np.array([np.cos(angle), np.sin(angle)])
    strain = rng.uniform(-0.02, 0.02)

    def field(x, y):
        return jump[0] + strain * (np.asarray(x) - 80), jump[1] - 0.3 * strain * (np.asarray(y) - 80)

    images = [render_speckle((160, 160), 1.2, None, noise_sigma=1.0, seed=seed, quantize=True),
              render_speckle((160, 160), 1.2, field, noise_sigma=1.0, seed=seed + 7, quantize=True)]
    t0 = time.perf_counter()
    tracks = SpeckleTracker(spacing=12, subset=21).track(images, roi=(10, 10, 150, 150))
    seconds = time.perf_counter() - t0
    truth = np.stack([tracks.reference, deformed_points(tracks.reference, field)])
    row = {"ours_speckle": {**_score(tracks.positions[1:], truth[1:], 10.0), "seconds": seconds,
                            "points": tracks.n_points, "lost_reasons": _reasons(tracks)}}
    inside = np.all((truth[1] > 22) & (truth[1] < 138), axis=1)
    row.update(_competitors(images, tracks.reference[inside], truth[:, inside], 10.0))
    row["jump_px"] = float(np.linalg.norm(jump))
    return row


def sample12_vs_dice(folder: Path) -> dict:
    """Our speckle tracker on Sample 12 (whole images) against DICe's solution in the last frame, at
    DICe's points a subset or more from the hole's edge: median and 95th percentile of |difference|."""
    paths = sorted(folder.glob("oht_cfrp_*.tiff"))
    images = load_images(paths)
    t0 = time.perf_counter()
    tracks = SpeckleTracker().track(images)
    seconds = time.perf_counter() - t0
    dice = read_dice(folder / "dice-solution")
    centre, radius, subset = SAMPLE12_HOLE
    seen = ~tracks.lost[-1]
    ours = LinearNDInterpolator(tracks.reference[seen], tracks.displacements()[-1][seen])
    away = (np.linalg.norm(dice.reference - centre, axis=1) > radius + subset) & ~dice.lost[-1]
    difference = np.linalg.norm(ours(dice.reference[away]) - dice.displacements()[-1][away], axis=1)
    covered = np.isfinite(difference)
    difference = difference[covered]
    holes = tracks.meta["outline"]["holes"]
    return {"frames": len(images), "points": tracks.n_points, "seconds": seconds,
            "points_in_hole": int(np.sum(np.linalg.norm(tracks.reference - centre, axis=1) < radius)),
            "holes_found": len(holes), "dice_points_compared": int(covered.sum()),
            "dice_points_not_covered": int((~covered).sum()),
            "median_px": float(np.median(difference)), "p95_px": float(np.percentile(difference, 95)),
            "lost_last_frame": int(tracks.lost[-1].sum()), "lost_reasons": _reasons(tracks)}


def mask_edges(seeds=range(4)) -> dict:
    """Where the pattern mask ends against known edges, px (+ = past the material, into the
    background or the hole): the specimen's straight edge (median over rows) and a hole (its true
    radius less the radius of the mask's hole of the same area), grid (pitch 10 px) and speckle."""
    from tracking._pattern_mask import pattern_mask
    rng = np.random.default_rng(0)
    out = {}
    for pattern in ("grid", "speckle"):
        edges, holes = [], []
        for seed in seeds:
            xe = rng.uniform(180, 200)
            hx, hy, r = rng.uniform(80, 120), rng.uniform(70, 110), rng.uniform(14, 20)
            scene = Scene(specimen=(-50.0, -50.0, xe, 400.0), holes=((hx, hy, r),))
            if pattern == "grid":
                image = render_grid((180, 240), PITCH, 2.0, None, noise_sigma=2.0, lighting_gradient=0.3,
                                    scene=scene, seed=seed, quantize=True)
                mask = pattern_mask(image, PITCH, None, np.eye(2) / PITCH)
            else:
                image = render_speckle((180, 240), 1.2, None, noise_sigma=1.0, scene=scene, seed=seed,
                                       pattern_seed=seed, quantize=True)
                mask = pattern_mask(image, 21)
            last = np.array([np.nonzero(mask[row])[0].max() for row in range(40, 140)]) + 0.5   # pixel's edge
            edges.append(float(np.median(last - xe)))
            yy, xx = np.mgrid[0:mask.shape[0], 0:mask.shape[1]]
            near = (xx - hx) ** 2 + (yy - hy) ** 2 < (r + 12) ** 2
            holes.append(float(r - np.sqrt(np.sum(~mask & near) / np.pi)))
        out[pattern] = {"edge_offset_px": edges, "hole_offset_px": holes,
                        "mean_abs_px": float(np.mean(np.abs(edges + holes)))}
    return out


def run(quick: bool, shared: Path, log=print) -> dict:
    """The rows: ``{"grid": {case: row}, "speckle_jump": row, "sample12_vs_dice": row or skip}``."""
    out = {"shape": SHAPE, "pitch_px": PITCH, "grid": {}}
    for name, (strains, seed, scene) in grid_cases(quick).items():
        out["grid"][name] = grid_row(strains, seed, scene)
        log(f"large motion: {name} done")
    out["speckle_jump"] = speckle_row()
    out["mask_edges"] = mask_edges()
    folder = shared / "data" / "dic-challenge-sample12"
    if folder.is_dir():
        out["sample12_vs_dice"] = sample12_vs_dice(folder)
    else:
        out["sample12_vs_dice"] = {"skipped": f"DIC Challenge Sample 12 not found at {folder} (set NONRIGID_SHARED)"}
    return out


def targets(large: dict) -> dict:
    """Ours within TARGET_RMS_PX RMS with no slip on every grid case and the speckle jump; the
    speckle mask's edge within 3 px of the true edges on average (5 px before it was tightened),
    the grid's within half a pitch
    (a grid's texture says where the last line is, not where the sheet beyond it ends); Sample 12
    within SAMPLE12 of DICe (skipped rows are not judged: pass None)."""
    rows = [{"case": name, "rms_px": r["ours_grid"]["rms_px"], "slips": r["ours_grid"]["slips"],
             "pass": bool(r["ours_grid"]["rms_px"] <= TARGET_RMS_PX and r["ours_grid"]["slips"] == 0)}
            for name, r in large["grid"].items()]
    s = large["speckle_jump"]["ours_speckle"]
    rows.append({"case": "speckle_jump", "rms_px": s["rms_px"], "slips": s["slips"],
                 "pass": bool(s["rms_px"] <= TARGET_RMS_PX and s["slips"] == 0)})
    out = {f"large_motion_rms_within_{TARGET_RMS_PX:g}_px_and_no_slip": {
        "threshold_px": TARGET_RMS_PX, "rows": rows, "pass": all(r["pass"] for r in rows)}}
    edges = large["mask_edges"]
    worst_grid = max(abs(v) for v in edges["grid"]["edge_offset_px"] + edges["grid"]["hole_offset_px"])
    out["mask_edge_speckle_mean_within_3_px_grid_within_half_pitch"] = {
        "speckle_mean_abs_px": edges["speckle"]["mean_abs_px"], "grid_worst_abs_px": worst_grid,
        "pass": bool(edges["speckle"]["mean_abs_px"] <= 3.0 and worst_grid <= 0.5 * PITCH)}
    d = large["sample12_vs_dice"]
    if "skipped" in d:
        out["sample12_agrees_with_dice"] = {**SAMPLE12, "pass": None, "skipped": d["skipped"]}
    else:
        out["sample12_agrees_with_dice"] = {
            "targets_px": SAMPLE12, "median_px": d["median_px"], "p95_px": d["p95_px"],
            "no_point_in_hole": d["points_in_hole"] == 0,
            "pass": bool(d["median_px"] <= SAMPLE12["median_px"] and d["p95_px"] <= SAMPLE12["p95_px"]
                         and d["points_in_hole"] == 0)}
    return out


def plot(large: dict, path: Path) -> None:
    """RMS (bars, log) and slips + lost (annotated) per case and method."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cases = {**large["grid"], "speckle_jump": large["speckle_jump"]}
    methods = ["ours", "opencv_lk_pyramid", "opencv_ecc_global_local"]
    fig, ax = plt.subplots(figsize=(13, 4.8))
    width = 0.27
    for m, method in enumerate(methods):
        for c, (name, row) in enumerate(cases.items()):
            r = row["ours_grid" if "ours_grid" in row else "ours_speckle"] if method == "ours" else row[method]
            measured = np.isfinite(r["rms_px"])
            value = r["rms_px"] if measured else 1e1          # nothing measured: a hatched bar to the top
            ax.bar(c + (m - 1) * width, value, width, color=f"C{m}", label=method if c == 0 else None,
                   hatch=None if measured else "//", alpha=1.0 if measured else 0.4)
            frac = (r["slips"] + r["lost"]) / max(r["point_frames"], 1)
            ax.text(c + (m - 1) * width, value * 1.15, f"{100 * frac:.0f}%", ha="center", fontsize=7, rotation=90)
    ax.axhline(TARGET_RMS_PX, color="k", ls="--", lw=0.8, label=f"target {TARGET_RMS_PX} px")
    ax.set_xticks(range(len(cases)), [n.replace("_", " ") for n in cases], rotation=20, fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("RMS of unslipped measured points (px)")
    d = large["sample12_vs_dice"]
    extra = (f"; Sample 12 vs DICe: median {d['median_px']:.4f} px, p95 {d['p95_px']:.4f} px"
             if "median_px" in d else "; Sample 12 skipped")
    ax.set_title("large motion and things in view: RMS (label: slipped + lost share of point-frames; "
                 "hatched: nothing measured)" + extra,
                 fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def summary(report: dict) -> None:
    """Print the large-motion rows and every target of ``report`` (trackers.json)."""
    for name, row in {**report["large_motion"]["grid"], "speckle_jump": report["large_motion"]["speckle_jump"]}.items():
        parts = [f"{m}: {v['rms_px']:.4f} px, {v['slips']} slips, {v['lost']} lost, {v['seconds']:.1f} s"
                 for m, v in row.items() if isinstance(v, dict)]
        print(f"{name:24s} " + " | ".join(parts))
    print("Sample 12 vs DICe:", {k: v for k, v in report["large_motion"]["sample12_vs_dice"].items()
                                 if k != "lost_reasons"})
    for name, target in report["targets"].items():
        print(f"target {name}: {'pass' if target['pass'] else ('skipped' if target['pass'] is None else 'FAIL')}")
