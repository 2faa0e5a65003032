"""``nonrigid track`` cuts the holes the tracker finds in the pattern from the bundle's domain, so
the model follows the material; ``--keep-holes`` leaves the domain whole for ``diagnose``."""

from __future__ import annotations

import numpy as np
import pytest

import jaxfem as jf
from refine.cli import track
from test_tracking_masks import _centroid, _hole_scene
from test_tracking_motion import PITCH, _grid_sequence

SCALE = 0.2  # mm per pixel


@pytest.fixture(scope="module")
def holed_images(tmp_path_factory):
    cv2 = pytest.importorskip("cv2")
    scene = _hole_scene(3)
    images, _ = _grid_sequence([0.0, 0.3 * PITCH / 200.0], 13, scene)
    folder = tmp_path_factory.mktemp("holed")
    paths = []
    for k, im in enumerate(images):
        paths.append(folder / f"frame_{k}.png")
        cv2.imwrite(str(paths[-1]), np.clip(np.rint(im), 0, 255).astype(np.uint8))
    return paths, scene


def test_a_hole_in_the_pattern_is_cut_from_the_domain(holed_images, tmp_path):
    paths, scene = holed_images
    bundle = track(paths, tmp_path / "b", scale=SCALE, quiet=True)
    holes = bundle.experiment.domain.holes
    assert len(holes) == 1
    hx, hy, radius = scene.holes[0]
    hole = np.asarray(holes[0])
    assert np.linalg.norm(_centroid(hole) - np.array([hx, hy]) * SCALE) < 0.3 * PITCH * SCALE
    assert not jf.Polygon(hole).contains(bundle.observations.reference).any()  # no point in the hole
    kept = track(paths, tmp_path / "c", scale=SCALE, quiet=True, cut_holes=False)
    assert kept.experiment.domain.holes == ()
    assert kept.observations.n_points == bundle.observations.n_points


def test_the_reference_frame_can_be_any_image_and_folders_expand_in_natural_order(holed_images, tmp_path):
    paths, _ = holed_images
    first = track([paths[0].parent], tmp_path / "a", scale=SCALE, quiet=True)       # a folder
    second = track(paths[::-1], tmp_path / "b", scale=SCALE, quiet=True, reference=1)
    np.testing.assert_allclose(second.observations.reference, first.observations.reference)
    np.testing.assert_allclose(second.observations.displacements, first.observations.displacements)
