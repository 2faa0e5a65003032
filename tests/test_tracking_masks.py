"""Things in view that are not the pattern: a hole, the specimen's edge on a dark background, glare.

The trackers find the pattern's extent (a mask), measure on the material only, list the rest
with a reason and give the material's outline (its polygon and its holes' polygons).
"""

import os
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import LinearNDInterpolator

from tracking import GridTracker, SpeckleTracker, load_images, read_dice, render_speckle
from tracking._lost import LOST_REASONS
from tracking._synthetic import Scene, clamped_displacement
from test_tracking_motion import CLAMP, PITCH, _grid_sequence, check_grid_tracks


def _centroid(polygon):
    """Area centroid (2,) of a closed polygon (k, 2)."""
    x, y = polygon.T
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    return np.array([np.sum((x + np.roll(x, -1)) * cross), np.sum((y + np.roll(y, -1)) * cross)]) / (3 * cross.sum())


def _hole_scene(seed):
    rng = np.random.default_rng(seed)
    return Scene(specimen=(-100.0, 30.0, 190.0, 150.0),
                 holes=((rng.uniform(90, 140), rng.uniform(80, 100), rng.uniform(14, 20)),))


@pytest.mark.parametrize("seed", [0, 1])
def test_grid_with_a_hole_tracks_around_it_and_outlines_it(seed):
    scene = _hole_scene(seed)
    strain = 0.9 * PITCH / (190.0 - CLAMP)
    images, fields = _grid_sequence([0.0, strain, 2 * strain], 10 + seed, scene)
    tracks = GridTracker().track(images)                    # no ROI: the hole sits in the middle
    rms = check_grid_tracks(tracks, fields, scene)          # no point in the hole, no slip
    assert max(rms) <= 0.05, rms
    hx, hy, radius = scene.holes[0]
    holes = tracks.meta["outline"]["holes"]
    assert len(holes) == 1
    assert np.linalg.norm(_centroid(holes[0]) - (hx, hy)) < 0.3 * PITCH
    assert tracks.meta["excluded"].get(LOST_REASONS[1], 0) > 0
    # every crossing on material, a pitch or more from its edges and the image's, is measured
    x, y = tracks.reference.T
    away = scene.material(x, y, margin=PITCH) & (x > PITCH)
    assert away.sum() > 100 and not tracks.lost[:, away].any()


def test_grid_specimen_edge_on_dark_background_and_its_outline():
    scene = Scene(specimen=(25.0, 30.0, 190.0, 150.0))
    images, fields = _grid_sequence([0.0, 0.03, 0.06], 20, scene)
    tracks = GridTracker().track(images)
    rms = check_grid_tracks(tracks, fields, scene)
    assert max(rms) <= 0.05, rms
    outer = tracks.meta["outline"]["outer"]
    assert np.allclose(outer.min(axis=0), (25, 30), atol=4) and np.allclose(outer.max(axis=0), (190, 150), atol=4)
    assert tracks.meta["outline"]["holes"] == []


def test_grid_glare_patch_is_left_out_with_its_reason():
    scene = Scene(specimen=(-100.0, 30.0, 190.0, 150.0), glare=(110.0, 95.0, 10.0, 170.0))
    strain = 0.9 * PITCH / (190.0 - CLAMP)
    images, fields = _grid_sequence([0.0, strain, 2 * strain], 30, scene)
    tracks = GridTracker().track(images)
    rms = check_grid_tracks(tracks, fields, scene)
    assert max(rms) <= 0.05, rms
    saturated = LOST_REASONS[2]
    seen = tracks.meta["excluded"].get(saturated, 0) + int(np.sum(tracks.meta["lost_reasons"] == 2))
    assert seen > 0
    assert np.all(np.hypot(tracks.reference[:, 0] - 110, tracks.reference[:, 1] - 95) > 10)


