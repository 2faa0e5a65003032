"""``nonrigid track``: images of a deforming sheet in, a measurement bundle out.

    nonrigid track --pattern grid --scale 0.5 --roi 40,20,250,150 ref.png f1.png f2.png --out BUNDLE

The first image is the reference (frame 0), the others are frames 1, 2, ... in the order given.
Bundle coordinates are the first image's axes in mm: x = column * scale, y = row * scale (shifted
by ``--origin``). The tracked points' outer ring becomes the boundary (the paper's set P), so the
domain is the outline through that ring: a rectangle when the ring is one (to 2 % of the point
spacing), else a polygon through the ring points. The model sections of experiment.toml come from
the flags and are only a starting point, which the file says in a comment.
"""

from __future__ import annotations

import argparse
import ast
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import tracking

from refine.bundle.io import Bundle, write_bundle
from refine.exceptions import RefineError
from jaxfem.materials import LAWS
from refine.bundle.experiment import Experiment, PolygonDomain, RectangleDomain
from refine.bundle.observations import Observations

RECTANGLE_TOLERANCE = 0.02  # of the point spacing: how far ring points may stray from a rectangle
TRACKER_FLAGS = ("spacing", "subset", "search", "min_zncc", "refiner", "line_shape", "max_jump", "min_quality")


class TrackCommandError(RefineError, ValueError):
    """The command line of ``nonrigid track`` cannot be carried out as given."""


