"""Measurement bundles: round trips, the example bundle, and every malformed input with its message."""

import os
import tomllib
from pathlib import Path

import numpy as np
import pytest

from refine.bundle.io import Bundle, read_bundle, write_bundle, write_displacements_csv
from refine.exceptions import BundleError, ExperimentError, ObservationError
from refine.bundle.experiment import Experiment, MeshDomain, PolygonDomain, RectangleDomain
from refine.bundle.observations import Forces, Observations


def shared_dir() -> Path | None:
    """The shared data directory: $NONRIGID_SHARED, else the checkout's sibling ``shared``."""
    candidates = [os.environ.get("NONRIGID_SHARED"), Path(__file__).resolve().parents[2] / "shared"]
    return next((Path(c) for c in candidates if c and Path(c).is_dir()), None)


def observations_2d(n_frames=3, forces=True) -> Observations:
    rng = np.random.default_rng(0)
    ids = np.array([3, 1, 7, 12, 5, 40])
    reference = rng.uniform(0, 10, (len(ids), 2))
    roles = ["boundary", "boundary", "guide", "guide", "validate", "guide"]
    u = rng.normal(0, 0.3, (n_frames, len(ids), 2))
    u[1, 2] = np.nan  # point 7 lost in frame 2
    u[2, 5] = np.nan
    f = Forces(("right", "left"), rng.normal(0, 100, (n_frames, 2, 2))) if forces else None
    return Observations(ids, reference, roles, u, f)


def experiment_2d(**changes) -> Experiment:
    fields = dict(name="sheet-07", kind="plane-stress", domain=RectangleDomain(0.0, 0.0, 10.0, 10.0),
                  law="neo-hookean", E=83.76, nu=0.3, thickness=1.0,
                  units={"length": "mm", "stress": "kPa", "force": "mN"}, noise_std=0.02,
                  extra={"meta": {"operator": "lt", "C01": 1.5, "solver": {"steps": 10, "tolerances": {"newton": 1e-10}},
                                  "note": "kept"}, "diagnose": {"seed": 3}})
    fields.update(changes)
    return Experiment(**fields)


def assert_same_observations(a: Observations, b: Observations):
    np.testing.assert_array_equal(a.ids, b.ids)
    np.testing.assert_array_equal(a.reference, b.reference)
    np.testing.assert_array_equal(a.roles, b.roles)
    np.testing.assert_array_equal(a.displacements, b.displacements)  # NaN == NaN here
    assert (a.forces is None) == (b.forces is None)
    if a.forces is not None:
        assert a.forces.edges == b.forces.edges
        np.testing.assert_array_equal(a.forces.values, b.forces.values)


# ------------------------------------------------------------------------------- round trips
def test_round_trip_2d_lost_points_forces_and_extra_keys(tmp_path):
    bundle = Bundle(experiment_2d(), observations_2d())
    write_bundle(tmp_path / "b", bundle)
    back = read_bundle(tmp_path / "b")
    assert back.experiment == bundle.experiment
    assert back.experiment.extra["meta"]["solver"]["tolerances"]["newton"] == 1e-10
    assert_same_observations(back.observations, bundle.observations)
    assert back.observations.valid.sum() == 18 - 2
    # A second write gives the same files byte for byte, and the TOML data is what we wrote.
    write_bundle(tmp_path / "c", back)
    for name in ("experiment.toml", "points.csv", "displacements.csv", "forces.csv"):
        assert (tmp_path / "b" / name).read_text() == (tmp_path / "c" / name).read_text()
    with open(tmp_path / "b" / "experiment.toml", "rb") as f:
        assert tomllib.load(f) == bundle.experiment.to_toml()


def test_lost_points_are_empty_cells(tmp_path):
    obs = observations_2d()
    path = write_displacements_csv(tmp_path / "pred.csv", obs.ids, obs.displacements)
    lines = path.read_text().splitlines()
    assert lines[0] == "frame,id,ux,uy"
    assert "2,7,," in lines and "3,40,," in lines
    assert len(lines) == 1 + obs.n_frames * obs.n_points


