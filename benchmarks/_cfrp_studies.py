"""Studies of the CFRP coupon's found hole (benchmarks/cfrp.py): the search's model and points
(:func:`search_setup`), what sets the hole's size (:func:`shortfall`, :func:`noise_figures`) and
the hole seen through the DIC subsets (:func:`subset_hole`)."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np


def search_setup(bundle, cfg, frames, sigma: float):
    """The search's model of the domain as tracked (the hole forgotten: a whole domain) on
    ``frames``, with the fitting and held-out points a diagnosis with ``cfg`` draws (same seed:
    the same split), and ``sigma`` (noise and model error) as the residuals' weight."""
    from refine.diagnosis.scale import at_frames, mesh_size
    from refine.model.measured import MeasuredModel, grid_spacing

    obs, ex = bundle.observations, bundle.experiment
    guide = obs.mask("guide")
    gidx = np.flatnonzero(guide)
    hold = np.zeros(obs.n_points, bool)
    hold[np.random.default_rng(cfg.seed).choice(gidx, max(1, int(round(cfg.holdout_fraction * len(gidx)))),
                                                replace=False)] = True
    h = cfg.h if cfg.h is not None else mesh_size(ex.domain, grid_spacing(obs.reference), cfg.max_cells)
    model = MeasuredModel(ex, at_frames(obs, frames), h=h, linear_solver=cfg.linear_solver)
    return model, guide & ~hold, hold, sigma


def shortfall(bundle, setup, centre, area: float, log=print) -> dict:
    """What sets the found hole's size (issue 22's CFRP shortfall: the 25 Nov run's hole came out
    +26 %), each cause tested on the search's frames and points: the laminate's anisotropy (the fibre-reinforced law fitted with
    the image's hole in the model, and the hole fitted in a fibre-reinforced material), how far
    the nearest tracked points lie from the hole's edge, and the noise estimate against the
    noise's correlation between neighbouring (overlapping-subset) points."""
    from refine.diagnosis.fitted import baseline
    from refine.diagnosis.hole_law import fit_hole_with_law
    from refine.diagnosis.holes import fit_hole
    from refine.diagnosis.laws import fit_law, law_parameters
    from refine.diagnosis.shapes import Hole
    from refine.model.measured import MeasuredModel

    model, fit, hold, sigma = setup
    radius = float(np.sqrt(area / np.pi))
    circle = Hole((float(centre[0]), float(centre[1])), (radius, radius), 0.0)
    ex = bundle.experiment
    holed = MeasuredModel(replace(ex, domain=replace(ex.domain, holes=(tuple(map(tuple, circle.outline()[1])),))),
                          model.obs, h=model.h, linear_solver=model.linear_solver)
    t = time.perf_counter()
    nh = baseline(holed, fit, hold, sigma)
    law = fit_law(holed, "fibre-reinforced", fit, hold, sigma)
    log(f"the image's hole in the model: neo-Hookean chi2 {nh.chi2_fit:.0f}, fibre-reinforced {law.chi2_fit:.0f} "
        f"({time.perf_counter() - t:.0f} s)")
    t = time.perf_counter()
    both = fit_hole_with_law(model, circle, "fibre-reinforced", fit, hold, sigma)
    found = both.shapes[0]
    log(f"hole with the fibre law: {both.describe()} ({time.perf_counter() - t:.0f} s)")
    t = time.perf_counter()
    alone = fit_hole(model, circle, fit, hold, sigma)
    log(f"hole alone (neo-Hookean): {alone.describe()} ({time.perf_counter() - t:.0f} s)")
    pts = bundle.observations.reference
    ring = np.hypot(*(pts - centre).T)
    g = found.geometry()
    d = pts - np.asarray(found.centre)
    c, s_ = np.cos(found.angle), np.sin(found.angle)
    norm = np.hypot((d @ [c, s_]) / found.axes[0], (d @ [-s_, c]) / found.axes[1])
    return {
        "image_hole_in_model": {"neo_hookean_chi2": nh.chi2_fit, "fibre_law_chi2": law.chi2_fit,
                                "neo_hookean_holdout": nh.chi2_holdout, "fibre_law_holdout": law.chi2_holdout,
                                "fibre_law_parameters": {k: v["value"] for k, v in law_parameters(law).items()}},
        "hole_alone": {"chi2": alone.chi2_fit, "holdout": alone.chi2_holdout,
                                                  "axes": list(alone.shapes[0].axes),
                                                  "area_error": alone.shapes[0].outline()[0] / area - 1},
        "hole_with_fibre_law": {"chi2": both.chi2_fit, "holdout": both.chi2_holdout, "axes": list(found.axes),
                                "angle": found.angle, "area_error": found.outline()[0] / area - 1,
                                "fibre_law_parameters": {k: v["value"] for k, v in law_parameters(both).items()}},
        "ring": {"image_radius": radius, "nearest_points_radius": [float(np.min(ring)), float(np.median(np.sort(ring)[:24]))],
                 "found_hole_edge_to_nearest_point": float(norm.min()), "points_inside_found_hole": int(g.contains(pts).sum())},
        "noise": noise_figures(bundle.observations),
        "sigma_used": sigma,
    }


