"""An independent 3D solver for test bundles (tests only; the library never imports it): scikit-fem
P2 tetrahedra (``ElementVector(ElementTetP2())``) on conforming gmsh meshes built with
OpenCASCADE booleans (an inclusion a volume of its own, a cavity cut out), the project's
compressible neo-Hookean law (``jaxfem.materials.neo_hookean``: psi = mu/2 (I1 - 3) - mu ln J +
lam/2 (ln J)^2), Newton written here on scikit-fem's forms with a hand-derived linearisation,
load steps and scipy's sparse direct solve.

Nothing is shared with ``jaxfem`` but the law's formula: another mesher (gmsh, its own settings),
element code and quadrature (scikit-fem), Dirichlet handling (scikit-fem's condense) and Newton.

A body is built by a function ``build(occ) -> volume tag`` of gmsh's OpenCASCADE kernel; the hidden
effect (:class:`Ellipsoid`) is fragmented into it (an inclusion, ``ratio > 0``) or cut out of it
(a cavity, ``ratio == 0``). Lengths mm, moduli kPa (any consistent set).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Ellipsoid:
    """A hidden ellipsoid: ``centre (3,)``, semi-axes ``axes (3,)`` (mm) along the columns of
    ``rotation (3, 3)``; ``ratio`` its modulus over the body's (0: a cavity)."""

    centre: tuple
    axes: tuple
    rotation: tuple
    ratio: float

    def inside(self, X) -> np.ndarray:
        """``(n,)`` bool: points ``X (n, 3)`` inside the ellipsoid."""
        local = (np.asarray(X, float) - np.asarray(self.centre)) @ np.asarray(self.rotation)
        return ((local / np.asarray(self.axes)) ** 2).sum(axis=1) <= 1.0

    def surface(self, n: int = 400) -> np.ndarray:
        """``(n, 3)`` points on its surface (a Fibonacci lattice of the unit sphere, mapped)."""
        k = np.arange(n) + 0.5
        phi, z = np.pi * (1 + 5 ** 0.5) * k, 1 - 2 * k / n
        s = np.sqrt(1 - z ** 2)
        unit = np.stack([s * np.cos(phi), s * np.sin(phi), z], 1)
        return self.centre + (unit * self.axes) @ np.asarray(self.rotation).T

    @property
    def volume(self) -> float:
        """Its volume (mm^3)."""
        return float(4.0 / 3.0 * np.pi * np.prod(self.axes))

    @property
    def kind(self) -> str:
        return "cavity" if self.ratio == 0 else ("stiffer-region" if self.ratio > 1 else "softer-region")

    def to_json(self) -> dict:
        return {"kind": self.kind, "centre": list(map(float, self.centre)), "axes": list(map(float, self.axes)),
                "rotation": [list(map(float, r)) for r in self.rotation], "ratio": float(self.ratio),
                "volume": self.volume}


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation ``(3, 3)`` drawn uniformly (QR of a Gaussian matrix, signs fixed)."""
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


# ------------------------------------------------------------------ mesh (gmsh, OpenCASCADE)
def _occ_body(build, effect: Ellipsoid | None):
    """The body in gmsh's current model, ``effect`` fragmented in or cut out; returns the effect's
    surface tags (for a size field)."""
    import gmsh

    occ = gmsh.model.occ
    body = build(occ)
    if effect is None:
        occ.synchronize()
        return []
    ball = occ.addSphere(0.0, 0.0, 0.0, 1.0)
    M = np.asarray(effect.rotation) @ np.diag(effect.axes)
    occ.affineTransform([(3, ball)], [*M[0], effect.centre[0], *M[1], effect.centre[1], *M[2], effect.centre[2]])
    if effect.ratio == 0:
        occ.cut([(3, body)], [(3, ball)])
    else:
        occ.fragment([(3, body)], [(3, ball)])
    occ.synchronize()
    lo, hi = np.asarray(effect.centre) - max(effect.axes) - 1e-3, np.asarray(effect.centre) + max(effect.axes) + 1e-3
    return [t for _, t in gmsh.model.getEntitiesInBoundingBox(*lo, *hi, 2)]


def gmsh_mesh(build, effect: Ellipsoid | None, h: float, h_near: float | None = None, order: int = 1,
              algorithm3d: int = 1, algorithm2d: int = 6, path: str | None = None):
    """A conforming tetrahedral mesh of the body ``build`` makes (with ``effect``), element size ``h``
    and ``h_near`` (default ``h / 2``) on the effect's surface. ``order`` 1: ``tet4`` cells, 2: gmsh's
    ``tet10``. ``path``: also write the mesh there (gmsh's writer, e.g. ``.msh``).

    Returns ``(nodes (n, 3), cells (t, 4 or 10) in gmsh's node order, inside (t,) bool)``:
    ``inside`` the cells of the inclusion's volume."""
    import gmsh

    h_near = h_near or 0.5 * h
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("body")
        near = _occ_body(build, effect)
        if near:
            f = gmsh.model.mesh.field
            dist = f.add("Distance")
            f.setNumbers(dist, "SurfacesList", near)
            f.setNumber(dist, "Sampling", 60)
            thr = f.add("Threshold")
            f.setNumber(thr, "InField", dist)
            f.setNumber(thr, "SizeMin", h_near)
            f.setNumber(thr, "SizeMax", h)
            f.setNumber(thr, "DistMin", 0.5 * h)
            f.setNumber(thr, "DistMax", 3.0 * h)
            f.setAsBackgroundMesh(thr)
            gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)  # OCC points carry a size from the bbox
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.25 * h_near)
        gmsh.option.setNumber("Mesh.Algorithm", algorithm2d)
        gmsh.option.setNumber("Mesh.Algorithm3D", algorithm3d)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.model.mesh.generate(3)
        if order == 2:
            gmsh.model.mesh.setOrder(2)
            gmsh.option.setNumber("Mesh.HighOrderOptimize", 0)
        if path is not None:
            gmsh.write(str(path))
        tags, coords, _ = gmsh.model.mesh.getNodes()
        index = np.zeros(int(tags.max()) + 1, np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        nodes = coords.reshape(-1, 3)
        cells, inside = [], []
        per = 4 if order == 1 else 10
        for _, vol in gmsh.model.getEntities(3):
            _, _, conn = gmsh.model.mesh.getElements(3, vol)
            t = index[np.asarray(conn[0], np.int64)].reshape(-1, per)
            cells.append(t)
            in_effect = effect is not None and effect.ratio > 0 and effect.inside(nodes[t[:, :4]].mean(1)).mean() > 0.5
            inside.append(np.full(len(t), in_effect))
    finally:
        gmsh.finalize()
    cells = np.concatenate(cells)
    used = np.unique(cells)  # nodes of cut-away shapes stay in gmsh's list
    renumber = np.full(len(nodes), -1)
    renumber[used] = np.arange(len(used))
    return nodes[used], renumber[cells], np.concatenate(inside)


# ------------------------------------------------------------------ solve (scikit-fem)
def _mm(A, B):
    return np.einsum("ij...,jk...->ik...", A, B)


def _forms():
    """The first Piola stress's weak form, P = mu F + (lam ln J - mu) F^-T, and one block of its
    linearisation on the scalar P2 basis: dP_iJ = A_iJkL dF_kL with the hand-derived
    A_iJkL = mu d_ik d_JL + (mu - lam ln J) F^-T_iL F^-T_kJ + lam F^-T_iJ F^-T_kL; the block
    (c, d) is int d_J v  A_cJdL  d_L du (``w["A"]`` the ``(3, 3)`` slice ``A[c, :, d, :]``)."""
    import skfem
    from skfem.helpers import ddot, det, grad, identity, inv, transpose

    def state(w):
        F = identity(grad(w["u"])) + grad(w["u"])
        return F, transpose(inv(F)), np.log(det(F))

    @skfem.LinearForm
    def residual(v, w):
        F, Fit, lnJ = state(w)
        return ddot(w["mu"] * F + (w["lam"] * lnJ - w["mu"]) * Fit, grad(v))

    @skfem.BilinearForm
    def block(du, v, w):
        A, gu, gv = w["A"], grad(du), grad(v)
        return sum(gv[J] * (A[J, 0] * gu[0] + A[J, 1] * gu[1] + A[J, 2] * gu[2]) for J in range(3))

    return residual, block, state


def tangent_tensor(Fit, lnJ, mu, lam) -> np.ndarray:
    """``A (3, 3, 3, 3, ...)``: dP_iJ / dF_kL of the neo-Hookean law (see :func:`_forms`)."""
    I = np.eye(3).reshape(3, 1, 3, 1, *([1] * mu.ndim)) * np.eye(3).reshape(1, 3, 1, 3, *([1] * mu.ndim))
    return (mu * I + (mu - lam * lnJ) * np.einsum("iL...,kJ...->iJkL...", Fit, Fit)
            + lam * np.einsum("iJ...,kL...->iJkL...", Fit, Fit))


def assemble_tangent(basis, block, A) -> "scipy.sparse.csr_matrix":
    """The vector basis's tangent from the six blocks of the scalar basis (the vector DOF of
    component c at scalar DOF j is 3 j + c, scikit-fem's interleaving; A's major symmetry gives
    block (d, c) as (c, d) transposed)."""
    from scipy.sparse import coo_matrix

    sb = basis.split_bases()[0]
    rows, cols, vals = [], [], []
    for c in range(3):
        for d in range(c, 3):
            K = block.assemble(sb, A=np.ascontiguousarray(A[c, :, d, :])).tocoo()
            for (a, b) in ((c, d), (d, c)) if d != c else ((c, d),):
                r, q = (K.row, K.col) if a == c else (K.col, K.row)
                rows.append(3 * r + a)
                cols.append(3 * q + b)
                vals.append(K.data)
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(basis.N, basis.N)).tocsr()


