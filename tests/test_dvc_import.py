"""``nonrigid import --dvc``: a digital volume correlation's points (inside a solid) to a bundle.

The body is a gmsh tet10 box with two physical faces (``fixed`` at x = 0, ``loaded`` at x = L);
the DVC points are a grid jittered at random under a seed, those of its end layers on the two faces
(a little off them, by their noise), the rest inside the volume. Their displacements are the
closed-form homogeneous uniaxial stretch of a neo-Hookean block (independent of any mesh,
tests/_verify_util.uniaxial_neo_hookean) at stretches drawn under the seed, plus noise.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from refine.bundle import Forces, Observations, read_bundle
from refine.cli.main import main
from refine.exceptions import ObservationError
from tests._verify_util import lame, uniaxial_neo_hookean

pytest.importorskip("gmsh")

E, NU, L, W = 10.0, 0.3, 10.0, 6.0
GEO = f"""SetFactory("OpenCASCADE");
Box(1) = {{0, 0, 0, {L}, {W}, {W}}};
Physical Volume("body") = {{1}};
Physical Surface("fixed") = {{1}};
Physical Surface("loaded") = {{2}};
"""


@pytest.fixture(scope="module")
def box_mesh(tmp_path_factory):
    from refine.bundle.mesher import mesh_geometry

    d = tmp_path_factory.mktemp("mesh")
    (d / "box.geo").write_text(GEO)
    mesh_geometry(d / "box.geo", 3.0, d / "box.msh")
    return d / "box.msh"


def dvc_points(seed: int, noise: float = 1e-4):
    """Grid x 0..L step 2, y, z 1..5 step 2, jittered; end layers on the faces off by ~noise."""
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(np.arange(0.0, L + 1, 2.0), [1.0, 3.0, 5.0], [1.0, 3.0, 5.0], indexing="ij"), -1)
    X = g.reshape(-1, 3)
    end = (X[:, 0] == 0.0) | (X[:, 0] == L)
    X = X + rng.uniform(-0.4, 0.4, X.shape) * np.where(end[:, None], [0.0, 1.0, 1.0], 1.0)
    X[end, 0] += rng.normal(0.0, 0.02, end.sum())  # a face's points a little off it, either side
    stretches = rng.uniform(1.02, 1.05, 2)
    U = []
    for s in stretches:
        lat, _ = uniaxial_neo_hookean(s, *lame(E, NU))
        U.append(X * (np.array([s, lat, lat]) - 1.0) + rng.normal(0.0, noise, X.shape))
    return X, np.array(U), end


def write_csv(path, X, U, lost=None):
    """Frames 1, 2 with an odd-cased header, an extra column, rows shuffled; ``lost`` (frame, row) empty."""
    rows = [(f + 1, i) for f in range(len(U)) for i in range(len(X))]
    order = np.random.default_rng(7).permutation(len(rows))
    lines = ["Frame,X,Y,z,UX,Uy,uz,score"]
    for k in order:
        f, i = rows[k]
        u = ",,," if lost == (f, i) else ",".join(repr(float(v)) for v in U[f - 1, i]) + ","
        lines.append(f"{f}," + ",".join(repr(float(v)) for v in X[i]) + "," + u + "0.9")
    path.write_text("\n".join(lines) + "\n")


def test_dvc_points_inside_a_tet10_box_import_and_interior_points_compare_where_they_are(tmp_path, box_mesh, capsys):
    from refine.model.measured import MeasuredModel

    X, U, end = dvc_points(seed=3)
    write_csv(tmp_path / "dvc.csv", X, U, lost=(2, 5))
    assert main(["import", "--dvc", str(tmp_path / "dvc.csv"), "--mesh", str(box_mesh), "--out", str(tmp_path / "b"),
                 "--boundary-faces", "fixed,loaded", "--E", str(E), "--nu", str(NU), "--noise-std", "1e-4",
                 "--seed", "5"]) == 0
    assert "imported 54 DVC points x 2 frames" in capsys.readouterr().out
    b = read_bundle(tmp_path / "b")
    obs, exp = b.observations, b.experiment
    assert exp.kind == "solid" and exp.domain.boundary_faces == ("fixed", "loaded")
    assert (tmp_path / "b" / "box.msh").is_file()
    # ids follow the points' first appearance in the file; match them back by position
    match = [int(np.argmin(np.linalg.norm(X - x, axis=1))) for x in obs.reference]
    np.testing.assert_allclose(obs.reference, X[match], atol=1e-12)
    np.testing.assert_array_equal(obs.roles == "boundary", end[match])
    assert (obs.roles == "validate").sum() == round(0.2 * (~end).sum())
    assert np.isnan(obs.displacements[1, match.index(5)]).all() and np.isfinite(obs.displacements[0]).all()
    np.testing.assert_allclose(obs.displacements[0], U[0][match], atol=1e-12)

    # a force measured across the face "loaded" (forces.csv's edge names a face of the mesh)
    force = Forces(("loaded",), np.random.default_rng(9).normal(0.0, 1.0, (2, 1, 3)))
    model = MeasuredModel(exp, replace(obs, forces=force), root=b.root)
    np.testing.assert_array_equal(model.sides["loaded"], model.mesh.side("loaded"))
    assert np.allclose(model.mesh.nodes[model.sides["loaded"], 0], L)
    inside = obs.roles != "boundary"
    np.testing.assert_array_equal(model.positions[inside], obs.reference[inside])  # compared where they are
    bx = model.positions[~inside, 0]
    assert np.all(np.isclose(bx, 0.0, atol=1e-9) | np.isclose(bx, L, atol=1e-9))  # on the faces
    # every node of the two faces is driven (the faces carry the load), nothing else
    faces = np.union1d(model.mesh.side("fixed"), model.mesh.side("loaded"))
    np.testing.assert_array_equal(np.sort(model.loop), faces)


def test_a_dvc_bundle_predicts_a_homogeneous_stretch_inside_the_body(tmp_path, box_mesh):
    from refine.model.measured import MeasuredModel

    X, U, end = dvc_points(seed=8)
    write_csv(tmp_path / "dvc.csv", X, U)
    assert main(["import", "--dvc", str(tmp_path / "dvc.csv"), "--mesh", str(box_mesh), "--out", str(tmp_path / "b"),
                 "--E", str(E), "--nu", str(NU)]) == 0
    b = read_bundle(tmp_path / "b")
    obs = b.observations
    # by default every face the mesh names (gmsh names the other four face_3 ... face_6); only the
    # two that hold points are the bundle's boundary faces (every node of them is driven)
    assert b.experiment.domain.boundary_faces == ("fixed", "loaded")
    match = [int(np.argmin(np.linalg.norm(X - x, axis=1))) for x in obs.reference]
    np.testing.assert_array_equal(obs.roles == "boundary", end[match])
    model = MeasuredModel(b.experiment, obs, root=b.root)
    inside = obs.roles != "boundary"
    pred = np.asarray(model.predict(model.params()))
    err = np.linalg.norm(pred - obs.displacements, axis=2)[:, inside]
    scale = np.linalg.norm(obs.displacements[:, inside], axis=2)
    # homogeneous stretch: the interior points' predictions match to the noise and the drive's
    # projection of the faces' points (offset ~0.02 mm times a strain of a few per cent); with only
    # the face nodes near the points driven (not every node of the faces), this was 6 % of the mean
    assert err.max() < 0.01 * scale.mean(), (err.max(), scale.mean())


def test_dvc_import_refuses_points_outside_the_mesh_and_unknown_faces(tmp_path, box_mesh, capsys):
    X, U, _ = dvc_points(seed=4)
    X[[3, 10]] += [[0.0, 0.0, 9.0], [0.0, 0.0, 4.0]]  # two points above the box, the first 9 mm
    write_csv(tmp_path / "dvc.csv", X, U)
    assert main(["import", "--dvc", str(tmp_path / "dvc.csv"), "--mesh", str(box_mesh), "--out",
                 str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "2 of 54 DVC points lie outside the mesh" in err and f"{X[3].round(6).tolist()}" in err, err
    X, U, _ = dvc_points(seed=4)
    write_csv(tmp_path / "dvc.csv", X, U)
    assert main(["import", "--dvc", str(tmp_path / "dvc.csv"), "--mesh", str(box_mesh), "--out", str(tmp_path / "c"),
                 "--boundary-faces", "fixed,grip"]) == 2
    err = capsys.readouterr().err
    assert "unknown face 'grip'" in err and "'loaded'" in err, err
    (tmp_path / "bad.csv").write_text("x,y,ux,uy\n1,2,0,0\n")
    assert main(["import", "--dvc", str(tmp_path / "bad.csv"), "--mesh", str(box_mesh), "--out",
                 str(tmp_path / "d")]) == 2
    assert "missing column(s) ['z', 'uz']" in capsys.readouterr().err


def test_a_boundary_point_off_the_named_faces_is_refused(tmp_path, box_mesh):
    from refine.model.measured import MeasuredModel

    X, U, end = dvc_points(seed=6)
    write_csv(tmp_path / "dvc.csv", X, U)
    assert main(["import", "--dvc", str(tmp_path / "dvc.csv"), "--mesh", str(box_mesh), "--out", str(tmp_path / "b"),
                 "--boundary-faces", "fixed,loaded"]) == 0
    b = read_bundle(tmp_path / "b")
    obs = b.observations
    roles, X = obs.roles.copy(), obs.reference.copy()
    k = int(np.flatnonzero(roles == "guide")[0])
    roles[k], X[k, 1] = "boundary", 0.0  # a point on the side y = 0: on the surface, not on the faces named
    moved = Observations(obs.ids, X, roles, obs.displacements)
    with pytest.raises(ObservationError, match=rf"not on the faces \['fixed', 'loaded'\].*point {obs.ids[k]}\b"):
        MeasuredModel(b.experiment, moved, root=b.root)
    top = replace(b.experiment, domain=replace(b.experiment.domain, boundary_faces=("fixed", "loaded", "top")))
    with pytest.raises(ObservationError, match=r"no boundary point lies on the face\(s\) \['top'\]"):
        MeasuredModel(top, obs, root=b.root)
    # the bounding box's side "bottom" (y = 0) named too: the point is on a boundary face and drives
    exp = replace(b.experiment, domain=replace(b.experiment.domain, boundary_faces=("fixed", "loaded", "bottom")))
    model = MeasuredModel(exp, moved, root=b.root)
    assert model.positions[k, 1] == 0.0 and set(model.mesh.side("bottom")) <= set(model.loop)
