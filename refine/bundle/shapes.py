"""Shapes that experiment.toml gives known regions and holes: ellipses, rectangles and polygons,
one small record each, read from and written to TOML tables through one registry (:data:`SHAPES`).

A shape is written as a one-key table, the key naming its kind (lengths in the bundle's unit,
angles in radians counter-clockwise from x, as report.json gives them)::

    { ellipse = { centre = [cx, cy], axes = [a, b], angle = 0.3 } }          semi-axes a, b
    { rectangle = { centre = [cx, cy], half_sides = [a, b], angle = 0.0 } }  half side lengths
    { polygon = [[x, y], ...] }                                            counter-clockwise

A new kind is a record with ``kind``, ``to_toml``, ``outline``, ``contains`` and ``geometry``
(its ``jaxfem`` shape, for meshing), registered in :data:`SHAPES`. Nothing here loads JAX until
``geometry`` is called.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from refine.exceptions import ExperimentError


def _number(value: Any, what: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ExperimentError(f"{what} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise ExperimentError(f"{what} must be positive, got {value}")
    return float(value)


def _pair(value: Any, what: str, positive: bool = False) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ExperimentError(f"{what} must be a pair [x, y], got {value!r}")
    return _number(value[0], f"{what}[0]", positive), _number(value[1], f"{what}[1]", positive)


def inside_polygon(vertices, points) -> np.ndarray:
    """Whether ``points (n, 2)`` lie inside the closed polygon ``vertices (m, 2)`` (even-odd
    rule; points on a side may go either way), ``(n,)`` bool."""
    v, p = np.asarray(vertices, float), np.atleast_2d(np.asarray(points, float))
    a, b = v, np.roll(v, -1, axis=0)
    x, y = p[:, :1], p[:, 1:2]
    crosses = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        at = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return (np.count_nonzero(crosses & (x < at), axis=1) % 2) == 1


@dataclass(frozen=True)
class _Affine:
    """A unit shape (circle or square) mapped by ``R(angle) diag(a, b)`` about ``centre``."""

    centre: tuple[float, float]
    axes: tuple[float, float]
    angle: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "centre", _pair(self.centre, f"{self.kind}.centre"))
        object.__setattr__(self, "axes", _pair(self.axes, f"{self.kind}.{self._axes_key}", positive=True))
        object.__setattr__(self, "angle", _number(self.angle, f"{self.kind}.angle"))

    def to_unit(self, points) -> np.ndarray:
        """``points (n, 2)`` in the shape's frame, scaled by its axes."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        d = np.atleast_2d(np.asarray(points, float)) - self.centre
        return np.stack([(c * d[:, 0] + s * d[:, 1]) / self.axes[0], (-s * d[:, 0] + c * d[:, 1]) / self.axes[1]], 1)

    def from_unit(self, xi) -> np.ndarray:
        c, s = math.cos(self.angle), math.sin(self.angle)
        u, v = xi[:, 0] * self.axes[0], xi[:, 1] * self.axes[1]
        return np.stack([self.centre[0] + c * u - s * v, self.centre[1] + s * u + c * v], 1)

    def to_toml(self) -> dict:
        return {self.kind: {"centre": list(self.centre), self._axes_key: list(self.axes), "angle": self.angle}}

    @classmethod
    def from_toml(cls, value: Any, what: str):
        if not isinstance(value, dict) or set(value) - {"centre", cls._axes_key, "angle"} or not \
                {"centre", cls._axes_key} <= set(value):
            raise ExperimentError(f"{what} must be {{ centre = [x, y], {cls._axes_key} = [a, b], angle = RADIANS }} "
                                  f"(angle optional), got {value!r}")
        return cls(value["centre"], value[cls._axes_key], value.get("angle", 0.0))


@dataclass(frozen=True)
class EllipseShape(_Affine):
    """An ellipse: ``centre``, semi-axes ``axes`` (a along the angle), ``angle`` (radians)."""

    kind = "ellipse"
    _axes_key = "axes"

    def contains(self, points) -> np.ndarray:
        return (self.to_unit(points) ** 2).sum(1) < 1.0

    def outline(self, n: int = 256) -> np.ndarray:
        """``(n, 2)`` points on the curve, counter-clockwise."""
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return self.from_unit(np.stack([np.cos(t), np.sin(t)], 1))

    @property
    def area(self) -> float:
        return math.pi * self.axes[0] * self.axes[1]

    def geometry(self):
        import jaxfem as jf

        return jf.Ellipse(*self.centre, *self.axes, self.angle)


