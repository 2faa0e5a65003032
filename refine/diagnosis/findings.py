"""What a diagnosis says about one cause (:class:`Finding`): report.json's ``findings`` entries,
as typed values."""

from __future__ import annotations

import math
from dataclasses import dataclass

from refine.diagnosis.laws import law_parameters
from refine.diagnosis.uncertainty import ShapeErrors, discretisation_errors, errors_of, shape_errors, total_errors


@dataclass(frozen=True)
class FoundRegion:
    """Where a finding lies, as report.json gives it (rounded to 1e-4).

    Attributes:
        centroid: ``(x, y)``; area: its area (length unit squared); polygon: its outline
        ``[[x, y], ...]``; shape: ``"ellipse"`` or ``"rectangle"`` (a hole is an ellipse);
        axes: semi-axes or half sides; angle: radians.
    """

    centroid: tuple[float, float]
    area: float
    polygon: list
    shape: str
    axes: tuple[float, float]
    angle: float

    def to_json(self) -> dict:
        return {"centroid": list(self.centroid), "area": self.area, "polygon": self.polygon, "shape": self.shape,
                "axes": list(self.axes), "angle": self.angle}


@dataclass(frozen=True)
class Finding:
    """One cause the diagnosis names, with the numbers report.json gives for it.

    Attributes:
        cause: ``"stiffer-region"``, ``"softer-region"``, ``"hole"`` or ``"material-law"``.
        region: where (None for a material law).
        relative_elasticity: E x thickness over the background's (0 for a hole; None for a law).
        modulus: the absolute modulus where measured forces fixed it, else None.
        relative_elasticity_std: its standard error, where known.
        law: the material law found (a material-law finding, or a hole or region fitted in a
            material of another law than the initial model's).
        parameters: the law's fitted parameters with their standard errors, ``{name: {"value":
            v, "std": s}}`` (:func:`~refine.diagnosis.laws.law_parameters`; an angle in radians).
        std: standard errors of every fitted quantity of the region (centroid, axes, angle,
            area, relative elasticity; :mod:`refine.diagnosis.uncertainty`), where known.
        discretisation: the discretisation errors of the same quantities (the mesh's, by
            Richardson's estimate), where estimated; total_std: ``std`` and ``discretisation``
            in quadrature, the error a truth is compared with; discretisation_parts: the
            discretisation error by source (``"mesh"``, ``"drive"``), where estimated.
        evidence: a sentence: the null test and what the hypothesis gains.

    ``finding["key"]`` reads the report.json entry (:meth:`to_json`).
    """

    cause: str
    evidence: str
    region: FoundRegion | None = None
    relative_elasticity: float | None = None
    modulus: float | None = None
    relative_elasticity_std: float | None = None
    law: str | None = None
    std: ShapeErrors | None = None
    parameters: dict | None = None
    discretisation: ShapeErrors | None = None
    total_std: ShapeErrors | None = None
    discretisation_parts: dict | None = None

    def to_json(self) -> dict:
        """The report.json entry (keys in the order of the bundle spec's example)."""
        if self.cause == "material-law":
            return {"cause": self.cause, "region": None, "relative_elasticity": None, "modulus": None,
                    "law": self.law, **self._law_parameters(), "evidence": self.evidence}
        std = {} if self.relative_elasticity_std is None else {"relative_elasticity_std": self.relative_elasticity_std}
        if std and not math.isfinite(std["relative_elasticity_std"]):  # refine.diagnosis.valley: draws reach a rigid region
            std["relative_elasticity_bounded_below_only"] = True
        if self.std is not None:
            std["std"] = self.std.to_json()
        if self.discretisation is not None:  # keys added after std (older readers ignore them)
            std["discretisation"] = self.discretisation.to_json()
            std["total_std"] = self.total_std.to_json()
            std["relative_elasticity_total_std"] = std["total_std"]["relative_elasticity"]
            if self.discretisation_parts:
                std["discretisation_parts"] = {k: e.to_json() for k, e in self.discretisation_parts.items()}
        law = {"law": self.law, **self._law_parameters()} if self.law else {}
        return {"cause": self.cause, "region": self.region.to_json(), "relative_elasticity": self.relative_elasticity,
                "modulus": self.modulus, **std, **law, "evidence": self.evidence}

    def _law_parameters(self) -> dict:
        return {"parameters": self.parameters} if self.parameters else {}

    def __getitem__(self, key: str):
        return self.to_json()[key]

    def get(self, key: str, default=None):
        return self.to_json().get(key, default)


def findings(chosen, evidence: str, background_modulus: float | None) -> list[Finding]:
    """The findings of the ``chosen`` fitted hypothesis (none for the initial model); moduli
    absolute where ``background_modulus`` is known."""
    if chosen.cause == "none":
        return []
    parameters = law_parameters(chosen) or None
    if chosen.cause == "material-law":
        return [Finding("material-law", evidence, law=chosen.law, parameters=parameters)]
    out = []
    errors = shape_errors(chosen) or [None] * len(chosen.shapes)
    disc = discretisation_errors(chosen) or [None] * len(chosen.shapes)
    parts = {k: [errors_of(row, s) for row, s in zip(d, chosen.shapes)]
             for k, d in (getattr(chosen, "q_disc_parts", None) or {}).items()}
    for i, shape in enumerate(chosen.shapes):
        # z holds the log ratios first, then the geometry unknowns: ratio i's standard error is std[i]
        # the same standard error as the total's (the draws through the map, where there are
        # errors); else the linearised ratio * std(log ratio)
        std = None
        if errors[i] is not None and errors[i].relative_elasticity is not None and shape.kind != "hole":
            std = round(float(errors[i].relative_elasticity), 4)
        elif chosen.z_std is not None and shape.kind != "hole":
            std = round(float(shape.ratio * chosen.z_std[i]), 4)
        area, polygon = shape.outline()
        region = FoundRegion((round(float(shape.centre[0]), 4), round(float(shape.centre[1]), 4)), round(area, 4),
                             polygon, "rectangle" if shape.kind == "rectangle" else "ellipse",
                             (round(float(shape.axes[0]), 4), round(float(shape.axes[1]), 4)),
                             round(float(shape.angle), 4))
        modulus = None if background_modulus is None else round(float(shape.ratio) * background_modulus, 4)
        law = chosen.law if parameters else None  # a hole in a material of another law (refine.diagnosis.hole_law)
        out.append(Finding(shape.cause, evidence, region, round(float(shape.ratio), 4), modulus, std, std=errors[i],
                           law=law, parameters=parameters, discretisation=disc[i],
                           total_std=None if disc[i] is None else total_errors(errors[i], disc[i]),
                           discretisation_parts={k: e[i] for k, e in parts.items()} or None))
    return out
