"""A diagnosis that stopped: what it had done when an error (or an interrupt) ended it after the
initial model, written as report.json, summary.txt and report.html like a finished one, so that
no work is lost without a word.

:func:`refine.diagnosis.diagnose` attaches an :class:`Incomplete` to the exception it lets
through (``exception.incomplete``); ``nonrigid diagnose`` writes it (:func:`write`) and exits
non-zero. A failure while a finished diagnosis is written (a figure, the ParaView series, the
refined bundle) is recorded the same way around the whole report (:func:`of_diagnosis`).
"""

from __future__ import annotations

import traceback
from dataclasses import dataclass
from html import escape
from pathlib import Path

from refine.diagnosis import atomic
from refine.diagnosis.fitted import hypothesis_rows


@dataclass(eq=False)
class Incomplete:
    """What a diagnosis did before ``error`` stopped it in ``stage`` (words, e.g. ``"the refit on
    every frame"``): the initial model (``baseline``, a Fitted) and its ``null`` test, the
    hypotheses fitted so far (``tried``, the baseline first) and those that failed (``failed``,
    :class:`~refine.diagnosis.fitted.Failed`), the ``candidates``, the ``seconds`` spent, the
    search ``model``; ``report_so_far``: a finished diagnosis's report where only its writing
    failed."""

    bundle: object
    config: object
    null: object
    baseline: object
    tried: list
    failed: list
    candidates: list
    stage: str
    error: BaseException
    seconds: float
    model: object = None
    report_so_far: dict | None = None

    @property
    def reason(self) -> dict:
        """``{"stage", "error" (the exception's class), "message", "traceback"}``."""
        tb = "".join(traceback.format_exception(type(self.error), self.error, self.error.__traceback__))
        return {"stage": self.stage, "error": type(self.error).__name__, "message": str(self.error),
                "traceback": tb[-4000:]}

    def report(self) -> dict:
        """report.json's content: the finished report's where there is one, else the null test,
        the hypotheses table so far and the candidates; ``incomplete`` says where and why it stopped."""
        from refine.diagnosis.provenance import machine, package_version

        if self.report_so_far is not None:
            return {**self.report_so_far, "incomplete": self.reason}
        n = self.null
        cfg = self.config
        return {"bundle": self.bundle.experiment.name, "incomplete": self.reason, "findings": [],
                "decision": {"null_statistic": n.statistic, "dof": n.dof, "p_value": n.p_value,
                             "noise_std": n.sigma, "model_error_std": n.sigma_model,
                             "hypotheses": hypothesis_rows(self.tried, self.failed),
                             "candidates": [{"source": c.source, "sign": c.sign,
                                             "centroid": [round(float(v), 4) for v in c.centroid],
                                             "axes": [round(float(v), 4) for v in c.axes]} for c in self.candidates]},
                "seconds": round(self.seconds, 2),
                "provenance": {"version": package_version(), "settings": cfg.settings(), "seed": cfg.seed,
                               "machine": machine()}}

    def summary(self) -> str:
        """A few lines: that the diagnosis stopped, where and why, and what it had done."""
        lines = [f"{self.bundle.experiment.name}: the diagnosis stopped in {self.stage} after {self.seconds:.0f} s: "
                 f"{type(self.error).__name__}: {self.error}"]
        if self.null is not None:
            lines.append(f"Initial model misfit {self.null.ratio:.1f}x what noise and discretisation explain "
                         f"(p = {self.null.p_value:.2g}).")
        lines.append(f"{max(len(self.tried) - 1, 0)} hypotheses fitted, {len(self.failed)} failed, "
                     f"{len(self.candidates)} candidate regions; report.json lists them.")
        for f in self.tried[1:]:
            lines.append(f"  tried {f.describe()}")
        for f in self.failed:
            lines.append(f"  {f.describe()}")
        return "\n".join(lines)

    def page(self) -> str:
        """report.html: the summary, the hypotheses table so far and the error."""
        rows = ""
        if self.report_so_far is None:
            for r in self.report()["decision"]["hypotheses"]:
                bic = "" if r["bic"] is None else f"{r['bic']:.1f}"
                rows += (f"<tr><td>{escape(str(r.get('tried', r['cause'])))}</td><td>{r['k']}</td><td>{bic}</td>"
                         f"<td>{escape(_why(r))}</td></tr>")
        table = ("<h2>Hypotheses so far</h2><table><tr><th>hypothesis</th><th>unknowns</th><th>BIC</th>"
                 f"<th>status</th></tr>{rows}</table>") if rows else ""
        name = escape(str(self.bundle.experiment.name))
        return (f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>Diagnosis of {name} "
                f"(incomplete)</title></head><body><h1>Diagnosis of {name}: incomplete</h1>"
                + "".join(f"<p>{escape(line)}</p>" for line in self.summary().splitlines()) + table
                + f"<h2>Where it stopped</h2><pre>{escape(self.reason['traceback'])}</pre></body></html>\n")


def _why(row: dict) -> str:
    failed = row.get("failed")
    return f"failed: {failed['error']}: {failed['message']}" if failed else "fitted"


def of_diagnosis(d, stage: str, error: BaseException) -> Incomplete:
    """A finished :class:`~refine.diagnosis.Diagnosis` ``d`` whose writing failed in ``stage``."""
    try:
        so_far = d.report()
    except Exception:  # noqa: BLE001 - the report itself may be what failed: keep the table alone
        so_far = None
    return Incomplete(d.bundle, d.config, d.null, d.baseline, d.tried, d.failed, d.candidates, stage, error,
                      d.seconds, d.model, so_far)


def write(inc: Incomplete, out: str | Path) -> Path:
    """Write OUT/report.json, summary.txt and report.html of ``inc`` (atomically); return report.json's path."""
    from refine.diagnosis.report import report_json
    from refine.reports import upgrade

    out = Path(out)
    path = atomic.write_text(out / "report.json", report_json(upgrade(inc.report())))  # schema 2
    atomic.write_text(out / "summary.txt", inc.summary() + "\n")
    atomic.write_text(out / "report.html", inc.page())
    return path
