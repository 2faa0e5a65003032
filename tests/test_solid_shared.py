"""The cup holder's loaded model on jaxfem.program's shared programs (refine.solid.loaded,
refine.model.objective.Compiled): each frame's pressure (the measured force over the loaded face's
area at the morphed geometry) is carried frame by frame, so the prediction and its Jacobian in the
hole's geometry and modulus equal those of the model's own frame scan, and a remesh of the hole
compiles no solve again."""

import copy

import numpy as np
import pytest

import jaxfem as jf
from examples.cup_holder import cup_holder
from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.io import Bundle
from refine.bundle.observations import Forces, Observations
from refine.diagnosis.shapes import Hole
from refine.model.objective import Compiled
from refine.solid.diagnose import SolidConfig, local_recipe
from refine.solid.loaded import LoadedModel
from refine.solid.local import SolidHole

R_IN, R_OUT, HEIGHT, BOTTOM = 8.0, 11.0, 8.0, 3.0


class ScanModel(LoadedModel):
    """The same model solved by its own frame scan (the path before the shared programs)."""

    @property
    def shares_programs(self) -> bool:
        return False


@pytest.fixture(scope="module")
def hole_model(tmp_path_factory):
    """A coarse local model (h 3 mm) of a floor with a 1.5 mm grid of points, squeezed by two
    frames' forces with the ring under the wall moved at random, a hole through it with a free
    modulus (the global fit's unknowns)."""
    tmp = tmp_path_factory.mktemp("shared")
    jf.write_vtu(tmp / "mesh.vtu", cup_holder(R_IN, R_OUT, HEIGHT, BOTTOM, 3.0).mesh)
    g = np.arange(-9.5, 9.6, 1.5)
    xy = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    hole = jf.Ellipse(0.2, -0.2, 2.6, 1.9, 0.4)
    xy = xy[(np.hypot(*xy.T) < 10.5) & ~hole.contains(xy)]
    n = len(xy)
    roles = np.where(np.hypot(*xy.T) > 7, "boundary", np.where(np.arange(n) % 3 == 0, "validate", "guide"))
    rng = np.random.default_rng(3)
    U = 0.01 * rng.normal(size=(2, n, 3))
    forces = Forces(("back",), np.array([[[0.1, 0.0, 0.6]], [[-0.1, 0.2, 1.2]]]))
    obs = Observations(np.arange(1, n + 1), np.c_[xy, np.zeros(n)], roles, U, forces=forces)
    exp = Experiment(name="cup", kind="solid", domain=MeshDomain("mesh.vtu"), law="neo-hookean", E=1.0, nu=0.4)
    _, local, _ = local_recipe(Bundle(exp, obs, root=tmp), SolidConfig(h=3.0))
    hyp = SolidHole(local, local.hole_from(Hole((0.2, -0.2), (2.6, 1.9), 0.4)), free_modulus=True)
    compiled, _ = hyp.build()
    return hyp, compiled


@pytest.mark.slow  # the frame scan's forward-mode Jacobian compiled: 23 s at load 3, 80 s at load 13 (2 cores)
def test_shared_programs_carry_each_frames_pressure_as_the_frame_scan_does(hole_model):
    hyp, compiled = hole_model
    model = compiled.model
    assert model.shares_programs and compiled._tractions is not None
    scan = copy.copy(model)
    scan.__class__ = ScanModel
    reference = Compiled(scan, compiled.param)
    z = np.asarray(compiled.param.z0, float) + np.r_[0.05, -0.04, 0.03, -0.02, 0.05, 0.3]
    pred, J = compiled.evaluate(z)
    ref_pred, ref_J = reference.evaluate(z)
    assert np.abs(pred).max() > 1e-2  # the force moves the floor well beyond round-off
    np.testing.assert_allclose(pred, ref_pred, atol=1e-9 * np.abs(pred).max())
    np.testing.assert_allclose(J, ref_J, atol=1e-7 * np.abs(ref_J).max())
    # the pressure follows the face's area: the modulus' and the axes' columns are not zero
    assert (np.abs(J).reshape(-1, J.shape[-1]).max(0) > 1e-4 * np.abs(J).max()).all()


@pytest.mark.slow  # the frame scan's drive Jacobian compiled: 33 s at load 3, 150 s at load 13
def test_the_drives_pull_back_loads_each_frame(hole_model):
    _, compiled = hole_model
    model = compiled.model
    theta = model.params()
    C = np.random.default_rng(5).normal(size=(2,) + model.obs.displacements.shape)
    whole = model.boundary_jacobian(theta)  # shared programs, a tangent per boundary value
    scan = copy.copy(model)
    scan.__class__ = ScanModel
    np.testing.assert_allclose(whole, scan.boundary_jacobian(theta), atol=1e-9 * np.abs(whole).max())
    np.testing.assert_allclose(model.boundary_vjp(theta, C), np.einsum("cfpd,fpdgm->cgm", C, whole),
                               atol=1e-9 * np.abs(whole).max())
