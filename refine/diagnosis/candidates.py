"""Candidate regions from what the data show, beside the fitted modulus field
(:mod:`refine.diagnosis.localize`): gaps in the tracked points inside the domain (a hole has no
material points, so nothing can be tracked there) and places where the measured strain map
departs from the initial model's (the paper reads a scar as a pocket of low measured strain, a
hole as one of high strain).

Any point layout: a gap is judged against the layout's own density where the points are not on a
full lattice (an export thinned for size leaves wide empty discs by chance), and a narrower gap
inside a softer candidate proposes a hole too; a candidate at the outline where the points are
noisier than elsewhere (correlation lost near a free edge) is judged against that edge's own
noise. Each way of proposing places is a registered source (:mod:`refine.causes.sources`) calling
these functions; :func:`data_candidates` lists every 2D source's candidates.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float
from scipy import ndimage
from scipy.spatial import cKDTree

import jaxfem as jf

from refine.bundle.experiment import PolygonDomain, RectangleDomain
from refine.diagnosis.localize import Candidate, moment_ellipse, segment, segment_cells
from refine.diagnosis.measured_strain import equivalent_strain, point_spacing, point_triangles, triangle_gradients

GAP = 1.5
"""A place is a gap in the points of a lattice when its nearest tracked point is more than this
many point spacings away (a single lost point of a grid leaves one spacing; two leave 1.1)."""

FALSE_GAPS = 0.05
"""Irregular layouts (a thinned or jittered lattice, scattered points): a gap is one so wide that
the layout's own density would leave one as wide anywhere in the domain this rarely (expected
count, :func:`gap_radius`)."""

SOFT_GAPS = 0.5
"""A narrower gap inside a softer candidate (:func:`soft_gaps`) proposes a hole when the
layout's density would leave one as wide inside that candidate this rarely (expected count)."""

EDGE_MISFIT = 2.0
"""A candidate at the domain's outline where the points are noisier than elsewhere is an edge
artefact when the initial model's misfit of its points, over their own noise, is below this
(per residual; :func:`edge_artefact`)."""


def domain_contains(domain, X: Float[np.ndarray, "n 2"]) -> np.ndarray:
    """``(n,)`` bool: inside a rectangle or polygon domain and outside its known holes (all True
    for a mesh file's domain, which says no more than its points)."""
    if isinstance(domain, RectangleDomain):
        inside = ((X[:, 0] >= domain.xmin) & (X[:, 0] <= domain.xmax)
                  & (X[:, 1] >= domain.ymin) & (X[:, 1] <= domain.ymax))
    elif isinstance(domain, PolygonDomain):
        inside = np.asarray(jf.Polygon(np.asarray(domain.vertices)).contains(X), bool)
    else:
        return np.ones(len(X), bool)
    for hole in getattr(domain, "holes", ()):
        inside &= ~np.asarray(jf.Polygon(np.asarray(hole)).contains(X), bool)
    return inside


def _raster(points, domain, s):
    """A raster of step ``s / 4`` over the points' box grown by ``s``: its positions ``(m, 2)``,
    shape, inside-domain mask and distance to the nearest point (both of that shape)."""
    step = s / 4.0
    lo, hi = points.min(0) - s, points.max(0) + s
    xs, ys = np.arange(lo[0], hi[0] + step, step), np.arange(lo[1], hi[1] + step, step)
    X = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    inside = domain_contains(domain, X).reshape(len(ys), len(xs))
    dist = cKDTree(points).query(X)[0].reshape(len(ys), len(xs))
    return X, step, inside, dist


def _empty_count(radius: float, density: float, area: float) -> float:
    """Expected number of empty discs of at least ``radius`` whose centres lie in ``area`` among
    points scattered at random at ``density``: twice the points there (a Delaunay triangle per
    point and a half) times the chance that a triangle's circumdisc is that wide, (1 + x) e^-x
    with x = density pi radius^2 (its area holds Gamma(2) points on average)."""
    x = density * np.pi * radius**2
    return 2.0 * density * area * (1.0 + x) * np.exp(-x)


