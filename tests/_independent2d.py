"""An independent 2D solver for test bundles with real exports' quirks (tests only; the library never
imports it): scikit-fem P2 triangles on conforming gmsh meshes, plane-stress compressible
neo-Hookean (the project's law, ``jaxfem.materials.neo_hookean``: psi = mu/2 (I1 - 3) - mu ln J +
lam/2 (ln J)^2, the out-of-plane stretch making the out-of-plane stress vanish at every quadrature
point), Newton written here on scikit-fem's forms with a hand-derived linearisation.

Nothing is shared with ``jaxfem`` but the law's formula: another mesher, element code, quadrature,
Dirichlet handling and Newton. A sheet (default 140 x 80 mm) is clamped at ``x = 0`` and pulled
along x at its right edge (both components prescribed there, as a grip holds it); a hidden effect
(:class:`Effect`: a stiffer or softer ellipse or rectangle, or an elliptic hole) is drawn at random
under a seed; the tracked points are sampled in a layout with a real export's quirks
(:func:`layout`) and written as a :class:`refine.bundle.io.Bundle`.

Quirks (:func:`quirky_bundle`'s ``quirk``):

- ``"grid"``: a regular lattice (the sound case);
- ``"thinned"``: a fine lattice thinned at random to a share of its sites (an export thinned for
  size), points also jittered off the lattice;
- ``"rim"``: a hole whose rim holds DIC points: a point is kept while most of its square subset
  lies on material, and reads the mean displacement of the material part of its subset
  (subsets straddling the rim); the bundle does not state the subset (an export that does not);
- ``"edge"``: the region of interest reaches the sheet's free edges, where correlation degrades:
  points within a band of a free edge are partly lost and the others' noise grows towards it;
- any of them with ``frames=1``: one load step only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SHEET = (0.0, 0.0, 140.0, 80.0)
ROI = (20.0, 10.0, 120.0, 70.0)


@dataclass(frozen=True)
class Effect:
    """A hidden effect: ``kind`` ``"none"``, ``"stiffer-region"``, ``"softer-region"`` or ``"hole"``;
    ``shape`` ``"ellipse"`` (semi-axes ``a, b``) or ``"rectangle"`` (half sides); centre, angle (rad)
    and ``ratio`` (E over the background's; 0 for a hole). Lengths mm."""

    kind: str = "none"
    shape: str = "ellipse"
    cx: float = 0.0
    cy: float = 0.0
    a: float = 0.0
    b: float = 0.0
    angle: float = 0.0
    ratio: float = 1.0

    def contains(self, X: np.ndarray) -> np.ndarray:
        """``(n,)`` bool: points ``(n, 2)`` inside the shape."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        d = np.asarray(X, float) - [self.cx, self.cy]
        u, v = d @ [c, s], d @ [-s, c]
        if self.shape == "rectangle":
            return (np.abs(u) <= self.a) & (np.abs(v) <= self.b)
        return (u / self.a) ** 2 + (v / self.b) ** 2 <= 1.0

    @property
    def area(self) -> float:
        return 4 * self.a * self.b if self.shape == "rectangle" else np.pi * self.a * self.b


def random_effect(rng: np.random.Generator, kind: str, roi=ROI, shape: str | None = None) -> Effect:
    """An effect of ``kind`` drawn inside ``roi`` (a margin of a sixth of its height plus its size
    from the edges): regions 8-12 mm across each semi-axis, ratio 3-8 or its inverse; holes 3-7 mm."""
    if kind == "none":
        return Effect()
    x0, y0, x1, y1 = roi
    m = (y1 - y0) / 6
    if kind == "hole":
        a = rng.uniform(3.0, 7.0)
        b = a * rng.uniform(0.7, 1.0)
        shape, ratio = "ellipse", 0.0
    else:
        a, b = rng.uniform(6.0, 11.0, 2)
        shape = shape or str(rng.choice(["ellipse", "rectangle"]))
        r = rng.uniform(3.0, 8.0)
        ratio = r if kind == "stiffer-region" else 1.0 / r
    reach = np.hypot(a, b)
    cx, cy = rng.uniform(x0 + m + reach, x1 - m - reach), rng.uniform(y0 + m + reach, y1 - m - reach)
    return Effect(kind, shape, float(cx), float(cy), float(a), float(b), float(rng.uniform(0, np.pi)), float(ratio))


# ------------------------------------------------------------------ mesh (gmsh)
def gmsh_mesh(effect: Effect, sheet=SHEET, h: float = 2.0, h_near: float | None = None):
    """A conforming triangle mesh of the sheet with ``effect``'s outline in its edges (an inclusion
    a surface of its own, a hole cut out), element size ``h`` and ``h_near`` (default ``h / 2``)
    along the outline. Returns ``(nodes (n, 2), triangles (t, 3), inside (t,) bool)``."""
    import gmsh

    X0, Y0, X1, Y1 = sheet
    h_near = h_near or 0.5 * h
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("sheet")
        occ = gmsh.model.occ
        plate = occ.addRectangle(X0, Y0, 0, X1 - X0, Y1 - Y0)
        inner = None
        if effect.kind != "none":
            if effect.shape == "rectangle":
                inner = occ.addRectangle(effect.cx - effect.a, effect.cy - effect.b, 0, 2 * effect.a, 2 * effect.b)
            else:
                big, small = max(effect.a, effect.b), min(effect.a, effect.b)
                inner = occ.addDisk(effect.cx, effect.cy, 0, big, small)
                if effect.b > effect.a:
                    occ.rotate([(2, inner)], effect.cx, effect.cy, 0, 0, 0, 1, np.pi / 2)
            occ.rotate([(2, inner)], effect.cx, effect.cy, 0, 0, 0, 1, effect.angle)
            if effect.kind == "hole":
                occ.cut([(2, plate)], [(2, inner)])
                inner = None
            else:
                occ.fragment([(2, plate)], [(2, inner)])
        occ.synchronize()
        curves = [t for d, t in gmsh.model.getEntities(1)]
        outline = [t for t in curves if not _on_sheet_edge(gmsh.model.getBoundingBox(1, t), sheet)]
        if outline:
            f = gmsh.model.mesh.field
            dist = f.add("Distance")
            f.setNumbers(dist, "CurvesList", outline)
            f.setNumber(dist, "Sampling", 200)
            thr = f.add("Threshold")
            f.setNumber(thr, "InField", dist)
            f.setNumber(thr, "SizeMin", h_near)
            f.setNumber(thr, "SizeMax", h)
            f.setNumber(thr, "DistMin", 1.0)
            f.setNumber(thr, "DistMax", 6.0)
            f.setAsBackgroundMesh(thr)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.model.mesh.generate(2)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        index = np.zeros(int(tags.max()) + 1, np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        nodes = coords.reshape(-1, 3)[:, :2]
        tris, inside = [], []
        for _, surface in gmsh.model.getEntities(2):
            _, _, conn = gmsh.model.mesh.getElements(2, surface)
            t = index[np.asarray(conn[0], np.int64)].reshape(-1, 3)
            tris.append(t)
            centre = nodes[t].mean(1)
            # a surface is the inclusion's when most of its triangles' centres lie in the shape
            inside.append(np.full(len(t), effect.kind not in ("none", "hole") and effect.contains(centre).mean() > 0.5))
    finally:
        gmsh.finalize()
    tri = np.concatenate(tris)
    used = np.unique(tri)  # gmsh keeps the cut shape's nodes
    renumber = np.full(len(nodes), -1)
    renumber[used] = np.arange(len(used))
    return nodes[used], renumber[tri], np.concatenate(inside)


def _on_sheet_edge(box, sheet) -> bool:
    x0, y0, _, x1, y1, _ = box
    X0, Y0, X1, Y1 = sheet
    tol = 1e-6
    return (abs(x0 - x1) < tol and (abs(x0 - X0) < tol or abs(x0 - X1) < tol)) or (
        abs(y0 - y1) < tol and (abs(y0 - Y0) < tol or abs(y0 - Y1) < tol))


# ------------------------------------------------------------------ solve (scikit-fem)
def _mm(A, B):
    return np.einsum("ij...,jk...->ik...", A, B)


def _plane_stress_state(F, mu, lam):
    """Out-of-plane stretch ``l3`` with zero out-of-plane stress, ``ln J`` of the 3D gradient and
    ``c = d ln J / d ln J2``: mu (l3^2 - 1) + lam ln(J2 l3) = 0, solved by Newton pointwise."""
    J2 = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    l3 = 1.0 / np.sqrt(J2)
    for _ in range(30):
        g = mu * (l3**2 - 1.0) + lam * np.log(J2 * l3)
        dl = g / (2.0 * mu * l3 + lam / l3)
        l3 = l3 - dl
        if np.max(np.abs(dl)) < 1e-14:
            break
    return np.log(J2 * l3), 2.0 * mu * l3**2 / (2.0 * mu * l3**2 + lam)


def _forms(nu: float):
    import skfem
    from skfem.helpers import ddot, grad, identity, inv, transpose

    def state(w):
        mu = w["E"] / (2 * (1 + nu))
        lam = w["E"] * nu / ((1 + nu) * (1 - 2 * nu))
        F = identity(grad(w["u"])) + grad(w["u"])
        lnJ, c = _plane_stress_state(F, mu, lam)
        return F, transpose(inv(F)), lnJ, c, mu, lam

    @skfem.LinearForm
    def residual(v, w):
        F, Fit, lnJ, _, mu, lam = state(w)
        return ddot(mu * F + (lam * lnJ - mu) * Fit, grad(v))

    @skfem.BilinearForm
    def tangent(du, v, w):
        F, Fit, lnJ, c, mu, lam = state(w)
        dF = grad(du)
        dP = mu * dF + (mu - lam * lnJ) * _mm(_mm(Fit, transpose(dF)), Fit) + lam * c * ddot(Fit, dF) * Fit
        return ddot(dP, grad(v))

    return residual, tangent


@dataclass
class Solution:
    """Displacements of the sheet at each load fraction, on scikit-fem's P2 basis."""

    basis: object
    u: list

    def at(self, X: np.ndarray) -> np.ndarray:
        """``(frames, n, 2)`` displacements at points ``(n, 2)`` (each inside the mesh)."""
        X = np.asarray(X, float).T
        parts = [(b.probes(X), idx) for b, idx in zip(self.basis.split_bases(), self.basis.split_indices())]
        return np.stack([np.stack([P @ u[idx] for P, idx in parts], 1) for u in self.u])