@dataclass
class Solution:
    """Displacements at each load step kept, on scikit-fem's vector P2 basis."""

    basis: object
    u: list

    def at(self, X: np.ndarray) -> np.ndarray:
        """``(frames, n, 3)`` displacements at points ``(n, 3)`` (each inside the mesh)."""
        X = nudged_inside(self.basis.mesh, np.asarray(X, float)).T
        parts = [(b.probes(X), idx) for b, idx in zip(self.basis.split_bases(), self.basis.split_indices())]
        return np.stack([np.stack([P @ u[idx] for P, idx in parts], 1) for u in self.u])

    def reaction(self, frame: int, dofs) -> float:
        """The sum of the internal forces at ``dofs`` in load step ``frame`` (the reaction there)."""
        return float(self.r[frame][np.asarray(dofs)].sum())


def nudged_inside(mesh, X: np.ndarray, k: int = 64) -> np.ndarray:
    """Points ``X (n, 3)`` moved 1e-7 of the way towards the centroid of the cell that holds them
    (the candidate among the ``k`` nearest centroids with the largest least barycentric
    coordinate), so that points on the mesh's faces lie strictly in a cell for scikit-fem's finder.
    Raises ValueError naming a point more than 1e-6 (in barycentric terms) outside every cell."""
    from scipy.spatial import cKDTree

    V = mesh.p.T[mesh.t.T]  # (t, 4, 3)
    centre = V.mean(1)
    _, cand = cKDTree(centre).query(X, k=min(k, len(V)))
    T = V[cand]  # (n, k, 4, 3)
    M = np.swapaxes(T[:, :, 1:] - T[:, :, :1], -1, -2)
    lam = np.linalg.solve(M, (X[:, None, :] - T[:, :, 0])[..., None])[..., 0]
    least = np.minimum(lam.min(-1), 1.0 - lam.sum(-1))
    best = least.argmax(1)
    worst = np.argmin(least[np.arange(len(X)), best])
    if least[worst, best[worst]] < -1e-6:
        if k < len(V):  # a sliver's centroid may be farther than k others: look wider
            return nudged_inside(mesh, X, 8 * k)
        raise ValueError(f"point {X[worst]} lies outside the mesh (barycentric {least[worst, best[worst]]:.3g})")
    return X + 1e-7 * (centre[cand[np.arange(len(X)), best]] - X)


