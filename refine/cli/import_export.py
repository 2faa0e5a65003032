"""``nonrigid import``: another DIC code's results in, a measurement bundle out.

    nonrigid import --format dice --scale 0.05 dice-output/ --out BUNDLE
    nonrigid import --format csv displacements.csv --out BUNDLE            (x, y, ux, uy in mm)

Formats (read by :func:`tracking.read_dice` and :func:`tracking.read_displacement_csv`):

- ``dice``: DICe solution files ``DICe_solution_NN.txt`` (a folder, or the files in frame order),
  one per deformed frame against one reference, columns COORDINATE_X/Y, DISPLACEMENT_X/Y in
  pixels (a subset is lost where SIGMA < 0 or MATCH is not 0);
- ``csv``: one file with columns ``frame,x,y,ux,uy[,id]``, or one file per frame with
  ``x,y,ux,uy[,id]`` (a folder's ``*.csv`` in natural order); empty ``ux, uy``: lost.

Coordinates become mm by ``--scale`` (mm per unit of the export: mm per pixel for DICe; 1 for a
CSV already in mm) after subtracting ``--origin``. Roles and the domain are assigned as
``nonrigid track`` does: the outer ring of points is the boundary and the domain the outline
through it; a hole left out of the DIC's region of interest is NOT cut from the domain (that is
what ``nonrigid diagnose`` can find). The model sections are a starting point to check.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Sequence

import tracking

from refine.bundle.from_tracks import ModelSkeleton, bundle_from_tracks
from refine.bundle.io import Bundle, read_bundle, write_bundle
from refine.bundle.roles import ROLES
from refine.exceptions import RefineError

FORMATS = ("dice", "csv")


class ImportCommandError(RefineError, ValueError):
    """The command line of ``nonrigid import`` cannot be carried out as given."""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``import`` sub-command to ``subparsers``."""
    from refine.cli.track import add_model_arguments

    p = subparsers.add_parser("import", help="turn a DIC code's export (DICe, CSV) into a bundle",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sources", nargs="+", help="export files or a folder (see the formats above)")
    p.add_argument("--format", choices=FORMATS, required=True, help="the export's format")
    p.add_argument("--out", required=True, metavar="BUNDLE", help="bundle directory to write")
    p.add_argument("--scale", type=float, default=None,
                   help="mm per unit of the export (required for dice, whose unit is the pixel; default 1 for csv)")
    p.add_argument("--origin", default="0,0", metavar="X,Y", help="export coordinates that become (0, 0) mm")
    add_model_arguments(p)
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid import``; 0 on success, 2 with a message on stderr when the input
    cannot be used."""
    from refine.cli.track import _numbers, model_from_arguments

    try:
        import_export(args.sources, args.out, format=args.format, scale=args.scale,
                      origin=_numbers(args.origin, 2, "--origin X,Y"), name=args.name,
                      model=model_from_arguments(args), validate_fraction=args.validate_fraction, seed=args.seed)
    except (tracking.TrackingError, RefineError, OSError) as e:
        print(f"nonrigid import: error: {e}", file=sys.stderr)
        return 2
    return 0


def import_export(sources: str | Path | Sequence[str | Path], out: str | Path, *, format: str,
                  scale: float | None = None, origin=(0.0, 0.0), name: str | None = None,
                  model: ModelSkeleton = ModelSkeleton(), validate_fraction: float = 0.2, seed: int = 0,
                  quiet: bool = False) -> Bundle:
    """Read a DIC export and write it as a measurement bundle (what ``nonrigid import`` does).

    Args:
        sources: the export's files or folder (see the module's docstring for the formats).
        out: the bundle directory to write.
        format: ``"dice"`` or ``"csv"``.
        scale: mm per unit of the export (mm/px for DICe, required there); None for a CSV: 1.
        origin: export coordinates ``(x, y)`` that become (0, 0) mm.
        name: experiment name; None: the name of ``out``.
        model: the model sections written to experiment.toml (a guess for the user to check).
        validate_fraction: share of interior points held out for validation.
        seed: the seed of that draw.
        quiet: do not print the summary.

    Returns:
        The bundle as read back from ``out``.
    """
    if format not in FORMATS:
        raise ImportCommandError(f"--format must be one of {', '.join(FORMATS)}, got {format!r}")
    if format == "dice":
        if scale is None:
            raise ImportCommandError("DICe coordinates are pixels: give --scale MM_PER_PX")
        tracks = tracking.read_dice(sources)
    else:
        tracks = tracking.read_displacement_csv(sources)
        tracks = replace(tracks, units="px")  # to_length scales from the file's own unit
        scale = 1.0 if scale is None else scale
    if not scale > 0:
        raise ImportCommandError(f"--scale must be a positive number, got {scale}")
    out = Path(out)
    bundle, dropped = bundle_from_tracks(tracks.to_length(scale, origin), name or out.resolve().name, model,
                                         validate_fraction, seed)
    write_bundle(out, bundle)
    _comment_experiment(out / "experiment.toml", format, sources, scale, origin)
    if not quiet:
        obs = bundle.observations
        counts = ", ".join(f"{int((obs.roles == r).sum())} {r}" for r in ROLES)
        lost = tracks.lost.sum(axis=1)
        print(f"imported {tracks.n_points} points x {tracks.n_frames - 1} frames from a {format} export: {counts}")
        print("  lost per frame: " + " ".join(f"{k}:{int(n)}" for k, n in enumerate(lost)))
        if dropped.size:
            print(f"  left out {dropped.size} points outside the outline (ids {dropped[:8].tolist()})")
        print(f"wrote {out}; check the [model] and [material] sections of experiment.toml before `nonrigid diagnose`")
    return read_bundle(out)


def _comment_experiment(path: Path, format: str, sources, scale: float, origin) -> None:
    names = [sources] if isinstance(sources, (str, Path)) else list(sources)
    head = (f"# written by `nonrigid import --format {format}` from {', '.join(Path(s).name for s in names)}\n"
            f"# coordinates in mm: x = (x_export - {origin[0]:g}) * {scale:.6g}, "
            f"y = (y_export - {origin[1]:g}) * {scale:.6g}\n"
            "# CHECK: the [model] and [material] sections are a starting point, not measured.\n\n")
    path.write_text(head + path.read_text(encoding="utf-8"), encoding="utf-8")