def test_round_trip_3d_with_mesh_and_no_forces(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "mesh.msh").write_text("not really a mesh\n")
    rng = np.random.default_rng(1)
    u = rng.normal(size=(2, 4, 3))
    u[0, 3] = np.nan
    obs = Observations([1, 2, 3, 4], rng.normal(size=(4, 3)), ["boundary", "guide", "guide", "validate"], u)
    exp = Experiment(name="cup", kind="solid", domain=MeshDomain("mesh.msh"), law="mooney-rivlin", E=10.0,
                     nu=0.45, extra={"meta": {"C01": 0.2}})
    write_bundle(src, Bundle(exp, obs))
    first = read_bundle(src)
    assert (src / "points.csv").read_text().startswith("id,x,y,z,role\n")
    assert (src / "displacements.csv").read_text().startswith("frame,id,ux,uy,uz\n")
    write_bundle(tmp_path / "copy", first)  # copies the mesh file along
    back = read_bundle(tmp_path / "copy")
    assert back.experiment == exp and back.experiment.thickness is None and back.experiment.noise_std is None
    assert (tmp_path / "copy" / "mesh.msh").read_text() == "not really a mesh\n"
    assert_same_observations(back.observations, obs)
    assert back.observations.dim == 3 and back.observations.forces is None


def test_round_trip_polygon_domain(tmp_path):
    exp = experiment_2d(domain=PolygonDomain(((0, 0), (10, 0), (10, 10), (0, 10))), extra={})
    obs = observations_2d(forces=False)
    write_bundle(tmp_path, Bundle(exp, obs))
    back = read_bundle(tmp_path)
    assert back.experiment == exp and back.experiment.domain.vertices[1] == (10.0, 0.0)
    assert not (tmp_path / "forces.csv").exists()


def test_observation_helpers():
    obs = observations_2d()
    assert obs.frames.tolist() == [1, 2, 3] and obs.n_frames == 3 and obs.dim == 2
    assert obs.mask("guide").tolist() == [False, False, True, True, False, True]
    guide = obs.subset("guide")
    assert guide.ids.tolist() == [7, 12, 40] and guide.displacements.shape == (3, 3, 2)
    assert guide.valid.tolist() == [[True] * 3, [False, True, True], [True, True, False]]
    np.testing.assert_array_equal(obs.positions, obs.reference + obs.displacements)
    assert obs.index_of([40, 3]).tolist() == [5, 0]
    assert obs.forces.on("left").shape == (3, 2)
    with pytest.raises(ObservationError, match="unknown point ids \\[99\\]"):
        obs.index_of([99])
    with pytest.raises(ObservationError, match="unknown role 'interior'"):
        obs.mask("interior")
    with pytest.raises(ValueError):  # read-only arrays: a frozen record stays frozen
        obs.displacements[0, 0, 0] = 1.0


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(ids=[1, 1, 2, 3, 4, 5]), "duplicate point ids: \\[1\\]"),
        (dict(roles=["boundary"] * 5 + ["interior"]), "unknown roles \\['interior'\\]"),
        (dict(reference=np.full((6, 2), np.inf)), "reference coordinates contain NaN or inf"),
        (dict(displacements=np.full((2, 6, 2), np.inf)), "is infinite; use NaN"),
        (dict(displacements=np.array([[[np.nan, 0.0]] * 6])), "some displacement components NaN"),
        (dict(displacements=np.zeros((2, 5, 2))), "displacements must have shape \\(n_frames, 6, 2\\)"),
        (dict(forces=Forces(("right",), np.zeros((5, 1, 2)))), "forces have shape"),
    ],
)
def test_observations_reject_bad_arrays(change, message):
    obs = observations_2d()
    fields = dict(ids=obs.ids, reference=obs.reference, roles=obs.roles, displacements=obs.displacements,
                  forces=obs.forces)
    fields.update(change)
    with pytest.raises(ObservationError, match=message):
        Observations(**fields)


