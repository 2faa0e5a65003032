"""``nonrigid track``: images of a deforming sheet in, a measurement bundle out.

    nonrigid track --pattern grid --scale 0.5 --roi 40,20,250,150 ref.png f1.png f2.png --out BUNDLE

The first image is the reference (frame 0), the others are frames 1, 2, ... in the order given.
Bundle coordinates are the first image's axes in mm: x = column * scale, y = row * scale (shifted
by ``--origin``). The tracked points' outer ring becomes the boundary (the paper's set P), so the
domain is the outline through that ring: a rectangle when the ring is one (to 2 % of the point
spacing), else a polygon through the ring points. The model sections of experiment.toml come from
the flags and are only a starting point, which the file says in a comment.

With range images (``--range RANGE_IMAGES --mesh BODY`` and a camera: ``--scale``, ``--fx --fy --cx
--cy`` or ``--camera FILE``) every tracked point is looked up sub-pixel in its frame's range image
and the bundle is 3D (``kind = "solid"``; see refine.cli.track_range); ``--clouds-only`` writes
clouds.csv from the range images alone.
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

import tracking

from refine.bundle.io import Bundle, read_bundle, write_bundle
from refine.bundle.roles import ROLES
from refine.exceptions import RefineError
from refine.bundle.experiment import Experiment, RectangleDomain
from refine.bundle.from_tracks import ModelSkeleton, bundle_from_tracks

TRACKER_FLAGS = ("spacing", "subset", "search", "min_zncc", "refiner", "line_shape", "max_jump", "min_quality")


class TrackCommandError(RefineError, ValueError):
    """The command line of ``nonrigid track`` cannot be carried out as given."""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``track`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("track", help="track a grid or speckle pattern through images into a bundle",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("images", nargs="*", help="image files, folders or glob patterns (natural order); the first "
                   "image is the reference (frame 0) unless --reference says otherwise (none with --clouds-only)")
    p.add_argument("--out", required=True, metavar="BUNDLE", help="bundle directory to write")
    p.add_argument("--pattern", choices=sorted(tracking.TRACKERS), default="grid", help="painted grid or speckle")
    scale = p.add_mutually_exclusive_group()
    scale.add_argument("--scale", type=float, metavar="MM_PER_PX", help="mm per pixel")
    scale.add_argument("--grid-pitch", type=float, metavar="MM",
                       help="grid pitch in mm (derives the scale; grid pattern only)")
    p.add_argument("--roi", metavar="X0,Y0,X1,Y1",
                   help="tracked region in pixels of the first image (default: all of it)")
    p.add_argument("--origin", default="0,0", metavar="X,Y", help="pixel of the first image that becomes (0, 0) mm")
    add_model_arguments(p)
    add_range_arguments(p)
    p.add_argument("--overlays", metavar="DIR", help="directory of the overlay images (default: BUNDLE/overlays)")
    p.add_argument("--reference", type=int, default=0, metavar="K",
                   help="which image is the reference (frame 0), counted from 0 (default: the first)")
    p.add_argument("--keep-holes", action="store_true",
                   help="do not cut holes found in the pattern from the model's domain (let diagnose find them)")
    t = p.add_argument_group("tracker options (see tracking.GridTracker / tracking.SpeckleTracker)")
    t.add_argument("--spacing", type=float, help="speckle: distance between correlation points, px")
    t.add_argument("--subset", type=int, help="speckle: subset side, px (odd)")
    t.add_argument("--search", type=int, help="speckle: integer search half-range, px")
    t.add_argument("--min-zncc", type=float, help="speckle: correlation under which a point is lost")
    t.add_argument("--refiner", help="grid: sub-pixel refiner (lines, hessian, snake)")
    t.add_argument("--line-shape", choices=("adaptive", "straight", "curved"),
                   help="grid, lines refiner: centre lines straight, parabolic, or chosen per line (default adaptive)")
    t.add_argument("--max-jump", type=float, help="grid: largest motion difference to neighbours, pitches")
    t.add_argument("--min-quality", type=float, help="grid: refiner quality under which a crossing is lost")
    t.add_argument("--option", action="append", default=[], metavar="KEY=VALUE", help="any other tracker field")
    p.set_defaults(run=run)
    return p


def add_range_arguments(p: argparse.ArgumentParser) -> None:
    """The flags of 3D tracking with range images (refine.cli.track_range)."""
    r = p.add_argument_group("range images: 3D points (a solid bundle) or clouds (docs/measurement-bundle.md)")
    r.add_argument("--range", nargs="+", metavar="RANGE", dest="ranges",
                   help="range images (.npy or 32-bit float TIFF, depth in mm, NaN or 0 = no data), one per image")
    r.add_argument("--mesh", metavar="FILE", help="the body's mesh (any meshio format), copied as the bundle's domain")
    r.add_argument("--camera", metavar="FILE", help="camera file (TOML: model, scale or fx/fy/cx/cy, optional pose)")
    for name in ("fx", "fy", "cx", "cy"):
        r.add_argument(f"--{name}", type=float, metavar="PX", help=f"perspective camera's {name}, px")
    r.add_argument("--range-order", type=int, choices=(1, 2, 3), default=2,
                   help="depth lookup: 1 bilinear from valid pixels, 2 least-squares quadratic on the valid "
                   "pixels of a 5 x 5 window (default: averages the depth noise), 3 bicubic")
    r.add_argument("--range-radius", type=int, default=2, metavar="PX",
                   help="half side of --range-order 2's window (default 2: 5 x 5 pixels); larger averages more "
                   "depth noise where the pattern's pitch spans many pixels")
    r.add_argument("--range-max-step", type=float, metavar="MM",
                   help="depth spread within a point's support above which it is lost (an occluding edge)")
    r.add_argument("--clouds", action="store_true", help="also write clouds.csv from the range images")
    r.add_argument("--clouds-only", action="store_true", help="no images: write clouds.csv from the range images only")
    r.add_argument("--cloud-spacing", type=float, metavar="MM", help="spacing of the clouds' points (default 3 pixels)")
    r.add_argument("--mask", metavar="IMAGE", help="clouds: image whose non-zero pixels are used (with --roi)")


def range_from_arguments(args: argparse.Namespace):
    """The :class:`~refine.cli.track_range.RangeOptions` of the flags, or None without --range."""
    if not args.ranges:
        if args.clouds_only or args.clouds or args.mesh:
            raise TrackCommandError("--clouds, --clouds-only and --mesh go with --range RANGE_IMAGES")
        return None
    from refine.cli.track_range import RangeOptions, camera_from_options

    camera = camera_from_options(args.camera, args.scale, _numbers(args.origin, 2, "--origin X,Y"), args.fx, args.fy,
                                 args.cx, args.cy)
    return RangeOptions(args.ranges, camera, args.mesh, args.range_order, args.range_max_step, args.clouds,
                        args.clouds_only, args.cloud_spacing, args.mask, args.range_radius)


def add_model_arguments(p: argparse.ArgumentParser) -> None:
    """The flags of the bundle a command writes (track, import): experiment name, validation
    share and seed, and the initial model in experiment.toml."""
    p.add_argument("--name", help="experiment name (default: the bundle directory's name)")
    p.add_argument("--validate-fraction", type=float, default=0.2, help="share of interior points held out")
    p.add_argument("--seed", type=int, default=0, help="seed of the choice of validation points")
    p.add_argument("--noise-std", default="auto", metavar="auto|MM",
                   help="displacement noise in mm, or 'auto' (estimated by diagnose)")
    p.add_argument("--kind", choices=("plane-stress", "plane-strain"), default="plane-stress")
    # no choices: the law registry lives in jaxfem, and the parser must not import JAX; the model is
    # checked against the registry before any tracking (an unknown law's message lists the known ones)
    p.add_argument("--law", default="neo-hookean", help="material law of jaxfem's registry (default neo-hookean)")
    p.add_argument("--E", type=float, default=1.0, help="background modulus (relative without forces)")
    p.add_argument("--nu", type=float, default=0.3)
    p.add_argument("--thickness", type=float, default=1.0, help="sheet thickness, mm")


def model_from_arguments(args: argparse.Namespace) -> ModelSkeleton:
    """The :class:`ModelSkeleton` the flags of :func:`add_model_arguments` describe."""
    return ModelSkeleton(args.kind, args.law, args.E, args.nu, args.thickness, _noise(args.noise_std))


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid track`` (``args`` from the parser of :func:`add_parser`); 0 on success,
    2 with a message on stderr when the input cannot be used."""
    try:
        model = model_from_arguments(args)
        ranges = range_from_arguments(args)
        track(args.images, args.out, ranges=ranges, pattern=args.pattern, scale=args.scale, grid_pitch=args.grid_pitch,
              roi=args.roi, origin=args.origin, name=args.name, model=model,
              validate_fraction=args.validate_fraction, seed=args.seed, overlays=args.overlays,
              tracker_options=_tracker_options(args), cut_holes=not args.keep_holes, reference=args.reference)
    except (tracking.TrackingError, RefineError, OSError) as e:
        print(f"nonrigid track: error: {e}", file=sys.stderr)
        return 2
    return 0


