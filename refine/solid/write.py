"""`nonrigid diagnose` on a solid bundle: the 3D diagnosis of the cup holder's bottom, its report,
and the global model with the finding (written and checked against the held-out points)."""

from __future__ import annotations

import json
from pathlib import Path

from refine.bundle.io import Bundle, read_bundle
from refine.diagnosis.atomic import write_text
from refine.solid.diagnose import SolidConfig, SolidDiagnosis, thin_wall_reason, diagnose_solid, report, squeeze_force
from refine.solid.global_model import global_check, global_mesh, write_global


def diagnose_and_write(bundle: Bundle | str | Path, out: str | Path, cfg: SolidConfig = SolidConfig(),
                       quiet: bool = False, global_h: float | None = None, engine_config=None) -> tuple[SolidDiagnosis, dict]:
    """Diagnose a cup holder's bundle (:func:`refine.solid.diagnose_solid`) and write ``OUT/report.json``
    (with ``global``: the global models' held-out errors, initial and refined) and ``OUT/global/``
    (the global model with the finding as a bundle, :func:`refine.solid.global_model.write_global`).
    ``global_h``: the global model's element size (default: the local model's). Returns the
    diagnosis and the report. A body without an observed thin wall
    (:func:`refine.solid.diagnose.thin_wall_reason`) is diagnosed by the 3D engine instead
    (:func:`refine.solid.engine.diagnose_body` with ``engine_config``) and written by it."""
    if isinstance(bundle, (str, Path)):
        bundle = read_bundle(bundle)
    log = (lambda m: None) if quiet else print
    reason = thin_wall_reason(bundle)
    if reason is not None:  # any other body: the one 3D engine, over the registry's 3D causes
        from refine.solid.engine import diagnose_body

        log(f"the body's diagnosis by the 3D engine ({reason}: no observed thin wall)")
        d = diagnose_body(bundle, engine_config, log=log)
        d.write(out)
        if not quiet:
            print(d.summary())
        return d, d.report()
    d = diagnose_solid(bundle, cfg, log=log)
    rep = report(d)
    h = global_h or d.local.h
    hole = (d.whole or d.chosen).shapes[0] if d.found else None
    root = write_global(bundle, d.shape, hole, Path(out) / "global", h)
    meshes = {"initial": global_mesh(d.shape, None, h)}
    if hole is not None:
        meshes["refined"] = global_mesh(d.shape, hole, h)
    tol = 0.05 * d.base.model.spacing
    rep["global"] = global_check(bundle, d.shape, squeeze_force(bundle.observations), meshes, tol, cfg.linear_solver)
    rep["global"]["bundle"] = str(root)
    Path(out).mkdir(parents=True, exist_ok=True)
    write_text(Path(out) / "report.json", json.dumps(rep, indent=1))  # atomically
    if not quiet:
        f = rep["findings"][0] if rep["findings"] else None
        log(f"finding: {rep['cause']}" + (f" at {[round(v, 2) for v in f['centroid']]}, area {f['area']:.2f}"
                                         if f else "") + f"; global model in {root}")
    return d, rep


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