# ------------------------------------------------------------------------------- the example
@pytest.mark.shared
def test_reads_the_example_bundle():
    shared = shared_dir()
    if shared is None or not (shared / "examples" / "sheet-stiff-inclusion" / "bundle").is_dir():
        pytest.skip("shared data not found: set NONRIGID_SHARED or check out ../shared beside the repository")
    bundle = read_bundle(shared / "examples" / "sheet-stiff-inclusion" / "bundle")
    exp, obs = bundle.experiment, bundle.observations
    assert (exp.name, exp.kind, exp.law, exp.E, exp.nu, exp.thickness, exp.noise_std) == (
        "sheet-stiff-inclusion", "plane-stress", "neo-hookean", 83.76, 0.3, 1.0, 0.02)
    assert exp.domain == RectangleDomain(20.0, 10.0, 120.0, 70.0) and exp.units["force"] == "mN"
    assert (obs.n_points, obs.n_frames, obs.dim) == (273, 4, 2)
    assert [obs.mask(r).sum() for r in ("boundary", "guide", "validate")] == [64, 167, 42]
    assert obs.valid.all() and obs.forces is None
    assert obs.displacements[0, 0].tolist() == [0.752634, 0.222582]


# ------------------------------------------------------------------------------- bad input
POINTS = "id,x,y,role\n1,0,0,boundary\n2,10,0,boundary\n3,5,5,guide\n"
DISPLACEMENTS = "frame,id,ux,uy\n1,1,0,0\n1,2,1,0\n1,3,0.5,0\n2,1,0,0\n2,2,2,0\n2,3,,\n"
FORCES = "frame,edge,fx,fy\n1,right,10,0\n2,right,20,0\n"
TOML = """[experiment]
name = "t"
[model]
kind = "plane-stress"
thickness = 1.0
domain = { rectangle = [0.0, 0.0, 10.0, 10.0] }
[material]
law = "neo-hookean"
E = 80.0
nu = 0.3
"""


def write_files(root: Path, **texts):
    files = {"experiment.toml": TOML, "points.csv": POINTS, "displacements.csv": DISPLACEMENTS,
             "forces.csv": FORCES}
    files.update({k.replace("_", "."): v for k, v in texts.items()})
    for name, text in files.items():
        if text is not None:
            (root / name).write_text(text)


def test_minimal_files_are_valid(tmp_path):
    write_files(tmp_path)
    obs = read_bundle(tmp_path).observations
    assert obs.valid.tolist() == [[True, True, True], [True, True, False]]
    assert obs.forces.on("right")[:, 0].tolist() == [10.0, 20.0]


