"""The shapes a diagnosis fits: a region of other stiffness (:class:`RegionShape`, an ellipse or a
rectangle with its relative elasticity) and a hole (:class:`Hole`, an ellipse removed). Lengths
in the bundle's unit, angles in radians (counter-clockwise from x)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

import jaxfem as jf

from refine.diagnosis.localize import shape_outline
from refine.model.parametrize import make_shape


def _bounds(domain) -> tuple[float, float, float, float] | None:
    """``(xmin, ymin, xmax, ymax)`` of a rectangle or polygon domain; None for a mesh file."""
    if hasattr(domain, "xmax"):
        return domain.xmin, domain.ymin, domain.xmax, domain.ymax
    if hasattr(domain, "vertices"):
        v = np.asarray(domain.vertices, float)
        return (*v.min(axis=0), *v.max(axis=0))
    return None


@dataclass(frozen=True)
class _Outline:
    """Centre ``(cx, cy)``, semi-axes (half sides for a rectangle) ``(a, b)`` and angle."""

    centre: tuple[float, float]
    axes: tuple[float, float]
    angle: float

    kind: ClassVar[str] = "ellipse"

    @property
    def params(self) -> np.ndarray:
        """``(5,)``: ``cx, cy, a, b, angle`` (the order of ``jaxfem``'s shapes)."""
        return np.array([*self.centre, *self.axes, self.angle])

    def geometry(self) -> jf.Ellipse | jf.Rect:
        """The ``jaxfem`` shape (to mesh)."""
        return make_shape("rectangle" if self.kind == "rectangle" else "ellipse", self.params)

    def outline(self) -> tuple[float, list[list[float]]]:
        """Area and outline polygon ``[[x, y], ...]`` (rounded to 1e-4)."""
        return shape_outline(self.kind, *self.centre, *self.axes, self.angle)

    def moved(self, other: _Outline) -> float:
        """How far ``other`` lies from this shape: the largest change of centre or axis, or of
        the outline by its turn (``|a - b|`` times the angle)."""
        turn = abs(np.angle(np.exp(2j * (other.angle - self.angle)))) / 2 * abs(other.axes[0] - other.axes[1])
        here, there = (*self.centre, *self.axes), (*other.centre, *other.axes)
        return float(max(np.max(np.abs(np.subtract(here, there))), turn))

    def clamped(self, domain, spacing: float):
        """The shape kept inside ``domain``'s bounding box (a margin of half a grid spacing;
        a polygon's box, the whole plane for a mesh file) and at least about one grid
        ``spacing`` across."""
        a, b = max(self.axes[0], 0.6 * spacing), max(self.axes[1], 0.6 * spacing)
        m = 0.5 * spacing
        cx, cy = self.centre
        box = _bounds(domain)
        if box is not None:
            xmin, ymin, xmax, ymax = box
            if xmax - xmin > 2 * (a + m):
                cx = float(np.clip(cx, xmin + a + m, xmax - a - m))
            if ymax - ymin > 2 * (b + m):
                cy = float(np.clip(cy, ymin + b + m, ymax - b - m))
        return replace(self, centre=(cx, cy), axes=(a, b))

    def _words(self, ratio: float) -> str:
        cx, cy = self.centre
        a, b = self.axes
        return (f"{self.kind} at ({cx:.1f}, {cy:.1f}) {'half sides' if self.kind == 'rectangle' else 'axes'} "
                f"({a:.1f}, {b:.1f}) angle {np.degrees(self.angle):.0f} deg ratio {ratio:.2f}")


@dataclass(frozen=True)
class RegionShape(_Outline):
    """A region of other stiffness: an ellipse (``axes`` its semi-axes) or a rectangle (``axes``
    its half sides), and ``ratio``, its relative elasticity (E x thickness over the
    background's; None where not fitted or started)."""

    kind: str = "ellipse"
    ratio: float | None = None

    @classmethod
    def of(cls, shape: jf.Ellipse | jf.Rect, ratio: float | None = None) -> RegionShape:
        """The region of a ``jaxfem`` shape."""
        cx, cy, a, b, angle = map(float, shape.params)
        return cls((cx, cy), (a, b), angle, "rectangle" if isinstance(shape, jf.Rect) else "ellipse", ratio)

    @property
    def cause(self) -> str:
        return "stiffer-region" if self.ratio > 1 else "softer-region"

    def describe(self) -> str:
        return self._words(self.ratio)


@dataclass(frozen=True)
class Hole(_Outline):
    """An elliptic hole: no material, relative elasticity 0."""

    ratio: ClassVar[float] = 0.0
    kind: ClassVar[str] = "hole"
    cause: ClassVar[str] = "hole"

    def describe(self) -> str:
        return self._words(0.0)


def report_row(shape: RegionShape | Hole) -> list[float]:
    """A shape as report.json lists a hypothesis' shapes: ``[cx, cy, a, b, angle, ratio]``."""
    return [float(v) for v in (*shape.centre, *shape.axes, shape.angle, shape.ratio)]
