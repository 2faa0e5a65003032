"""What ``measurement.subset`` promises is true of what the speckle tracker writes: every tracked
point's whole square subset lies on material (a hole's texture-less disc is not reached by more
than a pixel), and the rule is not bought by dropping subsets that clear the hole.

Generated speckle images with a dark hole drawn at random (place, radius, speckle size) under
seeds, tracked with the tracker's defaults; and the DIC Challenge's CFRP coupon, whose hole is
measured from the pixels apart from the tracker (a dark disc, as benchmarks/cfrp.py measures it).
Before the texture-less edge was read at the pixel scale, the squares reached 1.6-3.9 px into
generated holes (the speckle mask's 3-px smoothing) and 1.4 px into the CFRP coupon's disc."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tracking import LOST_REASONS, Scene, SpeckleTracker, render_speckle
from tracking._lost import SUBSET_EDGE
from tracking._synthetic import clamped_displacement

SAMPLE = Path(__file__).resolve().parents[2] / "shared" / "data" / "dic-challenge-sample12"
DEPTH = 0.5   # px: how far a tracked subset's pixel centres may reach into the hole
CLEAR = 6.0   # px: a lattice site whose subset clears the hole by this much must be tracked


def _square_depth(points: np.ndarray, subset: int, depth_of) -> np.ndarray:
    """The largest ``depth_of(x, y)`` over each point's square of pixel centres, ``(n,)``."""
    off = np.arange(-(subset // 2), subset // 2 + 1)
    return np.array([depth_of(*np.meshgrid(x + off, y + off)).max() for x, y in np.rint(points)])


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_no_tracked_subset_reaches_into_a_generated_hole_and_clear_ones_are_kept(seed):
    rng = np.random.default_rng(5200 + seed)  # not the seeds the rule was measured on (4100-4111)
    shape = (200, 200)
    hx, hy, r = rng.uniform(70, 130), rng.uniform(70, 130), rng.uniform(15, 35)
    scene = Scene(holes=((hx, hy, r),))
    field = clamped_displacement(0.0, 0.002, 0.3, 100.0, shift=tuple(rng.uniform(-2, 2, 2)))
    speckle = rng.uniform(1.0, 1.8)
    images = [render_speckle(shape, speckle, u, noise_sigma=1.0, scene=scene, seed=seed + k, pattern_seed=seed,
                             quantize=True) for k, u in enumerate((None, field))]
    tracker = SpeckleTracker()
    tracks = tracker.track(images)

    def depth(x, y):  # px into the hole (negative: outside)
        return r - np.hypot(x - hx, y - hy)

    reached = _square_depth(tracks.reference, tracker.subset, depth)
    assert reached.max() <= DEPTH, reached.max()
    sites, _ = tracker.points(np.ones(shape, bool))
    clearance = -_square_depth(sites, tracker.subset, depth)
    tracked = {tuple(p) for p in np.rint(tracks.reference).astype(int)}
    dropped = [c for s, c in zip(np.rint(sites).astype(int), clearance) if tuple(s) not in tracked]
    assert max(dropped) < CLEAR, max(dropped)
    assert tracks.meta["material_mask"].sum() <= tracks.meta["pattern_mask"].sum()
    assert set(tracks.meta["excluded"]) <= set(LOST_REASONS.values())


@pytest.mark.skipif(not SAMPLE.exists(), reason="../shared/data/dic-challenge-sample12 is absent")
def test_no_tracked_subset_reaches_into_the_cfrp_coupons_dark_disc():
    cv2 = pytest.importorskip("cv2")
    from scipy import ndimage

    first = cv2.imread(str(SAMPLE / "oht_cfrp_00.tiff"), cv2.IMREAD_GRAYSCALE)
    second = cv2.imread(str(SAMPLE / "oht_cfrp_01.tiff"), cv2.IMREAD_GRAYSCALE)
    label, _ = ndimage.label(cv2.medianBlur(first, 11) < 40)   # the hole as the pixels show it
    disc = ndimage.binary_fill_holes(label == label[541, 192])
    inside = ndimage.distance_transform_edt(disc)              # px into the disc, 0 outside
    tracker = SpeckleTracker()
    tracks = tracker.track([first, second])
    reached = _square_depth(tracks.reference, tracker.subset, lambda x, y: inside[y.astype(int), x.astype(int)])
    assert reached.max() <= DEPTH, reached.max()
    assert tracks.meta["excluded"][LOST_REASONS[SUBSET_EDGE]] > 0
    assert tracks.reference.shape[0] > 2700


def test_a_tracked_bundles_subsets_leave_the_true_hole_free(tmp_path):
    """What refine reads (``measurement.subset`` in the bundle's unit, each point's square of that
    side, :func:`refine.diagnosis.subsets.subset_distance`) leaves the true hole free: the hole a
    fit may grow to holds the true one, to the squares' pixel footprint (half a pixel wider than
    their pixel centres along the axes, half a diagonal at the corners)."""
    cv2 = pytest.importorskip("cv2")
    from refine.cli import track
    from refine.diagnosis.subsets import subset_distance

    rng = np.random.default_rng(5300)
    hx, hy, r = rng.uniform(80, 120), rng.uniform(80, 120), rng.uniform(20, 35)
    scene = Scene(holes=((hx, hy, r),))
    field = clamped_displacement(0.0, 0.002, 0.3, 100.0, shift=(0.7, -1.2))
    paths = []
    for k, u in enumerate((None, field)):
        paths.append(tmp_path / f"f{k}.png")
        cv2.imwrite(str(paths[-1]), render_speckle((200, 200), 1.3, u, noise_sigma=1.0, scene=scene, seed=k,
                                                   quantize=True).astype(np.uint8))
    scale = 0.25
    bundle = track(paths, tmp_path / "b", pattern="speckle", scale=scale, cut_holes=False, quiet=True)
    assert bundle.experiment.subset == pytest.approx(SpeckleTracker().subset * scale)
    clear = subset_distance(bundle.observations.reference, (hx * scale, hy * scale, r * scale, r * scale, 0.0),
                            bundle.experiment.subset) / scale
    assert clear.min() >= -(DEPTH + 0.5 * np.sqrt(2)), clear.min()
    assert clear.min() < CLEAR, clear.min()   # and the ring of kept subsets reaches the hole
