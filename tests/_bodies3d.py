"""3D test bodies that are neither a cup nor a block alone, their data from the independent solver
(:mod:`tests._independent3d`; tests and benchmarks only, the library never imports it).

- ``"bracket"``: an L-bracket (legs 60 mm, 20 thick, 15 deep) hiding a stiff ellipsoidal inclusion
  (ratio 3-8); the vertical leg's end (``top``, y = 60) clamped, the horizontal leg's end (``right``,
  x = 60) moved down and out; points on its two flat faces and its two outer faces.
- ``"tube"``: a thick-walled tube (ri 10, ro 26, length 60 along z) hiding an ellipsoidal cavity in
  its wall; the end ``back`` (z = 0) clamped, ``front`` (z = 60) pulled and twisted; points on a
  lattice inside the volume (a DVC export: every lattice site in material), those on the end faces
  the driving ones.
- ``"block2"``: a 48 x 24 x 24 block hiding a soft ellipsoidal inclusion (ratio 0.1-0.4), gripped at
  ``left`` and ``right`` (pulled along x), seen on two faces only (``top`` and ``front``).
- ``"sound"``: the bracket without an effect.

Each effect is drawn under a seed (rejection: the ellipsoid's surface keeps a margin from every
face of the body and from the driven faces). The data come from P2 tetrahedra on a gmsh mesh with
the effect in it (finer, and meshed with other algorithms, than the inversion's); the model mesh
written beside the bundle is a second-order gmsh mesh of the body without the effect
(``mesh.vtu``). Noise: Gaussian, ``noise`` (a share) of the largest displacement, under the seed.
Side names are jaxfem's bounding-box sides: left/right x, bottom/top y, back/front z min/max.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from tests._independent3d import Ellipsoid, affine_drive, basis_of, gmsh_mesh, random_rotation, solve

E, NU = 50.0, 0.3  # kPa, as the block's examples


@dataclass(frozen=True)
class Body:
    """A body as data: its OpenCASCADE ``build``, bounding box ``(x0, y0, z0, x1, y1, z1)``, the
    clamped and moved sides, the moved side's displacement ``motion(s, X (n, 3)) -> (n, 3)`` at
    load parameter ``s`` (1: the last frame), ``material(X, margin)`` (points at least ``margin``
    inside), the ``effect`` drawn for a seed, the tracked points ``points(rng, effect) -> (X, boundary)``,
    and the model's and data's element sizes (mm)."""

    name: str
    build: Callable
    bbox: tuple
    clamp: str
    moved: str
    motion: Callable
    material: Callable
    effect: Callable
    points: Callable
    h_model: float
    h_data: float


SIDES = {"left": (0, 0), "right": (0, 1), "bottom": (1, 0), "top": (1, 1), "back": (2, 0), "front": (2, 1)}


def side_value(bbox, name):
    axis, end = SIDES[name]
    return axis, bbox[axis + 3 * end]


def _grid(a, b):
    return np.stack(np.meshgrid(a, b, indexing="ij"), -1).reshape(-1, 2)


def _ticks(lo, hi, step, offset=0.0):
    return np.arange(lo + offset, hi + 1e-9, step)


def face_points(axis: int, value: float, u, v) -> np.ndarray:
    """Points of the plane ``x[axis] = value`` at the grid ``u x v`` of the other two axes (in order)."""
    g = _grid(u, v)
    others = [d for d in range(3) if d != axis]
    P = np.empty((len(g), 3))
    P[:, axis], P[:, others[0]], P[:, others[1]] = value, g[:, 0], g[:, 1]
    return P


def draw(rng, fits, axes_range, ratio_range, tries: int = 5000) -> Ellipsoid:
    """An ellipsoid whose sampled surface ``fits(points (n, 3)) -> bool`` everywhere, its semi-axes
    drawn in ``axes_range``, its ratio in ``ratio_range`` (``(0, 0)``: a cavity), rotation uniform
    and centre from ``fits.centre(rng)``."""
    ratio = 0.0 if ratio_range[1] == 0 else float(rng.uniform(*ratio_range))
    for _ in range(tries):
        e = Ellipsoid(tuple(map(float, fits.centre(rng))), tuple(map(float, rng.uniform(*axes_range, 3))),
                      tuple(map(tuple, random_rotation(rng))), ratio)
        if fits(e.surface()):
            return e
    raise RuntimeError("no ellipsoid fits the body; widen its bounds")


class _Fits:
    def __init__(self, ok, centre):
        self.ok, self.centre = ok, centre

    def __call__(self, P):
        return bool(self.ok(P).all())


# ------------------------------------------------------------------ the L-bracket
BRACKET = (0.0, 0.0, 0.0, 60.0, 60.0, 15.0)
LEG = 20.0


def _bracket_build(occ):
    x0, y0, z0, x1, y1, z1 = BRACKET
    a = occ.addBox(x0, y0, z0, x1 - x0, LEG, z1 - z0)
    b = occ.addBox(x0, y0, z0, LEG, y1 - y0, z1 - z0)
    (out, _) = occ.fuse([(3, a)], [(3, b)])
    return out[0][1]


def _bracket_material(X, margin=0.0):
    x0, y0, z0, x1, y1, z1 = BRACKET
    X = np.atleast_2d(X)
    z_ok = (X[:, 2] >= z0 + margin) & (X[:, 2] <= z1 - margin)
    leg_h = (X[:, 0] >= x0 + margin) & (X[:, 0] <= x1 - margin) & (X[:, 1] >= y0 + margin) & (X[:, 1] <= y0 + LEG - margin)
    leg_v = (X[:, 0] >= x0 + margin) & (X[:, 0] <= x0 + LEG - margin) & (X[:, 1] >= y0 + margin) & (X[:, 1] <= y1 - margin)
    return z_ok & (leg_h | leg_v)


def _bracket_effect(rng, sound=False):
    if sound:
        return None
    x0, y0, z0, x1, y1, z1 = BRACKET
    ok = lambda P: _bracket_material(P, 1.5) & (P[:, 0] < x1 - 10) & (P[:, 1] < y1 - 10)  # noqa: E731

    def centre(r):
        along = r.uniform(LEG + 6.0, 46.0)  # in a leg that bends, off the corner's square
        c = [along, LEG / 2, (z0 + z1) / 2] if r.random() < 0.5 else [LEG / 2, along, (z0 + z1) / 2]
        return np.asarray(c) + r.uniform(-2.0, 2.0, 3) * [1, 1, 0.5]

    return draw(rng, _Fits(ok, centre), (3.5, 6.5), (3.0, 8.0))


def _bracket_points(rng, effect=None, spacing=3.0):
    x0, y0, z0, x1, y1, z1 = BRACKET
    off = rng.uniform(0.2, 0.8, 2) * spacing
    seen = [face_points(2, z, _ticks(x0, x1, spacing, off[0]), _ticks(y0, y1, spacing, off[1])) for z in (z0, z1)]
    seen += [face_points(0, x0, _ticks(y0, y1, spacing, off[1]), _ticks(z0, z1, spacing, 0.5 * spacing)),
             face_points(1, y0, _ticks(x0, x1, spacing, off[0]), _ticks(z0, z1, spacing, 0.5 * spacing))]
    S = np.unique(np.round(np.concatenate(seen), 9), axis=0)
    S = S[_bracket_material(S) & (S[:, 0] < x1 - 0.5 * spacing) & (S[:, 1] < y1 - 0.5 * spacing)]
    top = face_points(1, y1, np.linspace(x0, x0 + LEG, 9), np.linspace(z0, z1, 7))
    right = face_points(0, x1, np.linspace(y0, y0 + LEG, 9), np.linspace(z0, z1, 7))
    B = np.concatenate([top, right])
    return np.concatenate([B, S]), np.r_[np.ones(len(B), bool), np.zeros(len(S), bool)]


def _bracket_motion(s, X):
    return np.broadcast_to(s * np.array([0.8, -3.0, 0.0]), X.shape).copy()


# ------------------------------------------------------------------ the tube
RI, RO, LENGTH = 10.0, 26.0, 60.0
TUBE = (-RO, -RO, 0.0, RO, RO, LENGTH)


def _tube_build(occ):
    outer = occ.addCylinder(0, 0, 0, 0, 0, LENGTH, RO)
    inner = occ.addCylinder(0, 0, -1, 0, 0, LENGTH + 2, RI)
    (out, _) = occ.cut([(3, outer)], [(3, inner)])
    return out[0][1]


def _tube_material(X, margin=0.0):
    X = np.atleast_2d(X)
    r = np.hypot(X[:, 0], X[:, 1])
    return (r >= RI + margin) & (r <= RO - margin) & (X[:, 2] >= margin) & (X[:, 2] <= LENGTH - margin)


def _tube_effect(rng, sound=False):
    if sound:
        return None
    ok = lambda P: _tube_material(P, 2.0) & (P[:, 2] > 10.0) & (P[:, 2] < LENGTH - 10.0)  # noqa: E731

    def centre(r):
        phi, rad = r.uniform(0, 2 * np.pi), r.uniform(RI + 6.0, RO - 6.0)
        return [rad * np.cos(phi), rad * np.sin(phi), r.uniform(20.0, 40.0)]

    return draw(rng, _Fits(ok, centre), (3.0, 6.0), (0.0, 0.0))


def _tube_points(rng, effect=None, spacing=4.0):
    off = rng.uniform(0, 1, 2) * spacing
    xy = _grid(_ticks(-RO, RO, spacing, off[0]), _ticks(-RO, RO, spacing, off[1]))
    z = _ticks(0.0, LENGTH, spacing)
    X = np.concatenate([np.c_[xy, np.full(len(xy), zz)] for zz in z])
    r = np.hypot(X[:, 0], X[:, 1])
    keep = (r >= RI + 0.3) & (r <= RO - 0.3)  # in the model's and the data's faceted mesh
    if effect is not None:  # a DVC lattice site is in material: off the cavity by a little
        grown = Ellipsoid(effect.centre, tuple(a + 0.3 for a in effect.axes), effect.rotation, 0.0)
        keep &= ~grown.inside(X)
    X = X[keep]
    return X, np.isclose(X[:, 2], 0.0) | np.isclose(X[:, 2], LENGTH)


def _tube_motion(s, X, twist=0.04, pull=1.2):
    a = s * twist
    c, si = np.cos(a), np.sin(a)
    U = np.zeros_like(X)
    U[:, 0] = c * X[:, 0] - si * X[:, 1] - X[:, 0]
    U[:, 1] = si * X[:, 0] + c * X[:, 1] - X[:, 1]
    U[:, 2] = s * pull
    return U


# ------------------------------------------------------------------ the block seen on two faces
BLOCK = (0.0, 0.0, 0.0, 48.0, 24.0, 24.0)


def _block_build(occ):
    x0, y0, z0, x1, y1, z1 = BLOCK
    return occ.addBox(x0, y0, z0, x1 - x0, y1 - y0, z1 - z0)


def _block_material(X, margin=0.0):
    lo, hi = np.asarray(BLOCK[:3]) + margin, np.asarray(BLOCK[3:]) - margin
    X = np.atleast_2d(X)
    return np.all((X >= lo) & (X <= hi), axis=1)


def _block_effect(rng, sound=False):
    if sound:
        return None
    lo, hi = np.asarray(BLOCK[:3]), np.asarray(BLOCK[3:])
    small = (hi - lo).min()
    ok = lambda P: _block_material(P, 0.1 * small) & (P[:, 0] > 6.0) & (P[:, 0] < hi[0] - 6.0)  # noqa: E731
    return draw(rng, _Fits(ok, lambda r: r.uniform(lo + 0.35 * small, hi - 0.35 * small)),
                (0.22 * small, 0.32 * small), (0.1, 0.4))


def _block_points(rng, effect=None, spacing=2.5):
    x0, y0, z0, x1, y1, z1 = BLOCK
    along = _ticks(x0, x1, spacing, (0.5 + rng.uniform(0, 0.5)) * spacing)
    along = along[(along > x0 + 0.5 * spacing) & (along < x1 - 0.5 * spacing)]
    seen = [face_points(1, y1, along, _ticks(z0, z1, spacing)), face_points(2, z1, along, _ticks(y0, y1, spacing))]
    S = np.unique(np.round(np.concatenate(seen), 9), axis=0)
    B = np.concatenate([face_points(0, x, _ticks(y0, y1, spacing), _ticks(z0, z1, spacing)) for x in (x0, x1)])
    return np.concatenate([B, S]), np.r_[np.ones(len(B), bool), np.zeros(len(S), bool)]


def _block_motion(s, X):
    return np.broadcast_to(s * np.array([2.4, 0.0, 0.0]), X.shape).copy()


BODIES = {
    "bracket": Body("bracket", _bracket_build, BRACKET, "top", "right", _bracket_motion, _bracket_material,
                    _bracket_effect, _bracket_points, h_model=6.0, h_data=4.0),
    "tube": Body("tube", _tube_build, TUBE, "back", "front", _tube_motion, _tube_material, _tube_effect,
                 _tube_points, h_model=8.0, h_data=5.0),
    "block2": Body("block2", _block_build, BLOCK, "left", "right", _block_motion, _block_material,
                   _block_effect, _block_points, h_model=5.0, h_data=3.5),
}
CASES = {"bracket": ("bracket", False), "tube": ("tube", False), "block2": ("block2", False),
         "sound": ("bracket", True)}
"""Bundle name -> (body, sound)."""


# ------------------------------------------------------------------ data, model mesh, bundle
FRAMES = (0.5, 1.0)


def solve_body(body: Body, effect: Ellipsoid | None, points: np.ndarray, h: float | None = None, log=None):
    """``(frames, n, 3)`` displacements at ``points`` of ``body`` hiding ``effect``, from P2
    tetrahedra on gmsh's HXT mesh at ``h`` (default ``body.h_data``; ``h / 2`` on the effect)."""
    nodes, cells, inside = gmsh_mesh(body.build, effect, h or body.h_data, algorithm3d=10, algorithm2d=6)
    basis = basis_of(nodes, cells)
    clamp_axis, clamp_at = side_value(body.bbox, body.clamp)
    move_axis, move_at = side_value(body.bbox, body.moved)
    tol = 1e-6 * max(np.ptp(nodes, axis=0))
    where = lambda x: np.isclose(x[clamp_axis], clamp_at, atol=tol) | np.isclose(x[move_axis], move_at, atol=tol)  # noqa: E731

    def motion(s, X):
        return np.where(np.isclose(X[:, move_axis], move_at, atol=tol)[:, None], body.motion(s, X), 0.0)

    ratio = 1.0 if effect is None or effect.ratio == 0 else effect.ratio
    sol = solve(basis, E * np.where(inside, ratio, 1.0), NU, affine_drive(basis, where, motion), FRAMES, log=log)
    return sol.at(points), {"cells": int(len(cells)), "dofs": int(basis.N)}


