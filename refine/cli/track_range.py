"""``nonrigid track --range``: intensity images plus range images in, a 3D (solid) bundle out.

Each tracked crossing (grid) or subset centre (speckle) is looked up SUB-PIXEL in its own frame's
range image (a least-squares quadratic on the valid pixels around it, bilinear from valid pixels
only, or bicubic; :func:`tracking.range_lookup`) and placed
in 3D by the camera (:class:`tracking.Camera`: orthographic mm per pixel, or perspective fx, fy,
cx, cy; an optional pose puts the points in the mesh's axes). A point whose depth is missing or
invalid in a frame is lost there with its reason (``lost.csv``); a point without depth in the
reference frame has no reference position and is left out of points.csv, listed in ``lost.csv``
and in the summary. With ``clouds_only`` no pattern is tracked: every frame's valid range pixels,
thinned on a grid of cells, become ``clouds.csv`` (frame 0 the reference shape).
"""

from __future__ import annotations

import csv
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

import tracking
from tracking import _lost as lost_codes

from refine.bundle.clouds import Clouds
from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.from_tracks import ModelSkeleton
from refine.bundle.io import Bundle, read_bundle, write_bundle
from refine.bundle.observations import Observations
from refine.bundle.roles import ROLES, assign_roles, point_spacing
from refine.exceptions import RefineError

CLOUD_FOOTPRINTS = 3.0  # default cloud spacing, in pixel footprints at the reference frame's median depth


class RangeCommandError(RefineError, ValueError):
    """The range options of ``nonrigid track`` cannot be carried out as given."""


@dataclass(frozen=True)
class RangeOptions:
    """How ``nonrigid track`` uses range images.

    Attributes:
        ranges: range image files, folders or glob patterns (or an array ``(n_frames, rows, cols)``),
            one per intensity image in the same order (see :func:`tracking.load_range_images`).
        camera: the :class:`tracking.Camera` (or a camera file's path).
        mesh: the body's mesh file (any meshio format, in the camera's world axes), copied into the
            bundle as its domain.
        order: 1 (bilinear on valid pixels), 2 (least-squares quadratic on the valid pixels of a
            (2 ``radius`` + 1)^2 window: averages the depth noise down) or 3 (bicubic, all 4 x 4
            pixels valid).
        max_step: largest depth spread within a point's interpolation support (length unit); a
            larger one is an occluding edge and the point is lost there (None: no test). Clouds:
            largest depth difference from a cell's median depth (None: half the spacing).
        clouds: also write ``clouds.csv`` (with tracked points).
        clouds_only: write ``clouds.csv`` only: no images, no pattern tracked.
        cloud_spacing: spacing of the clouds' points (length unit; cells of pixels of that side at the
            reference frame's median depth, :func:`tracking.range_cloud`); None: 3 pixels.
        mask: an image file or ``(rows, cols)`` bool array: the pixels whose range makes the clouds
            (besides the ROI); None: every pixel.
        radius: half side (px) of ``order`` 2's window: 2 (5 x 5) by default; a larger one averages
            more depth noise where a pattern's pitch spans many pixels (keep the window inside a
            pitch: it smooths what is narrower than itself).
    """

    ranges: object
    camera: object
    mesh: str | Path | None = None
    order: int = 2
    max_step: float | None = None
    clouds: bool = False
    clouds_only: bool = False
    cloud_spacing: float | None = None
    mask: object = None
    radius: int = 2


def camera_from_options(camera_file=None, scale=None, origin=(0.0, 0.0), fx=None, fy=None, cx=None,
                        cy=None) -> tracking.Camera:
    """The camera the command line describes: a camera file; or fx, fy, cx, cy (perspective); or
    --scale mm per px with --origin as the pixel of x = y = 0 (orthographic)."""
    pinhole = [fx, fy, cx, cy]
    if camera_file is not None:
        if scale is not None or any(v is not None for v in pinhole):
            raise RangeCommandError("give the camera once: --camera FILE, or --fx/--fy/--cx/--cy, or --scale")
        return tracking.read_camera(camera_file)
    if any(v is not None for v in pinhole):
        if None in pinhole or scale is not None:
            raise RangeCommandError("a perspective camera needs all of --fx --fy --cx --cy (px) and no --scale")
        return tracking.Camera("perspective", fx=fx, fy=fy, cx=cx, cy=cy)
    if scale is None:
        raise RangeCommandError("give the range camera: --scale MM_PER_PX (orthographic), --fx --fy --cx --cy "
                                "(perspective, px), or --camera FILE (see docs/measurement-bundle.md)")
    return tracking.Camera("orthographic", scale=scale, cx=origin[0], cy=origin[1])