def track(images: Sequence[str | Path], out: str | Path, *, pattern: str = "grid", scale: float | None = None,
          grid_pitch: float | None = None, roi=None, origin=(0.0, 0.0), name: str | None = None,
          model: ModelSkeleton = ModelSkeleton(), validate_fraction: float = 0.2, seed: int = 0,
          overlays: str | Path | None = None, tracker_options: dict | None = None, cut_holes: bool = True,
          reference: int = 0, quiet: bool = False, ranges=None) -> Bundle:
    """Track a painted grid or a speckle pattern through image files and write a measurement bundle.

    What ``nonrigid track`` does. ``images[0]`` is the reference (frame 0); bundle coordinates are
    its axes in mm: x = (column - origin_x) * scale, y = (row - origin_y) * scale.

    Args:
        images: two or more image files (or folders / glob patterns of them), in frame order.
        out: the bundle directory to write (experiment.toml, points.csv, displacements.csv).
        pattern: a tracker of :data:`tracking.TRACKERS` (``"grid"`` or ``"speckle"``).
        scale: mm per pixel; or ``grid_pitch``, the grid's pitch in mm, to derive it (grid only).
        roi: tracked region ``(x0, y0, x1, y1)`` in pixels of the first image (or ``"x0,y0,x1,y1"``);
            None: all of it.
        origin: pixel ``(x, y)`` (or ``"x,y"``) of the first image that becomes (0, 0) mm.
        name: experiment name; None: the name of the ``out`` directory.
        model: the model sections written to experiment.toml (a guess for the user to check).
        validate_fraction: share of interior points held out for validation.
        seed: the seed of that draw.
        overlays: directory of the overlay PNGs ``frame_000.png``, ...; None: ``out/overlays``.
        tracker_options: further fields of the tracker (``tracking.GridTracker`` /
            ``tracking.SpeckleTracker``), e.g. ``{"spacing": 12.0, "subset": 21}``.
        reference: which of ``images`` (after expanding folders and globs, natural order) is the
            reference, frame 0; the others follow in their order (default: the first).
        cut_holes: holes the tracker found in the pattern (``meta["outline"]["holes"]``) are cut
            from the bundle's domain (``model.domain.holes``), so the model follows the material;
            False leaves the domain whole (to let ``nonrigid diagnose`` find a hole).
        quiet: do not print the summary.
        ranges: :class:`refine.cli.track_range.RangeOptions`: range images, camera and mesh, for a 3D
            (solid) bundle of the points' 3D positions, or of clouds only; None: a 2D bundle.

    Returns:
        The bundle as read back from ``out``.

    Raises:
        TrackCommandError: the arguments cannot be used (the message names the command line flag).
        tracking.TrackingError: the images cannot be tracked as asked (unreadable, ROI outside).
        refine.exceptions.RefineError: the model or the tracked points cannot make a bundle.
    """
    if ranges is not None:
        return _track_range(images, out, ranges, pattern, grid_pitch, roi, name, model, validate_fraction, seed,
                            overlays, tracker_options, reference, quiet)
    if scale is None and grid_pitch is None:
        raise TrackCommandError("give the image scale: --scale MM_PER_PX, or --grid-pitch MM for a grid of known pitch")
    if grid_pitch is not None and pattern != "grid":
        raise TrackCommandError("--grid-pitch needs --pattern grid; give --scale MM_PER_PX for speckle images")
    images = tracking.image_paths(images)  # folders and globs expanded, in natural order
    if len(images) < 2:
        raise TrackCommandError("give at least two images: the reference and one deformed frame")
    if scale is not None and not scale > 0:
        raise TrackCommandError(f"--scale must be a positive number of mm per pixel, got {scale}")
    roi = None if roi is None else _numbers(roi, 4, "--roi X0,Y0,X1,Y1")
    origin = _numbers(origin, 2, "--origin X,Y")
    # the model is checked now rather than after the (slow) tracking
    Experiment(name="check", kind=model.kind, domain=RectangleDomain(0.0, 0.0, 1.0, 1.0), law=model.law,
               E=model.E, nu=model.nu, thickness=model.thickness)
    if not -len(images) <= reference < len(images):
        raise TrackCommandError(f"--reference {reference} is not one of the {len(images)} images (0 to {len(images) - 1})")
    images = [images[reference]] + [p for k, p in enumerate(images) if k != reference % len(images)]
    stack = tracking.load_images(images)
    tracks = tracking.track_images(stack, pattern, roi=roi, **(tracker_options or {}))
    scale = scale if grid_pitch is None else tracking.scale_from_grid(tracks, grid_pitch)
    out = Path(out)
    found = (tracks.meta.get("outline") or {}).get("holes", []) if cut_holes else []
    holes = [(np.asarray(h, dtype=np.float64) - np.asarray(origin)) * scale for h in found]
    bundle, dropped = bundle_from_tracks(tracks.to_length(scale, origin), name or out.resolve().name, model,
                                         validate_fraction, seed, holes=holes)
    write_bundle(out, bundle)
    _comment_experiment(out / "experiment.toml", pattern, images, scale, origin)
    from refine.cli.track_overlays import write_overlays

    written = write_overlays(stack, tracks, bundle, scale, origin, Path(overlays or out / "overlays"), roi)
    if not quiet:
        _summary(tracks, bundle, scale, dropped, out, written)
    return read_bundle(out)


