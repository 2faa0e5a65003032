"""Settings of a diagnosis, from Python, from the ``[diagnose]`` table of experiment.toml or
from ``nonrigid diagnose``'s options (:meth:`DiagnoseConfig.from_table`, checked either way)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from refine.exceptions import SettingsError, nearest_key


@dataclass(frozen=True)
class DiagnoseConfig:
    """Settings of a diagnosis (data, not a dozen keyword arguments).

    Attributes:
        alpha: significance of the null test (a misfit this unlikely under the initial model
            means something is wrong).
        holdout_fraction: share of guide points held out to choose between hypotheses.
        bic_margin: how much lower than the initial model's BIC a hypothesis must score.
        field_weight: smoothing weight of the localisation field (x number of residuals / cells).
        max_regions: largest number of regions tried.
        try_laws: also try other material laws.
        refit_element: element of the chosen model's final meshes (``"tri6"``: linear triangles
            at the same size are too stiff in a strongly strained region and bias its ratio).
        hole_below: a softer region fitted at less than this ratio is also fitted as a hole from
            its fitted outline (a hole started from the candidate's rough outline can settle in
            a worse place than the very soft region does, and then loses the comparison).
        hole_refit_below: a chosen softer region whose refit on every guide point falls below
            this ratio (it carries almost no load) is compared with a hole at its outline once
            more (:func:`~refine.diagnosis.final_fit._hole_if_as_likely`); lower than
            ``hole_below`` because the hole's fit and remesh cost true soft regions minutes.
        seed: seeds the holdout split.
        try_rectangles: when the first region, fitted as an ellipse, is the best hypothesis so
            far, also fit it as a rectangle (from the ellipse, turned 0 and pi/4, beside the
            ellipse remeshed at its fit); the best score is kept. False: never; True: always;
            None (default): where the data ask for it, i.e. the fitted ellipse leaves a misfit
            above what noise, its propagation and model error explain, and the tracked points
            resolve a rectangle's corners (the ellipse's smaller semi-axis is at least
            ``rectangle_spacings`` grid spacings). Fitted as ellipses, rectangles come out
            larger and too soft; on coarse grids rectangles out-score true ellipses that already
            explain the data, which the misfit gate leaves as ellipses (and spares their cost).
        rectangle_spacings: the gate of ``try_rectangles=None``, in grid spacings (1.5: a side
            spans at least three grid intervals).
        workers: hypotheses (and the set-up's independent models) fitted side by side in this
            many threads; XLA compiles and solves outside Python's lock, and compilation is most
            of a diagnosis.
        h: element size of the models' meshes, length unit; None: from ``max_cells``.
        linear_solver: ``"auto"`` or a solver of :data:`jaxfem.linsolve.SOLVERS` that is
            installed, for every model of the diagnosis.
        max_cells: the models' element size is half the point spacing, but at most this many
            linear triangles over the domain (:func:`refine.diagnosis.scale.mesh_size`): the
            cost of a solve follows the domain, not the number of tracked points.
        search_frames: the null test, the field and every hypothesis use this many frames, those
            of most motion (:func:`refine.diagnosis.scale.search_frames`); the chosen model is
            refitted on every frame. 0: all frames.
        strain_candidates: at most this many candidate regions also from the measured strain
            map (:func:`refine.diagnosis.candidates.strain_regions`), beside the field's and the
            gaps in the points.
        discretisation_error: estimate the discretisation error of the chosen hypothesis'
            quantities (two more fits: on a mesh sqrt(2) coarser, and driven by every other
            boundary point; :func:`refine.diagnosis.uncertainty.with_discretisation`) and report
            it beside the standard errors and in their total.
    """

    alpha: float = 1e-3
    holdout_fraction: float = 0.25
    bic_margin: float = 10.0
    field_weight: float = 2.0
    max_regions: int = 2
    try_laws: bool = True
    refit_element: str = "tri6"
    hole_below: float = 0.3
    hole_refit_below: float = 0.05
    seed: int = 0
    workers: int = 2
    try_rectangles: bool | None = None
    rectangle_spacings: float = 1.5
    h: float | None = None
    linear_solver: str = "auto"
    max_cells: int = 3000
    search_frames: int = 2
    strain_candidates: int = 1
    discretisation_error: bool = True

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            _check(f.name, value)
            if isinstance(value, int) and not isinstance(value, bool) and float in _types(f.name):
                object.__setattr__(self, f.name, float(value))

    @classmethod
    def from_table(cls, table: dict[str, Any], where: str = "[diagnose]", base: DiagnoseConfig | None = None
                   ) -> DiagnoseConfig:
        """Settings from a table (e.g. experiment.toml's ``[diagnose]``, or options given on the
        command line) over ``base`` (default: the defaults). ``try_rectangles = "auto"`` stands
        for None (TOML has no null).

        Raises:
            SettingsError: an unknown key (naming the nearest known one), a wrong type or range;
                the message starts with ``where``.
        """
        if not isinstance(table, dict):
            raise SettingsError(f"{where} must be a table of settings, got {table!r}")
        names = [f.name for f in fields(cls)]
        values = {f.name: getattr(base or cls(), f.name) for f in fields(cls)}
        for key, value in table.items():
            if key not in names:
                raise SettingsError(f"{where}: unknown setting {key!r}{nearest_key(key, names)}; "
                                    f"the settings are {', '.join(names)}")
            values[key] = None if (key == "try_rectangles" and value == "auto") else value
        try:
            return cls(**values)
        except SettingsError as e:
            raise SettingsError(f"{where}: {e}") from None

    def settings(self) -> dict[str, Any]:
        """Every setting by name, as report.json records them."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


#: (types, check, what it must be) per setting; int is accepted where a float is asked
_RULES = {
    "alpha": (float, lambda v: 0 <= v < 1, "a number in [0, 1) (0: never reject the initial model)"),
    "holdout_fraction": (float, lambda v: 0 < v < 1, "a number in (0, 1)"),
    "bic_margin": (float, lambda v: v >= 0, "a number >= 0"),
    "field_weight": (float, lambda v: v > 0, "a number > 0"),
    "max_regions": (int, lambda v: v >= 1, "an integer >= 1"),
    "try_laws": (bool, None, "true or false"),
    "refit_element": (str, lambda v: v in ("tri3", "tri6"), '"tri3" or "tri6"'),
    "hole_below": (float, lambda v: 0 <= v <= 1, "a number in [0, 1]"),
    "hole_refit_below": (float, lambda v: 0 <= v <= 1, "a number in [0, 1]"),
    "seed": (int, lambda v: v >= 0, "an integer >= 0"),
    "workers": (int, lambda v: v >= 1, "an integer >= 1"),
    "try_rectangles": ((bool, type(None)), None, 'true, false or "auto"'),
    "rectangle_spacings": (float, lambda v: v > 0, "a number > 0"),
    "h": ((float, type(None)), lambda v: v is None or v > 0, "an element size > 0 (length unit)"),
    "linear_solver": (str, None, '"auto" or an installed solver of jaxfem.linsolve'),
    "max_cells": (int, lambda v: v >= 10, "an integer >= 10"),
    "search_frames": (int, lambda v: v >= 0, "an integer >= 0 (0: all frames)"),
    "strain_candidates": (int, lambda v: v >= 0, "an integer >= 0"),
    "discretisation_error": (bool, None, "true or false"),
}


def _types(name: str) -> tuple:
    types = _RULES[name][0]
    return types if isinstance(types, tuple) else (types,)


def _check(name: str, value) -> None:
    _, ok, what = _RULES[name]
    types = _types(name)
    numeric = float in types and isinstance(value, int) and not isinstance(value, bool)
    if not (numeric or (isinstance(value, types) and not (isinstance(value, bool) and bool not in types))):
        raise SettingsError(f"{name} must be {what}, got {value!r}")
    if ok is not None and not ok(value):
        raise SettingsError(f"{name} must be {what}, got {value!r}")
    if name == "linear_solver":
        from jaxfem.linsolve import SOLVERS, available

        if value != "auto" and value not in SOLVERS:  # the nearest of every solver jaxfem knows
            raise SettingsError(f"linear_solver {value!r} is unknown{nearest_key(value, SOLVERS)}; "
                                f"use 'auto' or one of {', '.join(available())} (installed here)")
        if value != "auto" and value not in available():
            raise SettingsError(f"linear_solver {value!r} is not installed here (pip install "
                                f"'nonrigid[fast]' brings pypardiso and klujax); use 'auto' or one of "
                                f"{', '.join(available())}")


def settings_of(bundle, given: dict | None = None):
    """The :class:`refine.diagnosis.DiagnoseConfig` of a bundle: the defaults, then its
    experiment.toml's ``[diagnose]`` table, then ``given`` (e.g. command-line options)."""
    where = f"{bundle.root / 'experiment.toml' if bundle.root else 'experiment.toml'} [diagnose]"
    cfg = DiagnoseConfig.from_table(bundle.experiment.extra.get("diagnose", {}), where)
    return DiagnoseConfig.from_table(given or {}, "options", base=cfg)
