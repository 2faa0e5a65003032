"""Writing a diagnosis: report.json exactly as the bundle spec says (schema 2, :mod:`refine.reports`), the figures a person looks
at (:mod:`refine.diagnosis.figures`), report.html (:mod:`refine.diagnosis.html`), the ParaView
series (:mod:`refine.diagnosis.paraview`), and a short summary for the terminal."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from refine.diagnosis import atomic
from refine.reports import upgrade


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
        if np.isinf(k.get("relative_elasticity_std") or 0):  # refine.diagnosis.valley: draws reach a rigid region
            pm += " (the data bound it from below only)"
        disc = (k.get("discretisation") or {}).get("relative_elasticity")
        if k.get("relative_elasticity_total_std") is not None and disc is not None:  # noise and discretisation
            pm += f" (standard error; discretisation {disc:.2f}, total {k['relative_elasticity_total_std']:.2f})"
        absolute = f", E = {k['modulus']:.4g}" if k.get("modulus") is not None else ""
        what = ("hole" if k["cause"] == "hole"
                else f"{k['cause']} ({k['relative_elasticity']:.2f}{pm} x the background{absolute})")
        lines.append(f"Finding: {what} centred at ({reg['centroid'][0]:.1f}, {reg['centroid'][1]:.1f}), "
                     f"area {reg['area']:.1f}, semi-axes {reg['axes'][0]:.1f} x {reg['axes'][1]:.1f}{orientation(k)}.")
    if r["findings"]:
        g = r["gain"]["validation_error"]
        lines.append(f"Validation error {b['validation_error']:.4g} -> {f['validation_error']:.4g}"
                     + (f" ({g:.1f}x lower)" if g else "") + f"; guide error {b['guide_error']:.4g} -> "
                     f"{f['guide_error']:.4g}; tracking error {b['tracking_error']:.4g} -> {f['tracking_error']:.4g}.")
    if r.get("note"):
        lines.append(f"Note: {r['note']}.")
    lines.append(f"({r['seconds']:.0f} s)")
    return "\n".join(lines)


UNDETERMINED_ORIENTATION = np.pi / 4
"""An orientation whose two total errors (or standard errors) reach this (radians: 45 degrees,
half of all orientations inside its 95 % interval) is reported as undetermined: a nearly round
shape (:func:`refine.diagnosis.uncertainty.orientation_variance`)."""


def orientation(k: dict) -> str:
    """The summary's words for a finding's orientation (report.json's finding ``k``): ``", axis
    a at 103 +- 5 deg"`` (its total error where estimated, else its standard error, else none),
    or that it is undetermined (:data:`UNDETERMINED_ORIENTATION`); nothing without an angle."""
    if k["region"].get("angle") is None:
        return ""
    err = next((e["angle"] for e in (k.get("total_std"), k.get("std")) if e and e.get("angle") is not None), None)
    if err is not None and 2 * err >= UNDETERMINED_ORIENTATION:
        return ", orientation undetermined (nearly round: 2 errors reach 45 deg)"
    deg = np.degrees(k["region"]["angle"]) % 180.0
    return f", axis a at {deg:.0f}" + ("" if err is None else f" +- {np.degrees(err):.0f}") + " deg"


def write(d, out, with_figures: bool = True) -> Path:
    """Write DIR/report.json, summary.txt, the figures (PNG), report.html (the page a person
    reads, figures embedded) and the ParaView series in DIR/paraview/, each atomically
    (:mod:`refine.diagnosis.atomic`); return report.json's path.
    ``with_figures=False`` (e.g. in a batch, where they can take longer than a small bundle's
    diagnosis) writes report.json and summary.txt alone."""
    from refine.diagnosis import html
    from refine.diagnosis.figures import equilibria
    from refine.diagnosis.paraview import write_series

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = atomic.write_text(out / "report.json", report_json(upgrade(d.report())))  # schema 2: refine.reports
    text = summary(d)
    atomic.write_text(out / "summary.txt", text + "\n")
    if not with_figures:
        return path
    U = equilibria(d)
    figs = figures(d, out, U)
    with atomic.folder(out / "paraview") as tmp:  # the series appear whole or not at all
        series = write_series(d, tmp, U)
    files = ["report.json", "summary.txt", *(f"{k}.png" for k in figs),
             *(("paraview" / p.relative_to(tmp)).as_posix() for p in series.values())]
    html.write(d, out / "report.html", figs, text, files)
    return path


def report_json(report: dict) -> str:
    """A report's dict as report.json's text (strict JSON: :func:`_finite`)."""
    return json.dumps(_finite(report), indent=2, default=_plain)


def _finite(x):
    """``x`` (a report's dict) with every non-finite number written as null: strict JSON has no
    Infinity or NaN (an unbounded error is flagged beside it, e.g. the finding's
    ``relative_elasticity_bounded_below_only``)."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_finite(v) for v in (x.tolist() if isinstance(x, np.ndarray) else x)]
    if isinstance(x, (float, np.floating)) and not np.isfinite(x):
        return None
    return x


def _plain(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(type(x))


def figures(d, out: Path, U: dict | None = None) -> dict:
    """Save the figures of :func:`refine.diagnosis.figures.all_figures` as DIR/<key>.png (strain
    maps measured / initial / refined, residuals, the found regions, the error table) and return
    them by key (matplotlib Figures). ``U``: the models' equilibria, if already solved."""
    from refine.diagnosis.figures import all_figures

    figs = all_figures(d, U)
    for key, fig in figs.items():
        atomic.save_figure(fig, Path(out) / f"{key}.png", dpi=110, bbox_inches="tight")
    return figs
