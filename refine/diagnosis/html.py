"""report.html: one self-contained page a person reads (figures embedded as base64 PNG, no
external file, no script): the finding with its uncertainty, the strain the points show beside
the initial and the refined model's, the residuals, where the field points, the hypotheses tried
and why the chosen one won, the errors, and the settings and provenance."""

from __future__ import annotations

import base64
import io
from html import escape
from pathlib import Path

from matplotlib.figure import Figure

_STYLE = """body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{font-size:1.2em;margin-top:1.8em;border-bottom:1px solid #ccc}
.finding{background:#f3f6fb;border-left:4px solid #2a6ebb;padding:.6em 1em}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f0f0f0}td:first-child,th:first-child{text-align:left}tr.chosen{background:#e6f4e6;font-weight:600}
img{max-width:100%}.note{color:#555;font-size:.9em}code{background:#f4f4f4;padding:0 .2em}"""

#: figure key -> (section title, what to read in it)
_SECTIONS = {
    "strain_before_after": ("Strain: measured, initial model, refined model",
                            "Equivalent Green-Lagrange strain in the last frame on one colour scale. Left: the "
                            "strain the tracked points show (per triangle of their Delaunay triangulation, no "
                            "model); middle: the initial model; right: the refined model. A model that explains "
                            "the data draws the pattern on the left."),
    "residuals": ("Residuals", "Measured minus predicted displacement at every tracked point in the last frame "
                  "(arrows on one scale; colour: length in noise standard deviations), before and after."),
    "regions": ("Where", "The localisation field (a modulus per cell fitted with smoothing) and the outline of "
                "each found region."),
}


