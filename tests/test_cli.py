"""The command functions of ``refine.cli`` called from Python do what the commands do;
``nonrigid --version``; the parser imports no JAX.

``diagnose`` and ``demo`` take minutes; the end-to-end test (tests/test_end_to_end.py) calls
:func:`refine.cli.track` then the diagnosis.
"""

import importlib.metadata
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from refine.bundle import (Bundle, Experiment, ModelSkeleton, Observations, RectangleDomain, read_bundle,
                           write_bundle)
from refine.cli import main, simulate, track
from refine.cli.track import TrackCommandError


@pytest.fixture(scope="module")
def small_bundle(tmp_path_factory):
    """A 40 x 30 mm region on a 10 mm grid stretched uniformly (exact for the uniform model), two frames."""
    x, y = np.meshgrid(np.arange(20.0, 61.0, 10.0), np.arange(10.0, 41.0, 10.0))
    reference = np.stack([x.ravel(), y.ravel()], axis=1)
    on_edge = (x.ravel() % 40 == 20) | (y.ravel() % 30 == 10)
    roles = np.where(on_edge, "boundary", "guide")
    roles[[6, 8]] = "validate"
    stretch = np.array([[0.04, 0.0], [0.0, -0.012]])
    displacements = np.stack([f * (reference - [20.0, 10.0]) @ stretch.T for f in (0.5, 1.0)])
    experiment = Experiment(name="small", kind="plane-stress", domain=RectangleDomain(20.0, 10.0, 60.0, 40.0),
                            law="neo-hookean", E=1.0, nu=0.3, thickness=1.0, units={"length": "mm"})
    path = tmp_path_factory.mktemp("bundle") / "small"
    write_bundle(path, Bundle(experiment, Observations(np.arange(1, 21), reference, roles, displacements)))
    return path


def test_simulate_from_python(small_bundle, tmp_path, capsys):
    summary = simulate(small_bundle, tmp_path / "sim")
    assert {"frames", "points", "cells", "newton_iterations", "seconds", "guide_error", "validate_error",
            "tracking_error"} <= set(summary)
    assert summary["frames"] == 2 and summary["points"] == 20
    assert summary["validate_error"] < 1e-6  # a uniform stretch: the model reproduces it
    text = capsys.readouterr().out.splitlines()
    assert text[0].startswith(f"simulated 2 frames of 'small' on {summary['cells']} cells "
                              f"({summary['newton_iterations']} Newton iterations, ")
    assert text[1:4] == [f"  guide error: {summary['guide_error']:.4g}",
                         f"  validate error: {summary['validate_error']:.4g}",
                         f"  tracking error: {summary['tracking_error']:.4g}"]
    assert text[4] == f"  wrote {tmp_path / 'sim' / 'displacements.csv'} and 2 strain maps"
    assert sorted(p.name for p in (tmp_path / "sim").iterdir()) == [
        "displacements.csv", "paraview", "strain_frame01.png", "strain_frame02.png"]
    predicted = read_bundle(small_bundle).observations.displacements  # the same format, so read it as data
    # ParaView: the model and the points, one VTU per frame, read back with meshio
    import meshio

    from jaxfem import read_pvd

    for name, fields in (("model", {"displacement", "green_lagrange_strain", "principal_strain_1", "principal_strain_2",
                                    "equivalent_strain", "modulus", "region"}),
                         ("points", {"measured_displacement", "predicted_model", "residual_model", "role", "id"})):
        steps = read_pvd(tmp_path / "sim" / "paraview" / f"{name}.pvd")
        assert [t for t, _ in steps] == [1.0, 2.0]
        last = meshio.read(steps[-1][1])
        assert fields <= set(last.point_data) | set(last.cell_data)
    assert np.abs(last.point_data["residual_model"]).max() < 1e-6
    np.testing.assert_allclose(last.point_data["measured_displacement"][:, :2], predicted[1], atol=1e-12)
    written = np.loadtxt(tmp_path / "sim" / "displacements.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(written[:, 2:].reshape(2, 20, 2), predicted, atol=1e-6)


def test_a_missing_bundle_is_an_error_of_the_command(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "nowhere"), "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.startswith("nonrigid simulate: error:")


@pytest.fixture(scope="module")
def grid_images(tmp_path_factory):
    from tracking import render_grid, scaled, smooth_displacement

    folder = tmp_path_factory.mktemp("images")
    shape = (120, 160)
    field = smooth_displacement(shape, stretch=0.04, seed=1)
    paths = []
    for k in range(2):
        image = render_grid(shape, 12.0, 2.0, None if k == 0 else scaled(field, 1.0), noise_sigma=2.0, seed=k)
        paths.append(folder / f"frame{k}.png")
        cv2.imwrite(str(paths[-1]), np.clip(np.rint(image), 0, 255).astype(np.uint8))
    return paths


def test_track_from_python_writes_what_the_command_writes(grid_images, tmp_path, capsys):
    bundle = track(grid_images, tmp_path / "py", scale=0.5, roi=(20, 20, 140, 100),
                   model=ModelSkeleton(E=2.0, noise_std=0.01), seed=4, quiet=True)
    assert capsys.readouterr().out == ""
    assert bundle.root == tmp_path / "py" and bundle.experiment.name == "py"
    assert (bundle.experiment.E, bundle.experiment.noise_std) == (2.0, 0.01)
    assert bundle.observations.n_frames == 1 and np.isin(["boundary", "guide", "validate"],
                                                         bundle.observations.roles).all()

    assert main(["track", "--scale", "0.5", "--roi", "20,20,140,100", *map(str, grid_images),
                 "--out", str(tmp_path / "cli"), "--name", "py", "--E", "2", "--noise-std", "0.01",
                 "--seed", "4"]) == 0
    assert capsys.readouterr().out.startswith(f"tracked {read_bundle(tmp_path / 'cli').observations.n_points} points")
    for name in ("experiment.toml", "points.csv", "displacements.csv"):
        assert (tmp_path / "py" / name).read_text() == (tmp_path / "cli" / name).read_text()
    assert sorted(p.name for p in (tmp_path / "py" / "overlays").iterdir()) == ["frame_000.png", "frame_001.png"]


def test_track_refuses_bad_arguments_before_tracking(grid_images, tmp_path):
    with pytest.raises(TrackCommandError, match="give the image scale"):
        track(grid_images, tmp_path / "b")
    with pytest.raises(ValueError, match="takes 4 numbers"):  # TrackCommandError is a ValueError too
        track(grid_images, tmp_path / "b", scale=0.5, roi=(1, 2, 3))
    assert not (tmp_path / "b").exists()


def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out == f"nonrigid {importlib.metadata.version('nonrigid')}\n"


def test_the_parser_and_the_command_functions_import_no_jax():
    code = ("import sys\nfrom refine.cli import main, simulate, diagnose, track, demo\n"
            "try:\n    main(['track', '--help'])\nexcept SystemExit:\n    pass\n"
            "assert 'jax' not in sys.modules and 'jaxfem' not in sys.modules, 'jax imported'\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          cwd=Path(__file__).resolve().parents[1])
    assert done.returncode == 0, done.stderr
    assert "usage: nonrigid track" in done.stdout
