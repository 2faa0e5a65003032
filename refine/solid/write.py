"""The cup holder's diagnosis as :func:`refine.diagnose` reports and writes it: report.json
(schema 2, :mod:`refine.reports`, with ``global``: the global models' held-out errors, initial and
refined), summary.txt and ``OUT/global/`` (the global model with the finding as a bundle)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from refine.bundle.io import Bundle, read_bundle
from refine.diagnosis import atomic
from refine.solid.diagnose import SolidConfig, SolidDiagnosis, report, squeeze_force
from refine.solid.global_model import global_check, global_mesh, write_global


def cup_report(bundle: Bundle, d: SolidDiagnosis, cfg: SolidConfig) -> dict:
    """report.json's content (schema 2) of a cup holder's diagnosis ``d``: the cup's report
    (:func:`refine.solid.diagnose.report`) upgraded (:func:`refine.reports.cup`), with the
    ``bundle``'s name, the local model's ``baseline`` and ``refined`` errors on the bottom's points
    and their ``gain``, ``provenance``, and ``global``: the global models' held-out errors
    without and with the found hole (their solves run here; ``global.bundle`` is null until
    :func:`write_cup` writes it)."""
    from refine.diagnosis.pipeline import _errors
    from refine.diagnosis.provenance import machine, package_version
    from refine.reports import cup

    old = report(d)
    meshes = {"initial": global_mesh(d.shape, None, d.local.h)}
    if d.found:
        meshes["refined"] = global_mesh(d.shape, _hole(d), d.local.h)
    tol = 0.05 * d.base.model.spacing
    old["global"] = {**global_check(bundle, d.shape, squeeze_force(bundle.observations), meshes, tol,
                                    cfg.linear_solver), "bundle": None}
    rep = cup(old)
    obs = d.local.obs
    eb, er = _errors(obs, d.base.predicted), _errors(obs, d.chosen.predicted)
    settings = {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)}
    rep.update(bundle=bundle.experiment.name, baseline=eb, refined=er,
               gain={"validation_error": eb["validation_error"] / er["validation_error"]
                     if er.get("validation_error") else None},
               provenance={"version": package_version(), "settings": settings, "machine": machine()})
    return rep


def _hole(d: SolidDiagnosis):
    return (d.whole or d.chosen).shapes[0] if d.found else None


def write_cup(bundle: Bundle, d: SolidDiagnosis, rep: dict, out: str | Path) -> Path:
    """Write ``OUT/global/`` (the global model with the found hole as a bundle,
    :func:`refine.solid.global_model.write_global`), then report.json (``rep`` from
    :func:`cup_report`, its ``global.bundle`` set) and summary.txt, each atomically; returns
    report.json's path."""
    from refine.diagnosis.report import report_json

    out = Path(out)
    with atomic.folder(out / "global") as tmp:  # the bundle appears whole or not at all
        write_global(bundle, d.shape, _hole(d), tmp, d.local.h)
    rep["global"]["bundle"] = str(out / "global")
    path = atomic.write_text(out / "report.json", report_json(rep))
    atomic.write_text(out / "summary.txt", cup_summary(rep) + "\n")
    return path


def cup_summary(rep: dict) -> str:
    """A few lines saying what the cup holder's diagnosis found (``rep``: its report.json)."""
    n = rep["null_test"]
    lines = [f"{rep['bundle']}: the {n.get('model', 'local')} model's misfit is {n['ratio']:.2f}x the null level "
             f"(p = {n['p_value']:.2g}); {rep['point_gaps']} gap(s) in the bottom's points."]
    if not rep["findings"]:
        lines.append("No finding: no hole beat the initial model.")
    for f in rep["findings"]:
        c = ", ".join(f"{v:.2f}" for v in f["centroid"])
        lines.append(f"Finding: a hole through the bottom centred at ({c}), area {f['area']:.2f}, "
                     f"semi-axes {f['axes'][0]:.2f} x {f['axes'][1]:.2f}.")
    if rep["findings"]:
        lines.append(f"Held-out gain {rep['held_out_gain']:.2f} (validate rms {rep['validate_rms']['initial']:.4g} -> "
                     f"{rep['validate_rms']['refined']:.4g}).")
    g = {k: v for k, v in rep["global"].items() if isinstance(v, dict)}
    lines.append("Global model, all validate points: " + ", ".join(f"{k} rms {v['validate_rms']:.4g}"
                                                                  for k, v in g.items()) + ".")
    lines.append(f"({rep['seconds']:.0f} s)")
    return "\n".join(lines)


def diagnose_and_write(bundle: Bundle | str | Path, out: str | Path, cfg: SolidConfig = SolidConfig(),
                       quiet: bool = False, engine_config=None):
    """:func:`refine.diagnose` of a solid bundle, written to ``out``: ``cfg`` for an observed
    thin wall (the cup holder), ``engine_config`` for any other body (the 3D engine). Returns
    the body's own diagnosis (:class:`~refine.solid.diagnose.SolidDiagnosis` or
    :class:`~refine.solid.engine.BodyDiagnosis`) and the report (schema 2)."""
    from refine.api import diagnose, route

    if isinstance(bundle, (str, Path)):
        bundle = read_bundle(bundle)
    thin_wall = route(bundle)[0] == "thin-wall"
    d = diagnose(bundle, cfg if thin_wall else engine_config, out=out, log=None if quiet else print)
    if not quiet:
        print(d.summary())
    return d.result, d.report()


def write_paraview(d: SolidDiagnosis, folder: str | Path) -> dict:
    """ParaView time series of the diagnosis' models (:func:`refine.model.paraview.write_model_series`:
    nodal displacement, per-cell strain and modulus, one file per frame): ``local_initial`` (the
    local model without a hole), ``local_refined`` and ``global_refined`` (with the found hole,
    where one was found). Returns ``{name: .pvd path}``. Each costs a solve of its model's frames."""
    from refine.model.paraview import write_model_series

    fits = {"local_initial": d.base}
    if d.found:
        fits["local_refined"] = d.chosen
        if d.whole is not None:
            fits["global_refined"] = d.whole
    return {name: write_model_series(folder, name, f.model, f.theta, f.model.solve_frames(f.theta))
            for name, f in fits.items()}