def track_range(images: Sequence, out: Path, options: RangeOptions, *, pattern: str, roi, name: str,
                model: ModelSkeleton, validate_fraction: float, seed: int, overlays, tracker_options: dict,
                reference: int, quiet: bool) -> Bundle:
    """Track images, look the points up in the range images and write a solid bundle (see the module)."""
    if not (isinstance(options.radius, (int, np.integer)) and options.radius >= 1):
        raise RangeCommandError(f"--range-radius must be a whole number of pixels >= 1, got {options.radius!r}")
    camera, mesh = _camera(options.camera), _mesh(options.mesh)
    ranges, names = _ordered(tracking.load_range_images(options.ranges), reference)
    exp = Experiment(name=name, kind="solid", domain=MeshDomain(mesh.name), law=model.law, E=model.E, nu=model.nu,
                     units={"length": "mm"}, noise_std=model.noise_std)
    clouds = None
    if options.clouds_only:
        if images:
            raise RangeCommandError("--clouds-only makes clouds from the range images alone; give no intensity images")
        clouds = _clouds(ranges, camera, options, roi)
        return _write(out, Bundle(exp, None, root=mesh.parent, clouds=clouds), camera, quiet,
                      f"wrote {out}: clouds.csv of {len(ranges)} frames "
                      f"({', '.join(str(len(p)) for p in clouds.points)} points)")
    paths = tracking.image_paths(images)
    if len(paths) != len(ranges):
        raise RangeCommandError(f"{len(paths)} images but {len(ranges)} range images; give one range image per image, "
                                "in the same order")
    if not -len(paths) <= reference < len(paths):
        raise RangeCommandError(f"--reference {reference} is not one of the {len(paths)} images")
    paths = [paths[reference]] + [p for k, p in enumerate(paths) if k != reference % len(paths)]
    stack = tracking.load_images(paths)
    if stack.shape[1:] != ranges.shape[1:]:
        raise RangeCommandError(f"the images are {stack.shape[1:]} pixels, the range images {ranges.shape[1:]}; "
                                "the range images must be registered with the intensity images, pixel for pixel")
    tracks = tracking.track_images(stack, pattern, roi=roi, **tracker_options)
    xyz, lost, why = tracking.points_3d(tracks, ranges, options.order, explain=True, camera=camera,
                                        max_step=options.max_step, radius=options.radius)
    kept = ~lost[0]
    if kept.sum() < 3:
        raise RangeCommandError(f"only {int(kept.sum())} tracked points have range data in the reference frame "
                                f"({names[0]}); a bundle needs at least 3 (lost: {tracking_reasons(why[0])})")
    roles = assign_roles(tracks.reference[kept], validate_fraction, seed, tracks.grid_index[kept])
    obs = Observations(ids=tracks.ids[kept], reference=xyz[0, kept], roles=roles,
                       displacements=xyz[1:, kept] - xyz[0, kept])
    if options.clouds:
        clouds = _clouds(ranges, camera, options, roi)
    bundle = Bundle(exp, obs, root=mesh.parent, clouds=clouds)
    _write_lost(out, tracks, why, kept)
    from refine.cli.track_overlays import write_overlays

    written = write_overlays(stack, tracks, bundle, None, None, Path(overlays or out / "overlays"), roi)
    counts = ", ".join(f"{int(np.sum(roles == r))} {r}" for r in ROLES)
    off = _off_mesh(mesh, obs.reference)
    summary = (f"tracked {tracks.n_points} points through {tracks.n_frames} images and range images: {counts}\n"
               f"  lost per frame (tracking or range): {' '.join(f'{k}:{int(n)}' for k, n in enumerate(lost.sum(1)))}\n"
               f"  left out {int((~kept).sum())} points without range in the reference frame "
               f"({tracking_reasons(why[0])}); every lost point and its reason: lost.csv\n"
               f"  reference points off {mesh.name}'s surface: median {np.median(off):.3g}, max {off.max():.3g} mm"
               f"{_pose_hint(off, obs.reference)}\n"
               f"wrote {out} (experiment.toml kind = \"solid\", {mesh.name}, points.csv, displacements.csv"
               f"{', clouds.csv' if clouds else ''}, lost.csv, camera.toml) and {len(written)} overlays")
    return _write(out, bundle, camera, quiet, summary)


def tracking_reasons(codes: np.ndarray) -> str:
    """``"3 no range data (...), 1 ..."`` for the non-zero ``codes``; ``"none"`` without any."""
    counts = lost_codes.reason_counts(codes)
    return ", ".join(f"{n} {why}" for why, n in counts.items()) or "none"


