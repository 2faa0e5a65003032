"""Candidate regions from what the data show, beside the fitted modulus field
(:mod:`refine.diagnosis.localize`): gaps in the tracked points inside the domain (a hole has no
material points, so nothing can be tracked there) and places where the measured strain map
departs from the initial model's (the paper reads a scar as a pocket of low measured strain, a
hole as one of high strain).
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
"""A place is a gap in the points when its nearest tracked point is more than this many point
spacings away (a single lost point of a grid leaves one spacing; two leave 1.1)."""


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


def missing_point_regions(points: Float[np.ndarray, "n 2"], domain, gap: float = GAP) -> list[Candidate]:
    """Gaps in the tracked points inside the domain, largest first, as softer candidates (source
    ``"missing-points"``): the places farther than ``gap`` point spacings from every point, in
    connected patches that do not reach the domain's outline and span at least a disc of one
    spacing. Each is summarised by its ellipse of moments, grown by ``gap - 1/2`` spacings (the
    patch stops ``gap`` spacings short of the points, which stop about half a spacing short of
    the hole's edge); a hole fitted from it is shrunk until no point lies inside
    (:func:`refine.diagnosis.holes.hole_hypothesis`)."""
    points = np.asarray(points, float)
    s = point_spacing(points)
    step = s / 4.0
    lo, hi = points.min(0) - s, points.max(0) + s
    xs, ys = np.arange(lo[0], hi[0] + step, step), np.arange(lo[1], hi[1] + step, step)
    X = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    inside = domain_contains(domain, X).reshape(len(ys), len(xs))
    dist = cKDTree(points).query(X)[0].reshape(len(ys), len(xs))
    empty = inside & (dist > gap * s)
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
        out.append(Candidate(-1, idx, centre, axes + (gap - 0.5) * s, angle, float(area),
                             float(dist[patch].max() / s), "missing-points"))
    out.sort(key=lambda c: -c.strength)
    return out


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


def data_candidates(model, z, predicted, fit, sigma: float, cfg) -> list[Candidate]:
    """Where to look, strongest evidence first: gaps in the tracked points inside the domain
    (no material was seen there: a hole, or material that could not be tracked), the fitted
    modulus field's regions, then the measured strain map's departures from the initial
    model's in the frame of most motion; one place seen twice is kept once.

    Args: model: the search's model; z: the fitted log-modulus field per cell; predicted: the
    initial model's displacements ``(frames, n_points, 2)``; fit: ``(n_points,)`` mask of the
    fitting points (no held-out point proposes a place); sigma: the noise (length unit); cfg: a
    :class:`~refine.diagnosis.config.DiagnoseConfig`."""
    obs = model.obs
    field = segment(model.mesh, z, min_area=0.5 * model.spacing**2, max_regions=cfg.max_regions)
    field = [c for c in field if c.strength >= 0.2 * field[0].strength] if field else []
    gaps = missing_point_regions(obs.reference, model.experiment.domain)[:cfg.max_regions]
    strain = []
    if cfg.strain_candidates > 0:
        k = int(np.nanargmax(np.nanmedian(np.linalg.norm(obs.displacements, axis=2), axis=1)))
        seen = (fit | (obs.roles == "boundary")) & obs.valid[k]  # no held-out point proposes a place
        strain = strain_regions(obs.reference[seen], obs.displacements[k, seen], predicted[k, seen], sigma,
                                min_area=2.0 * model.spacing**2, max_regions=cfg.strain_candidates)
    return merged(gaps, field, strain)