@pytest.mark.parametrize(
    "file, text, line, message",
    [
        ("points.csv", POINTS.replace("5,5,guide", "nan,5,guide"), 4, "x = 'nan': NaN or inf where a number"),
        ("points.csv", POINTS + "1,3,3,guide\n", 5, "point id 1 is listed twice \\(lines 2 and 5\\)"),
        ("points.csv", POINTS.replace("5,5,guide", "5,5,interior"), 4, "unknown role 'interior'"),
        ("points.csv", POINTS.replace("3,5,5", "3.5,5,5"), 4, "id = '3.5' is not an integer"),
        ("points.csv", POINTS.replace("5,5,guide", "5,five,guide"), 4, "y = 'five' is not a number"),
        ("points.csv", POINTS.replace("5,5,guide", "5,guide"), 4, "expected 4 values"),
        ("points.csv", POINTS.replace("id,x,y,role", "id,x,y,z,role"), 1, "header must be id,x,y,role"),
        ("points.csv", "id,x,y,role\n", None, "lists no points"),
        ("points.csv", None, None, "is missing"),
        ("displacements.csv", DISPLACEMENTS + "2,99,0,0\n", 8, "point id 99 is not in points.csv"),
        ("displacements.csv", DISPLACEMENTS.replace("2,2,2,0", "2,2,inf,0"), 6, "ux = 'inf': NaN or inf"),
        ("displacements.csv", DISPLACEMENTS.replace("2,2,2,0", "2,2,,0"), 6, "some of ux,uy empty"),
        ("displacements.csv", DISPLACEMENTS.replace("2,2,2,0\n", ""), None, "point 2 has no row in frame 2"),
        ("displacements.csv", DISPLACEMENTS + "2,1,0,0\n", 8, "point 1 has two rows in frame 2 \\(lines 5 and 8\\)"),
        ("displacements.csv", DISPLACEMENTS.replace("\n2,", "\n3,"), None, "frame 2 is missing"),
        ("displacements.csv", DISPLACEMENTS.replace("\n1,", "\n0,"), 2, "frame 0 is the reference configuration"),
        ("displacements.csv", DISPLACEMENTS.replace("\n1,", "\n-1,"), 2, "frame -1 is negative"),
        ("displacements.csv", "frame,id,ux,uy\n", None, "lists no frames"),
        ("displacements.csv", DISPLACEMENTS.replace("ux,uy", "u,v"), 1, "header must be frame,id,ux,uy"),
        ("forces.csv", FORCES + "3,right,5,0\n", 4, "frame 3 is not in displacements.csv"),
        ("forces.csv", FORCES.replace("1,right", "1,east"), 2, "unknown edge 'east'"),
        ("forces.csv", FORCES + "1,left,1,0\n", None, "edge 'left' has no force in frame 2"),
        ("forces.csv", FORCES.replace("20,0", ",0"), 3, "fx = '' is not a number"),
        ("forces.csv", FORCES.replace("20,0", "nan,0"), 3, "NaN or inf where a number is required"),
        ("forces.csv", FORCES + "2,right,1,0\n", 4, "edge 'right' has two rows in frame 2"),
        ("experiment.toml", TOML + "nu = 0.2\n", None, "is not valid TOML"),
        ("experiment.toml", TOML.replace("plane-stress", "plate"), None, "model.kind 'plate' is unknown"),
        ("experiment.toml", TOML.replace("E = 80.0\n", ""), None, "\\[material\\] has no 'E'"),
        ("experiment.toml", TOML.replace("E = 80.0", "E = -80.0"), None, "material.E must be positive"),
        ("experiment.toml", TOML.replace("E = 80.0", "E = nan"), None, "material.E must be a finite number"),
        ("experiment.toml", TOML.replace("E = 80.0", 'E = "80"'), None, "material.E must be a number"),
        ("experiment.toml", TOML.replace("nu = 0.3", "nu = 0.5"), None, "material.nu must lie in"),
        ("experiment.toml", TOML.replace("neo-hookean", "ogden"), None, "material.law 'ogden' is unknown"),
        ("experiment.toml", TOML + "[measurement]\nnoise_std = -0.01\n", None, "noise_std must be >= 0"),
        ("experiment.toml", TOML.replace("[0.0, 0.0, 10.0, 10.0]", "[10.0, 0.0, 0.0, 10.0]"), None,
         "xmin < xmax"),
        ("experiment.toml", TOML.replace("rectangle = [0.0, 0.0, 10.0, 10.0]", "polygon = [[0,0],[0,10],[10,0]]"),
         None, "clockwise"),
        ("experiment.toml", TOML.replace("rectangle = [0.0, 0.0, 10.0, 10.0]", 'mesh = "m.msh"'), None,
         "names mesh file 'm.msh', which is not in"),
        ("experiment.toml", TOML.replace("plane-stress", "solid"), None, 'a "solid" model needs domain'),
        ("experiment.toml", TOML.replace("{ rectangle", "{ circle"), None, "domain kind 'circle' is unknown"),
    ],
)
def test_bad_bundle_names_file_line_and_problem(tmp_path, file, text, line, message):
    write_files(tmp_path, **{file.replace(".", "_"): text})
    if text is None:
        (tmp_path / file).unlink(missing_ok=True)
    with pytest.raises(BundleError, match=message) as caught:
        read_bundle(tmp_path)
    assert caught.value.path.name == file and caught.value.line == line
    assert str(caught.value).startswith(f"{tmp_path / file}:{'' if line is None else f'{line}:'}")


def test_bundle_that_is_not_a_directory(tmp_path):
    with pytest.raises(BundleError, match="is not a directory"):
        read_bundle(tmp_path / "nope")


def test_experiment_extra_cannot_shadow_known_keys():
    with pytest.raises(ExperimentError, match="would overwrite"):
        experiment_2d(extra={"material": {"E": 1.0}}).to_toml()


def test_write_refuses_what_it_could_not_read_back(tmp_path):
    obs = observations_2d()
    bad_edges = Observations(obs.ids, obs.reference, obs.roles, obs.displacements,
                             Forces(("east",), np.zeros((obs.n_frames, 1, 2))))
    with pytest.raises(ObservationError, match="unknown edge .east.: the domain does not define that side"):
        write_bundle(tmp_path, Bundle(experiment_2d(), bad_edges))
    with pytest.raises(ObservationError, match="observations are 2D"):
        write_bundle(tmp_path, Bundle(experiment_2d(kind="solid", domain=MeshDomain("m.msh")), obs))