def _radius_for(count: float, density: float, area: float) -> float:
    """The radius at which :func:`_empty_count` falls to ``count``."""
    r = np.sqrt(1.0 / (density * np.pi))
    while _empty_count(r, density, area) > count:
        r *= 1.02
    return float(r)


def gap_radius(points: Float[np.ndarray, "n 2"], area: float, gap: float = GAP) -> float:
    """How far from every point a place must be to be a gap (length unit): ``gap`` point spacings
    on a regular layout (a lattice with most of its sites tracked, jittered or not: the median
    nearest-neighbour distance at least 0.7 times that of a square lattice of the same density
    over ``area``; scattered points reach about 0.47, a lattice thinned to a third about 0.55);
    on any other layout the radius that the layout's density would exceed by chance
    :data:`FALSE_GAPS` times in ``area`` (:func:`_empty_count`), and at least ``gap``
    spacings."""
    s = point_spacing(points)
    r = gap * s
    if s >= 0.7 * np.sqrt(area / len(points)):
        return r
    return max(r, _radius_for(FALSE_GAPS, len(points) / area, area))


def missing_point_regions(points: Float[np.ndarray, "n 2"], domain, gap: float = GAP) -> list[Candidate]:
    """Gaps in the tracked points inside the domain, largest first, as softer candidates (source
    ``"missing-points"``): the places farther than :func:`gap_radius` from every point (on a
    lattice ``gap`` point spacings; on an irregular layout farther than its density explains),
    in connected patches that do not reach the domain's outline and span at least a disc of one
    spacing. Each is summarised by its ellipse of moments, grown by the gap radius less half a
    spacing (the patch stops that far short of the points, which stop about half a spacing
    short of the hole's edge); a hole fitted from it is shrunk until no point lies inside
    (:func:`refine.diagnosis.holes.hole_hypothesis`)."""
    points = np.asarray(points, float)
    s = point_spacing(points)
    X, step, inside, dist = _raster(points, domain, s)
    radius = gap_radius(points, inside.sum() * step**2, gap)
    empty = inside & (dist > radius)
    at_outline = ndimage.binary_dilation(~inside, iterations=2)
    label, n = ndimage.label(empty)
    out = []
    for k in range(1, n + 1):
        patch = label == k
        area = patch.sum() * step**2
        if (patch & at_outline).any() or area < np.pi * s**2:
            continue
        idx = np.flatnonzero(patch.ravel())
        centre, axes, angle = moment_ellipse(X[idx], np.full(len(idx), step**2))
        out.append(Candidate(-1, idx, centre, axes + radius - 0.5 * s, angle, float(area),
                             float(dist[patch].max() / s), "missing-points"))
    out.sort(key=lambda c: -c.strength)
    return out


def soft_gaps(points: Float[np.ndarray, "n 2"], domain, soft: list[Candidate]) -> list[Candidate]:
    """Holes where a gap and a softer candidate coincide: in each softer candidate's ellipse
    (grown by a point spacing), the widest empty disc of the points (its centre inside the domain,
    clear of the outline), if the layout's density would leave one as wide there only
    :data:`SOFT_GAPS` times (:func:`_empty_count` over the ellipse's area) and it is wider than a
    spacing; a candidate of source ``"missing-points"``: the disc less half a spacing (the points
    stop about that short of a hole's edge). A hole nobody modelled in a thinned export leaves a
    gap too narrow to stand out on its own, but the modulus field or the strain map finds a
    softer place there."""
    points = np.asarray(points, float)
    s = point_spacing(points)
    X, step, inside, dist = _raster(points, domain, s)
    density = len(points) / (inside.sum() * step**2)
    free = (inside & ~ndimage.binary_dilation(~inside, iterations=int(np.ceil(2 * s / step)))).ravel()
    d = dist.ravel()
    out = []
    for c in soft:
        if c.sign > 0:
            continue
        area = np.pi * (c.axes[0] + s) * (c.axes[1] + s)
        near = free & jf.Ellipse(*c.centroid, c.axes[0] + s, c.axes[1] + s, c.angle).contains(X)
        if not near.any():
            continue
        i = np.flatnonzero(near)[np.argmax(d[near])]
        r = float(d[i])
        if r < 1.5 * s or _empty_count(r, density, area) > SOFT_GAPS:
            continue
        a = r - 0.5 * s
        out.append(Candidate(-1, np.array([i]), X[i].copy(), np.array([a, a]), 0.0, float(np.pi * a * a),
                             r / s, "missing-points"))
    return out