def _track_range(images, out, ranges, pattern, grid_pitch, roi, name, model, validate_fraction, seed, overlays,
                 tracker_options, reference, quiet) -> Bundle:
    from refine.cli.track_range import track_range

    if grid_pitch is not None:
        raise TrackCommandError("--grid-pitch does not go with --range: the camera gives the 3D scale")
    if not ranges.clouds_only and not images:
        raise TrackCommandError("give the intensity images to track (or --clouds-only for clouds from range alone)")
    Experiment(name="check", kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 1.0, 1.0), law=model.law,
               E=model.E, nu=model.nu)
    out = Path(out)
    return track_range(images, out, ranges, pattern=pattern, name=name or out.resolve().name, model=model,
                       roi=None if roi is None else _numbers(roi, 4, "--roi X0,Y0,X1,Y1"),
                       validate_fraction=validate_fraction, seed=seed, overlays=overlays,
                       tracker_options=tracker_options or {}, reference=reference, quiet=quiet)


def _numbers(text, count: int, what: str) -> tuple[float, ...]:
    values = text if isinstance(text, (tuple, list)) else str(text).replace(" ", "").split(",")
    try:
        numbers = tuple(float(v) for v in values)
    except ValueError:
        numbers = ()
    if len(numbers) != count or not np.all(np.isfinite(numbers)):
        raise TrackCommandError(f"{what} takes {count} numbers separated by commas, got {text!r}")
    return numbers


