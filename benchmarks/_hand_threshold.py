"""benchmarks/hand.py's threshold section (issue 25, items 3/6): is the strain threshold found
"within 5 % of the motion where the generated data put it"?

The threshold (one definition for truth, estimate and every report: ``RULE.find``, i.e.
``refine.threshold.ThresholdRule.find``): where the strain's growth speeds up, the hinge of a
two-segment fit whose second segment is the steeper (``strain_threshold(rising=True)``; the free
hinge takes the up-down curve's early slowing-down on the coarse mesh and its late speed-up on the
fine one), a threshold only where the rate rises >= 1.25x with p < 0.01, else none.
:func:`detect_json` is that answer as hand.json writes it (the paper runs' rows, :func:`redetect`;
the target ``threshold_found``, :func:`found_target`).

The solves (:func:`curve_data`, saved by hand.py to results/hand_threshold.npz) are apart from the
analysis (:func:`threshold_truth`, per motion over its own area of interest, any frame stride).
The truth: that hinge of the FINE, noise-free curve: the paper-size hand meshed finer and moved in
``dense`` equal steps, the maximum skin strain over the area of interest against the marked
point's displacement. The detection: on the paper-size (COARSE) model's curve (``frames`` steps),
as a tracked study gets it, in two ways:

- ``tracked``: the curve of the model fitted to the measurements, i.e. the coarse model's strain
  and displacement at TRACKED joint angles, each angle of each frame off by a Gaussian error of
  ``ANGLE_NOISE_DEG`` (the tracking section's joint-angle errors), independent between frames. The
  paper computes strain from the model driven by the tracked motion, not from raw grid strains.
  Propagated to first order: per frame the Jacobian of (displacement, area maximum strain) in all
  joint angles by forward differences (``STEP_DEG``, warm-started solves), so a draw costs no solve.
- ``raw``: the coarse noise-free curve with independent noise on each frame's maximum
  (``STRAIN_NOISE``), the maximum of directly measured strains (kept for comparison; a painted
  grid's strain is far noisier than this, see the README).

``DRAWS`` draws per motion under a seed; reported: the share within 5 % of the motion and the
share whose reported 95 % interval holds the truth (coverage).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from examples.hand import Box, run_motion, skin_strain_function, standard_motions
from refine.exceptions import ObservationError
from refine.threshold import ThresholdRule, strain_threshold

#: noise of a directly measured maximum strain (absolute strain), the ``raw`` way
STRAIN_NOISE = 0.002
#: a tracked joint angle's error (degrees, standard deviation, each angle and frame): the tracking
#: section's errors are 0.1-0.3 degrees RMS (largest 0.3-0.5 on the thumb tip)
ANGLE_NOISE_DEG = 0.3
#: the sweep of the tracked angles' error (degrees)
ANGLE_SWEEP = (0.1, 0.3, 1.0)
#: forward-difference step of the curve's Jacobian in the joint angles (degrees)
STEP_DEG = 0.05
DRAWS = 50
WITHIN = 0.05
#: when a curve has a threshold at all (the same for the truth and every estimate): the growth rate at
#: least 1.25 times faster past the hinge, F test p < 0.01 (refine.threshold.ThresholdRule)
RULE = ThresholdRule()
#: the rule's min_rise swept in the JSON (the truths' classification is the same for any value between
#: the wrist curves' rises, ~1.1, and the thumb's, ~1.5)
RISE_SWEEP = (1.15, 1.25, 1.5)


def _detect(x, s):
    """``(fraction, (low, high), rise, p_value)`` of the rising hinge; NaNs where the curve cannot
    be read (its displacement not monotone: counted as a miss)."""
    try:
        th = RULE.find(x, s).hinge
        return th.fraction, th.fraction_interval, th.rise, th.p_value
    except ObservationError:
        return float("nan"), (float("nan"), float("nan")), float("nan"), float("nan")


def detect_json(x, s) -> dict:
    """The one definition's answer for the curve ``s`` against ``x`` as JSON (:data:`RULE`'s
    ``find(...).to_json()``: a threshold with its 95 % interval, or none with why); an ``error``
    where the curve cannot be read."""
    try:
        return RULE.find(np.asarray(x, float), np.asarray(s, float)).to_json()
    except ObservationError as e:
        return {"error": str(e)}


def redetect(paper: dict) -> dict:
    """hand.json's ``paper`` runs with each row's ``threshold`` found again by :func:`detect_json`
    from the row's own curve (the area's maximum against the marked point's displacement): the
    solves' figures unchanged, their detection by the one definition."""
    out = {}
    for m, rows in paper.items():
        if not isinstance(rows, dict):
            out[m] = rows
            continue
        out[m] = {k: r | {"threshold": detect_json(r["curve"]["displacement_mm"], r["curve"]["area_max_strain"])}
                  if isinstance(r, dict) and "curve" in r else r for k, r in rows.items()}
    return out