def edge_artefact(c: Candidate, obs, residuals, fit, domain, spacing: float, sigma: float) -> bool:
    """Whether candidate ``c`` is an artefact of a noisy edge: its ellipse grown by a point
    ``spacing`` reaches the domain's outline, the points there are noisier than ``sigma`` (the
    whole data's noise; their own noise by :func:`~refine.diagnosis.noise.noise_at`, 1.25 times
    ``sigma`` or more), and the initial model's ``residuals`` ``(frames, n_points, 2)`` at its
    fitting points (``fit`` mask) are within :data:`EDGE_MISFIT` of that own noise per residual.
    Correlation degrades near a free edge (subsets run off the specimen); the modulus field
    reads the larger scatter there as softer or stiffer material."""
    from refine.diagnosis.noise import noise_at

    grown = jf.Ellipse(*c.centroid, c.axes[0] + spacing, c.axes[1] + spacing, c.angle)
    t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    (ca, sa), (a, b) = (np.cos(c.angle), np.sin(c.angle)), grown.params[2:4]
    u, v = a * np.cos(t), b * np.sin(t)
    ring = np.asarray(c.centroid) + np.c_[ca * u - sa * v, sa * u + ca * v]
    if domain_contains(domain, ring).all():
        return False
    there = grown.contains(obs.reference)
    own = noise_at(obs, there)
    if own < 1.25 * sigma:
        return False
    r = residuals[:, there & fit]
    r = r[np.isfinite(r)]
    return bool(r.size) and float(np.mean(r**2) / own**2) < EDGE_MISFIT


def triangle_pairs(triangles: np.ndarray) -> np.ndarray:
    """Pairs of triangles ``(m, 2)`` that share an edge."""
    e = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(len(triangles)), 3)
    order = np.lexsort(e.T[::-1])
    e, owner = e[order], owner[order]
    same = np.all(e[1:] == e[:-1], axis=1)
    return np.stack([owner[:-1][same], owner[1:][same]], 1)


def strain_departure(points, measured, predicted, noise: float, smooth: int = 2):
    """How the measured strain departs from a model's, per triangle of the points
    (:func:`~refine.diagnosis.measured_strain.point_triangles`): ``log((e_model + e0) /
    (e_measured + e0))`` of the equivalent strains, positive where the material strains less
    than the model says (stiffer), negative where more (softer, or a hole). ``e0`` is the strain
    that the noise alone gives a triangle (noise over the point spacing), so that noise at small
    strain is not read as a large ratio; the values are averaged ``smooth`` times with the
    neighbouring triangles'. Returns ``(triangles (t, 3), departure (t,), pairs (m, 2))``; 0 in
    triangles with a lost corner."""
    points = np.asarray(points, float)
    tri = point_triangles(points)
    F = [triangle_gradients(points, tri, u) + np.eye(2) for u in (measured, predicted)]
    em, ep = (equivalent_strain(0.5 * (np.swapaxes(f, -1, -2) @ f - np.eye(2))) for f in F)
    e0 = np.sqrt(2.0) * noise / point_spacing(points) + 1e-12
    q = np.nan_to_num(np.log((ep + e0) / (em + e0)))
    pairs = triangle_pairs(tri)
    for _ in range(smooth):
        total, count = q.copy(), np.ones(len(q))
        for i, j in ((pairs[:, 0], pairs[:, 1]), (pairs[:, 1], pairs[:, 0])):
            np.add.at(total, i, q[j])
            np.add.at(count, i, 1.0)
        q = total / count
    return tri, q, pairs