def _noise(text) -> float | None:
    if text is None or str(text) == "auto":
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or not np.isfinite(value):
        raise TrackCommandError(f"--noise-std takes 'auto' or a positive number of mm, got {text!r}")
    return value


def _tracker_options(args) -> dict:
    options = {name: getattr(args, name) for name in TRACKER_FLAGS if getattr(args, name, None) is not None}
    for item in getattr(args, "option", None) or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise TrackCommandError(f"--option takes KEY=VALUE, got {item!r}")
        try:
            options[key.strip().replace("-", "_")] = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError):
            options[key.strip().replace("-", "_")] = value.strip()
    return options


def _comment_experiment(path: Path, pattern: str, images, scale: float, origin) -> None:
    """Say where experiment.toml came from and that its model is a guess (TOML keeps comments)."""
    head = (f"# written by `nonrigid track --pattern {pattern}` from {', '.join(Path(p).name for p in images)}\n"
            f"# coordinates in mm on the first image's axes: x = (column - {origin[0]:g}) * {scale:.6g}, "
            f"y = (row - {origin[1]:g}) * {scale:.6g}\n\n")
    model = ("# CHECK: the model below comes from the command line flags (or their defaults), not from the\n"
             "# images: set kind, thickness, law, E and nu to what you know of the specimen. The domain is\n"
             "# the outline through the outer ring of tracked points (the boundary points lie on it).\n")
    text = head + path.read_text(encoding="utf-8").replace("[model]", model + "[model]", 1)
    if "noise_std" not in text:
        text += ("\n# [measurement] noise_std is not given: `nonrigid diagnose` estimates it from the data;\n"
                 "# set it (mm) if you know the tracking noise.\n")
    path.write_text(text, encoding="utf-8")