def found_target(res: dict) -> dict:
    """hand.json's ``threshold_found``, as issue 25 item 3 asks: "maximum-strain vs displacement
    curves for each motion with the threshold where the growth rate changes detected automatically
    and reported (with its uncertainty)". Per motion of the threshold section (its area, the
    paper-size model's noise-free curve): the answer of :func:`detect_json` and whether it says
    what the finest mesh's truth says (a threshold within 5 % of the motion, or none). Beside it,
    the longer motions' answers and every paper run's (over the wrist's area, with and without the
    scars). ``{}`` where ``res`` has no threshold section."""
    sec = res.get("threshold_truth", {})
    sec = sec.get("against_finest_mesh", sec)
    motions = [m for m, v in sec.items() if isinstance(v, dict) and "truth_has_threshold" in v]
    if not motions:
        return {}
    per = {}
    for m in motions:
        v, c = sec[m], sec[m]["coarse_curve"]
        found, has = detect_json(c["displacement_mm"], c["area_max_strain"]), v["truth_has_threshold"]
        near = has and abs(found.get("fraction", np.inf) - v["truth_fraction"]) <= WITHIN
        agrees = found.get("has_threshold") == has and (near or not has)
        per[m] = {"model": found, "truth_has_threshold": has, "truth_fraction": v["truth_fraction"] if has else None,
                  "truth_rise": v["truth_rise"], "agrees": bool(agrees)}
    more = {}
    for key, label in (("longer", ""), ("longer_wrist_refined", " (model refined at the wrist)")):
        longer = res.get("threshold_truth", {}).get(key, {})
        more |= {f"{m} x{longer['scales'][m]:g}{label}": {
            "model": detect_json(v["coarse_curve"]["displacement_mm"], v["coarse_curve"]["area_max_strain"]),
            "elements": longer["coarse_elements"], "truth_has_threshold": v["truth_has_threshold"],
            "truth_fraction": v["truth_fraction"]}
            for m, v in longer.items() if isinstance(v, dict) and "coarse_curve" in v}
    said = "; ".join(f"{m}: " + (f"a threshold at {p['model']['fraction']:.2f} of the motion "
                                 f"[{p['model']['fraction_interval'][0]:.2f}, {p['model']['fraction_interval'][1]:.2f}]"
                                 if p["model"].get("has_threshold") else "none")
                     for m, p in (per | more).items())
    runs = {m: {k: {key: r["threshold"].get(key) for key in ("has_threshold", "fraction", "fraction_interval")}
                for k, r in rows.items() if isinstance(r, dict) and "threshold" in r}
            for m, rows in res.get("paper", {}).items() if isinstance(rows, dict)}
    return {"threshold_found": {
        "target": "each motion's maximum-strain vs displacement curve (the paper-size model, noise-free, over the "
                  "motion's area) gets its answer automatically (refine.threshold.ThresholdRule.find: a threshold "
                  f"where the rate rises >= {RULE.min_rise}x with p < {RULE.alpha}, reported with its 95 % interval, "
                  "or none with why), and the answer is the finest mesh's truth's (a threshold within 5 % of the "
                  "motion, or none)",
        "found": said, "motions": per, "longer_motions": more,
        "paper_80_90_pct": "informational: the paper found its thresholds at 80-90 % of the motion; here see found",
        "paper_runs_over_wrist_area": runs,
        "pass": all(p["agrees"] for p in per.values())}}


def _holds(found, rule: ThresholdRule = RULE) -> np.ndarray:
    """Whether each detection of :func:`_detect` is a threshold by ``rule``."""
    return np.array([v[3] < rule.alpha and v[2] >= rule.min_rise for v in found])


