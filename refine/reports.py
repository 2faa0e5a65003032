"""report.json, schema 2: one shape for every body's diagnosis (2D sheets, the cup holder's
observed thin wall, any other solid through the 3D engine), and the reading of older reports.

Every report has the keys of :data:`COMMON` (``schema`` 2, ``bundle``, ``dim``, ``cause``,
``findings``, ``baseline``, ``refined``, ``gain``, ``decision``, ``note``, ``seconds``,
``provenance``), ``incomplete`` where the diagnosis stopped, and a body's own keys beside them
(2D: ``background``; the cup holder: ``null_test``, ``point_gaps``, ``local_model``,
``validate_rms``, ``held_out_gain``, ``global``; the 3D engine and the cup holder: ``details``).
Every finding has the fields of :data:`FINDING` (``cause``, ``kind``, ``centroid``, ``axes``,
``relative_elasticity``, ``std``) with the same meaning in 2D and 3D, and its body's own
(2D: ``region``, ``angle``, ``area``, ``modulus``...; 3D: ``volume``, ``directions``...).

A report written before schema 2 has no ``schema`` key: :func:`upgrade` turns it (2D, the cup
holder's, a block's inclusion report) into schema 2, keeping every key it had; :func:`read_report`
reads any report.json. The field list and its units: docs/measurement-bundle.md (report.json).
"""

from __future__ import annotations

import json
from pathlib import Path

from refine.exceptions import RefineError

SCHEMA = 2
#: the top-level keys of every schema-2 report, in the order they are written
COMMON = ("schema", "bundle", "dim", "cause", "findings", "baseline", "refined", "gain", "decision", "note",
          "seconds", "provenance")
#: the fields every finding has (null where they do not apply: a material law has no centroid)
FINDING = ("cause", "kind", "centroid", "axes", "relative_elasticity", "std")
_NULL_TEST = ("statistic", "dof", "p_value", "noise_std", "model_error_std")


class ReportError(RefineError, ValueError):
    """A report.json this version cannot read (not a diagnosis report, or a newer schema)."""


def cause_of(findings: list) -> str:
    """The report's ``cause``: ``"none"`` without findings, the findings' cause where they share
    one, else ``"regions"`` (several regions of different causes)."""
    causes = list(dict.fromkeys(f["cause"] for f in findings))
    return "none" if not causes else causes[0] if len(causes) == 1 else "regions"


def plane_finding(f: dict) -> dict:
    """A 2D finding (report.json's, :meth:`refine.diagnosis.findings.Finding.to_json`) with the
    shared fields: ``kind`` (``"hole"``, ``"ellipse"``, ``"rectangle"`` or ``"material-law"``)
    and ``centroid``, ``axes``, ``angle``, ``area`` taken from its ``region``; every key it had kept."""
    region = f.get("region") or {}
    kind = ("material-law" if f["cause"] == "material-law" else "hole" if f["cause"] == "hole"
            else region.get("shape", "ellipse"))
    shared = {"cause": f["cause"], "kind": kind, "centroid": region.get("centroid"), "axes": region.get("axes"),
              "angle": region.get("angle"), "area": region.get("area"),
              "relative_elasticity": f.get("relative_elasticity"), "std": f.get("std")}
    return {**shared, **f}


def plane(report: dict) -> dict:
    """An older 2D report (finished or stopped) as schema 2: every key kept, ``schema``,
    ``dim`` and ``cause`` added, each finding's shared fields (:func:`plane_finding`)."""
    findings = [plane_finding(f) for f in report.get("findings", [])]
    out = {"schema": SCHEMA, "bundle": report.get("bundle"), "dim": 2, "cause": cause_of(findings),
           "findings": findings}
    out.update({k: report.get(k) for k in COMMON if k not in out})
    out["gain"] = out["gain"] or {"validation_error": None}
    out.update({k: v for k, v in report.items() if k not in out})
    return out


def _total(stages: dict) -> float:
    """The seconds of a diagnosis from its seconds per stage (their ``total`` where given)."""
    return round(float(stages["total"] if "total" in stages else sum(stages.values())), 2)


def _decision(null_test: dict) -> dict:
    return {"null_statistic": null_test.get("statistic"), "dof": null_test.get("dof"),
            "p_value": null_test.get("p_value"), "noise_std": null_test.get("noise_std"),
            "model_error_std": null_test.get("model_error_std")}