def test_speckle_with_a_hole_and_edges_has_no_point_off_the_material():
    scene = Scene(specimen=(20.0, -50.0, 150.0, 250.0), holes=((85.0, 100.0, 22.0),))
    field = clamped_displacement(0.0, 0.0, 0.3, 100.0, shift=(1.3, -2.1))
    images = [render_speckle((200, 170), 1.2, None, noise_sigma=1.0, scene=scene, seed=1),
              render_speckle((200, 170), 1.2, field, noise_sigma=1.0, scene=scene, seed=2)]
    tracks = SpeckleTracker(spacing=8, subset=15).track(images)
    x, y = tracks.reference.T
    assert scene.material(x, y, margin=2.0).all()    # subsets may reach a few px past the edge
    assert tracks.n_points > 150
    moved = ~tracks.lost[1]
    error = np.linalg.norm(tracks.displacements()[1][moved] - (1.3, -2.1), axis=1)
    assert np.sqrt(np.mean(error ** 2)) <= 0.05
    hole = tracks.meta["outline"]["holes"]
    assert len(hole) == 1 and np.linalg.norm(_centroid(hole[0]) - (85, 100)) < 2.0


def _shared() -> Path:
    return Path(os.environ.get("NONRIGID_SHARED", Path(__file__).resolve().parents[1] / ".." / "shared"))


@pytest.mark.slow
def test_dic_challenge_sample12_agrees_with_dice_away_from_the_hole():
    folder = _shared() / "data" / "dic-challenge-sample12"
    if not folder.is_dir():
        pytest.skip(f"DIC Challenge Sample 12 not found at {folder} (set NONRIGID_SHARED)")
    tracks = SpeckleTracker().track(load_images(sorted(folder.glob("oht_cfrp_*.tiff"))))
    dice = read_dice(folder / "dice-solution")
    hole_centre, hole_radius, subset = np.array([194.0, 543.0]), 51.0, 27.0   # DICe's excluded circle
    assert np.all(np.linalg.norm(tracks.reference - hole_centre, axis=1) > hole_radius)
    holes = tracks.meta["outline"]["holes"]
    assert len(holes) == 1 and np.linalg.norm(_centroid(holes[0]) - hole_centre) < 5.0
    seen = ~tracks.lost[-1]
    ours = LinearNDInterpolator(tracks.reference[seen], tracks.displacements()[-1][seen])
    away = (np.linalg.norm(dice.reference - hole_centre, axis=1) > hole_radius + subset) & ~dice.lost[-1]
    # our tracker keeps a subset only where its whole square lies on textured material (tracks.meta's
    # material_mask); DICe's outermost column (x = 341 px, its 27 px subset to 354) reaches the coupon's
    # texture-less right edge (material to x = 342-354), where ours stop at x = 334: compared where DICe's
    # subset lies on our material (measured: 197 of DICe's 227 points away from the hole; all 27 outside
    # our points' hull are among the 30 left out)
    half = int(subset) // 2
    material = tracks.meta["material_mask"]
    on_material = np.array([material[y - half:y + half + 1, x - half:x + half + 1].all()
                            for x, y in np.rint(dice.reference).astype(int)])
    assert on_material[away].mean() > 0.85
    away &= on_material
    error = np.linalg.norm(ours(dice.reference[away]) - dice.displacements()[-1][away], axis=1)
    assert np.isfinite(error).mean() > 0.95
    error = error[np.isfinite(error)]
    assert np.median(error) <= 0.02 and np.percentile(error, 95) <= 0.05, (np.median(error), np.percentile(error, 95))


@pytest.mark.parametrize("seed", [0, 1])
def test_speckle_mask_ends_at_the_material_edge(seed):
    """The mask's edge against a known straight edge and a known hole (random under seeds): within
    3.5 px (it reached 4.7-5.3 px past them when a blur, not a median, took the level off the image)."""
    from tracking._pattern_mask import pattern_mask
    rng = np.random.default_rng(seed)
    xe, (hx, hy), r = rng.uniform(120, 140), rng.uniform(50, 70, 2), rng.uniform(14, 20)
    scene = Scene(specimen=(-50.0, -50.0, xe, 300.0), holes=((hx, hy, r),))
    image = render_speckle((130, 170), 1.2, None, noise_sigma=1.0, scene=scene, seed=seed, pattern_seed=seed,
                           quantize=True)
    mask = pattern_mask(image, 21)
    last = np.array([np.nonzero(mask[row])[0].max() for row in range(20, 110)]) + 0.5
    assert abs(np.median(last - xe)) <= 3.5
    yy, xx = np.mgrid[0:130, 0:170]
    near = (xx - hx) ** 2 + (yy - hy) ** 2 < (r + 10) ** 2
    assert abs(r - np.sqrt(np.sum(~mask & near) / np.pi)) <= 3.5
