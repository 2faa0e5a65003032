"""DIC exports read as tracks (tracking.read_dice, read_displacement_csv) and image inputs given as
folders, globs or multi-page TIFFs in natural order."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import tracking
from tracking._exports import ExportError, read_dice, read_displacement_csv, write_dice
from tracking._images import image_paths, load_images

SAMPLE12 = Path(__file__).resolve().parents[2] / "shared" / "data" / "dic-challenge-sample12"


def _random_tracks(seed: int, n: int = 40, frames: int = 4) -> tracking.Tracks:
    rng = np.random.default_rng(seed)
    ref = rng.uniform(0, 500, (n, 2))
    u = np.cumsum(rng.normal(0, 1.5, (frames, n, 2)), axis=0)
    u[0] = 0.0
    lost = rng.random((frames, n)) < 0.1
    lost[0] = False
    pos = np.where(lost[..., None], np.nan, ref + u)
    quality = np.where(lost, 0.0, -rng.uniform(0, 0.02, (frames, n)))
    quality[0] = 0.0
    return tracking.Tracks(ids=rng.permutation(1000)[:n], reference=ref, positions=pos, lost=lost, quality=quality,
                           grid_index=np.full((n, 2), -1))


def test_a_dice_export_written_from_known_tracks_reads_back_equal(tmp_path):
    t = _random_tracks(3)
    files = write_dice(tmp_path, t)
    assert len(files) == t.n_frames - 1
    back = read_dice(tmp_path)
    np.testing.assert_array_equal(back.ids, t.ids)
    np.testing.assert_array_equal(back.lost, t.lost)
    np.testing.assert_allclose(back.positions, t.positions, rtol=0, atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(back.quality[1:], t.quality[1:], atol=1e-12)


def test_dice_files_are_taken_in_natural_order_and_matched_by_subset_id(tmp_path):
    t = _random_tracks(5, frames=12)
    write_dice(tmp_path, t)
    for p in tmp_path.glob("*.txt"):  # DICe_solution_02 -> DICe_solution_2: lexical order would put 10 before 2
        p.rename(p.with_name(p.name.replace("_0", "_")))
    back = read_dice(tmp_path)
    np.testing.assert_allclose(back.positions, t.positions, atol=1e-9, equal_nan=True)


def test_a_failed_dice_subset_is_lost_and_bad_files_are_named(tmp_path):
    t = _random_tracks(7)
    files = write_dice(tmp_path, t)
    text = files[0].read_text().replace("COORDINATE_Y,", "")
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "DICe_solution_1.txt").write_text(text)
    with pytest.raises(ExportError, match="missing column"):
        read_dice(tmp_path / "broken")
    with pytest.raises(ExportError, match="not found"):
        read_dice(tmp_path / "nothing.txt")


def test_a_csv_export_in_one_file_or_one_file_per_frame(tmp_path):
    t = _random_tracks(11)
    u = t.displacements()
    one = ["frame,id,x,y,ux,uy"]
    for k in range(1, t.n_frames):
        per = ["x,y,ux,uy"]
        for i in range(t.n_points):
            ux, uy = ("", "") if t.lost[k, i] else (repr(float(u[k, i, 0])), repr(float(u[k, i, 1])))
            x, y = (repr(float(v)) for v in t.reference[i])
            one.append(f"{k},{t.ids[i]},{x},{y},{ux},{uy}")
            per.append(f"{x},{y},{ux},{uy}")
        (tmp_path / f"frame_{k}.csv").write_text("\n".join(per) + "\n")
    (tmp_path / "all.csv").write_text("\n".join(one) + "\n")
    a = read_displacement_csv(tmp_path / "all.csv")
    np.testing.assert_array_equal(a.ids, t.ids)
    np.testing.assert_allclose(a.positions, t.positions, atol=1e-9, equal_nan=True)
    per_frame = sorted(tmp_path.glob("frame_*.csv"))
    b = read_displacement_csv(per_frame)
    np.testing.assert_allclose(b.positions, t.positions, atol=1e-9, equal_nan=True)
    np.testing.assert_array_equal(b.lost, t.lost)


def test_image_folders_globs_and_multipage_tiffs_load_in_natural_order(tmp_path):
    tifffile = pytest.importorskip("tifffile")
    rng = np.random.default_rng(0)
    frames = [(rng.random((16, 20)) * 60000).astype(np.uint16) for _ in range(11)]
    for k, f in enumerate(frames):
        tifffile.imwrite(tmp_path / f"img_{k}.tif", f)
    names = [p.name for p in image_paths(tmp_path)]
    assert names[:3] == ["img_0.tif", "img_1.tif", "img_2.tif"] and names[-1] == "img_10.tif"
    stack = load_images(str(tmp_path / "img_*.tif"))
    np.testing.assert_array_equal(stack, np.stack(frames).astype(float))  # 16-bit values kept
    tifffile.imwrite(tmp_path / "stack.tiff", np.stack(frames[:3]), photometric="minisblack")
    np.testing.assert_array_equal(load_images(tmp_path / "stack.tiff"), np.stack(frames[:3]).astype(float))
    with pytest.raises(tracking.ImageError, match="matches no file"):
        load_images(str(tmp_path / "nothing_*.png"))


@pytest.mark.skipif(not SAMPLE12.is_dir(), reason="needs ../shared/data/dic-challenge-sample12 (DIC Challenge images)")
def test_the_dice_solutions_of_sample12_read_as_tracks():
    t = read_dice(SAMPLE12 / "dice-solution")
    assert (t.n_frames, t.n_points) == (12, 230)
    assert t.units == "px" and not t.lost.any()
    v = t.displacements()[-1, :, 1]
    assert 4.0 < np.nanmax(np.abs(v)) < 20.0  # the coupon is pulled along y by several pixels
