"""Tracking points through images of a deforming object: painted grids and speckle patterns.

Images go in, :class:`Tracks` (identities, positions per frame, lost flags, quality) come out;
nothing here knows of finite elements.

    tracks = track_images(load_images(paths), pattern="grid", roi=(40, 30, 600, 420))
    ranges, _ = load_range_images("scans/*.npy")           # depth in mm, NaN where no data
    camera = Camera("perspective", fx=2400.0, fy=2400.0, cx=320.0, cy=240.0)
    xyz, lost = points_3d(tracks, ranges, order=2, camera=camera)   # 3D, sub-pixel, holes lost
    mm = tracks.to_length(scale_from_grid(tracks, pitch_mm=2.0))
"""

from ._api import TRACKERS, make_tracker, track_images
from ._errors import GridNotFoundError, ImageError, OptionError, RoiError, TrackingError
from ._exports import ExportError, read_dice, read_displacement_csv, regular_lattice, write_dice
from ._grid_tracker import REFINERS, GridTracker
from ._images import image_paths, load_images, natural_key, roi_mask
from ._lost import LOST_REASONS
from ._pattern_mask import material_outline, pattern_mask
from ._camera import Camera, camera_from_table, read_camera
from ._range import points_3d, range_lookup
from ._range_cloud import cell_pixels, range_cloud
from ._range_io import load_range_images, range_paths
from ._snake import SnakeOptions
from ._speckle_tracker import SpeckleTracker
from ._synthetic import (GridPattern, Scene, SpecklePattern, clamped_displacement, creased_displacement,
                         deformed_points, grid_truth, render_grid, render_pattern, render_range, render_speckle,
                         scaled, smooth_displacement)
from ._tracks import Tracks, scale_from_grid

__all__ = [
    "Tracks", "track_images", "make_tracker", "TRACKERS", "GridTracker", "SpeckleTracker",
    "SnakeOptions", "REFINERS", "load_images", "roi_mask", "range_lookup", "points_3d",
    "scale_from_grid", "render_grid", "render_speckle", "render_range",
    "render_pattern", "grid_truth", "deformed_points", "smooth_displacement", "creased_displacement", "scaled",
    "GridPattern", "SpecklePattern",
    "TrackingError", "ImageError", "RoiError", "GridNotFoundError", "OptionError",
    "read_dice", "regular_lattice", "write_dice", "read_displacement_csv", "ExportError", "image_paths", "natural_key",
    "Scene", "clamped_displacement", "LOST_REASONS", "pattern_mask", "material_outline",
    "Camera", "read_camera", "camera_from_table", "load_range_images", "range_paths", "range_cloud", "cell_pixels",
]
