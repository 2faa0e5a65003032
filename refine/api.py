"""One entry point for every body: ``refine.diagnose(bundle, config) -> Diagnosis``, then
``Diagnosis.write(out)``; the command line (``nonrigid diagnose``), the batch runner and the
notebooks all go through it.

    import refine
    d = refine.diagnose("runs/sheet-07/bundle", {"alpha": 1e-3})
    print(d.summary())
    d.write("reports/sheet-07")            # report.json (schema 2, refine.reports), summary.txt, ...

Where a bundle goes is read off the bundle, never off its name (:func:`route`): a 2D bundle to
:func:`refine.diagnosis.diagnose`; a solid one whose guide points lie on an observed thin wall
inside a rim (:func:`refine.solid.diagnose.thin_wall_reason`) to that wall's local model
(:func:`refine.solid.diagnose_solid`, the cup holder's strategy); any other solid to the 3D
engine (:func:`refine.solid.engine.diagnose_body`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

from refine.bundle.io import Bundle, read_bundle
from refine.exceptions import ObservationError, SettingsError, nearest_key
from refine.reports import upgrade

#: settings the command line names otherwise than a 3D diagnosis does: (CLI name, the 3D name)
ALIASES = {"max_regions": "max_candidates"}
#: what each route is, in words: (the bundle, whose settings)
_WHO = {"plane": ("a 2D bundle", "the 2D diagnosis"), "thin-wall": ("a solid bundle", "the thin wall's local model"),
        "engine": ("a solid bundle", "the 3D engine")}


def route(bundle: Bundle) -> tuple[str, str | None]:
    """Which diagnosis a bundle takes: ``("plane", None)`` for a 2D bundle, ``("thin-wall",
    None)`` for a solid one whose guide points lie on an observed thin wall inside a rim,
    ``("engine", reason)`` for any other solid body (``reason``: why the thin wall's strategy
    does not apply)."""
    if bundle.experiment.kind != "solid":
        return "plane", None
    from refine.solid.diagnose import thin_wall_reason

    reason = thin_wall_reason(bundle)
    return ("thin-wall", None) if reason is None else ("engine", reason)


def _classes() -> dict:
    from refine.diagnosis.config import DiagnoseConfig
    from refine.solid.diagnose import SolidConfig
    from refine.solid.engine import EngineConfig

    return {"plane": DiagnoseConfig, "thin-wall": SolidConfig, "engine": EngineConfig}


def settings_for(bundle: Bundle, way: str, config) -> tuple[object, tuple[str, ...]]:
    """The settings object of route ``way`` (see :func:`route`) from ``config`` and the names of
    the settings given that do not apply to it.

    ``config``: None (the defaults; a 2D bundle's ``[diagnose]`` table over them); that route's
    settings object (:class:`~refine.diagnosis.DiagnoseConfig`,
    :class:`~refine.solid.diagnose.SolidConfig` or :class:`~refine.solid.engine.EngineConfig`),
    used as it is; or a dict of settings by name (the command line's names; ``max_regions`` is the
    3D ``max_candidates``): a 2D bundle's applied over its ``[diagnose]`` table, a solid's over the
    defaults, and a name that is a setting of another route only is left out and named.

    Raises:
        SettingsError: a setting no route has (the nearest named), an invalid value, or the
            settings object of another route.
    """
    classes = _classes()
    cls = classes[way]
    if config is None:
        config = {}
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        if isinstance(config, cls):
            return config, ()
        what, whose = _WHO[way]
        raise SettingsError(f"{type(config).__name__} holds the settings of another diagnosis; {what} takes "
                            f"{whose}: give a {cls.__name__}, or a dict of settings by name")
    if not isinstance(config, dict):
        raise SettingsError(f"settings are a dict of settings by name or a settings object, not {config!r}")
    known = set(ALIASES) | {f.name for c in classes.values() for f in dataclasses.fields(c)}
    unknown = [k for k in config if k not in known]
    names = {f.name for f in dataclasses.fields(cls)}
    if unknown and way != "plane":  # (a 2D bundle's unknown names: DiagnoseConfig.from_table says which)
        raise SettingsError(f"unknown setting {unknown[0]!r}{nearest_key(unknown[0], known)}; the settings of "
                            f"{_WHO[way][1]} are {', '.join(sorted(names))}")
    name = (lambda k: k) if way == "plane" else (lambda k: ALIASES.get(k, k))
    ignored = tuple(sorted(k for k in config if k in known and name(k) not in names))
    given = {name(k): v for k, v in config.items() if k not in ignored}
    if way == "plane":
        from refine.diagnosis.config import settings_of

        return settings_of(bundle, given), ignored
    try:
        return cls(**given), ignored
    except (TypeError, ValueError) as e:
        raise SettingsError(f"settings of {_WHO[way][1]}: {e}") from None


@dataclass(eq=False)
class Diagnosis:
    """A bundle's diagnosis, whichever body: the ``bundle``, its ``route`` (:func:`route`; with
    the ``reason`` an engine's body has no thin wall), the settings ``config`` and the names of
    the settings given that did not apply (``ignored``), the body's own diagnosis ``result``
    (:class:`refine.diagnosis.Diagnosis`, :class:`refine.solid.diagnose.SolidDiagnosis` or
    :class:`refine.solid.engine.BodyDiagnosis`; where the run stopped after the initial model,
    what it had done: :class:`refine.diagnosis.incomplete.Incomplete` or a ``BodyDiagnosis`` with
    ``incomplete``), the ``error`` that stopped it (None: it finished), and after :meth:`write`
    the report's path (``written``) and the refined bundle's (``refined``, 2D)."""

    bundle: Bundle
    route: str
    result: object
    config: object = None
    ignored: tuple = ()
    reason: str | None = None
    error: BaseException | None = None
    written: Path | None = None
    refined: Path | None = None
    _report: dict | None = field(default=None, repr=False)

    @property
    def dim(self) -> int:
        return 2 if self.route == "plane" else 3

    def report(self) -> dict:
        """report.json's content, schema 2 (:mod:`refine.reports`)."""
        if self._report is not None:
            return self._report
        return self.result.report() if self.route == "engine" else upgrade(self.result.report())

    def summary(self) -> str:
        """A few lines saying what was found, in words (summary.txt)."""
        if self.route == "thin-wall":
            from refine.solid.write import cup_summary

            return cup_summary(self.report())
        if self.route == "plane" and self.error is None:
            from refine.diagnosis import report

            return report.summary(self.result)
        return self.result.summary()

    @property
    def findings(self) -> list[dict]:
        """report.json's findings (each with :data:`refine.reports.FINDING`'s fields)."""
        return self.report()["findings"]

    @property
    def cause(self) -> str:
        return self.report()["cause"]

    @property
    def found(self) -> bool:
        return bool(self.findings)

    def write(self, out: str | Path, figures: bool = True) -> Path:
        """Write the diagnosis to the folder ``out`` (created), each file atomically
        (:mod:`refine.diagnosis.atomic`): report.json, summary.txt and, by body, report.html, the
        figures and ``paraview/`` (2D, :func:`refine.diagnosis.report.write`; ``figures=False``:
        report.json and summary.txt alone) and ``refined/`` (2D, :func:`refine.diagnosis.refined.write`),
        ``global/`` (the cup holder's global model, :func:`refine.solid.write.write_cup`), report.html
        (the 3D engine). A stopped run's report says where it stopped (``incomplete``). Returns
        report.json's path.

        Raises:
            Exception: what failed while writing a finished 2D diagnosis, once report.json,
                summary.txt and report.html record it (``exception.diagnosis``: the stopped one).
        """
        out = Path(out)
        if self.route == "engine":
            self.result.write(out)  # report.json, summary.txt, report.html
            self.written = out / "report.json"
        elif self.route == "thin-wall":
            from refine.solid.write import write_cup

            self.written = write_cup(self.bundle, self.result, self.report(), out)
        elif self.error is not None:
            from refine.diagnosis.incomplete import write

            self.written = write(self.result, out)
        else:
            self._write_plane(out, figures)
        return self.written

    def _write_plane(self, out: Path, figures: bool) -> None:
        from refine.diagnosis import refined, report

        stage = "the report"
        try:
            self.written = report.write(self.result, out, with_figures=figures)
            stage = "the refined bundle"
            self.refined = refined.write(self.result, out)  # OUT/refined/: the chosen model as a bundle
        except BaseException as e:
            from refine.diagnosis.incomplete import of_diagnosis

            stopped = dataclasses.replace(self, result=of_diagnosis(self.result, f"writing {stage}", e), error=e)
            stopped.write(out)
            e.diagnosis = stopped
            raise


def diagnose(bundle: Bundle | str | Path, config=None, *, out: str | Path | None = None, log=print,
             figures: bool = True) -> Diagnosis:
    """Diagnose a measurement bundle, 2D or 3D (the route: see the module and :func:`route`).

    Args:
        bundle: a :class:`refine.bundle.Bundle` or a bundle directory.
        config: the settings (:func:`settings_for`): None, a dict of settings by name, or the
            route's settings object.
        out: where to write it (:meth:`Diagnosis.write`) as soon as it is done; None: not written.
        log: called with each progress line (None: silent).
        figures: with ``out``, draw a 2D diagnosis' figures and ParaView series.

    Returns:
        The :class:`Diagnosis`.

    Raises:
        refine.exceptions.BundleError: the bundle directory is malformed.
        refine.exceptions.ObservationError: the bundle has no tracked points.
        refine.exceptions.SettingsError: a setting is unknown, invalid or of another route.
        Exception: any error (or ``KeyboardInterrupt``) of the diagnosis; one after the initial
            model (2D, the 3D engine) carries what was done as ``exception.diagnosis`` (a
            :class:`Diagnosis` with ``error``), written to ``out`` first where ``out`` is given.
    """
    if isinstance(bundle, (str, Path)):
        bundle = read_bundle(bundle)
    if bundle.observations is None:
        raise ObservationError("the bundle holds unlabelled clouds only (clouds.csv, no points.csv); diagnose needs "
                               "tracked points: follow the clouds with `nonrigid follow BUNDLE --out DIR`")
    say = log if log is not None else (lambda m: None)
    way, reason = route(bundle)
    cfg, ignored = settings_for(bundle, way, config)
    if ignored:
        what, whose = _WHO[way]
        say(f"ignored for {what} (no such setting of {whose}): {', '.join(ignored)}")
    made = dict(bundle=bundle, route=way, config=cfg, ignored=ignored, reason=reason)
    try:
        d = _run(bundle, way, reason, cfg, say, made)
    except BaseException as e:
        done = getattr(e, "incomplete", None)
        if done is not None:  # after the initial model: what was done is kept (and written), then the error goes on
            e.diagnosis = Diagnosis(**made, result=done, error=e)
            if out is not None:
                e.diagnosis.write(out)
        raise
    if out is not None:
        d.write(out, figures)
    return d


def _run(bundle: Bundle, way: str, reason: str | None, cfg, say, made: dict) -> Diagnosis:
    if way == "plane":
        from refine.diagnosis import diagnose as plane

        return Diagnosis(**made, result=plane(bundle, cfg, log=say))
    if way == "engine":
        from refine.solid.engine import diagnose_body

        say(f"the body's diagnosis by the 3D engine ({reason}: no observed thin wall)")
        return Diagnosis(**made, result=diagnose_body(bundle, cfg, log=say))
    from refine.solid.diagnose import diagnose_solid
    from refine.solid.write import cup_report

    d = diagnose_solid(bundle, cfg, log=say)
    return Diagnosis(**made, result=d, _report=cup_report(bundle, d, cfg))


__all__ = ["ALIASES", "Diagnosis", "diagnose", "route", "settings_for"]
