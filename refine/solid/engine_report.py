"""report.json (schema 2), summary.txt and report.html of a solid body's diagnosis
(:class:`refine.solid.engine.BodyDiagnosis`): the same top-level keys as the 2D report
(``schema``, ``bundle``, ``dim``, ``cause``, ``findings``, ``baseline``, ``refined``, ``gain``,
``decision``, ``note``, ``seconds``, ``provenance``), the body's own (the null test, the model, the
held-out rms, the field's regions, seconds per stage) under ``details``, a finding's own (strength,
profile, total intervals, discretisation, coarse fit, starts) under the finding's ``details``."""

from __future__ import annotations

from html import escape
from pathlib import Path

import numpy as np

from refine.diagnosis import atomic


def _rms(d, f) -> float:
    obs = d.base.model.obs
    n = max(1, 3 * obs.n_frames * int((obs.roles == "validate").sum()))
    return float(np.sqrt(f.chi2_holdout / n) * f.sigma)


def body_report(d) -> dict:
    """report.json's content of ``d`` (see the module)."""
    from refine.diagnosis.pipeline import _errors
    from refine.diagnosis.provenance import machine, package_version
    from refine.solid.engine import finding_of, rows

    obs, n = d.base.model.obs, d.null
    finding = finding_of(d)
    chosen = d.chosen if d.chosen is not None else d.base
    eb, er = _errors(obs, d.base.predicted), _errors(obs, chosen.predicted)
    gain = eb["validation_error"] / er["validation_error"] if er.get("validation_error") else None
    details = {"null_test": {"statistic": n.statistic, "dof": n.dof, "p_value": n.p_value, "noise_std": n.sigma},
               "model": {"cells": int(d.base.model.mesh.n_cells), "element": d.base.model.mesh.element,
                         "points": int(len(obs.ids))},
               "validate_rms": {"initial": _rms(d, d.base)}, "seconds": d.seconds}
    if d.found:
        details["validate_rms"]["refined"] = _rms(d, chosen)
        details["held_out_gain"] = details["validate_rms"]["initial"] / max(details["validate_rms"]["refined"], 1e-300)
    if d.modulus is not None:
        details["field"] = {"gradients": d.modulus.gradients, "regions": [
            {"sign": b.sign, "centroid": b.centroid.tolist(), "axes": b.axes.tolist(), "volume": b.volume,
             "peak_ratio": b.ratio} for b in d.modulus.blobs]}
    out = {"schema": 2, "bundle": d.bundle.experiment.name, "dim": 3, "cause": chosen.cause if d.found else "none",
           "findings": [finding] if finding else [], "baseline": eb, "refined": er,
           "gain": {"validation_error": gain},
           "decision": {"null_statistic": n.statistic, "dof": n.dof, "p_value": n.p_value, "noise_std": n.sigma,
                        "model_error_std": getattr(n, "sigma_model", None), "hypotheses": rows(d),
                        "candidates": [{"source": c.source, "sign": int(c.sign),
                                        "centroid": [round(float(v), 4) for v in c.centroid],
                                        "axes": [round(float(v), 4) for v in c.axes]} for c in d.candidates]},
           "note": "moduli are relative (displacement driving): only ratios to the background are identifiable",
           "seconds": round(float(d.seconds.get("total", 0.0)), 2),
           "provenance": {"version": package_version(), "settings": d.config.settings(), "machine": machine()},
           "details": details}
    if d.incomplete is not None:
        stage, e = d.incomplete
        out["incomplete"] = {"stage": stage, "error": type(e).__name__, "message": str(e)}
    return out


def body_summary(d) -> str:
    """A few lines saying what was found, in words."""
    r = body_report(d)
    lines = [f"{r['bundle']}: initial model misfit is {d.null.ratio:.1f}x what noise explains (p = {d.null.p_value:.2g})."]
    if r.get("incomplete"):
        lines.append(f"The diagnosis stopped in {r['incomplete']['stage']}: {r['incomplete']['error']}: "
                     f"{r['incomplete']['message']}")
    tried = [h for h in r["decision"]["hypotheses"][1:]]
    lines.append(f"{sum(h.get('failed') is None for h in tried)} hypotheses fitted, "
                 f"{sum(h.get('failed') is not None for h in tried)} failed, {len(r['decision']['candidates'])} candidates.")
    if not r["findings"]:
        lines.append("No finding: the initial model explains the data within its noise, or no hypothesis beat it.")
    for k in r["findings"]:
        if k["kind"] == "material-law":
            lines.append(f"Finding: material law - {k['law']} fits better than {d.bundle.experiment.law}.")
            continue
        std = k.get("std") or {}
        pm = f" +- {std['relative_elasticity']:.2g}" if std.get("relative_elasticity") is not None else ""
        what = "cavity" if k["kind"] == "cavity" else f"{k['cause']} ({k['relative_elasticity']:.3g}{pm} x the background)"
        c = ", ".join(f"{v:.2f}" for v in k["centroid"])
        lines.append(f"Finding: {what}, a {k['kind']} centred at ({c}), volume {k['volume']:.4g}, "
                     f"semi-axes {' x '.join(f'{a:.2f}' for a in k['axes'])}.")
    if r["findings"] and r["gain"]["validation_error"]:
        lines.append(f"Validation error {r['baseline']['validation_error']:.4g} -> {r['refined']['validation_error']:.4g} "
                     f"({r['gain']['validation_error']:.2f}x lower).")
    lines.append(f"({r['seconds']:.0f} s)")
    return "\n".join(lines)


def page(d, rep: dict) -> str:
    """A minimal report.html: the summary and the hypotheses table."""
    rows = "".join(f"<tr><td>{escape(str(h.get('tried') or h['cause']))}</td><td>{escape(str(h.get('kind')))}</td>"
                   f"<td>{h['k']}</td><td>{_bic(h)}</td>"
                   f"<td>{escape(h['failed']['message']) if h.get('failed') else 'fitted'}</td></tr>"
                   for h in rep["decision"]["hypotheses"])
    name = escape(str(rep["bundle"]))
    return (f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>Diagnosis of {name}</title></head>"
            f"<body><h1>Diagnosis of {name}</h1>" + "".join(f"<p>{escape(x)}</p>" for x in d.summary().splitlines())
            + "<h2>Hypotheses</h2><table><tr><th>hypothesis</th><th>kind</th><th>unknowns</th><th>BIC</th>"
            f"<th>status</th></tr>{rows}</table></body></html>\n")


def write_body(d, out) -> Path:
    """Write OUT/report.json (atomically), summary.txt and report.html; returns report.json's path."""
    from refine.diagnosis.report import report_json

    out = Path(out)
    rep = body_report(d)
    path = atomic.write_text(out / "report.json", report_json(rep))
    atomic.write_text(out / "summary.txt", body_summary(d) + "\n")
    atomic.write_text(out / "report.html", page(d, rep))
    return path


def _bic(h: dict) -> str:
    return "" if h["bic"] is None else f"{h['bic']:.1f}"
