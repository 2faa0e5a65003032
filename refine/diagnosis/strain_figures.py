"""The measured strain map beside the models' (the paper's Figs. 8, 10, 11): the strain of the
tracked point cloud, and the strain the initial and the refined model give the same points, on
the same triangles (:mod:`refine.diagnosis.measured_strain`), so that the three maps compare
like with like. Figures are returned, never shown or saved here, and no backend is chosen."""

from __future__ import annotations

import numpy as np
from jaxtyping import Float
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from refine.diagnosis.measured_strain import equivalent_strain, measured_strain


def strain_maps_figure(points: Float[np.ndarray, "n 2"], maps: dict, title: str = "",
                       outlines: list | None = None) -> Figure:
    """One panel per displacement field, the equivalent strain (:func:`equivalent_strain`) per
    triangle of the points, on one colour scale (that of the first map, 1st to 99th percentile).

    Args:
        points: reference positions ``(n, 2)``, length unit.
        maps: panel title -> displacements of the points ``(n, 2)`` (NaN where lost), the
            measured ones first.
        title: the figure's title.
        outlines: polygons ``[[x, y], ...]`` drawn on every panel (e.g. the found regions).
    """
    points = np.asarray(points, float)
    ok = np.all([np.isfinite(u).all(axis=1) for u in maps.values()], axis=0)
    pts = points[ok]
    fields = {}
    for name, u in maps.items():
        triangles, E = measured_strain(pts, np.asarray(u, float)[ok])
        fields[name] = equivalent_strain(E)
    first = next(iter(fields.values()))
    lo, hi = np.nanpercentile(first, [1, 99]) if np.isfinite(first).any() else (0.0, 1.0)
    fig = Figure(figsize=(4.2 * len(maps) + 1.0, 4.6))
    axes = fig.subplots(1, len(maps), sharex=True, sharey=True, squeeze=False)[0]
    tri = Triangulation(pts[:, 0], pts[:, 1], triangles)
    for ax, (name, e) in zip(axes, fields.items()):
        image = ax.tripcolor(tri, facecolors=np.nan_to_num(e, nan=lo), vmin=lo, vmax=hi, cmap="viridis")
        for polygon in outlines or ():
            p = np.asarray(list(polygon) + [polygon[0]], float)
            ax.plot(p[:, 0], p[:, 1], "w-", lw=1.5)
        ax.set_title(name)
        ax.set_aspect("equal")
    fig.colorbar(image, ax=list(axes), label="equivalent Green-Lagrange strain |E|", shrink=0.8)
    if title:
        fig.suptitle(title)
    return fig


def diagnosis_strain_figure(d, frame: int | None = None) -> Figure:
    """The measured strain map of a diagnosis ``d`` (:class:`~refine.diagnosis.pipeline.Diagnosis`)
    beside its initial and its refined model's, in ``frame`` (0-based; default the last), with
    the found regions outlined."""
    obs = d.bundle.observations
    k = obs.n_frames - 1 if frame is None else frame
    maps = {"measured": obs.displacements[k], "initial model": d.baseline.predicted[k],
            "refined model": d.chosen.predicted[k]}
    outlines = [f.region.polygon for f in d.findings if f.region is not None]
    return strain_maps_figure(obs.reference, maps, f"{d.bundle.experiment.name}: strain in frame {k + 1}", outlines)
