"""``nonrigid import``: another DIC code's results in, a measurement bundle out.

    nonrigid import --format dice --scale 0.05 dice-output/ --out BUNDLE
    nonrigid import --format csv displacements.csv --out BUNDLE            (x, y, ux, uy in mm)
    nonrigid import --dvc points.csv --mesh body.msh --out BUNDLE          (x, y, z, ux, uy, uz in mm)

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

``--dvc FILE.csv --mesh MESH``: a digital volume correlation's points (columns ``x,y,z,ux,uy,uz``,
optional ``frame``, header in any case; :mod:`refine.cli.import_dvc`) in the mesh's axes and unit
(times ``--scale``, default 1), inside the body: a solid bundle. The points on the mesh's named
faces (or those of ``--boundary-faces NAME,...``: named faces or bounding-box sides) are the
boundary; the rest guide or validate. A point outside the mesh is an error.
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
    p.add_argument("sources", nargs="*", help="export files or a folder (see the formats above)")
    p.add_argument("--format", choices=FORMATS, help="the export's format (dice or csv; not with --dvc)")
    p.add_argument("--dvc", metavar="FILE.csv", help="a DVC export (x,y,z,ux,uy,uz[,frame]) inside the --mesh body")
    p.add_argument("--mesh", metavar="MESH", help="with --dvc: the body's 3D mesh (any meshio format; copied in)")
    p.add_argument("--boundary-faces", metavar="NAME,...",
                   help="with --dvc: the faces whose points drive the model (default: every face the mesh names)")
    p.add_argument("--face-tolerance", type=float, default=None, metavar="MM",
                   help="with --dvc: how far from a face (or outside the mesh) a point may lie; default 1/4 spacing")
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
        if args.dvc is not None or args.format is None:
            return _run_dvc(args, model_from_arguments(args))
        if not args.sources:
            raise ImportCommandError(f"--format {args.format} needs the export's files or folder")
        import_export(args.sources, args.out, format=args.format, scale=args.scale,
                      origin=_numbers(args.origin, 2, "--origin X,Y"), name=args.name,
                      model=model_from_arguments(args), validate_fraction=args.validate_fraction, seed=args.seed)
    except (tracking.TrackingError, RefineError, OSError) as e:
        print(f"nonrigid import: error: {e}", file=sys.stderr)
        return 2
    return 0


def _run_dvc(args: argparse.Namespace, model: ModelSkeleton) -> int:
    from refine.cli.import_dvc import import_dvc

    if args.dvc is None:
        raise ImportCommandError("give --format dice|csv with the export's files, or --dvc FILE.csv --mesh MESH")
    if args.format is not None or args.sources:
        raise ImportCommandError("--dvc reads one CSV file; give no --format and no other files with it")
    if args.mesh is None:
        raise ImportCommandError("--dvc needs the body's mesh: --mesh FILE (any meshio format, in the points' axes)")
    faces = None if args.boundary_faces is None else tuple(
        f.strip() for f in args.boundary_faces.split(",") if f.strip())
    import_dvc(args.dvc, args.mesh, args.out, scale=1.0 if args.scale is None else args.scale, faces=faces,
               tolerance=args.face_tolerance, name=args.name, model=model,
               validate_fraction=args.validate_fraction, seed=args.seed)
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