def figure_png(fig: Figure, dpi: int = 110) -> bytes:
    """A matplotlib Figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def _img(fig: Figure, alt: str, png: bytes | None = None) -> str:
    data = base64.b64encode(figure_png(fig) if png is None else png).decode("ascii")
    return f'<img alt="{escape(alt)}" src="data:image/png;base64,{data}">'


def _table(header, rows, classes=None) -> str:
    head = "".join(f"<th>{escape(str(h))}</th>" for h in header)
    body = []
    for i, row in enumerate(rows):
        cls = f' class="{classes[i]}"' if classes and classes[i] else ""
        body.append(f"<tr{cls}>" + "".join(f"<td>{escape(str(c))}</td>" for c in row) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _num(x, fmt=".4g") -> str:
    return "-" if x is None else format(x, fmt)


def findings_table(report: dict) -> str:
    """The findings with their numbers and standard errors, as an HTML table ("" if none)."""
    rows = []
    for k in report["findings"]:
        if k["cause"] == "material-law":
            rows.append([k["cause"], "-", "-", "-", f"law: {k['law']}", "-"])
            continue
        reg = k["region"]
        ratio = _num(k["relative_elasticity"])
        if k.get("relative_elasticity_std") is not None:
            ratio += f" \u00b1 {k['relative_elasticity_std']:.2g}"
        rows.append([k["cause"], f"({reg['centroid'][0]:.2f}, {reg['centroid'][1]:.2f})", f"{reg['area']:.1f}",
                     f"{reg['axes'][0]:.2f} x {reg['axes'][1]:.2f} ({reg['shape']})", ratio, _num(k["modulus"])])
    other = sorted({key for k in report["findings"] for key in k if key.endswith("_std")}
                   - {"relative_elasticity_std"})
    extra = ("<p class='note'>Other standard errors: " + "; ".join(
        f"{key}: {k[key]}" for k in report["findings"] for key in other if key in k) + "</p>") if other else ""
    if not rows:
        return ""
    return _table(["cause", "centroid", "area", "semi-axes / half sides", "relative elasticity \u00b1 std. error",
                   "modulus"], rows) + extra


def hypotheses_table(d) -> str:
    """Every hypothesis tried with its score, and why the chosen one won (HTML)."""
    from refine.diagnosis.search import _choose, _score

    base, cfg = d.baseline, d.config
    winner = _choose(base, d.tried, cfg)
    rows, classes = [], []
    for f in d.tried:
        if f is base:
            verdict = "the initial model: every hypothesis is compared with it"
        elif f.bic >= base.bic - cfg.bic_margin:
            verdict = f"rejected: BIC not lower than the initial model's by {cfg.bic_margin:g}"
        elif f.chi2_holdout >= base.chi2_holdout:
            verdict = "rejected: held-out misfit not lower"
        elif f is winner:
            verdict = "chosen: lowest BIC + held-out misfit of those that pass"
        else:
            verdict = f"passes, but scores {_score(f) - _score(winner):.0f} worse than the chosen one"
        label = "initial model" if f is base else f.cause
        rows.append([f"{label} [{'; '.join(s.describe() for s in f.shapes) or f.law}]", f.k, f"{f.chi2_fit:.1f}",
                     f"{f.chi2_holdout:.1f}", f"{f.bic:.1f}",
                     f"{f.bic - base.bic:+.1f}", f"{_score(f):.1f}", verdict])
        classes.append("chosen" if (f is winner and winner is not base) else "")
    for f in getattr(d, "failed", ()):  # could not be fitted: the reason instead of a score
        rows.append([f"{f.cause} [{f.name}]", "", "", "", "", "", "", f"failed: {f.error}: {f.message}"])
        classes.append("")
    rule = (f"A hypothesis passes when its BIC is lower than the initial model's by at least {cfg.bic_margin:g} "
            "(it pays for its extra unknowns) and its misfit on the held-out guide points (which no fit saw) is "
            "lower too; of those, the lowest BIC + held-out misfit wins and is refitted on every guide point "
            "(remeshed at its fitted shapes). None passing: the initial model stands.")
    note = "" if winner is base else f"<p>Refitted on every guide point: {escape(d.chosen.describe())}.</p>"
    if winner is not base and d.chosen.cause != winner.cause:
        note += (f"<p class='note'>Refitted on every guide point, the chosen {winner.cause} was compared once more "
                f"with a hole at its outline; the report gives the {d.chosen.cause}.</p>")
    return (_table(["hypothesis", "unknowns", "chi\u00b2 fit", "chi\u00b2 held-out", "BIC", "\u0394BIC",
                    "BIC + held-out", "verdict"], rows, classes) + f"<p class='note'>{escape(rule)}</p>" + note)


def render(d, figures: dict[str, Figure], summary: str, files: list[str] = (), pngs: dict | None = None) -> str:
    """The page as a string.

    Args:
        d: the :class:`~refine.diagnosis.Diagnosis`.
        figures: the figures by key (:func:`refine.diagnosis.figures.all_figures`); keys of
            ``_SECTIONS`` get their own section, any other figure goes under "More figures".
        summary: the summary in words (:func:`refine.diagnosis.report.summary`).
        files: the other files written beside the page, listed at its end.
        pngs: figure key -> that figure's PNG bytes, already rendered as :func:`figure_png` does
            (embedded as they are instead of drawing the figure again); None: every figure drawn.
    """
    pngs = pngs or {}
    r = d.report()
    name = escape(str(r["bundle"]))
    parts = [f"<!doctype html><html lang='en'><head><meta charset='utf-8'><title>Diagnosis of {name}</title>"
             f"<style>{_STYLE}</style></head><body><h1>Diagnosis of {name}</h1>"]
    parts.append("<div class='finding'>" + "".join(f"<p>{escape(line)}</p>" for line in summary.splitlines())
                 + "</div>")
    parts.append(findings_table(r))
    null = r["decision"]
    parts.append("<h2>Is anything wrong beyond the noise?</h2>" + _table(
        ["null test", "value"],
        [["misfit / its null level", f"{d.null.ratio:.2f}"], ["p-value", f"{null['p_value']:.3g}"],
         ["significance (alpha)", f"{d.config.alpha:g}"], ["residuals", null["dof"]],
         ["noise std (length unit)", _num(null["noise_std"])],
         ["model discretisation error std", _num(null["model_error_std"])]]))
    for key, (title, text) in _SECTIONS.items():
        if key in figures:
            parts.append(f"<h2>{escape(title)}</h2><p class='note'>{escape(text)}</p>{_img(figures[key], title, pngs.get(key))}")
    more = [k for k in figures if k not in _SECTIONS and k != "errors"]
    if more:
        parts.append("<h2>More figures</h2>" + "".join(_img(figures[k], k, pngs.get(k)) for k in more))
    parts.append("<h2>Hypotheses tried, and why the chosen one won</h2>" + hypotheses_table(d))
    rows = [[k.replace("_", " "), _num(r["baseline"][k]), _num(r["refined"][k])]
            for k in ("guide_error", "validation_error", "tracking_error")]
    gain = r["gain"]["validation_error"]
    parts.append("<h2>Errors (validation points were held out of every fit)</h2>"
                 + _table(["error", "initial model", "refined model"], rows)
                 + (f"<p>Validation error {gain:.2f}x lower.</p>" if gain else "")
                 + f"<p class='note'>{escape(r.get('note') or '')}</p>")
    p = r["provenance"]
    rows = [["nonrigid version", p["version"]], ["seed", p["seed"]],
            ["linear solver", f"{p['linear_solver']['setting']} (used: {p['linear_solver']['used']})"],
            ["seconds", p["seconds"]], ["written (UTC)", p["written"]],
            *[[f"machine: {k}", v] for k, v in p["machine"].items()],
            *[[f"setting: {k}", v] for k, v in p["settings"].items()]]
    parts.append("<h2>Settings and provenance</h2>" + _table(["", "value"], rows))
    if files:
        parts.append("<h2>Files beside this page</h2><ul>" + "".join(f"<li><code>{escape(f)}</code></li>"
                                                                     for f in files) + "</ul>"
                     "<p class='note'>Open <code>paraview/*.pvd</code> in ParaView (File &gt; Open) to step "
                     "through the frames.</p>")
    return "".join(parts) + "</body></html>\n"


def write(d, path: str | Path, figures: dict[str, Figure], summary: str, files: list[str] = ()) -> Path:
    """Write :func:`render`'s page to ``path`` (atomically: :mod:`refine.diagnosis.atomic`); return it.
    A figure whose ``<key>.png`` is among ``files`` is embedded from that file beside the page
    (written from the same figure at :func:`figure_png`'s settings, as
    :func:`refine.diagnosis.report.figures` does), not drawn a second time."""
    from refine.diagnosis.atomic import write_text

    beside = Path(path).parent
    pngs = {k: (beside / f"{k}.png").read_bytes() for k in figures
            if f"{k}.png" in files and (beside / f"{k}.png").is_file()}
    return write_text(path, render(d, figures, summary, files, pngs))