def _off_mesh(mesh: Path, points: np.ndarray) -> np.ndarray:
    """Each point's distance to the mesh's surface (a wrong camera pose shows here first), ``(n,)``."""
    import jaxfem as jf
    from jaxfem.surface import project_to_surface

    body = jf.read_mesh(mesh)
    if body.nodes.shape[1] != 3:
        raise RangeCommandError(f"--mesh {mesh} is a {body.nodes.shape[1]}D mesh; a solid bundle needs a 3D one")
    return project_to_surface(body, points)[1]


def _pose_hint(off: np.ndarray, points: np.ndarray) -> str:
    spacing = point_spacing(points)
    return (f" (more than the point spacing {spacing:.3g}: check the camera's pose, rotation and translation, "
            "which carry camera axes to the mesh's)") if np.median(off) > spacing else ""


def _camera(camera) -> tracking.Camera:
    return camera if isinstance(camera, tracking.Camera) else tracking.read_camera(camera)


def _mesh(mesh) -> Path:
    if mesh is None:
        raise RangeCommandError('a 3D bundle (model kind "solid") needs the body\'s mesh: give --mesh FILE (any '
                                "meshio format, in the camera's world axes: see the camera's pose)")
    path = Path(mesh)
    if not path.is_file():
        raise RangeCommandError(f"mesh file not found: {path}")
    return path


def _ordered(loaded, reference: int):
    stack, names = loaded
    if not -len(stack) <= reference < len(stack):
        raise RangeCommandError(f"--reference {reference} is not one of the {len(stack)} range images")
    order = [reference % len(stack)] + [k for k in range(len(stack)) if k != reference % len(stack)]
    return stack[order], [names[k] for k in order]


def _clouds(ranges: np.ndarray, camera: tracking.Camera, options: RangeOptions, roi) -> Clouds:
    mask = np.ones(ranges.shape[1:], bool)
    if roi is not None:
        mask &= tracking.roi_mask(roi, ranges.shape[1:])
    if options.mask is not None:
        drawn = options.mask if isinstance(options.mask, np.ndarray) else tracking.load_images(options.mask)[0]
        if drawn.shape != mask.shape:
            raise RangeCommandError(f"--mask is {drawn.shape} pixels, the range images {mask.shape}")
        mask &= np.asarray(drawn) != 0
    depth = float(np.nanmedian(ranges[0][mask])) if np.isfinite(ranges[0][mask]).any() else None
    if depth is None:
        raise RangeCommandError("the reference range image has no data inside --roi / --mask")
    spacing = options.cloud_spacing or CLOUD_FOOTPRINTS * camera.footprint(depth)
    return Clouds(tuple(tracking.range_cloud(r, camera, spacing, mask, depth, options.max_step) for r in ranges))


def _write_lost(out: Path, tracks: tracking.Tracks, why: np.ndarray, kept: np.ndarray) -> None:
    """``lost.csv``: ``frame,id,u,v,reason`` for every point lost in a frame (u, v: its tracked pixel,
    empty where tracking lost it); a point left out for want of a reference depth is listed in every
    frame (``not measured in the reference frame`` where nothing else failed there)."""
    out.mkdir(parents=True, exist_ok=True)
    codes = np.where(~kept[None] & (why == lost_codes.MEASURED), lost_codes.NO_REFERENCE, why)
    with open(out / "lost.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["frame", "id", "u", "v", "reason"])
        for frame, i in zip(*np.nonzero(codes)):
            u, v = tracks.positions[frame, i]
            w.writerow([int(frame), int(tracks.ids[i]), "" if np.isnan(u) else f"{u:.3f}",
                        "" if np.isnan(v) else f"{v:.3f}", lost_codes.LOST_REASONS[int(codes[frame, i])]])


def _write(out: Path, bundle: Bundle, camera: tracking.Camera, quiet: bool, summary: str) -> Bundle:
    import tomli_w

    write_bundle(out, bundle)
    mesh = bundle.root / bundle.experiment.domain.path
    if not (out / mesh.name).is_file():  # write_bundle copies a mesh with observations only
        shutil.copyfile(mesh, out / mesh.name)
    (out / "camera.toml").write_text("# the range camera `nonrigid track` used (tracking.read_camera reads it)\n"
                                     + tomli_w.dumps(camera.to_toml()), encoding="utf-8")
    path = out / "experiment.toml"
    path.write_text("# written by `nonrigid track --range`: 3D points from range images (camera.toml)\n"
                    "# CHECK: the [material] section comes from the command line flags (or their defaults)\n\n"
                    + path.read_text(encoding="utf-8"), encoding="utf-8")
    if not quiet:
        print(summary)
    return read_bundle(out)