def solve_sheet(effect: Effect, E: float = 83.76, nu: float = 0.3, pull: float = 0.15,
                fractions=(0.25, 0.5, 0.75, 1.0), sheet=SHEET, h: float = 2.0, h_near: float | None = None,
                substeps: int = 2) -> Solution:
    """The pulled sheet hiding ``effect`` at each load fraction of ``pull`` (stretch of the sheet)."""
    import skfem

    nodes, tri, inside = gmsh_mesh(effect, sheet, h, h_near)
    mesh = skfem.MeshTri(nodes.T.copy(), tri.T.copy())
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTriP2()), intorder=4)
    Ecell = np.where(inside, E * effect.ratio, E)
    Eq = np.repeat(Ecell[:, None], basis.X.shape[1], axis=1)
    residual, tangent = _forms(nu)
    X0, _, X1, _ = sheet
    left = basis.get_dofs(lambda x: np.isclose(x[0], X0)).all()
    right_dofs = basis.get_dofs(lambda x: np.isclose(x[0], X1))
    right_x, right_all = right_dofs.all("u^1"), right_dofs.all()
    fixed = np.unique(np.concatenate([left, right_all]))
    u = np.zeros(basis.N)
    out = []
    steps = [prev + (s - prev) * (k + 1) / substeps for prev, s in zip((0.0, *fractions[:-1]), fractions)
             for k in range(substeps)]
    xdofs = np.zeros(basis.N, bool)
    xdofs[basis.split_indices()[0]] = True
    ramp = np.where(xdofs, (basis.doflocs[0] - X0) / (X1 - X0), 0.0)  # a start: the last state plus a uniform stretch
    done = 0.0
    for s in steps:
        target = np.zeros(basis.N)
        target[right_x] = s * pull * (X1 - X0)
        u = u + (s - done) * pull * (X1 - X0) * ramp
        u[fixed] = target[fixed]
        done = s
        for it in range(40):
            uh = basis.interpolate(u)
            r = residual.assemble(basis, u=uh, E=Eq)
            K = tangent.assemble(basis, u=uh, E=Eq)
            r[fixed] = 0.0
            du = skfem.solve(*skfem.condense(K, -r, D=fixed))
            u = u + du
            if np.max(np.abs(du)) < 1e-10 * (1.0 + np.max(np.abs(u))):
                break
        else:
            raise RuntimeError(f"Newton did not converge at load fraction {s:.3f}")
        if any(np.isclose(s, f) for f in fractions):
            out.append(u.copy())
    return Solution(basis, out)


