"""``nonrigid follow BUNDLE --out DIR``: follow a sequence of unlabelled clouds, refining the model
where its prediction of the next frame fails beyond the noise."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``follow`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("follow", help="follow unlabelled clouds frame by frame, refining the model")
    p.add_argument("bundle", help="a bundle with clouds.csv (its tracked points, if any, are fitted too)")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--clamped", default="left", help="sides that do not move, comma separated (default left; in 3D "
                                                      "the sides of the mesh's bounding box, left ... front)")
    p.add_argument("--gripped", default="right", help="sides moved rigidly by a grip (default right)")
    p.add_argument("--h", type=float, default=5.0, help="element size of a 2D model (length unit; a 3D model is the "
                                                        "bundle's mesh)")
    p.add_argument("--noise", type=float, default=None,
                   help="noise of a point's coordinates (default: the bundle's noise_std, else 0.05)")
    p.add_argument("--no-refine", action="store_true", help="predict and track only")
    p.add_argument("--seed", type=int, default=0, help="seeds the held-out points")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid follow`` (``args`` from the parser of :func:`add_parser`); 0 on success."""
    from refine.correspond.model import Grips

    grips = Grips(Grips.parse(args.clamped, ()), Grips.parse(args.gripped, ()))
    follow(args.bundle, args.out, grips=grips, h=args.h, noise=args.noise, refine=not args.no_refine,
           seed=args.seed)
    return 0


def follow(bundle, out: str | Path, grips=None, h: float = 5.0, noise: float | None = None, refine: bool = True,
           seed: int = 0, quiet: bool = False):
    """Follow the bundle's clouds (:func:`refine.correspond.follow_clouds`; its tracked points of
    points.csv, if any, fitted as extra data) and write to ``out``: ``follow.json`` (per frame the
    prediction error before and after refinement, the refinements and what they changed, the
    regions found), ``correspondences.csv`` (every model node in every frame) and ``errors.png``
    (error against frame).

    Args:
        bundle: a bundle directory or :class:`refine.bundle.Bundle` holding clouds.
        grips: a :class:`refine.correspond.Grips` (default: left clamped, right gripped).
    Returns the :class:`refine.correspond.FollowResult`.
    """
    from refine.bundle.io import read_bundle
    from refine.correspond import CloudModel, FitConfig, FollowConfig, Grips, follow_clouds
    from refine.correspond.output import plot_errors, write_correspondences, write_summary
    from refine.exceptions import CorrespondenceError

    if isinstance(bundle, (str, Path)):
        bundle = read_bundle(bundle)
    if bundle.clouds is None:
        raise CorrespondenceError("the bundle has no clouds.csv; follow works on unlabelled clouds (tracked points "
                                  "are diagnosed by `nonrigid diagnose`)")
    noise = noise or bundle.experiment.noise_std or 0.05
    config = FollowConfig(fit=FitConfig(noise=noise, seed=seed), grips=grips or Grips(), h=h, refine=refine)
    say = (lambda *a: None) if quiet else print
    model = CloudModel(bundle.experiment, config.grips, h, root=bundle.root)
    if bundle.observations is not None:
        say(f"fitting the {len(bundle.observations.ids)} tracked points of points.csv too")
    result = follow_clouds(bundle.experiment, bundle.clouds.points, config, model=model,
                           observations=bundle.observations,
                           progress=lambda r: say(f"frame {r.frame}: error {r.error_before:.4g} -> {r.error_after:.4g}"
                                                  + (" (refined)" if r.refined else "")))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_summary(out / "follow.json", result.summary())
    write_correspondences(out / "correspondences.csv", result.nodes, result.positions)
    plot_errors(out / "errors.png", result.records, result.null_level)
    say(f"null level {result.null_level:.4g}; refinements at frames "
        f"{[r.frame for r in result.records if r.refined] or 'none'}; findings {result.findings}; wrote {out}")
    for f in result.findings:  # a refit's radius or ratio the data leave undetermined
        if f.get("note"):
            say(f"{f['cause']} at {[round(c, 2) for c in f['centroid']]}: {f['note']}")
    if result.refit is not None and result.refit["rejected"]:
        say(f"regions of the field rejected by the BIC (misfit drop below {result.refit['bic_penalty']:.3g}): "
            f"{[(r['cause'], [round(c, 2) for c in r['centroid']]) for r in result.refit['rejected']]}")
    return result
