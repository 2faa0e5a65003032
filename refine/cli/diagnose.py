"""``nonrigid diagnose BUNDLE --out DIR``: find what the initial model gets wrong, and the gain."""

from __future__ import annotations

import argparse
from pathlib import Path

#: the options that set a :class:`refine.diagnosis.DiagnoseConfig` setting: (flags, setting,
#: argparse keywords). Only options given override the bundle's ``[diagnose]`` table (whose
#: settings override the defaults); the values are checked by ``DiagnoseConfig.from_table``.
OPTIONS = (
    (("--seed",), "seed", dict(type=int, help="seed of the held-out split and of the noise draws (default 0)")),
    (("--alpha", "--significance"), "alpha", dict(type=float, help="significance of the null test (default 1e-3)")),
    (("--max-regions",), "max_regions", dict(type=int, help="most regions tried (default 2)")),
    (("--laws",), "try_laws", dict(action=argparse.BooleanOptionalAction,
                                   help="also try other material laws (default: --laws)")),
    (("--workers",), "workers", dict(type=int, help="hypotheses fitted side by side in this many threads (default 2)")),
    (("--h", "--element-size"), "h", dict(type=float, help="element size of the models' meshes, length unit "
                                                          "(default: half the point spacing, at most --max-cells "
                                                          "triangles)")),
    (("--linear-solver",), "linear_solver", dict(help="auto (default) or a solver of jaxfem.linsolve: pardiso, "
                                                      "klu, superlu, cholmod, cg, dense")),
    (("--holdout-fraction",), "holdout_fraction", dict(type=float, help="share of guide points held out to choose "
                                                                        "between hypotheses (default 0.25)")),
    (("--bic-margin",), "bic_margin", dict(type=float, help="how much lower than the initial model's BIC a "
                                                            "hypothesis must score (default 10)")),
    (("--field-weight",), "field_weight", dict(type=float, help="smoothing weight of the localisation field "
                                                                "(default 2)")),
    (("--refit-element",), "refit_element", dict(choices=("tri3", "tri6"), help="element of the chosen model's "
                                                                                 "final meshes (default tri6)")),
    (("--try-rectangles",), "try_rectangles", dict(choices=("yes", "no", "auto"), help="also fit a found region as "
                                                   "a rectangle; auto (default): where the ellipse leaves misfit above the null "
                                                   "level and the points resolve corners")),
    (("--hole-below",), "hole_below", dict(type=float, help="a softer region below this ratio is also fitted as a "
                                                            "hole (default 0.3)")),
    (("--hole-refit-below",), "hole_refit_below", dict(type=float, help="a chosen softer region refitted below "
                                                                        "this ratio is compared with a hole "
                                                                        "(default 0.05)")),
    (("--rectangle-spacings",), "rectangle_spacings", dict(type=float, help="the gate of --try-rectangles auto, in "
                                                                            "grid spacings (default 1.5)")),
    (("--max-cells",), "max_cells", dict(type=int, help="most linear triangles of a model's mesh (default 3000)")),
    (("--search-frames",), "search_frames", dict(type=int, help="frames of most motion the search uses; the chosen "
                                                                "model is refitted on all (default 2; 0: all)")),
    (("--strain-candidates",), "strain_candidates", dict(type=int, help="candidate regions also from the measured "
                                                                        "strain map (default 1)")),
    (("--discretisation-error",), "discretisation_error",
     dict(action=argparse.BooleanOptionalAction, help="estimate the discretisation error of the finding (a refit on a "
                                                      "coarser mesh, one driven by every other boundary point) and "
                                                      "add it to the reported errors (default: on)")),
)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``diagnose`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("diagnose", help="find what the initial model gets wrong and measure the gain",
                              description="Settings come from the defaults, then the bundle's [diagnose] table "
                              "in experiment.toml, then these options.")
    p.add_argument("bundle")
    p.add_argument("--out", required=True, help="output directory (report.json, report.html, figures, paraview/)")
    p.add_argument("--cache", default=None, metavar="DIR",
                   help="keep compiled programs in DIR for later runs (jaxfem.compilation_cache; or set "
                   "JAX_COMPILATION_CACHE_DIR); programs that call a host linear solver are not kept")
    settings = p.add_argument_group("settings of the diagnosis (override the bundle's [diagnose] table)")
    for flags, name, kw in OPTIONS:
        settings.add_argument(*flags, dest=name, default=argparse.SUPPRESS, **kw)
    p.set_defaults(run=run)
    return p


def settings_given(args: argparse.Namespace) -> dict:
    """The settings given as options (``{setting: value}``; ``--try-rectangles yes|no|auto`` as
    true, false or ``"auto"``)."""
    given = {name: getattr(args, name) for _, name, _ in OPTIONS if hasattr(args, name)}
    if "try_rectangles" in given:
        given["try_rectangles"] = {"yes": True, "no": False}.get(given["try_rectangles"], "auto")
    return given


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid diagnose`` (``args`` from the parser of :func:`add_parser`); 0 on success."""
    if getattr(args, "cache", None):
        import jaxfem

        jaxfem.compilation_cache(args.cache)
    diagnose(args.bundle, args.out, config=settings_given(args))
    return 0


def diagnose(bundle, out: str | Path, config=None, quiet: bool = False):
    """Diagnose a bundle, 2D or solid, and write its report (:func:`refine.diagnose` with ``out``).

    Args:
        bundle: a bundle directory (str or Path) or a :class:`refine.bundle.Bundle`.
        out: output directory (created if missing): ``report.json`` (schema 2, with the settings
            and provenance), ``summary.txt`` and, by body, ``report.html``, the figures and
            ``paraview/`` of :func:`refine.diagnosis.report.write` and ``refined/``, a bundle whose
            initial model is the chosen one (:func:`refine.diagnosis.refined.write`); a cup
            holder's ``global/`` (see :meth:`refine.api.Diagnosis.write`).
        config: the settings (:func:`refine.api.settings_for`): None, the bundle's
            ``[diagnose]`` table over the defaults; a dict of settings, applied over that table
            (a solid body's: over its diagnosis' defaults; a setting of another body's diagnosis
            is named and left out); the body's settings object, used as it is.
        quiet: print neither the progress log nor the summary.

    Returns:
        The body's own diagnosis (:class:`refine.diagnosis.Diagnosis`, or a solid body's:
        :attr:`refine.api.Diagnosis.result`).

    Raises:
        refine.exceptions.BundleError: the bundle directory is malformed.
        Exception: any error (or ``KeyboardInterrupt``) after the initial model, once report.json,
            summary.txt and report.html say what was done, where it stopped and why
            (:mod:`refine.diagnosis.incomplete`); ``nonrigid diagnose`` then exits non-zero.
        refine.exceptions.SettingsError: a setting is unknown (the nearest is named) or invalid.
    """
    from refine.api import diagnose as entry

    try:
        d = entry(bundle, config, out=out, log=None if quiet else print)
    except BaseException as e:
        stopped = getattr(e, "diagnosis", None)
        if stopped is not None and stopped.written is not None and not quiet:
            print(stopped.summary())
            print(f"wrote what was done to {stopped.written}, {Path(out) / 'summary.txt'} and "
                  f"{Path(out) / 'report.html'}")
        raise
    if not quiet:
        print(d.summary())
        if d.route == "plane":
            print(f"wrote {d.written}, {Path(out) / 'report.html'} and figures in {Path(out)}; "
                  f"ParaView: open {Path(out) / 'paraview'}/*.pvd"
                  + (f"; the refined model as a bundle in {d.refined}" if d.refined else ""))
        else:
            print(f"wrote {d.written} and {Path(out) / 'summary.txt'}"
                  + (f"; the global model with the finding as a bundle in {Path(out) / 'global'}"
                     if d.route == "thin-wall" else f" and {Path(out) / 'report.html'}"))
    return d.result


def settings_of(bundle, given: dict | None = None):
    """The :class:`refine.diagnosis.DiagnoseConfig` of a bundle: the defaults, then its
    experiment.toml's ``[diagnose]`` table, then ``given`` (e.g. command-line options); see
    :func:`refine.diagnosis.config.settings_of` (imported here on call: the parser loads no JAX)."""
    from refine.diagnosis.config import settings_of as of

    return of(bundle, given)