def basis_of(nodes: np.ndarray, cells: np.ndarray, intorder: int = 3):
    """scikit-fem's vector P2 basis on the straight-sided tetrahedra ``cells[:, :4]``."""
    import skfem

    mesh = skfem.MeshTet(nodes.T.copy(), np.ascontiguousarray(cells[:, :4].T))
    return skfem.Basis(mesh, skfem.ElementVector(skfem.ElementTetP2()), intorder=intorder)


def solve(basis, E_cell: np.ndarray, nu: float, drive, steps, substeps: int = 1, tol: float = 1e-10,
          log=None) -> Solution:
    """Solve the body on ``basis`` with cell moduli ``E_cell (t,)`` and Poisson's ratio ``nu``.

    ``drive(s) -> (dofs, values)``: the prescribed displacement components at load parameter ``s``;
    ``steps``: the load parameters kept (increasing, > 0), each reached in ``substeps`` increments
    from the one before. Each increment starts from the tangent's response to the increment of the
    prescribed values (a consistent predictor) and iterates Newton with that factorised tangent
    (scipy's SuperLU), factorising the tangent again where an iteration contracts by less than
    half, until the largest correction is under ``tol`` times the largest prescribed value (plus
    one). Returns a :class:`Solution` whose ``r`` holds the internal force vector at each kept step."""
    import skfem
    from scipy.sparse.linalg import splu

    residual, block, state = _forms()
    nq = basis.X.shape[1]
    E = np.repeat(np.asarray(E_cell, float)[:, None], nq, axis=1)
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    u = np.zeros(basis.N)
    kept, forces = [], []
    params = [prev + (s - prev) * (k + 1) / substeps for prev, s in zip((0.0, *steps[:-1]), steps)
              for k in range(substeps)]

    def tangent(u):
        _, Fit, lnJ = state({"u": basis.interpolate(u)})
        if np.any(~np.isfinite(lnJ)):
            raise RuntimeError("an element inverted; use more substeps")
        return assemble_tangent(basis, block, tangent_tensor(Fit, lnJ, mu, lam))

    for s in params:
        dofs, values = drive(s)
        dofs = np.asarray(dofs)
        scale = 1.0 + (np.max(np.abs(values)) if len(values) else 0.0)
        x = np.zeros(basis.N)
        x[dofs] = values - u[dofs]
        r = residual.assemble(basis, u=basis.interpolate(u), mu=mu, lam=lam)
        A, b, du, free = skfem.condense(tangent(u), -r, x=x, D=dofs)
        lu = splu(A.tocsc(), permc_spec="COLAMD")
        du[free] = lu.solve(b)
        u = u + du
        last = np.inf
        for it in range(60):
            r = residual.assemble(basis, u=basis.interpolate(u), mu=mu, lam=lam)
            du = np.zeros(basis.N)
            du[free] = lu.solve(-r[free])
            u = u + du
            step = np.max(np.abs(du))
            if log:
                log(f"s {s:.3f} it {it} |du| {step:.3e}")
            if step < tol * scale:
                break
            if step > 0.5 * last:
                lu = splu(tangent(u)[free][:, free].tocsc(), permc_spec="COLAMD")
            last = step
        else:
            raise RuntimeError(f"Newton did not converge at load parameter {s:.3f}")
        if any(np.isclose(s, t) for t in steps):
            kept.append(u.copy())
            forces.append(residual.assemble(basis, u=basis.interpolate(u), mu=mu, lam=lam))
    sol = Solution(basis, kept)
    sol.r = forces
    return sol


def component_dofs(basis, where, component: int) -> np.ndarray:
    """DOFs of displacement ``component`` (0, 1, 2) at the nodes and edge midpoints ``where(x)``
    selects (``x (3, n)`` -> ``(n,)`` bool)."""
    return basis.get_dofs(where).all(f"u^{component + 1}")


def affine_drive(basis, where, motion):
    """A drive (see :func:`solve`) holding every component at the DOFs ``where`` selects to
    ``motion(s, X (n, 3)) -> (n, 3)``, the prescribed displacement at load parameter ``s``."""
    dofs = [component_dofs(basis, where, c) for c in range(3)]
    X = [basis.doflocs[:, d].T for d in dofs]

    def drive(s):
        return np.concatenate(dofs), np.concatenate([motion(s, x)[:, c] for c, x in enumerate(X)])

    return drive