def cup(report: dict) -> dict:
    """An older cup holder's report (:func:`refine.solid.diagnose.report`) as schema 2: its keys
    kept, but ``seconds`` (per stage) moved to ``details.seconds`` and the total in ``seconds``;
    ``decision`` from ``null_test``; each hole's ``cause`` ``"hole"`` and ``relative_elasticity``
    0 added. ``baseline``, ``refined``, ``gain`` and ``bundle`` are null: older cup reports lack them."""
    stages = dict(report.get("seconds") or {})
    findings = [{"cause": "hole", "kind": f.get("kind", "hole"), "centroid": f.get("centroid"), "axes": f.get("axes"),
                 "relative_elasticity": 0.0, "std": f.get("std"), **f} for f in report.get("findings", [])]
    out = {"schema": SCHEMA, "bundle": None, "dim": 3, "cause": report.get("cause", cause_of(findings)),
           "findings": findings, "baseline": None, "refined": None, "gain": {"validation_error": None},
           "decision": _decision(report.get("null_test") or {}), "note": None,
           "seconds": _total(stages), "provenance": None}
    out.update({k: v for k, v in report.items() if k not in out})
    out["details"] = {**(report.get("details") or {}), "seconds": stages}
    return out


#: an older block report's finding keys that the 3D engine's report keeps under the finding's ``details``
_INCLUSION_DETAILS = ("ratio_at_bound", "strength", "profile", "total", "discretisation", "coarse_fit", "fit_start",
                      "starts")


def block(report: dict) -> dict:
    """An older block's report (:func:`refine.solid.inclusion_diagnosis.inclusion_report`) as
    the 3D engine's schema 2 writes it: the body's keys (``null_test``, ``model``,
    ``validate_rms``, ``held_out_gain``, ``field``, ``seconds`` per stage) under ``details``, the
    inclusion (``kind`` ``"ellipsoid"``) with its profile and other extras under its ``details``."""
    findings = []
    for f in report.get("findings", []):
        g = {k: v for k, v in f.items() if k not in _INCLUSION_DETAILS}
        g["kind"] = "ellipsoid" if g.get("kind") == "inclusion" else g.get("kind")
        findings.append({**{k: g.get(k) for k in FINDING}, **g,
                         "details": {k: f[k] for k in _INCLUSION_DETAILS if k in f}})
    details = {k: v for k, v in report.items() if k not in ("cause", "findings")}
    details["seconds"] = dict(report.get("seconds") or {})
    return {"schema": SCHEMA, "bundle": None, "dim": 3, "cause": report.get("cause", cause_of(findings)),
            "findings": findings, "baseline": None, "refined": None, "gain": {"validation_error": None},
            "decision": _decision(report.get("null_test") or {}), "note": None,
            "seconds": _total(details["seconds"]), "provenance": None, "details": details}


def upgrade(report: dict) -> dict:
    """Any report.json's content as schema 2 (a new dict; a schema-2 report is returned as a
    copy whose findings have every field of :data:`FINDING`). Which body an older report (no ``schema`` key) is from is read off its keys: the cup
    holder's has ``local_model``, a block's ``null_test`` and ``model``, a 2D one ``bundle`` and
    ``decision``.

    Raises:
        ReportError: not a diagnosis report, or a schema newer than this version reads.
    """
    if not isinstance(report, dict):
        raise ReportError(f"a report is a JSON object (a dict), not {type(report).__name__}")
    schema = report.get("schema")
    if schema == SCHEMA:  # every finding with the shared fields (null where a writer left one out)
        return {**report, "findings": [{**{k: None for k in FINDING}, **f} for f in report.get("findings", [])]}
    if schema is not None:
        raise ReportError(f"report schema {schema!r} is not one this version reads (schema {SCHEMA}, or an older "
                          "report without a 'schema' key); read it with the nonrigid version that wrote it "
                          "(its provenance.version)")
    if "local_model" in report or "point_gaps" in report:
        return cup(report)
    if "null_test" in report and "model" in report:
        return block(report)
    if "bundle" in report and "decision" in report:
        return plane(report)
    raise ReportError("not a diagnosis report: no 'schema' key and none of the keys of an older one (a 2D report's "
                      f"'bundle' and 'decision', a cup holder's 'local_model', a block's 'null_test' and 'model'); "
                      f"it has {sorted(report)[:12]}")


def read_report(path: str | Path) -> dict:
    """Read a report.json (a file, or a diagnosis' output folder holding one) of any schema, as
    schema 2 (:func:`upgrade`).

    Raises:
        ReportError: the file is missing, not JSON, or not a report :func:`upgrade` reads.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "report.json"
    if not path.is_file():
        raise ReportError(f"no report at {path}; give a report.json or the output folder of `nonrigid diagnose`")
    try:
        report = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ReportError(f"{path} is not JSON ({e}); a report written while a run was killed is rewritten by "
                          "running the diagnosis again") from e
    return upgrade(report)