def noise_figures(obs) -> dict:
    """The noise estimated from neighbour differences (``estimate_noise``'s local quadratic over
    k neighbours) for growing k, and the correlation of a smooth fit's residuals between points
    10 and 20 px apart (the last frame): overlapping DIC subsets make neighbours' noise alike, so
    a small neighbourhood's quadratic absorbs part of it and the estimate comes out low."""
    from scipy.spatial import cKDTree

    from refine.diagnosis.noise import estimate_noise

    X, U = obs.reference, obs.displacements[-1]
    tree = cKDTree(X)
    _, nb = tree.query(X, k=49)
    res = np.full_like(U, np.nan)
    for i in range(len(X)):
        d = X[nb[i, 1:]] - X[i]
        d = d / np.abs(d).max()
        A = np.column_stack([np.ones(len(d)), d, d**2, d[:, 0] * d[:, 1], d**3, d[:, 0] ** 2 * d[:, 1], d[:, 0] * d[:, 1] ** 2])
        res[i] = U[i] - np.linalg.lstsq(A, U[nb[i, 1:]], rcond=None)[0][0]
    corr = {}
    for lag in (10.0, 20.0):
        pairs = np.array([p for p in tree.query_pairs(lag + 0.5) if abs(np.linalg.norm(X[p[0]] - X[p[1]]) - lag) < 0.6])
        a, b = res[pairs[:, 0]], res[pairs[:, 1]]
        ok = np.isfinite(a).all(1) & np.isfinite(b).all(1)
        corr[f"{lag:g}px"] = [float(np.corrcoef(a[ok, q], b[ok, q])[0, 1]) for q in (0, 1)]
    return {"estimate_by_neighbours": {str(k): estimate_noise(obs, k=k) for k in (12, 24, 48, 96)},
            "residual_correlation": corr}


def subset_hole(bundle, setup, centre, area: float, width: float, log=print) -> dict:
    """The hole seen through the DIC subsets (refine.diagnosis.subsets), on the search's frames and
    points (``setup``, :func:`search_setup`): the ellipse between the correlated and the failed
    subsets alone, and the hole fitted to the data from there with every tracked point's subset
    kept in material; each against the image's hole (centre over the specimen's width, area)."""
    from refine.diagnosis.holes import fit_hole, subset_start
    from refine.diagnosis.shapes import Hole
    from refine.diagnosis.subsets import hole_from_subsets

    model, fit, hold, sigma = setup
    subset = model.experiment.subset
    radius = float(np.sqrt(area / np.pi))
    evidence = hole_from_subsets(model.obs.reference, subset, centre, 2 * radius)
    start = subset_start(model, Hole((float(centre[0]), float(centre[1])), (radius, radius), 0.0))
    t = time.perf_counter()
    fitted = fit_hole(model, start, fit, hold, sigma)
    seconds = time.perf_counter() - t
    log(f"hole with subsets {subset:g}: {fitted.describe()} ({seconds:.0f} s)")

    def scored(shape_area, shape_centre):
        return {"area_error": float(shape_area / area - 1),
                "centre_error_over_width": float(np.hypot(*(np.asarray(shape_centre) - centre)) / width)}

    found = fitted.shapes[0]
    return {"subset": subset, "evidence": {"params": evidence.params.tolist(), "misclassified": evidence.misclassified,
                                           "tracked_sites": len(evidence.tracked), "failed_sites": len(evidence.untracked),
                                           **scored(np.pi * evidence.params[2] * evidence.params[3], evidence.params[:2])},
            "fitted": {"centre": list(found.centre), "axes": list(found.axes), "angle": found.angle,
                       "chi2": fitted.chi2_fit, "holdout": fitted.chi2_holdout, "seconds": round(seconds, 1),
                       **scored(found.outline()[0], found.centre)}}