# ------------------------------------------------------------------ point layouts and bundles
def _lattice(roi, step: float) -> np.ndarray:
    x0, y0, x1, y1 = roi
    xs = np.linspace(x0, x1, int(round((x1 - x0) / step)) + 1)
    ys = np.linspace(y0, y1, int(round((y1 - y0) / step)) + 1)
    return np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)


def _on_outline(X, roi, tol: float = 1e-9) -> np.ndarray:
    x0, y0, x1, y1 = roi
    return ((np.abs(X[:, 0] - x0) < tol) | (np.abs(X[:, 0] - x1) < tol)
            | (np.abs(X[:, 1] - y0) < tol) | (np.abs(X[:, 1] - y1) < tol))


def layout(quirk: str, rng: np.random.Generator, effect: Effect, roi=ROI, spacing: float = 5.0,
           fine: float = 2.0, keep: float = 0.3, subset: float | None = None):
    """Tracked points of a layout with ``quirk`` (see the module docstring). Returns
    ``(points (n, 2), boundary (n,) bool, subset_of (n,) float or None, noise_gain (n,))``:
    ``subset_of`` the side of the square whose material part a point reads (None: the point
    itself), ``noise_gain`` the factor on each point's noise. Points whose centre is in a hole
    (or, for ``"rim"``, whose subset is mostly on it) are left out."""
    if quirk in ("grid", "edge"):
        X = _lattice(roi, spacing)
    else:  # a fine lattice thinned at random, its outline at every other site, interior sites jittered
        X = _lattice(roi, fine)
        edge = _on_outline(X, roi)
        ij = np.round((X - roi[:2]) / fine).astype(int)
        keep_edge = edge & (((ij[:, 0] + ij[:, 1]) % 2) == 0)
        kept = keep_edge | (~edge & (rng.random(len(X)) < keep))
        X = X[kept]
        inner = ~_on_outline(X, roi)
        X[inner] += rng.uniform(-0.15, 0.15, (inner.sum(), 2)) * fine
    boundary = _on_outline(X, roi)
    gain = np.ones(len(X))
    side = None
    if quirk == "edge":  # correlation degrades towards the sheet's free edges y = roi's ymin and ymax
        d = np.minimum(X[:, 1] - roi[1], roi[3] - X[:, 1])
        gain = 1.0 + 3.0 * np.exp(-d / spacing)
        lost = (d > 0) & (d < 1.5 * spacing) & (rng.random(len(X)) < 0.3) & ~boundary
        X, boundary, gain = X[~lost], boundary[~lost], gain[~lost]
    if effect.kind == "hole":
        if quirk == "rim":
            side = subset or 1.5 * fine
            t = (np.arange(7) + 0.5) / 7 - 0.5
            S = np.stack(np.meshgrid(t, t), -1).reshape(-1, 2) * side
            on = ~effect.contains((X[:, None, :] + S[None]).reshape(-1, 2)).reshape(len(X), -1)
            ok = on.mean(1) >= 0.55
        else:
            ok = ~effect.contains(X) & ~_near_outline(effect, X, 0.3 * fine if quirk == "thinned" else 0.3 * spacing)
        ok |= boundary
        X, boundary, gain = X[ok], boundary[ok], gain[ok]
    return X, boundary, side, gain


