"""Writing a diagnosis: report.json exactly as the bundle spec says, the figures a person looks
at, and a short summary for the terminal."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def summary(d) -> str:
    """A few lines saying what was found, in words."""
    r = d.report()
    b, f = r["baseline"], r["refined"]
    lines = [f"{r['bundle']}: initial model misfit is {d.null.ratio:.1f}x what noise and discretisation explain "
             f"(p = {d.null.p_value:.2g})."]
    if r["background"]["modulus"] is not None:
        lines.append(f"Background modulus {r['background']['modulus']:.4g} (from the measured force; "
                     f"the initial model assumed {d.bundle.experiment.E:g}).")
    if not r["findings"]:
        lines.append("No finding: the initial model explains the data within its noise.")
    for k in r["findings"]:
        if k["cause"] == "material-law":
            lines.append(f"Finding: material law - {k['law']} fits better than {d.bundle.experiment.law}.")
            continue
        reg = k["region"]
        pm = f" +- {k['relative_elasticity_std']:.2f}" if k.get("relative_elasticity_std") is not None else ""
        absolute = f", E = {k['modulus']:.4g}" if k.get("modulus") is not None else ""
        what = ("hole" if k["cause"] == "hole"
                else f"{k['cause']} ({k['relative_elasticity']:.2f}{pm} x the background{absolute})")
        lines.append(f"Finding: {what} centred at ({reg['centroid'][0]:.1f}, {reg['centroid'][1]:.1f}), "
                     f"area {reg['area']:.1f}, semi-axes {reg['axes'][0]:.1f} x {reg['axes'][1]:.1f}.")
    if r["findings"]:
        g = r["gain"]["validation_error"]
        lines.append(f"Validation error {b['validation_error']:.4g} -> {f['validation_error']:.4g}"
                     + (f" ({g:.1f}x lower)" if g else "") + f"; guide error {b['guide_error']:.4g} -> "
                     f"{f['guide_error']:.4g}; tracking error {b['tracking_error']:.4g} -> {f['tracking_error']:.4g}.")
    if r.get("note"):
        lines.append(f"Note: {r['note']}.")
    lines.append(f"({r['seconds']:.0f} s)")
    return "\n".join(lines)


def write(d, out, with_figures: bool = True) -> Path:
    """Write DIR/report.json, summary.txt and the figures (not with ``with_figures=False``, e.g. in a
    batch: they can take longer than a small bundle's diagnosis); return the report's path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "report.json"
    path.write_text(json.dumps(d.report(), indent=2, default=_plain))
    if with_figures:
        figures(d, out)
    (out / "summary.txt").write_text(summary(d) + "\n")
    return path


def _plain(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(type(x))


def figures(d, out: Path) -> None:
    """Strain maps before and after, residual arrows, the found region, the error table."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import jaxfem as jf

    obs = d.bundle.observations
    last = obs.n_frames - 1
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.5))
    for ax, fitted, title in ((axes[0], d.baseline, "initial model"), (axes[1], d.chosen, "refined model")):
        m, th = fitted.model, fitted.theta
        u = m.solve_frames(th, frames=[last])[0]
        eq = np.asarray(jf.equivalent_strain(m.solver, u, th))
        jf.plot.cell_map(m.mesh if "X" not in th else m.mesh.with_nodes(np.asarray(th["X"])), eq, ax=ax,
                         label="equivalent strain", title=f"{title}: strain, frame {last + 1}")
    fig.savefig(out / "strain_before_after.png", dpi=110, bbox_inches="tight")
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(13, 4.5), sharey=True)
    ref = obs.reference
    for ax, fitted, title in ((axes[0], d.baseline, "initial"), (axes[1], d.chosen, "refined")):
        r = np.nan_to_num(obs.displacements[last] - fitted.predicted[last])
        for role, c in (("guide", "tab:blue"), ("validate", "tab:red")):
            k = obs.mask(role)
            ax.quiver(ref[k, 0], ref[k, 1], r[k, 0], r[k, 1], color=c, angles="xy", label=role,
                      scale_units="xy", scale=max(np.abs(r).max(), 1e-12) / (0.8 * d.model.spacing))
        ax.set_title(f"{title} model: measured - predicted, frame {last + 1} (arrows x scale)")
        ax.set_aspect("equal")
        ax.legend(loc="upper right", fontsize=7)
    fig.savefig(out / "residuals.png", dpi=110, bbox_inches="tight")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4.5))
    if d.field is not None:
        jf.plot.cell_map(d.model.mesh, np.exp(d.field), ax=ax, cmap="coolwarm", label="relative modulus (field)")
    ax.plot(ref[:, 0], ref[:, 1], "k.", ms=2)
    for f in d.findings:
        if f.region:
            p = np.array(f.region.polygon + f.region.polygon[:1])
            ax.plot(p[:, 0], p[:, 1], "k-", lw=2)
            ax.annotate(f.cause, f.region.centroid, ha="center")
    ax.set_title("found regions over the localisation field")
    ax.set_aspect("equal")
    fig.savefig(out / "regions.png", dpi=110, bbox_inches="tight")
    plt.close(fig)

    rep = d.report()
    rows = [[k.replace("_", " "), f"{rep['baseline'][k]:.4g}", f"{rep['refined'][k]:.4g}"]
            for k in ("guide_error", "validation_error", "tracking_error") if rep["baseline"][k] is not None]
    fig, ax = plt.subplots(figsize=(5, 1.2 + 0.3 * len(rows)))
    ax.axis("off")
    ax.table(cellText=rows, colLabels=["error", "initial", "refined"], loc="center")
    fig.savefig(out / "errors.png", dpi=110, bbox_inches="tight")
    plt.close(fig)