def strain_regions(points, measured, predicted, noise: float, min_area: float, max_regions: int) -> list[Candidate]:
    """Connected patches of triangles where the measured strain departs from the model's
    (:func:`strain_departure`), by :func:`~refine.diagnosis.localize.segment_cells` (source
    ``"strain"``; sign +1 where the material strains less than the model: stiffer)."""
    tri, q, pairs = strain_departure(points, measured, predicted, noise)
    P = np.asarray(points, float)[tri]
    a, b = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    return segment_cells(q - np.median(q), area, P.mean(1), pairs, min_area=min_area, max_regions=max_regions,
                         source="strain")


def merged(*lists: list[Candidate]) -> list[Candidate]:
    """Candidates of several sources in the order given, without one whose centre lies inside an
    earlier kept candidate's ellipse of the same sign (the same place, seen twice)."""
    out: list[Candidate] = []
    for c in (c for cs in lists for c in cs):
        if not any(k.sign == c.sign and jf.Ellipse(*k.centroid, *k.axes, k.angle).contains(c.centroid[None])[0]
                   for k in out):
            out.append(c)
    return out


def joined(cands: list[Candidate], mesh, gap: float) -> list[Candidate]:
    """Field candidates with one sign whose cells come within ``gap`` (length unit) of each other
    joined into one (their cells together, the ellipse of their moments, strengths summed),
    strongest first. A stiff square pulled along a side reads in the regularised field as two
    patches at the sides across the pull (the load paths); fitted from one of them the region
    stopped at a thin ellipse twice as stiff, too thin to be tried as a rectangle."""
    cent, area = mesh.centroids(), mesh.volumes()
    groups = [[c] for c in cands]
    merged_any = True
    while merged_any:
        merged_any = False
        for i in range(len(groups)):
            for j in range(i + 1, len(groups)):
                gi, gj = groups[i], groups[j]
                if gi[0].sign != gj[0].sign:
                    continue
                a = cent[np.concatenate([c.cells for c in gi])]
                b = cent[np.concatenate([c.cells for c in gj])]
                if cKDTree(a).query(b)[0].min() <= gap:
                    groups[i] = gi + gj
                    del groups[j]
                    merged_any = True
                    break
            if merged_any:
                break
    out = []
    for g in groups:
        if len(g) == 1:
            out.append(g[0])
            continue
        cells = np.concatenate([c.cells for c in g])
        centre, axes, angle = moment_ellipse(cent[cells], area[cells])
        out.append(Candidate(g[0].sign, cells, centre, axes, angle, float(sum(c.strength for c in g)),
                             max(c.peak for c in g), g[0].source))
    out.sort(key=lambda c: -c.strength)
    return out


def data_candidates(model, z, predicted, fit, sigma: float, cfg) -> list[Candidate]:
    """Where to look: every registered 2D candidate source's candidates
    (:func:`refine.causes.sources.sources`), listed in the sources' order (today gaps in the
    tracked points inside the domain, then narrower gaps inside a softer candidate, the fitted
    modulus field's regions, the measured strain map's departures from the initial model's), one
    place seen twice kept once (:func:`merged`).

    Args: model: the search's model; z: the fitted log-modulus field per cell; predicted: the
    initial model's displacements ``(frames, n_points, 2)``; fit: ``(n_points,)`` mask of the
    fitting points (no held-out point proposes a place); sigma: the noise (length unit); cfg: a
    :class:`~refine.diagnosis.config.DiagnoseConfig`."""
    from refine.causes.sources import Look, find_all  # (the sources import this module)

    return merged(*find_all(2, Look(model, z, predicted, fit, sigma, cfg)))