def _near_outline(effect: Effect, X, dist: float) -> np.ndarray:
    """Points within ``dist`` of the effect's outline (sampled densely)."""
    t = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    c, s = np.cos(effect.angle), np.sin(effect.angle)
    u, v = effect.a * np.cos(t), effect.b * np.sin(t)
    curve = np.stack([effect.cx + c * u - s * v, effect.cy + s * u + c * v], 1)
    from scipy.spatial import cKDTree

    return cKDTree(curve).query(X)[0] < dist


def measured(solution: Solution, X, effect: Effect, side: float | None) -> np.ndarray:
    """``(frames, n, 2)``: each point's displacement, or with a subset ``side`` the mean over the
    material part of its square subset (7 x 7 samples)."""
    if side is None:
        return solution.at(X)
    t = (np.arange(7) + 0.5) / 7 - 0.5
    S = np.stack(np.meshgrid(t, t), -1).reshape(-1, 2) * side
    Y = (X[:, None, :] + S[None]).reshape(-1, 2)
    on = ~effect.contains(Y) if effect.kind == "hole" else np.ones(len(Y), bool)
    x0, y0, x1, y1 = SHEET
    on &= (Y[:, 0] >= x0) & (Y[:, 0] <= x1) & (Y[:, 1] >= y0) & (Y[:, 1] <= y1)
    U = np.zeros((len(solution.u), len(Y), 2))
    U[:, on] = solution.at(Y[on])
    w = on.reshape(len(X), -1).astype(float)
    return np.einsum("fnsk,ns->fnk", U.reshape(len(solution.u), len(X), -1, 2), w) / w.sum(1)[None, :, None]