def perturbed_skin(model, motion, result, strains, step_deg: float = STEP_DEG):
    """Per frame of ``result`` (a :func:`examples.hand.run_motion` of ``motion``) and per joint angle
    of the hand, the marked point's displacement (mm) and the skin strain per facet with that angle
    ``step_deg`` further: ``((n_frames, n_angles), (n_frames, n_angles, n_skin))``, each a
    warm-started solve from the frame's solution (forward differences of any area's curve)."""
    names = model.hand.body.angle_names
    mark = model.hand.marks[motion.mark]
    full = {k: np.radians(v) for k, v in motion.angles.items()}
    disp = np.zeros((len(result.fraction), len(names)))
    skin = np.zeros((len(result.fraction), len(names), result.skin_strain.shape[1]))
    for k, share in enumerate(result.fraction):
        angles = {n: share * full.get(n, 0.0) for n in names}
        theta = model.params(angles)
        start = (np.asarray(result.u[k]).reshape(-1), {key: theta[key] for key in ("u_D", "f", "traction")})
        for j, n in enumerate(names):
            th = model.params(angles | {n: angles[n] + np.radians(step_deg)})
            u = model.solver.solve(th, start=start).u
            disp[k, j] = np.linalg.norm(np.asarray(u)[mark])
            skin[k, j] = np.asarray(strains(u, th)[0])
    return disp, skin


def curve_data(coarse, fine, frames: int = 20, dense: int = 24) -> dict:
    """The solves the section needs, as arrays (``<motion>/<key>``): the fine hand's ``dense``-step
    curve (marked displacement, skin strain per facet) and the coarse hand's ``frames``-step one with
    its :func:`perturbed_skin`; each mesh's skin-facet centres (mm) to pick areas from."""
    centre = lambda h: h.mesh.nodes[h.skin_facets[:, :3]].mean(axis=1)  # noqa: E731
    out = {"fine/centres": centre(fine.hand), "coarse/centres": centre(coarse.hand), "step_deg": np.array(STEP_DEG),
           "fine/elements": np.array(fine.hand.mesh.n_cells), "coarse/elements": np.array(coarse.hand.mesh.n_cells)}
    fine_motions = standard_motions(fine.hand.body, dense)
    strains = skin_strain_function(coarse)
    for name, motion in standard_motions(coarse.hand.body, frames).items():
        f = run_motion(fine, fine_motions[name])
        c = run_motion(coarse, motion, strains=strains)
        disp, skin = perturbed_skin(coarse, motion, c, strains)
        out |= {f"{name}/fine_x": f.displacement, f"{name}/fine_skin": f.skin_strain, f"{name}/coarse_x": c.displacement,
                f"{name}/coarse_skin": c.skin_strain, f"{name}/perturbed_x": disp, f"{name}/perturbed_skin": skin}
        print("threshold curves", name, flush=True)
    return out


def _score(found, truth, has: bool, rule: ThresholdRule = RULE):
    """The detections ``found`` against the ``truth`` hinge's fraction, which is a threshold by
    ``rule`` if ``has``. ``share_agreeing``: the share that says what the truth says (a threshold
    within 5 % of it, or none); ``coverage``: the share whose interval holds the truth (where it has
    one); the ``hinge_*`` figures score the hinge's place whether or not it is a threshold."""
    f = np.array([v[0] for v in found])
    if np.isnan(f).all():  # every curve unreadable (displacements not monotone at large angle errors)
        return {"share_agreeing": 0.0, "share_with_threshold": 0.0, "coverage": 0.0 if has else None,
                "unreadable": len(f), "hinge_share_within_5pct": 0.0, "hinge_coverage": 0.0}
    lo, hi = np.array([v[1][0] for v in found]), np.array([v[1][1] for v in found])
    near, inside, holds = np.abs(f - truth) <= WITHIN, (lo <= truth) & (truth <= hi), _holds(found, rule)
    return {"share_agreeing": float(np.mean(holds & near) if has else np.mean(~holds & np.isfinite(f))),
            "share_with_threshold": float(np.mean(holds)),
            "coverage": float(np.mean(holds & inside)) if has else None,
            "unreadable": int(np.sum(~np.isfinite(f))),
            "hinge_share_within_5pct": float(np.mean(near)), "hinge_coverage": float(np.mean(inside)),
            "median_fraction": float(np.nanmedian(f)), "abs_difference_median": float(np.nanmedian(np.abs(f - truth))),
            "interval_width_median": float(np.nanmedian(hi - lo)),
            "rise_quartiles": np.nanquantile([v[2] for v in found], [0.25, 0.5, 0.75]).tolist()}


