"""The paper's tracking without point correspondences (Tsap, Goldgof & Sarkar 2000, Sec. 5.1,
after its ref. [37]), the baseline of the differentiable fit.

Frame to frame: find the model node with the largest directed Hausdorff distance between the
model and the next frame's data, apply a force at that node along the shortest distance from it
to the data, recompute the equilibrium and the largest difference, and iterate; the forces
found for one frame are the start of the next. Both directed distances are taken: model boundary
nodes to the cloud (the model sticks out), and boundary points of the cloud to the model's
boundary (the data stick out; the force then goes to the nearest node of the nearest facet: an
outline edge in 2D, a surface triangle in 3D). In 3D only the nodes a camera saw in the reference
frame take part (a range cloud shows one side of the body). The force at a node grows by
``gain x E x thickness x distance`` in 2D (a point force on a sheet moves it by about F / (E t)),
``gain x E x h x distance`` in 3D (h the model's mean boundary edge: a point force on a solid moves
it by about F / (E h))); a step that makes the largest distance grow is undone and the gain halved, a
step that shrinks it raises the gain by half. Every iteration is logged: frame, node, force,
distances before and after. The geometry is SciPy's (KD-tree, ``directed_hausdorff``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.distance import directed_hausdorff

import jaxfem as jf

from refine.correspond.fit import FitConfig, split_frames
from refine.correspond.geometry import facet_distances, on_boundary, point_spacing, seen_nodes
from refine.correspond.model import CloudModel
from refine.exceptions import CorrespondenceError


@dataclass(frozen=True)
class HausdorffConfig:
    """Settings of the Hausdorff force method (data).

    Attributes:
        tol: stop a frame when the largest distance falls below this (length).
        noise: the clouds' noise (length), for the outline split.
        max_iterations: force updates per frame at most.
        patience: stop a frame after this many updates without a new smallest largest distance.
        gain: initial force per distance, in units of E x thickness.
    """

    tol: float
    noise: float = 0.05
    max_iterations: int = 300
    patience: int = 40
    gain: float = 1.0


@dataclass(frozen=True, eq=False)
class HausdorffResult:
    """What the force method recovered.

    Attributes:
        positions: ``(n_frames + 1, n_nodes, dim)`` every node's position in every frame (frame 0
            the reference): the dense correspondences.
        forces: ``(n_frames, n_nodes, dim)`` the nodal forces found for each frame.
        log: one dict per iteration: frame, iteration, node, side (``model`` or ``data``: which
            directed distance was the largest), distance, force (the increment), gain,
            hausdorff_after, accepted.
        largest: ``(n_frames,)`` the largest distance at the end of each frame.
        seconds: wall time.
    """

    positions: np.ndarray
    forces: np.ndarray
    log: list = field(default_factory=list)
    largest: np.ndarray = None
    seconds: float = 0.0


def _largest(x, bnodes, facets, cloud, outline):
    """The larger directed Hausdorff distance: ``(distance, node, target point, side)``."""
    bx = x[bnodes]
    d_model, i_node, j_pt = directed_hausdorff(bx, cloud)
    D = np.asarray(facet_distances(outline, x, facets))
    nearest = D.argmin(axis=1)
    far = int(np.argmax(D[np.arange(len(outline)), nearest]))
    d_data = float(D[far, nearest[far]])
    if d_model >= d_data:
        return float(d_model), int(bnodes[i_node]), cloud[j_pt], "model"
    ends = facets[nearest[far]]
    node = ends[int(np.argmin(np.linalg.norm(x[ends] - outline[far], axis=1)))]
    return d_data, int(node), outline[far], "data"


def hausdorff_track(model: CloudModel, clouds, config: HausdorffConfig) -> HausdorffResult:
    """Track the clouds ``[frame 0, frame 1, ...]`` (``(n_k, dim)`` each) by nodal forces.

    The model is held only at its clamped sides; its gripped sides are free and moved by the
    forces like any other node. Returns a :class:`HausdorffResult`. Raises
    :class:`CorrespondenceError` before any solve for clouds the fit would refuse too (fewer than
    two frames, an empty frame, NaN, too few boundary points, a reference cloud far from the model).
    """
    if not model.grips.clamped:
        raise CorrespondenceError("the Hausdorff force method needs a clamped side: forces alone leave rigid modes")
    if len(clouds) < 2:
        raise CorrespondenceError("a sequence needs frame 0 (the reference shape) and at least one more frame")
    split_frames(clouds, FitConfig(noise=config.noise))
    model.check_reference(clouds[0], config.noise, max(10 * config.noise, 0.02 * model.size))
    t0 = time.perf_counter()
    mesh, ex = model.mesh, model.experiment
    problem = jf.Problem(mesh, ex.law, ex.kind, fixed=jf.dofs(mesh, model.clamp))
    solver = jf.Solver(problem)
    movable = np.setdiff1d(model.boundary_nodes, model.clamp)
    dim, facets = model.dim, model.facets
    if dim == 3:  # only the surface a camera saw
        ref = np.asarray(clouds[0], float)
        movable = movable[seen_nodes(mesh.nodes[movable], ref, 2.0 * point_spacing(ref) + 3.0 * config.noise)]
        edge = np.linalg.norm(mesh.nodes[facets] - mesh.nodes[np.roll(facets, 1, axis=1)], axis=2).mean()
        stiffness = ex.E * float(edge)
    else:
        stiffness = ex.E * (ex.thickness or 1.0)
    f = np.zeros(problem.n_dofs)
    u = np.zeros(problem.n_dofs)
    theta0 = model.params()
    base = problem.params(E=theta0["E"], nu=theta0["nu"], thickness=theta0["thickness"])
    positions, forces, largest, log = [mesh.nodes.copy()], [], [], []

    def solve(f_new, u_start, f_start):
        theta = {**base, "f": f_new}
        try:
            return np.asarray(solver.solve(theta, start=(u_start, {**_loads(base), "f": f_start})).u).reshape(-1)
        except jf.SolverError:
            return None

    for k, cloud in enumerate(clouds[1:], start=1):
        cloud = np.asarray(cloud, float)
        if len(cloud) == 0 or not np.all(np.isfinite(cloud)):
            raise CorrespondenceError(f"frame {k}'s cloud is empty or has NaN coordinates")
        outline = cloud[on_boundary(cloud, 4 * config.noise)]
        gain, best, stale = config.gain, np.inf, 0
        x = mesh.nodes + u.reshape(-1, dim)
        dist, node, target, side = _largest(x, movable, facets, cloud, outline)
        for it in range(config.max_iterations):
            if dist < config.tol or stale >= config.patience or gain < 1e-4 * config.gain:
                break
            direction = (target - x[node]) / max(dist, 1e-300)
            df = np.zeros_like(f)
            df[dim * node: dim * node + dim] = gain * stiffness * dist * direction
            u_new = solve(f + df, u, f)
            nxt = None
            if u_new is not None:
                x_new = mesh.nodes + u_new.reshape(-1, dim)
                nxt = _largest(x_new, movable, facets, cloud, outline)
            accepted = nxt is not None and nxt[0] <= dist
            log.append({"frame": k, "iteration": it + 1, "node": node, "side": side, "distance": dist,
                        "force": (df[dim * node: dim * node + dim]).tolist(), "gain": gain,
                        "hausdorff_after": None if nxt is None else float(nxt[0]), "accepted": accepted})
            if accepted:
                f, u, x = f + df, u_new, x_new
                dist, node, target, side = nxt
                gain = min(gain * 1.5, 50 * config.gain)
            else:
                gain *= 0.5
            stale = 0 if dist < best - 1e-12 else stale + 1
            best = min(best, dist)
        positions.append(x.copy())
        forces.append(f.reshape(-1, dim).copy())
        largest.append(dist)
    return HausdorffResult(np.stack(positions), np.stack(forces), log, np.array(largest), time.perf_counter() - t0)


def _loads(theta) -> dict:
    return {"u_D": theta["u_D"], "f": theta["f"], "traction": theta["traction"]}

