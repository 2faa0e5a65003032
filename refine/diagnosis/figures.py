"""The figures of a diagnosis, as matplotlib ``Figure`` objects (no pyplot, no backend switch):
a notebook shows them, :func:`refine.diagnosis.report.write` saves them as PNG and embeds them in
report.html.

Each function takes the :class:`~refine.diagnosis.Diagnosis` and, optionally, the equilibria of
its initial and refined models from :func:`equilibria` (solve once, draw many).
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

import jaxfem as jf

from refine.diagnosis.measured_strain import equivalent, measured_strain
from refine.model.paraview import model_fields


def equilibria(d) -> dict[str, np.ndarray]:
    """The initial and the refined (chosen) model's nodal displacements in every frame,
    ``{"initial": (n_frames, n_nodes, 2), "refined": ...}`` (one solve when they are the same model)."""
    base = np.asarray(d.baseline.model.solve_frames(d.baseline.theta))
    if d.chosen is d.baseline:
        return {"initial": base, "refined": base}
    return {"initial": base, "refined": np.asarray(d.chosen.model.solve_frames(d.chosen.theta))}


def strain_maps(d, U: dict | None = None, frame: int | None = None) -> Figure:
    """Equivalent Green-Lagrange strain in ``frame`` (default: the last), on one colour scale:
    measured (:func:`~refine.diagnosis.measured_strain.measured_strain` of the tracked points),
    the initial model and the refined model, on the reference configuration."""
    U = U or equilibria(d)
    obs = d.bundle.observations
    f = obs.n_frames - 1 if frame is None else frame
    tri, E = measured_strain(obs.reference, obs.displacements[f])
    eq_measured = equivalent(E)
    model_eq = {key: model_fields(fitted.model, fitted.theta, U[key])[2]["equivalent_strain"][f]  # all frames:
                for key, fitted in (("initial", d.baseline), ("refined", d.chosen))}          # the series' compile
    finite = np.concatenate([eq_measured[np.isfinite(eq_measured)], *model_eq.values()])
    vmin, vmax = np.percentile(finite, [1, 99]) if finite.size else (None, None)
    fig = Figure(figsize=(18, 4.6), layout="constrained")
    axes = fig.subplots(1, 3, sharex=True, sharey=True)
    x, y = obs.reference.T
    pc = axes[0].tripcolor(x, y, tri, facecolors=np.ma.masked_invalid(eq_measured), vmin=vmin, vmax=vmax)
    fig.colorbar(pc, ax=axes[0], label="equivalent strain")
    axes[0].set_title(f"measured (tracked points), frame {f + 1}")
    axes[0].set_aspect("equal")
    for ax, key, fitted in ((axes[1], "initial", d.baseline), (axes[2], "refined", d.chosen)):
        mesh = fitted.model.mesh.with_nodes(np.asarray(fitted.theta["X"]))
        jf.plot.cell_map(mesh, model_eq[key], ax=ax, vmin=vmin, vmax=vmax, label="equivalent strain",
                         title=f"{key} model{'' if fitted.cause == 'none' else f' ({fitted.cause})'}, frame {f + 1}")
    return fig


def residual_maps(d, frame: int | None = None) -> Figure:
    """Measured minus predicted displacement at every tracked point in ``frame`` (default: the
    last), initial and refined model side by side: arrows (one scale for both) over the residual's
    length in noise units (colour)."""
    obs = d.bundle.observations
    f = obs.n_frames - 1 if frame is None else frame
    ref = obs.reference
    sigma = max(float(d.null.sigma), 1e-12)
    R = {key: obs.displacements[f] - fitted.predicted[f] for key, fitted in (("initial", d.baseline),
                                                                             ("refined", d.chosen))}
    top = max(float(np.nanmax(np.abs(r))) if np.isfinite(r).any() else 0.0 for r in R.values()) or 1e-12
    fig = Figure(figsize=(14, 4.6), layout="constrained")
    axes = fig.subplots(1, 2, sharex=True, sharey=True)
    lengths = np.linalg.norm(R["initial"], axis=1)
    vmax = max(float(np.nanmax(lengths)) / sigma, 1.0) if np.isfinite(lengths).any() else 1.0
    for ax, key in zip(axes, ("initial", "refined")):
        r = R[key]
        size = np.linalg.norm(r, axis=1) / sigma
        sc = ax.scatter(ref[:, 0], ref[:, 1], c=size, s=24, cmap="magma_r", vmin=0, vmax=vmax)
        ok = np.isfinite(r).all(axis=1)
        for role, colour in (("guide", "tab:blue"), ("validate", "tab:red")):
            k = ok & obs.mask(role)
            ax.quiver(ref[k, 0], ref[k, 1], r[k, 0], r[k, 1], color=colour, angles="xy", label=role,
                      scale_units="xy", scale=top / (0.8 * d.model.spacing), minlength=0)  # no dot for a tiny one
        ax.set_title(f"{key} model: measured - predicted, frame {f + 1} (arrows x {0.8 * d.model.spacing / top:.3g})")
        ax.set_aspect("equal")
        ax.legend(loc="upper right", fontsize=7)
    fig.colorbar(sc, ax=axes, label="|residual| / noise std")
    return fig


def regions_map(d) -> Figure:
    """The localisation field (relative modulus per cell, where it was fitted), the tracked
    points and the outline of every found region."""
    fig = Figure(figsize=(7, 4.6), layout="constrained")
    ax = fig.subplots()
    if d.field is not None:
        jf.plot.cell_map(d.model.mesh, np.exp(d.field), ax=ax, cmap="coolwarm", label="relative modulus (field)")
    ref = d.bundle.observations.reference
    ax.plot(ref[:, 0], ref[:, 1], "k.", ms=2)
    for f in d.findings:
        if f.region:
            p = np.array(f.region.polygon + f.region.polygon[:1])
            ax.plot(p[:, 0], p[:, 1], "k-", lw=2)
            ax.annotate(f.cause, f.region.centroid, ha="center")
    ax.set_title("found regions over the localisation field" if d.field is not None else
                 "found regions (no localisation field: nothing beyond the noise)")
    ax.set_aspect("equal")
    return fig


def errors_table(d) -> Figure:
    """The error measures of the initial and the refined model as a small table."""
    rep = d.report()
    rows = [[k.replace("_", " "), f"{rep['baseline'][k]:.4g}", f"{rep['refined'][k]:.4g}"]
            for k in ("guide_error", "validation_error", "tracking_error") if rep["baseline"][k] is not None]
    fig = Figure(figsize=(5, 1.2 + 0.3 * len(rows)))
    ax = fig.subplots()
    ax.axis("off")
    if rows:
        ax.table(cellText=rows, colLabels=["error", "initial", "refined"], loc="center")
    return fig


def all_figures(d, U: dict | None = None) -> dict[str, Figure]:
    """Every figure of the report by file stem: ``strain_before_after``, ``residuals``,
    ``regions``, ``errors``."""
    U = U or equilibria(d)
    return {"strain_before_after": strain_maps(d, U), "residuals": residual_maps(d), "regions": regions_map(d),
            "errors": errors_table(d)}