def _summary(tracks: tracking.Tracks, bundle: Bundle, scale: float, dropped: np.ndarray, out: Path,
             overlays: list[Path]) -> None:
    obs, domain = bundle.observations, bundle.experiment.domain
    counts = ", ".join(f"{int(np.sum(obs.roles == r))} {r}" for r in ROLES)
    print(f"tracked {tracks.n_points} points ({tracks.meta.get('tracker', '?')}) through {tracks.n_frames} images "
          f"at {scale:.6g} mm/px: {counts}")
    print("  lost per frame: " + " ".join(f"{k}:{int(n)}" for k, n in enumerate(tracks.lost.sum(axis=1))))
    if dropped.size:
        print(f"  left out {dropped.size} points outside the lattice's outline (ids {dropped[:8].tolist()}"
              f"{'...' if dropped.size > 8 else ''})")
    if getattr(domain, "holes", ()):
        print(f"  {len(domain.holes)} hole(s) in the pattern cut from the domain (--keep-holes leaves them in)")
    if isinstance(domain, RectangleDomain):
        print(f"  domain: rectangle [{domain.xmin:.4g}, {domain.ymin:.4g}, {domain.xmax:.4g}, {domain.ymax:.4g}] mm")
    else:
        print(f"  domain: polygon of {len(domain.vertices)} vertices through the outer ring")
    print(f"wrote {out} (experiment.toml, points.csv, displacements.csv) and {len(overlays)} overlays in "
          f"{overlays[0].parent if overlays else '-'}")
    print("check the [model] and [material] sections of experiment.toml before `nonrigid diagnose`")