def tracked_draws(x, s, J, sigma_deg, rng, draws=None):
    """Detections on ``draws`` (default :data:`DRAWS`) tracked curves: the coarse curve ``(x, s)`` with each frame's joint
    angles off by ``N(0, sigma_deg)``, to first order through ``J (n_frames, 2, n_angles)``."""
    out = []
    for _ in range(DRAWS if draws is None else draws):
        d = np.einsum("kij,kj->ki", J, rng.normal(0.0, np.radians(sigma_deg), (len(x), J.shape[2])))
        out.append(_detect(x + d[:, 0], s + d[:, 1]))
    return out


def _curve(data, name, mesh, box):
    """The area's maximum strain per frame (``box`` a examples.hand.Box over the skin-facet centres)."""
    area = box.contains(data[f"{mesh}/centres"])
    if not area.any():
        raise SystemExit(f"the area {box} holds no skin facet of the {mesh} hand")
    return data[f"{name}/{mesh}_x"], data[f"{name}/{mesh}_skin"][:, area].max(axis=1), area


def threshold_truth(data, areas: dict, seed: int = 0, noise: float = STRAIN_NOISE,
                    sigma_deg: float = ANGLE_NOISE_DEG, every: int = 1, truths: dict | None = None,
                    draws: int | None = None) -> dict:
    """For each motion of :func:`curve_data` ``data``, over its area ``areas[motion]`` (a Box): the
    truth (fine, noise-free: its hinge, and whether that is a threshold by :data:`RULE`) and the
    detections on the coarse curve (every ``every``-th frame), tracked (``sigma_deg``, and the
    :data:`ANGLE_SWEEP`) and raw (``noise``), ``DRAWS`` draws each, scored by :func:`_score`; the
    tracked draws scored again for each ``min_rise`` of :data:`RISE_SWEEP`. ``truths``: ``{motion:
    (displacement, area maximum, elements)}`` of a finer mesh to take the truth from instead of
    ``data``'s fine curve (``_threshold_mesh.finest_curves``). ``draws``: per score (default :data:`DRAWS`)."""
    draws = DRAWS if draws is None else draws
    rng = np.random.default_rng(seed)
    motions = [k.split("/")[0] for k in data if k.endswith("/coarse_x")]
    h = np.radians(float(data["step_deg"]))
    fine_elements = int(data["fine/elements"]) if truths is None else sorted({int(v[2]) for v in truths.values()})
    out = {"fine_elements": fine_elements, "coarse_elements": int(data["coarse/elements"]),
           "strain_noise": noise, "angle_noise_deg": sigma_deg, "draws": draws, "seed": seed,
           "definition": "refine.threshold.ThresholdRule.find: the rising hinge (where growth speeds up); a "
                         f"threshold only where its rate rises >= {RULE.min_rise}x with F test p < {RULE.alpha} "
                         "(refine.threshold.ThresholdRule), for the truth and the estimate alike",
           "rule": {"min_rise": RULE.min_rise, "alpha": RULE.alpha}}
    for name in motions:
        box = areas[name]
        xf, sf, _ = _curve(data, name, "fine", box) if truths is None else truths[name]
        x, s, area = _curve(data, name, "coarse", box)
        J = np.stack([(data[f"{name}/perturbed_x"] - x[:, None]) / h,
                      (data[f"{name}/perturbed_skin"][:, :, area].max(axis=2) - s[:, None]) / h], axis=1)
        x, s, J = x[::every], s[::every], J[::every]
        found = RULE.find(xf, sf)
        truth, has = found.hinge, found.found
        clean = _detect(x, s)
        m = {"area_box_mm": [box.lo, box.hi], "frames": len(x) - 1, "dense_frames": len(xf) - 1,
             "truth_fraction": truth.fraction, "truth_interval": list(truth.fraction_interval),
             "truth_p_value": truth.p_value, "truth_rise": truth.rise, "truth_has_threshold": has,
             "free_hinge_truth_fraction": strain_threshold(xf, sf).fraction,
             "coarse_noise_free_fraction": clean[0], "coarse_noise_free_interval": list(clean[1]),
             "coarse_noise_free_rise": clean[2], "coarse_noise_free_has_threshold": bool(_holds([clean])[0]),
             "jacobian_per_deg": (np.radians(1.0) * J).round(6).tolist(),
             "fine_curve": {"displacement_mm": xf.tolist(), "area_max_strain": sf.tolist()},
             "coarse_curve": {"displacement_mm": x.tolist(), "area_max_strain": s.tolist()}}
        tracked = tracked_draws(x, s, J, sigma_deg, rng, draws)
        m["tracked"] = _score(tracked, truth.fraction, has)
        m["tracked_by_min_rise"] = {
            f"{r:g}": {"truth_has_threshold": ThresholdRule(r, RULE.alpha).holds(truth)}
            | _score(tracked, truth.fraction, ThresholdRule(r, RULE.alpha).holds(truth), ThresholdRule(r, RULE.alpha))
            for r in RISE_SWEEP}
        m["tracked_sweep"] = {f"{v:g}": _score(tracked_draws(x, s, J, v, rng, draws), truth.fraction, has)
                              for v in ANGLE_SWEEP}
        m["raw"] = _score([_detect(x, s + rng.normal(0, noise, len(s))) for _ in range(draws)], truth.fraction, has)
        out[name] = m
        print("threshold", name, {"truth": truth.fraction, "rise": truth.rise, "has": has, "clean": clean[0],
                                  "tracked": m["tracked"], "raw": m["raw"]}, flush=True)
    return out


