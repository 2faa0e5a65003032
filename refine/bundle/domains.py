"""The domains of experiment.toml's ``model.domain``: a rectangle, a polygon, an outline built
from the points, or a mesh file; each with its known holes and named sides."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Union

from refine.bundle.shapes import PolygonShape, shape_from_toml
from refine.bundle.sides import checked_faces, checked_sides, faces_to_toml, sides_to_toml
from refine.exceptions import ExperimentError


RECTANGLE_EDGES = ("left", "right", "bottom", "top")


def _loop(vertices, what: str) -> tuple[tuple[float, float], ...]:
    """A closed polygon as a tuple of (x, y), checked: at least 3 finite vertices, not degenerate."""
    try:
        verts = tuple((float(x), float(y)) for x, y in vertices)
    except (TypeError, ValueError):
        raise ExperimentError(f"{what} must be a list of [x, y] pairs") from None
    if len(verts) < 3:
        raise ExperimentError(f"{what} needs at least 3 vertices, got {len(verts)}")
    if not all(math.isfinite(c) for v in verts for c in v):
        raise ExperimentError(f"{what} has a NaN or inf coordinate")
    return verts


def _signed_area2(verts) -> float:
    return sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1) in zip(verts, verts[1:] + verts[:1]))


def _holes(holes) -> tuple:
    """Polygons as tuples of (x, y), counter-clockwise; an ellipse or a rectangle (a table
    ``{ ellipse = {...} }`` or a shape of :mod:`refine.bundle.shapes`) as its shape."""
    out = []
    for k, h in enumerate(holes or ()):
        if isinstance(h, dict):
            h = shape_from_toml(h, f"domain.holes[{k}]")
        if isinstance(h, PolygonShape):
            h = h.vertices
        if hasattr(h, "kind"):
            out.append(h)
            continue
        verts = _loop(h, f"domain.holes[{k}]")
        area = _signed_area2(verts)
        if area == 0:
            raise ExperimentError(f"domain.holes[{k}] is degenerate (zero area)")
        out.append(verts if area > 0 else verts[::-1])  # counter-clockwise, as the outline
    return tuple(out)


@dataclass(frozen=True)
class RectangleDomain:
    """Axis-aligned rectangular domain ``[xmin, xmax] x [ymin, ymax]``, length unit, minus the
    polygons ``holes`` (known holes: no material there; each a tuple of (x, y))."""

    xmin: float
    ymin: float
    xmax: float
    ymax: float
    holes: tuple = ()
    sides: tuple = ()  # named sides beyond left/right/bottom/top (refine.bundle.sides)

    def __post_init__(self):
        for name in ("xmin", "ymin", "xmax", "ymax"):
            object.__setattr__(self, name, _number(getattr(self, name), f"domain.rectangle {name}"))
        if not (self.xmin < self.xmax and self.ymin < self.ymax):
            raise ExperimentError(
                f"domain.rectangle must be [xmin, ymin, xmax, ymax] with xmin < xmax and ymin < ymax, "
                f"got {[self.xmin, self.ymin, self.xmax, self.ymax]}"
            )
        object.__setattr__(self, "holes", _holes(self.holes))
        object.__setattr__(self, "sides", checked_sides(self.sides, None))

    @property
    def side_names(self) -> tuple[str, ...]:
        """The sides a measured force may cross: left, right, bottom, top and the named ones."""
        return tuple(dict.fromkeys([*RECTANGLE_EDGES, *(n for n, _, _ in self.sides)]))

    def to_toml(self) -> dict:
        return {"rectangle": [self.xmin, self.ymin, self.xmax, self.ymax], **_holes_toml(self.holes),
                **sides_to_toml(self.sides)}


@dataclass(frozen=True)
class PolygonDomain:
    """Polygonal 2-D domain; ``vertices`` is a tuple of (x, y), counter-clockwise, length unit,
    minus the polygons ``holes`` (known holes, as for :class:`RectangleDomain`)."""

    vertices: tuple[tuple[float, float], ...]
    holes: tuple = ()
    sides: tuple = ()  # named sides (refine.bundle.sides): a polygon has none of its own

    def __post_init__(self):
        verts = _loop(self.vertices, "domain.polygon")
        if _signed_area2(verts) <= 0:
            raise ExperimentError(
                "domain.polygon is clockwise or degenerate (signed area <= 0); list its vertices counter-clockwise"
            )
        object.__setattr__(self, "vertices", verts)
        object.__setattr__(self, "holes", _holes(self.holes))
        object.__setattr__(self, "sides", checked_sides(self.sides, len(verts)))

    @property
    def side_names(self) -> tuple[str, ...]:
        """The sides a measured force may cross: the named ones only."""
        return tuple(n for n, _, _ in self.sides)

    # the bounding box, as a rectangle's (e.g. to keep a shape inside the domain)
    xmin = property(lambda self: min(x for x, _ in self.vertices))
    xmax = property(lambda self: max(x for x, _ in self.vertices))
    ymin = property(lambda self: min(y for _, y in self.vertices))
    ymax = property(lambda self: max(y for _, y in self.vertices))

    def to_toml(self) -> dict:
        return {"polygon": [list(v) for v in self.vertices], **_holes_toml(self.holes), **sides_to_toml(self.sides)}


OUTLINES = ("concave", "convex")


@dataclass(frozen=True)
class FromPointsDomain:
    """A 2-D domain whose outline is built from the tracked points themselves
    (:func:`refine.bundle.outline.outline_of_points`): their ``"concave"`` outline (an alpha
    shape whose edges are at most ``max_edge`` long, length unit; None: 2.5 point spacings) or
    their ``"convex"`` hull, through every boundary point; minus the known ``holes``, with named
    ``sides`` (as for :class:`PolygonDomain`)."""

    outline: str = "concave"
    max_edge: float | None = None
    holes: tuple = ()
    sides: tuple = ()

    def __post_init__(self):
        if self.outline not in OUTLINES:
            raise ExperimentError(f"domain.from_points must be one of {list(OUTLINES)}, got {self.outline!r}")
        if self.max_edge is not None:
            object.__setattr__(self, "max_edge", _number(self.max_edge, "domain.max_edge", positive=True))
        object.__setattr__(self, "holes", _holes(self.holes))
        object.__setattr__(self, "sides", checked_sides(self.sides, None))

    @property
    def side_names(self) -> tuple[str, ...]:
        return tuple(n for n, _, _ in self.sides)

    def to_toml(self) -> dict:
        return {"from_points": self.outline, **({} if self.max_edge is None else {"max_edge": self.max_edge}),
                **_holes_toml(self.holes), **sides_to_toml(self.sides)}


def _holes_toml(holes) -> dict:
    return {"holes": [h.to_toml() if hasattr(h, "kind") else [list(v) for v in h] for h in holes]} if holes else {}


def _outline(domain) -> list:
    """The outline of a rectangle or polygon domain, ``[(x, y), ...]`` counter-clockwise."""
    if isinstance(domain, RectangleDomain):
        return [(domain.xmin, domain.ymin), (domain.xmax, domain.ymin), (domain.xmax, domain.ymax),
                (domain.xmin, domain.ymax)]
    return list(domain.vertices)


@dataclass(frozen=True)
class MeshDomain:
    """Domain given by a mesh file (any meshio format), ``path`` relative to the bundle directory.

    Attributes:
        faces: faces named in experiment.toml beside the mesh file's own (``domain.faces``,
            :func:`refine.bundle.sides.checked_faces`: a box or a plane each).
        boundary_faces: the faces (or bounding-box sides) the ``boundary`` points lie on (a solid):
            the model refuses a boundary point off them and drives every node of them (empty:
            anywhere on the surface, driving the nodes near the points).
    """

    path: str
    faces: tuple = ()
    boundary_faces: tuple = ()

    def __post_init__(self):
        if not isinstance(self.path, str) or not self.path:
            raise ExperimentError(f"domain.mesh must be a file name, got {self.path!r}")
        object.__setattr__(self, "faces", checked_faces(self.faces))
        names = self.boundary_faces
        if isinstance(names, str) or not all(isinstance(n, str) and n for n in names):
            raise ExperimentError(f'domain.boundary_faces must be a list of face names, e.g. ["fixed", "loaded"]; '
                                  f"got {names!r}")
        object.__setattr__(self, "boundary_faces", tuple(names))

    side_names = None  # forces may name the mesh's faces and bounding-box sides (left, right, ..., back, front)

    def to_toml(self) -> dict:
        return {"mesh": self.path, **faces_to_toml(self.faces),
                **({"boundary_faces": list(self.boundary_faces)} if self.boundary_faces else {})}


Domain = Union[RectangleDomain, PolygonDomain, MeshDomain, FromPointsDomain]


def _number(value: Any, what: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ExperimentError(f"{what} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ExperimentError(f"{what} must be a finite number, got {value}")
    if positive and value <= 0:
        raise ExperimentError(f"{what} must be positive, got {value}")
    return value