def to_bundle(X, boundary, U, noise: float, rng: np.random.Generator, roi=ROI, name: str = "independent",
              gain=None, E: float = 83.76, nu: float = 0.3, validate_fraction: float = 0.2):
    """A :class:`refine.bundle.io.Bundle` of points ``X`` (``boundary`` the driving ones on the
    outline of ``roi``, the domain) with displacements ``U`` plus Gaussian noise (``noise`` mm,
    times ``gain`` per point); a share of the interior points are validation points. The stated
    noise is ``noise`` (0: noise-free)."""
    from refine.bundle.experiment import Experiment, RectangleDomain
    from refine.bundle.io import Bundle
    from refine.bundle.observations import Observations

    gain = np.ones(len(X)) if gain is None else gain
    disp = U + noise * gain[None, :, None] * rng.standard_normal(U.shape)
    roles = np.where(boundary, "boundary", "guide").astype(object)
    interior = np.flatnonzero(~boundary)
    roles[rng.choice(interior, int(round(validate_fraction * len(interior))), replace=False)] = "validate"
    ex = Experiment(name=name, kind="plane-stress", domain=RectangleDomain(*roi), law="neo-hookean", E=E, nu=nu,
                    thickness=1.0, units={"length": "mm", "stress": "kPa", "force": "mN"}, noise_std=noise)
    obs = Observations(ids=np.arange(1, len(X) + 1), reference=np.asarray(X, float), roles=np.asarray(roles, str),
                       displacements=disp)
    return Bundle(ex, obs)


QUIRKS = ("grid", "thinned", "rim", "edge")


def quirky_bundle(seed: int, quirk: str, kind: str, frames: int = 1, noise: float = 0.01, h: float = 2.0,
                  shape: str | None = None):
    """A bundle of a sheet hiding an effect of ``kind`` drawn under ``seed``, its points in the
    ``quirk`` layout, ``frames`` load steps up to 15 % stretch. Returns ``(bundle, effect)``."""
    rng = np.random.default_rng(seed)
    effect = random_effect(rng, kind, shape=shape)
    roi = (20.0, 0.0, 120.0, 80.0) if quirk == "edge" else ROI
    fractions = tuple(np.linspace(1.0 / frames, 1.0, frames))
    sol = solve_sheet(effect, fractions=fractions, h=h)
    X, boundary, side, gain = layout(quirk, rng, effect, roi)
    U = measured(sol, X, effect, side)
    return to_bundle(X, boundary, U, noise, rng, roi, name=f"{quirk}-{kind}-{seed}", gain=gain), effect


def square_bundle(h: float = 1.5):
    """The noise-free square of issue 44: 20 x 20 mm, ratio 10, in the 140 x 80 mm sheet pulled 15 %,
    observed on ROI's 5 mm grid, 4 frames. Returns ``(bundle, effect)``."""
    effect = Effect("stiffer-region", "rectangle", 67.0, 38.0, 10.0, 10.0, 0.0, 10.0)
    sol = solve_sheet(effect, h=h)
    X, boundary, _, _ = layout("grid", np.random.default_rng(0), effect)
    return to_bundle(X, boundary, sol.at(X), 0.0, np.random.default_rng(0), name="square-ratio-10"), effect
