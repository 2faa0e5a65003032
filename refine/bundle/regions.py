"""Known regions of a bundle's initial model (``[[model.regions]]`` in experiment.toml): a shape
of other stiffness, and optionally another material law, inside the domain; and the check that
regions and holes lie inside the domain and apart (a conforming mesh needs both).

A refined model written by ``nonrigid diagnose`` (``OUT/refined/``) gives its finding this way,
so that the next analysis starts from it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from refine.bundle.shapes import PolygonShape, Shape, _number, shape_from_toml
from refine.exceptions import ExperimentError


@dataclass(frozen=True)
class KnownRegion:
    """A region of the initial model with its own stiffness (and law).

    Attributes:
        shape: an :class:`~refine.bundle.shapes.EllipseShape`, ``RectangleShape`` or
            ``PolygonShape`` (length unit, reference configuration).
        relative_elasticity: its modulus over the background's (E x thickness ratio, > 0), or
        modulus: its absolute Young's modulus (stress unit, > 0); exactly one of the two.
        law: its own material law (a name of ``jaxfem.materials.LAWS``); None: the background's.
        parameters: the law's extra parameters (e.g. ``{"c01_fraction": 0.3}``); unset ones
            take the law's defaults.
        name: names the region in meshes and messages (default ``region1``, ``region2``, ...).
        tag: the cell tag of this region in the model's mesh file (``model.mesh``), where it has
            one; None: a mesh file's cells whose centroid lies in the shape (a mesh the model
            makes itself follows the shape and tags it).
    """

    shape: Shape
    relative_elasticity: float | None = None
    modulus: float | None = None
    law: str | None = None
    parameters: dict[str, float] = field(default_factory=dict)
    name: str = "region"
    tag: int | None = None

    def __post_init__(self):
        what = f"model.regions {self.name!r}"
        if (self.relative_elasticity is None) == (self.modulus is None):
            raise ExperimentError(f"{what} needs exactly one of relative_elasticity (ratio to the background "
                                  "modulus) or modulus (absolute, stress unit)")
        for key in ("relative_elasticity", "modulus"):
            if getattr(self, key) is not None:
                object.__setattr__(self, key, _number(getattr(self, key), f"{what}.{key}", positive=True))
        if not isinstance(self.name, str) or not self.name:
            raise ExperimentError(f"model.regions name must be a non-empty string, got {self.name!r}")
        object.__setattr__(self, "parameters", {k: _number(v, f"{what}.{k}") for k, v in self.parameters.items()})
        if self.tag is not None and (isinstance(self.tag, bool) or not isinstance(self.tag, int)):
            raise ExperimentError(f"{what}.tag must be an integer cell tag of model.mesh, got {self.tag!r}")

    def modulus_over(self, background: float) -> float:
        """Its Young's modulus (stress unit) over a background of modulus ``background``."""
        return self.modulus if self.modulus is not None else self.relative_elasticity * background

    def to_toml(self) -> dict:
        out: dict[str, Any] = {"name": self.name, **self.shape.to_toml()}
        if self.relative_elasticity is not None:
            out["relative_elasticity"] = self.relative_elasticity
        else:
            out["modulus"] = self.modulus
        if self.law is not None:
            out["law"] = self.law
        if self.tag is not None:
            out["tag"] = self.tag
        out.update(self.parameters)
        return out


def regions_from_toml(tables: Any) -> tuple[KnownRegion, ...]:
    """``[[model.regions]]`` as :class:`KnownRegion` s; a key that is no shape, modulus, law or
    name is taken as a parameter of the region's law (checked against the law later)."""
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise ExperimentError("model.regions must be an array of tables ([[model.regions]]), each with a shape "
                              "(ellipse, rectangle or polygon) and relative_elasticity or modulus")
    out = []
    for k, table in enumerate(tables):
        rest = dict(table)
        name = rest.pop("name", f"region{k + 1}")
        shape = shape_from_toml(rest, f"model.regions[{k}]")
        rest.pop(shape.kind)
        known = {key: rest.pop(key) for key in ("relative_elasticity", "modulus", "law", "tag") if key in rest}
        if "law" in known and not isinstance(known["law"], str):
            raise ExperimentError(f"model.regions[{k}].law must be a law's name, got {known['law']!r}")
        out.append(KnownRegion(shape, name=name, parameters=rest, **known))
    return tuple(out)


def check_parameters(parameters: dict, law: str, laws: dict, what: str) -> None:
    """Raise if ``law`` is not in ``laws`` (name -> ``jaxfem.Material``) or a key of
    ``parameters`` is not one of its extra parameters; ``what`` names the table in errors."""
    if law not in laws:
        raise ExperimentError(f"{what}: law {law!r} is unknown; use one of {list(laws)}")
    known = [q.name for q in laws[law].extra]
    for key in parameters:
        if key not in known:
            raise ExperimentError(f"{what}: {key!r} is no parameter of the {law} law (its parameters: "
                                  f"{known or 'none beyond E and nu'})")


def check_layout(outline, holes, regions) -> None:
    """Raise if a region or a hole leaves the domain, or two of them overlap or touch.

    Args:
        outline: the domain's outline, ``(m, 2)`` counter-clockwise.
        holes: the domain's holes, shapes (a polygon hole as a :class:`PolygonShape`).
        regions: the known regions (:class:`KnownRegion`).
    """
    named = [(f"domain.holes[{k}]", h) for k, h in enumerate(holes)]
    named += [(f"model.regions {r.name!r}", r.shape) for r in regions]
    edges = [(name, s.outline()) for name, s in named]
    domain = PolygonShape(tuple(map(tuple, np.asarray(outline))))
    for name, curve in edges:
        if not domain.contains(curve).all():
            bad = curve[~domain.contains(curve)][0]
            raise ExperimentError(f"{name} leaves the domain (its outline passes ({bad[0]:.4g}, {bad[1]:.4g})); "
                                  "a region or a hole lies strictly inside the domain's outline")
    for i, (name_i, s_i) in enumerate(named):
        for j, (name_j, s_j) in enumerate(named):
            if i < j and (s_j.contains(edges[i][1]).any() or s_i.contains(edges[j][1]).any()):
                raise ExperimentError(f"{name_i} and {name_j} overlap or touch; known regions and holes must be "
                                      "disjoint, with a gap between them")