def write_model_mesh(path, body: Body, h: float | None = None) -> int:
    """A second-order gmsh mesh (Delaunay, MeshAdapt faces) of the sound body at ``h`` (default
    ``body.h_model``) written to ``path`` (``.vtu``: tet10 in VTK's node order). Returns its cells."""
    import meshio

    nodes, cells, _ = gmsh_mesh(body.build, None, h or body.h_model, order=2, algorithm3d=1, algorithm2d=1)
    meshio.Mesh(nodes, [("tetra10", cells[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]])]).write(str(path))
    return len(cells)


def body_bundle(name: str, seed: int, noise: float = 0.005, log=None):
    """The bundle ``name`` (:data:`CASES`) under ``seed``: returns ``(bundle, effect or None, info)``."""
    from refine.bundle.experiment import Experiment, MeshDomain
    from refine.bundle.io import Bundle
    from refine.bundle.observations import Observations

    body_name, sound = CASES[name]
    body = BODIES[body_name]
    rng = np.random.default_rng(seed)
    effect = body.effect(rng, sound)
    X, boundary = body.points(rng, effect)
    U, info = solve_body(body, effect, X, log=log)
    std = noise * float(np.linalg.norm(U, axis=-1).max())
    U = U + rng.normal(0.0, std, U.shape)
    roles = np.where(boundary, "boundary", np.where(rng.uniform(size=len(X)) < 1 / 3, "validate", "guide"))
    exp = Experiment(name=name, kind="solid", domain=MeshDomain("mesh.vtu"), law="neo-hookean", E=E, nu=NU,
                     units={"length": "mm", "stress": "kPa", "force": "mN"}, noise_std=std)
    info.update(points=int(len(X)), boundary=int(boundary.sum()), noise_std=std, seed=seed, body=body_name)
    return Bundle(exp, Observations(np.arange(1, len(X) + 1), X, roles.astype(str), U)), effect, info


def write_body_bundle(root, name: str, seed: int, log=None, **kw) -> Path:
    """:func:`body_bundle` written to ``root`` with ``mesh.vtu`` (the model mesh) and ``truth.json``
    (the effect: kind, centre, axes, rotation, ratio, volume; ``{"kind": "none"}`` for a sound body)."""
    from refine.bundle.io import write_bundle

    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    bundle, effect, info = body_bundle(name, seed, log=log, **kw)
    info["model_cells"] = write_model_mesh(root / "mesh.vtu", BODIES[CASES[name][0]])
    write_bundle(root, bundle)
    lo, hi = np.asarray(BODIES[CASES[name][0]].bbox[:3]), np.asarray(BODIES[CASES[name][0]].bbox[3:])
    truth = {"kind": "none"} if effect is None else effect.to_json()
    truth.update(body=CASES[name][0], diagonal=float(np.linalg.norm(hi - lo)), data=info)
    (root / "truth.json").write_text(json.dumps(truth, indent=1))
    return root