@dataclass(frozen=True)
class ModelSkeleton:
    """The initial model written to experiment.toml (to be checked by the user)."""

    kind: str = "plane-stress"
    law: str = "neo-hookean"
    E: float = 1.0
    nu: float = 0.3
    thickness: float = 1.0
    noise_std: float | None = None  # None: ``nonrigid diagnose`` estimates it from the data


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``track`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("track", help="track a grid or speckle pattern through images into a bundle",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("images", nargs="+", help="image files; the first is the reference (frame 0)")
    p.add_argument("--out", required=True, metavar="BUNDLE", help="bundle directory to write")
    p.add_argument("--pattern", choices=sorted(tracking.TRACKERS), default="grid", help="painted grid or speckle")
    scale = p.add_mutually_exclusive_group()
    scale.add_argument("--scale", type=float, metavar="MM_PER_PX", help="mm per pixel")
    scale.add_argument("--grid-pitch", type=float, metavar="MM",
                       help="grid pitch in mm (derives the scale; grid pattern only)")
    p.add_argument("--roi", metavar="X0,Y0,X1,Y1",
                   help="tracked region in pixels of the first image (default: all of it)")
    p.add_argument("--origin", default="0,0", metavar="X,Y", help="pixel of the first image that becomes (0, 0) mm")
    p.add_argument("--name", help="experiment name (default: the bundle directory's name)")
    p.add_argument("--validate-fraction", type=float, default=0.2, help="share of interior points held out")
    p.add_argument("--seed", type=int, default=0, help="seed of the choice of validation points")
    p.add_argument("--noise-std", default="auto", metavar="auto|MM",
                   help="displacement noise in mm, or 'auto' (estimated by diagnose)")
    p.add_argument("--kind", choices=("plane-stress", "plane-strain"), default="plane-stress")
    p.add_argument("--law", choices=LAWS, default="neo-hookean")
    p.add_argument("--E", type=float, default=1.0, help="background modulus (relative without forces)")
    p.add_argument("--nu", type=float, default=0.3)
    p.add_argument("--thickness", type=float, default=1.0, help="sheet thickness, mm")
    p.add_argument("--overlays", metavar="DIR", help="directory of the overlay images (default: BUNDLE/overlays)")
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
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid track`` (``args`` from the parser of :func:`add_parser`); 0 on success,
    2 with a message on stderr when the input cannot be used."""
    try:
        _track(args)
    except (tracking.TrackingError, RefineError, OSError) as e:
        print(f"nonrigid track: error: {e}", file=sys.stderr)
        return 2
    return 0


def _track(args) -> None:
    if args.scale is None and args.grid_pitch is None:
        raise TrackCommandError("give the image scale: --scale MM_PER_PX, or --grid-pitch MM for a grid of known pitch")
    if args.grid_pitch is not None and args.pattern != "grid":
        raise TrackCommandError("--grid-pitch needs --pattern grid; give --scale MM_PER_PX for speckle images")
    if len(args.images) < 2:
        raise TrackCommandError("give at least two images: the reference and one deformed frame")
    if args.scale is not None and not args.scale > 0:
        raise TrackCommandError(f"--scale must be a positive number of mm per pixel, got {args.scale}")
    roi = None if args.roi is None else _numbers(args.roi, 4, "--roi X0,Y0,X1,Y1")
    origin = _numbers(args.origin, 2, "--origin X,Y")
    skeleton = ModelSkeleton(args.kind, args.law, args.E, args.nu, args.thickness, _noise(args.noise_std))
    # the model flags are checked now rather than after the (slow) tracking
    Experiment(name="check", kind=skeleton.kind, domain=RectangleDomain(0.0, 0.0, 1.0, 1.0), law=skeleton.law,
               E=skeleton.E, nu=skeleton.nu, thickness=skeleton.thickness)
    stack = tracking.load_images(args.images)
    tracks = tracking.track_images(stack, args.pattern, roi=roi, **_tracker_options(args))
    scale = args.scale if args.grid_pitch is None else tracking.scale_from_grid(tracks, args.grid_pitch)
    out = Path(args.out)
    name = args.name or out.resolve().name
    bundle, dropped = bundle_from_tracks(tracks.to_length(scale, origin), name, skeleton, args.validate_fraction,
                                         args.seed)
    write_bundle(out, bundle)
    _comment_experiment(out / "experiment.toml", args.pattern, args.images, scale, origin)
    overlays = write_overlays(stack, tracks, bundle, scale, origin, Path(args.overlays or out / "overlays"), roi)
    _summary(tracks, bundle, scale, dropped, out, overlays)


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


# ------------------------------------------------------------------------------ tracks -> bundle
def bundle_from_tracks(tracks: tracking.Tracks, name: str, model: ModelSkeleton = ModelSkeleton(),
                       validate_fraction: float = 0.2, seed: int = 0) -> tuple[Bundle, np.ndarray]:
    """A bundle of tracked points in length units (see :meth:`tracking.Tracks.to_length`).

    The boundary is the outline through the outer ring of the lattice (``grid_index``); interior
    points are split into guide and validate points by :func:`tracking.assign_roles`. Points
    outside that outline (tracked crossings that belong to no cell of the lattice) cannot be
    compared with a model and are left out.

    Returns:
        The bundle and the ids of the points left out, ``(k,)``.
    """
    from refine.model.measured import grid_spacing  # imported here: it brings jax, which the parser does not need

    if tracks.n_frames < 2:
        raise TrackCommandError("the tracks have only the reference frame; a bundle needs at least one more")
    reference = tracks.reference
    loop = lattice_outline(tracks.grid_index) if np.all(tracks.grid_index >= 0) else _hull_loop(reference)
    ring = reference[loop]
    if _signed_area(ring) < 0:
        loop, ring = loop[::-1], ring[::-1]
    inside = _strictly_inside(ring, reference)
    inside[loop] = True
    roles = tracking.assign_roles(reference, validate_fraction, seed, tracks.grid_index)
    roles[(roles == "boundary")] = "guide"  # only the outline's own points drive the model
    roles[loop] = "boundary"
    keep = np.flatnonzero(inside)
    lo, hi = reference[keep].min(axis=0), reference[keep].max(axis=0)
    off = np.min(np.abs(np.concatenate([ring - lo, ring - hi], axis=1)), axis=1)
    if off.max() <= RECTANGLE_TOLERANCE * grid_spacing(reference[keep]):
        domain = RectangleDomain(*lo, *hi)
    else:
        domain = PolygonDomain(tuple(map(tuple, ring)))
    obs = Observations(ids=tracks.ids[keep], reference=reference[keep], roles=roles[keep],
                       displacements=tracks.displacements()[1:, keep])
    experiment = Experiment(name=name, kind=model.kind, domain=domain, law=model.law, E=model.E, nu=model.nu,
                            thickness=model.thickness, units={"length": tracks.units}, noise_std=model.noise_std)
    return Bundle(experiment, obs), tracks.ids[~inside]


def lattice_outline(grid_index: np.ndarray) -> np.ndarray:
    """Indices of the points on the outer outline of a lattice, in order around it.

    The lattice's cells are the squares whose four corners are all points (``grid_index``
    (n, 2) holds each point's (row, col)); the outline is the boundary of their union, traced
    with the cells on its left. Where two parts of the union touch at a single corner the trace
    keeps to one part; the largest loop is returned.
    """
    index = np.asarray(grid_index, dtype=np.int64)
    lookup = {tuple(ij): k for k, ij in enumerate(index)}
    edges = set()
    for i, j in lookup:
        square = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)]
        if all(c in lookup for c in square):
            edges.update(zip(square, square[1:] + square[:1]))
    edges = {e for e in edges if e[::-1] not in edges}
    if not edges:
        raise TrackCommandError("the tracked points form no cell of a lattice (too few points); enlarge the ROI")
    leaving: dict = {}
    for a, b in edges:
        leaving.setdefault(a, []).append(b)
    loops = []
    while leaving:
        start = min(leaving)
        loop, here, heading = [start], start, None
        while True:
            nexts = leaving[here]
            step = max(nexts, key=lambda b: _turn(heading, (b[0] - here[0], b[1] - here[1])))
            nexts.remove(step)
            if not nexts:
                del leaving[here]
            heading, here = (step[0] - here[0], step[1] - here[1]), step
            if here == start:
                break
            loop.append(here)
        loops.append(loop)
    largest = max(loops, key=lambda lp: abs(_signed_area(np.array(lp, float))))
    return np.array([lookup[v] for v in largest])


def _turn(heading, direction) -> float:
    """Left turn from ``heading`` to ``direction`` (lattice steps (di, dj)) in radians, in the
    (x = j, y = i) frame in which the cells lie on the left of the outline."""
    if heading is None:
        return 0.0
    cross = heading[1] * direction[0] - heading[0] * direction[1]
    return float(np.arctan2(cross, heading[0] * direction[0] + heading[1] * direction[1]))


def _hull_loop(points: np.ndarray) -> np.ndarray:
    """Without a lattice: the points on the convex hull, in order around it."""
    from scipy.spatial import ConvexHull

    return ConvexHull(points).vertices


def _signed_area(ring: np.ndarray) -> float:
    x, y = ring[:, 0], ring[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _strictly_inside(ring: np.ndarray, points: np.ndarray) -> np.ndarray:
    from matplotlib.path import Path as Outline

    return Outline(ring).contains_points(points)


# ------------------------------------------------------------------------------ writing
def _comment_experiment(path: Path, pattern: str, images, scale: float, origin) -> None:
    """Say where experiment.toml came from and that its model is a guess (TOML keeps comments)."""
    head = (f"# written by `nonrigid track --pattern {pattern}` from {', '.join(Path(p).name for p in images)}\n"
            f"# coordinates in mm on the first image's axes: x = (column - {origin[0]:g}) * {scale:.6g}, "
            f"y = (row - {origin[1]:g}) * {scale:.6g}\n\n")
    model = ("# CHECK: the model below comes from the command line flags (or their defaults), not from the\n"
             "# images: set kind, thickness, law, E and nu to what you know of the specimen. The domain is\n"
             "# the outline through the outer ring of tracked points (the boundary points lie on it).\n")
    text = head + path.read_text(encoding="utf-8").replace("[model]", model + "[model]", 1)
    if "[measurement]" not in text:
        text += ("\n# [measurement] noise_std is not given: `nonrigid diagnose` estimates it from the data;\n"
                 "# set it (mm) if you know the tracking noise.\n")
    path.write_text(text, encoding="utf-8")


ROLE_COLOURS = {"boundary": "tab:orange", "guide": "tab:green", "validate": "tab:blue"}


def write_overlays(stack: np.ndarray, tracks: tracking.Tracks, bundle: Bundle, scale: float, origin,
                   directory: Path, roi=None) -> list[Path]:
    """One PNG per frame, ``frame_000.png`` ...: the image with the tracked points coloured by role.

    Frame 0 also shows the ROI (dashed) and the bundle's domain (black); in later frames a lost
    point is a red x where its neighbours' motion would put it.

    Args:
        stack: images ``(n_frames, rows, cols)``.
        tracks: the tracks in pixels; ``bundle`` the bundle made of them, in mm with ``scale`` (mm/px)
            and ``origin`` (px).
    """
    from matplotlib.figure import Figure  # not pyplot: the caller's backend (a notebook's) stays as it is
    from scipy.spatial import cKDTree

    directory.mkdir(parents=True, exist_ok=True)
    role = dict(zip(bundle.observations.ids.tolist(), bundle.observations.roles.tolist()))
    colours = np.array([ROLE_COLOURS.get(role.get(int(i)), "0.5") for i in tracks.ids])
    rows, cols = stack.shape[1:]
    zoom = float(np.clip(900.0 / cols, 1.0, 4.0))
    marker = 2.0 + zoom
    paths = []
    for k, image in enumerate(stack):
        fig = Figure(figsize=(zoom * cols / 100, zoom * rows / 100), dpi=100)
        ax = fig.add_axes([0, 0, 1, 1])
        ax.imshow(image, cmap="gray", interpolation="nearest")
        ok = ~tracks.lost[k]
        xy = tracks.positions[k]
        ax.scatter(xy[ok, 0], xy[ok, 1], s=marker ** 2, c=colours[ok], linewidths=0)
        if k == 0:
            outline_px = _domain_outline(bundle.experiment.domain) / scale + np.asarray(origin)
            ax.plot(*np.vstack([outline_px, outline_px[:1]]).T, "k-", lw=1)
            if roi is not None:
                x0, y0, x1, y1 = roi
                ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "y--", lw=1)
        elif (~ok).any():
            found = np.flatnonzero(ok)
            guess = tracks.reference[~ok].copy()
            if found.size:
                _, near = cKDTree(tracks.reference[found]).query(guess, k=min(4, found.size))
                near = found[near.reshape(len(guess), -1)]
                guess += tracks.displacements()[k][near].mean(axis=1)
            ax.scatter(guess[:, 0], guess[:, 1], s=(2.5 * marker) ** 2, c="red", marker="x", linewidths=1.5)
        ax.text(4, 4, f"frame {k}: {int(ok.sum())} tracked, {int((~ok).sum())} lost", color="yellow",
                va="top", fontsize=8 + zoom, bbox={"facecolor": "black", "alpha": 0.5, "lw": 0})
        ax.set_xlim(-0.5, cols - 0.5)
        ax.set_ylim(rows - 0.5, -0.5)
        ax.axis("off")
        path = directory / f"frame_{k:03d}.png"
        fig.savefig(path)
        paths.append(path)
    return paths


def _domain_outline(domain) -> np.ndarray:
    if isinstance(domain, RectangleDomain):
        return np.array([[domain.xmin, domain.ymin], [domain.xmax, domain.ymin],
                         [domain.xmax, domain.ymax], [domain.xmin, domain.ymax]])
    return np.asarray(domain.vertices)


def _summary(tracks: tracking.Tracks, bundle: Bundle, scale: float, dropped: np.ndarray, out: Path,
             overlays: list[Path]) -> None:
    obs, domain = bundle.observations, bundle.experiment.domain
    counts = ", ".join(f"{int(np.sum(obs.roles == r))} {r}" for r in ROLE_COLOURS)
    print(f"tracked {tracks.n_points} points ({tracks.meta.get('tracker', '?')}) through {tracks.n_frames} images "
          f"at {scale:.6g} mm/px: {counts}")
    print("  lost per frame: " + " ".join(f"{k}:{int(n)}" for k, n in enumerate(tracks.lost.sum(axis=1))))
    if dropped.size:
        print(f"  left out {dropped.size} points outside the lattice's outline (ids {dropped[:8].tolist()}"
              f"{'...' if dropped.size > 8 else ''})")
    if isinstance(domain, RectangleDomain):
        print(f"  domain: rectangle [{domain.xmin:.4g}, {domain.ymin:.4g}, {domain.xmax:.4g}, {domain.ymax:.4g}] mm")
    else:
        print(f"  domain: polygon of {len(domain.vertices)} vertices through the outer ring")
    print(f"wrote {out} (experiment.toml, points.csv, displacements.csv) and {len(overlays)} overlays in "
          f"{overlays[0].parent if overlays else '-'}")
    print("check the [model] and [material] sections of experiment.toml before `nonrigid diagnose`")