def curves_from_json(section: dict):
    """``(data, areas)`` for :func:`threshold_truth` rebuilt from a threshold section it wrote
    (hand.json's ``threshold_truth`` or one of its ``variants``): each motion's fine and coarse
    curves of the area's maximum and the Jacobian, as one skin "facet" (the area's maximum) at the
    origin, so that the analysis reruns without the solves (results/hand_threshold.npz). The
    same numbers as from the solves: the curves and Jacobians are the ones they gave."""
    h = np.radians(STEP_DEG)
    data = {"step_deg": np.array(STEP_DEG), "fine/centres": np.zeros((1, 3)), "coarse/centres": np.zeros((1, 3)),
            "fine/elements": np.array(section["fine_elements"]), "coarse/elements": np.array(section["coarse_elements"])}
    areas = {}
    for name, m in section.items():
        if not (isinstance(m, dict) and "jacobian_per_deg" in m):
            continue
        J = np.asarray(m["jacobian_per_deg"]) / np.radians(1.0)
        x, s = np.asarray(m["coarse_curve"]["displacement_mm"]), np.asarray(m["coarse_curve"]["area_max_strain"])
        data |= {f"{name}/fine_x": np.asarray(m["fine_curve"]["displacement_mm"]),
                 f"{name}/fine_skin": np.asarray(m["fine_curve"]["area_max_strain"])[:, None],
                 f"{name}/coarse_x": x, f"{name}/coarse_skin": s[:, None],
                 f"{name}/perturbed_x": x[:, None] + h * J[:, 0], f"{name}/perturbed_skin": (s[:, None] + h * J[:, 1])[..., None]}
        areas[name] = Box((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
    return data, areas


def section(previous: dict, model, make_fine, reuse: bool, areas: dict, wrist, saved, finest=None) -> dict:
    """hand.py's ``threshold_truth``: :func:`threshold_truth` over ``areas`` ({motion: Box}), with
    the variants every 2nd frame and the ``wrist`` Box for every motion. The curves: from the npz
    ``saved`` if ``reuse`` and it exists; else, if ``reuse``, from the ``previous`` section
    (:func:`curves_from_json`); else solved (:func:`curve_data` on the coarse ``model`` and the
    fine model ``make_fine()``) and saved to ``saved``. ``finest``: a function giving the finest
    mesh's curves (``truths`` of :func:`threshold_truth`): the analysis again against that truth
    (``against_finest_mesh``, the one the target reads where it is there)."""
    from_json = reuse and not Path(saved).exists() and "variants" in previous
    if reuse and Path(saved).exists():
        data = dict(np.load(saved))
        wrist_data = (data, {m: wrist for m in areas})
    elif from_json:
        data, areas = curves_from_json(previous)
        wrist_data = curves_from_json(previous["variants"]["wrist area for every motion"])
    else:
        data = curve_data(model, make_fine())
        np.savez_compressed(saved, **data)
        wrist_data = (data, {m: wrist for m in areas})
    out = threshold_truth(data, areas) | {"curves_from": "the last hand.json's curves and Jacobians (rounded to "
                                                         "1e-6 per degree)" if from_json else "the solves"}
    out["variants"] = {"every 2nd frame (10 frames)": threshold_truth(data, areas, every=2),
                       "wrist area for every motion": threshold_truth(*wrist_data)}
    if finest is not None:
        out["against_finest_mesh"] = threshold_truth(data, areas, truths=finest())
    return out | {"load": float(open("/proc/loadavg").read().split()[0])}


def targets(res: dict) -> dict:
    """The targets on the section ``res``: against the finest mesh's truth where the section has it,
    else against the fine curve's; and over its longer motions (``_threshold_mesh.longer_motions``)."""
    t = _target(res.get("against_finest_mesh", res), "threshold_within_5pct")
    if "longer" not in res:
        return t
    key, paper = "threshold_within_5pct_longer_motion", res["longer"]
    refined = res.get("longer_wrist_refined")
    if refined is None:
        return t | _target(paper, key, f"over the longer motions {paper['scales']} (x the standard range): ")
    t |= _target(refined, key, f"over the longer motions {refined['scales']} (x the standard range), the estimate's "
                               f"model refined at the wrist to {refined['wrist_h_mm']:g} mm "
                               f"({refined['coarse_elements']} elements) where the area's maximum strain sits: ")
    motions = [m for m in refined["scales"] if m in paper and "tracked" in paper[m]]
    if key in t:  # the paper-size model's figures kept beside the refined model's
        t[key] |= {"draws": refined["draws"], "model": {m: refined[m]["model"] for m in motions},
                   "wrist_study": {m: refined[m]["wrist_study"] for m in motions},
                   "paper_size_model": {"elements": paper["coarse_elements"], "draws": paper["draws"],
                                        "share_agreeing": {m: paper[m]["tracked"]["share_agreeing"] for m in motions},
                                        "coverage": {m: paper[m]["tracked"]["coverage"] for m in motions},
                                        "noise_free_fraction": {m: paper[m]["coarse_noise_free_fraction"]
                                                                for m in motions}}}
    return t


def _target(res: dict, key: str, prefix: str = "") -> dict:
    motions = [k for k, v in res.items() if isinstance(v, dict) and "truth_fraction" in v]
    if not all("share_agreeing" in res[m].get("tracked", {}) for m in motions):  # an older section's result
        return {}
    share = {m: res[m]["tracked"]["share_agreeing"] for m in motions}
    t = {key: {
        "target": prefix + "the coarse model's curve at tracked joint angles (error "
                  f"{res['angle_noise_deg']} deg per angle and frame) says what the fine noise-free curve says: a "
                  f"threshold (rising hinge, rate rising >= {res['rule']['min_rise']}x, p < {res['rule']['alpha']}) "
                  "within 5 % of the motion of the truth's, or none where the truth has none; in at least 80 % of "
                  "the draws, for each motion",
        "truth_elements": res["fine_elements"],
        "truth_has_threshold": {m: res[m]["truth_has_threshold"] for m in motions},
        "truth_fraction": {m: res[m]["truth_fraction"] for m in motions},
        "truth_rise": {m: res[m]["truth_rise"] for m in motions},
        "coarse_noise_free_fraction": {m: res[m]["coarse_noise_free_fraction"] for m in motions},
        "share_agreeing": share,
        "coverage": {m: res[m]["tracked"]["coverage"] for m in motions},
        "hinge_share_within_5pct": {m: res[m]["tracked"]["hinge_share_within_5pct"] for m in motions},
        "hinge_coverage": {m: res[m]["tracked"]["hinge_coverage"] for m in motions},
        "share_agreeing_by_min_rise": {m: {k: v["share_agreeing"] for k, v in res[m]["tracked_by_min_rise"].items()}
                                       for m in motions},
        "share_agreeing_by_angle_noise": {m: {k: v["share_agreeing"] for k, v in res[m]["tracked_sweep"].items()}
                                          for m in motions},
        "raw_strain_noise": res["strain_noise"],
        "raw_share_agreeing": {m: res[m]["raw"]["share_agreeing"] for m in motions},
        "pass": all(v >= 0.8 for v in share.values())}}
    return t