@dataclass(frozen=True)
class RectangleShape(_Affine):
    """A rectangle: ``centre``, half sides ``axes`` (written ``half_sides``), ``angle`` (radians)."""

    kind = "rectangle"
    _axes_key = "half_sides"

    def contains(self, points) -> np.ndarray:
        return (np.abs(self.to_unit(points)) < 1.0).all(1)

    def outline(self, n: int = 256) -> np.ndarray:
        s = np.linspace(-1, 1, max(2, n // 4), endpoint=False)
        one = np.ones_like(s)
        square = np.concatenate([np.stack(p, 1) for p in ((s, -one), (one, s), (-s, one), (-one, -s))])
        return self.from_unit(square)

    @property
    def area(self) -> float:
        return 4.0 * self.axes[0] * self.axes[1]

    def geometry(self):
        import jaxfem as jf

        (cx, cy), (a, b) = self.centre, self.axes
        return jf.Rect(cx - a, cy - b, cx + a, cy + b, self.angle)


@dataclass(frozen=True)
class PolygonShape:
    """A simple polygon, ``vertices`` ``((x, y), ...)`` counter-clockwise (clockwise ones are turned)."""

    vertices: tuple

    kind = "polygon"

    def __post_init__(self):
        if not isinstance(self.vertices, (list, tuple)) or len(self.vertices) < 3:
            raise ExperimentError(f"polygon needs at least 3 vertices [[x, y], ...], got {self.vertices!r}")
        verts = tuple(_pair(v, f"polygon vertex {k}") for k, v in enumerate(self.vertices))
        area2 = sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(verts, verts[1:] + verts[:1]))
        if area2 == 0:
            raise ExperimentError("polygon is degenerate (zero area)")
        object.__setattr__(self, "vertices", verts if area2 > 0 else verts[::-1])

    def contains(self, points) -> np.ndarray:
        return inside_polygon(self.vertices, points)

    def outline(self, n: int = 256) -> np.ndarray:
        v = np.asarray(self.vertices)
        per = max(2, n // len(v))
        s = np.linspace(0, 1, per, endpoint=False)[:, None]
        return np.concatenate([a + s * (b - a) for a, b in zip(v, np.roll(v, -1, axis=0))])

    @property
    def area(self) -> float:
        v = np.asarray(self.vertices)
        return float(0.5 * abs(np.dot(v[:, 0], np.roll(v[:, 1], -1)) - np.dot(v[:, 1], np.roll(v[:, 0], -1))))

    def to_toml(self) -> dict:
        return {"polygon": [list(v) for v in self.vertices]}

    @classmethod
    def from_toml(cls, value: Any, what: str) -> PolygonShape:
        if not isinstance(value, list):
            raise ExperimentError(f"{what} must be a list of [x, y] pairs, got {value!r}")
        return cls(tuple(value))

    def geometry(self):
        import jaxfem as jf

        return jf.Polygon(np.asarray(self.vertices))


Shape = EllipseShape | RectangleShape | PolygonShape

#: shape kind (its key in a TOML table) -> ``from_toml(value, what)``
SHAPES: dict[str, Callable[[Any, str], Any]] = {
    "ellipse": EllipseShape.from_toml,
    "rectangle": RectangleShape.from_toml,
    "polygon": PolygonShape.from_toml,
}


def shape_from_toml(table: dict, what: str) -> Shape:
    """The shape of ``table``, which holds exactly one key of :data:`SHAPES` (and nothing else
    of a shape's); ``what`` names it in errors."""
    found = [k for k in table if k in SHAPES]
    if len(found) != 1:
        raise ExperimentError(f"{what} must give exactly one shape, one of {', '.join(f'{k} = ...' for k in SHAPES)}; "
                              f"got keys {sorted(table)}")
    return SHAPES[found[0]](table[found[0]], f"{what}.{found[0]}")
