"""``nonrigid import``: DIC exports (DICe solution files, plain CSV) to measurement bundles."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import tracking
from refine.bundle import read_bundle, write_bundle
from refine.cli import import_export
from refine.cli.main import main
from refine.exceptions import RefineError

SAMPLE12 = Path(__file__).resolve().parents[2] / "shared" / "data" / "dic-challenge-sample12"


def _lattice_tracks(seed: int, scale: float) -> tracking.Tracks:
    """A lattice of DIC points (step 35 px, a hole left out) moving smoothly over 3 frames."""
    rng = np.random.default_rng(seed)
    cols, rows = np.meshgrid(np.arange(9), np.arange(7))
    keep = np.hypot(cols - 4.2, rows - 3.1) > 1.3  # a hole in the region of interest
    index = np.c_[rows[keep], cols[keep]]
    ref = 40.0 + 35.0 * index[:, ::-1].astype(float)
    strain = rng.uniform(0.01, 0.03)
    u = np.stack([np.c_[0.2 * k * strain * (ref[:, 0] - 40), k * strain * (ref[:, 1] - 40)] for k in range(4)])
    u[1:] += rng.normal(0, 0.01, u[1:].shape)
    lost = np.zeros(u.shape[:2], bool)
    lost[2, rng.integers(len(ref))] = True
    pos = np.where(lost[..., None], np.nan, ref + u)
    return tracking.Tracks(ids=np.arange(len(ref)) + 100, reference=ref, positions=pos, lost=lost,
                           quality=np.zeros(lost.shape), grid_index=np.full((len(ref), 2), -1))


def test_a_dice_export_written_from_known_tracks_imports_as_the_same_bundle(tmp_path):
    t = _lattice_tracks(1, 0.05)
    tracking.write_dice(tmp_path / "dice", t)
    b = import_export(tmp_path / "dice", tmp_path / "b", format="dice", scale=0.05, origin=(40.0, 40.0), quiet=True)
    obs = b.observations
    order = np.argsort(obs.ids)
    np.testing.assert_array_equal(obs.ids[order], t.ids)
    np.testing.assert_allclose(obs.reference[order], (t.reference - 40.0) * 0.05, atol=1e-9)
    np.testing.assert_allclose(obs.displacements[:, order], t.displacements()[1:] * 0.05, atol=1e-9, equal_nan=True)
    assert (obs.roles == "boundary").sum() >= 24  # the lattice's outer ring, not the hull's corners
    assert not (obs.roles[order][np.hypot(t.reference[:, 0] - 187, t.reference[:, 1] - 148.5) < 60] == "boundary").any()
    again = tmp_path / "again"
    write_bundle(again, read_bundle(tmp_path / "b"))
    np.testing.assert_array_equal(read_bundle(again).observations.displacements, obs.displacements)


def test_a_csv_export_imports_from_the_command_line(tmp_path, capsys):
    t = _lattice_tracks(2, 1.0)
    u = t.displacements()
    lines = ["frame,id,x,y,ux,uy"]
    for k in range(1, t.n_frames):
        for i in range(t.n_points):
            ux, uy = ("", "") if t.lost[k, i] else (repr(float(u[k, i, 0])), repr(float(u[k, i, 1])))
            lines.append(f"{k},{t.ids[i]},{float(t.reference[i, 0])!r},{float(t.reference[i, 1])!r},{ux},{uy}")
    (tmp_path / "export.csv").write_text("\n".join(lines) + "\n")
    assert main(["import", "--format", "csv", str(tmp_path / "export.csv"), "--out", str(tmp_path / "b"),
                 "--noise-std", "0.01"]) == 0
    assert "imported" in capsys.readouterr().out
    b = read_bundle(tmp_path / "b")
    assert b.experiment.noise_std == 0.01 and b.observations.n_frames == 3
    order = np.argsort(b.observations.ids)
    np.testing.assert_allclose(b.observations.displacements[:, order], u[1:], atol=1e-9, equal_nan=True)


def test_import_refuses_what_it_cannot_use(tmp_path, capsys):
    t = _lattice_tracks(3, 1.0)
    tracking.write_dice(tmp_path / "dice", t)
    with pytest.raises(RefineError, match="--scale"):
        import_export(tmp_path / "dice", tmp_path / "b", format="dice")
    assert main(["import", "--format", "dice", str(tmp_path / "nothing"), "--scale", "1", "--out",
                 str(tmp_path / "c")]) == 2
    assert "not found" in capsys.readouterr().err


@pytest.mark.skipif(not SAMPLE12.is_dir(), reason="needs ../shared/data/dic-challenge-sample12 (DICe's solutions)")
def test_dice_results_of_the_cfrp_coupon_import_with_their_hole_out(tmp_path):
    b = import_export(SAMPLE12 / "dice-solution", tmp_path / "b", format="dice", scale=0.05, quiet=True)
    obs = b.observations
    assert obs.n_frames == 11 and obs.n_points >= 220
    # DICe's region of interest leaves the hole out: no point there, and none of its rim is boundary
    centre = np.array([194.0, 543.0]) * 0.05
    d = np.linalg.norm(obs.reference - centre, axis=1)
    assert d.min() > 51 * 0.05
    assert not (obs.roles[d < 51 * 0.05 + 2.5] == "boundary").any()
