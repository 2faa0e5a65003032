"""What was measured and the initial model: the content of a bundle's experiment.toml.

A key the library does not know is an error that names the nearest known key (a misspelt
``thicknes`` or ``noise_sd`` would otherwise leave the thickness or the noise unset without a
word). User-defined metadata goes in a ``[meta]`` table, free-form; the ``[diagnose]`` table holds
settings of the diagnosis (checked by :meth:`refine.diagnosis.DiagnoseConfig.from_table`). Both
are kept in :attr:`Experiment.extra` and written back, so reading and writing a bundle never
loses anything a user wrote. A new key of the format is popped in :meth:`Experiment.from_toml`
and listed in :data:`KNOWN_KEYS`.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Union

from refine.bundle.regions import KnownRegion, check_layout, check_parameters, regions_from_toml
from refine.bundle.shapes import PolygonShape, shape_from_toml
from refine.exceptions import ExperimentError, nearest_key
from refine.bundle.sides import checked_sides, sides_to_toml

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
    """Domain given by a mesh file (any meshio format), ``path`` relative to the bundle directory."""

    path: str

    def __post_init__(self):
        if not isinstance(self.path, str) or not self.path:
            raise ExperimentError(f"domain.mesh must be a file name, got {self.path!r}")

    side_names = None  # forces may name the mesh's bounding-box sides (left, right, ..., back, front)

    def to_toml(self) -> dict:
        return {"mesh": self.path}


Domain = Union[RectangleDomain, PolygonDomain, MeshDomain, FromPointsDomain]


@dataclass(frozen=True)
class Experiment:
    """The experiment and the initial (background) model of a bundle.

    Attributes:
        name: experiment name.
        kind: ``"plane-stress"`` | ``"plane-strain"`` | ``"solid"`` (3-D).
        domain: :class:`RectangleDomain`, :class:`PolygonDomain`, :class:`FromPointsDomain` or
            :class:`MeshDomain` (required for solid).
        law: ``"neo-hookean"`` | ``"linear-elastic"`` | ``"saint-venant-kirchhoff"`` |
            ``"mooney-rivlin"``.
        E: background Young's modulus, stress unit (> 0).
        nu: Poisson's ratio, in (-1, 0.5).
        thickness: assumed sheet thickness for plane stress, length unit; None if not given.
        units: e.g. ``{"length": "mm", "stress": "kPa", "force": "mN"}`` (free text, a consistent set).
        noise_std: standard deviation of each measured displacement component, length unit (>= 0;
            0: noise-free data); None if unknown.
        extra: the free tables of experiment.toml (:data:`FREE_TABLES`: ``meta``, user-defined
            metadata; ``diagnose``, settings of the diagnosis), nested as in the file.
        regions: known regions of other stiffness or law (:class:`~refine.bundle.regions.KnownRegion`,
            ``[[model.regions]]``), inside the domain and apart from each other and the holes.
        parameters: the law's extra parameters (e.g. ``{"c01_fraction": 0.3}``; ``[material]``).
        mesh: a mesh file (relative to the bundle) of this domain that the initial model uses as
            it is (``model.mesh``; e.g. the refined model's, which follows its regions); None: the
            domain is meshed at the element size asked for.
    """

    name: str
    kind: str
    domain: Domain
    law: str
    E: float
    nu: float
    thickness: float | None = None
    units: dict[str, str] = field(default_factory=dict)
    noise_std: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    regions: tuple[KnownRegion, ...] = ()
    parameters: dict[str, float] = field(default_factory=dict)
    mesh: str | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ExperimentError(f"experiment.name must be a non-empty string, got {self.name!r}")
        kinds, laws = _registries()
        if self.kind not in kinds:
            raise ExperimentError(f"model.kind {self.kind!r} is unknown; use one of {list(kinds)}")
        if not isinstance(self.domain, (RectangleDomain, PolygonDomain, MeshDomain, FromPointsDomain)):
            raise ExperimentError(f"domain must be a RectangleDomain, PolygonDomain or MeshDomain, got {self.domain!r}")
        if self.kind == "solid" and not isinstance(self.domain, MeshDomain):
            raise ExperimentError('a "solid" model needs domain = { mesh = "FILE" }')
        if self.law not in laws:
            raise ExperimentError(f"material.law {self.law!r} is unknown; use one of {list(laws)}")
        object.__setattr__(self, "E", _number(self.E, "material.E", positive=True))
        nu = _number(self.nu, "material.nu")
        if not -1.0 < nu < 0.5:
            raise ExperimentError(f"material.nu must lie in (-1, 0.5), got {nu}")
        object.__setattr__(self, "nu", nu)
        if self.thickness is not None:
            object.__setattr__(self, "thickness", _number(self.thickness, "model.thickness", positive=True))
        if self.noise_std is not None:
            noise = _number(self.noise_std, "measurement.noise_std")
            if noise < 0:  # 0 is a standard deviation too: noise-free data
                raise ExperimentError(f"measurement.noise_std must be >= 0, got {noise}")
            object.__setattr__(self, "noise_std", noise)
        if not isinstance(self.units, dict) or not all(isinstance(v, str) for v in self.units.values()):
            raise ExperimentError('experiment.units must be a table of strings, e.g. { length = "mm" }')
        _check_extra(self.extra)
        self._check_model()

    def _check_model(self):
        """Regions, their laws and parameters, shaped holes and the model's mesh file."""
        laws = _laws()
        object.__setattr__(self, "regions", tuple(self.regions))
        check_parameters(self.parameters, self.law, laws, "[material]")
        for r in self.regions:
            check_parameters(r.parameters, r.law or self.law, laws, f"model.regions {r.name!r}")
        if self.mesh is not None and (not isinstance(self.mesh, str) or not self.mesh):
            raise ExperimentError(f"model.mesh must be a file name, got {self.mesh!r}")
        holes = getattr(self.domain, "holes", ())
        if self.regions and isinstance(self.domain, MeshDomain):
            raise ExperimentError("model.regions go with a 2-D rectangle or polygon domain; a mesh domain gives its "
                                  "regions as the mesh's cell tags")
        if len({r.name for r in self.regions}) != len(self.regions):
            raise ExperimentError(f"model.regions names must differ, got {[r.name for r in self.regions]}")
        if self.regions or any(hasattr(h, "kind") for h in holes):
            check_layout(_outline(self.domain), [h if hasattr(h, "kind") else PolygonShape(h) for h in holes],
                         self.regions)

    @property
    def dim(self) -> int:
        """Spatial dimension of the model: 3 for ``solid``, else 2."""
        return 3 if self.kind == "solid" else 2

    @classmethod
    def from_toml(cls, data: dict[str, Any]) -> Experiment:
        """Build from the dict tomllib returns for experiment.toml (the free tables go to
        ``extra``; an unknown key is an :class:`ExperimentError` naming the nearest known one)."""
        rest = copy.deepcopy(data)
        sections = {}
        for section in ("experiment", "model", "material", "measurement"):
            table = rest.pop(section, {})
            if not isinstance(table, dict):
                raise ExperimentError(f"[{section}] must be a table")
            sections[section] = table
        exp, model, mat, meas = (sections[s] for s in ("experiment", "model", "material", "measurement"))
        for key, table, section in (("kind", model, "model"), ("domain", model, "model"),
                                    ("law", mat, "material"), ("E", mat, "material"), ("nu", mat, "material"),
                                    ("name", exp, "experiment")):
            if key not in table:
                raise ExperimentError(f"[{section}] has no {key!r}; it is required")
        fields = dict(
            name=exp.pop("name"),
            units=exp.pop("units", {}),
            kind=model.pop("kind"),
            thickness=model.pop("thickness", None),
            domain=_domain_from_toml(model.pop("domain")),
            law=mat.pop("law"),
            E=mat.pop("E"),
            nu=mat.pop("nu"),
            noise_std=meas.pop("noise_std", None),
            regions=regions_from_toml(model.pop("regions", [])),
            mesh=model.pop("mesh", None),
        )
        law = get_law(fields["law"])
        if law is not None:  # the law's extra parameters ([material] c01_fraction = ...)
            fields["parameters"] = {q.name: mat.pop(q.name) for q in law.extra if q.name in mat}
        extra = {s: t for s, t in sections.items() if t}
        extra.update(rest)
        return cls(**fields, extra=extra)

    def to_toml(self) -> dict[str, Any]:
        """The dict to write as experiment.toml; ``from_toml(to_toml())`` equals ``self``."""
        data: dict[str, Any] = {
            "experiment": {"name": self.name, **({"units": dict(self.units)} if self.units else {})},
            "model": {"kind": self.kind, **({} if self.thickness is None else {"thickness": self.thickness}),
                      "domain": self.domain.to_toml()},
            "material": {"law": self.law, "E": self.E, "nu": self.nu, **self.parameters},
        }
        if self.regions:
            data["model"]["regions"] = [r.to_toml() for r in self.regions]
        if self.mesh is not None:
            data["model"]["mesh"] = self.mesh
        if self.noise_std is not None:
            data["measurement"] = {"noise_std": self.noise_std}
        _merge(data, copy.deepcopy(self.extra))
        return data


def _domain_from_toml(table: Any) -> Domain:
    if not isinstance(table, dict):
        raise ExperimentError(f"model.domain must be a table, e.g. {{ rectangle = [0, 0, 100, 60] }}; got {table!r}")
    table = dict(table)
    holes = table.pop("holes", [])
    sides = table.pop("sides", {})
    max_edge = table.pop("max_edge", None)
    if len(table) != 1:
        raise ExperimentError(
            "model.domain must hold exactly one of rectangle = [xmin, ymin, xmax, ymax], "
            "polygon = [[x, y], ...], from_points = \"concave\" or mesh = \"FILE\" (and optionally "
            f"holes = [[[x, y], ...], ...] and sides = {{ NAME = [[x0, y0], [x1, y1]] }}); got {table!r}"
        )
    if not isinstance(holes, list):
        raise ExperimentError(f"domain.holes must be a list of polygons [[[x, y], ...], ...] or shapes "
                              f"{{ ellipse = {{ centre = [x, y], axes = [a, b], angle = RADIANS }} }}, got {holes!r}")
    (kind, value), = table.items()
    if max_edge is not None and kind != "from_points":
        raise ExperimentError("domain.max_edge goes with from_points = \"concave\"")
    if kind == "from_points":
        return FromPointsDomain(value, max_edge, holes=holes, sides=sides)
    if sides and kind == "mesh":
        raise ExperimentError("domain.sides goes with a rectangle, a polygon or from_points")
    if kind == "rectangle":
        if not isinstance(value, list) or len(value) != 4:
            raise ExperimentError(f"domain.rectangle must be [xmin, ymin, xmax, ymax], got {value!r}")
        return RectangleDomain(*value, holes=holes, sides=sides)
    if kind == "polygon":
        if not isinstance(value, list) or not all(isinstance(v, list) and len(v) == 2 for v in value):
            raise ExperimentError(f"domain.polygon must be a list of [x, y] pairs, got {value!r}")
        return PolygonDomain(tuple(tuple(v) for v in value), holes=holes, sides=sides)
    if kind == "mesh":
        if holes:
            raise ExperimentError("domain.holes goes with a rectangle or a polygon; a mesh has its holes already")
        return MeshDomain(value)
    raise ExperimentError(f"model.domain kind {kind!r} is unknown; use rectangle, polygon, from_points or mesh")


def _number(value: Any, what: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ExperimentError(f"{what} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ExperimentError(f"{what} must be a finite number, got {value}")
    if positive and value <= 0:
        raise ExperimentError(f"{what} must be positive, got {value}")
    return value


def _merge(into: dict, extra: dict) -> None:
    """Deep-merge ``extra`` into ``into``; a key present in both must be a table in both."""
    for key, value in extra.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            _merge(into[key], value)
        elif key in into:
            raise ExperimentError(f"extra key {key!r} would overwrite a key the library writes itself")
        else:
            into[key] = value


def _registries() -> tuple[tuple[str, ...], tuple[str, ...]]:
    """jaxfem's model kinds and law names (imported here, on first use, so that reading the bundle
    package does not load JAX)."""
    from jaxfem.kinematics import KINDS
    from jaxfem.materials import LAWS

    return KINDS, tuple(LAWS)


#: the keys of experiment.toml's tables that are fields of :class:`Experiment`
KNOWN_KEYS = {"experiment": ("name", "units"), "model": ("kind", "thickness", "domain", "regions", "mesh"),
              "material": ("law", "E", "nu"), "measurement": ("noise_std",)}
#: tables kept as they are in :attr:`Experiment.extra`: ``meta`` (user-defined metadata, any
#: keys) and ``diagnose`` (settings of the diagnosis, checked by refine.diagnosis)
FREE_TABLES = ("meta", "diagnose")


def _check_extra(extra: Any) -> None:
    """Raise :class:`ExperimentError` for anything in ``extra`` but the free tables, naming the
    nearest known key (``model.thicknes`` -> ``model.thickness``)."""
    if not isinstance(extra, dict):
        raise ExperimentError(f"extra must be a dict of TOML tables, got {extra!r}")
    known = [f"{t}.{k}" for t, keys in KNOWN_KEYS.items() for k in keys] + [f"[{t}]" for t in FREE_TABLES]
    hint = "; user-defined metadata goes in a [meta] table"
    for table, value in extra.items():
        if table in FREE_TABLES:
            if not isinstance(value, dict):
                raise ExperimentError(f"[{table}] must be a table, got {value!r}")
            continue
        if table not in KNOWN_KEYS or not isinstance(value, dict):
            near = nearest_key(table, [*KNOWN_KEYS, *FREE_TABLES]) or nearest_key(table, known)
            raise ExperimentError(f"experiment.toml: unknown key {table!r}{near}{hint}")
        for key in value:
            if key in KNOWN_KEYS[table]:
                raise ExperimentError(f"extra key {table}.{key} would overwrite a key the library writes itself")
            raise ExperimentError(f"experiment.toml: unknown key {table}.{key}{nearest_key(f'{table}.{key}', known)}"
                                  f"{hint}")


def _laws() -> dict:
    """jaxfem's law registry, name -> ``jaxfem.Material`` (imported on first use)."""
    from jaxfem.materials import LAWS

    return LAWS


def get_law(name: Any):
    """The ``jaxfem.Material`` called ``name``, or None for an unknown name (reported later)."""
    return _laws().get(name) if isinstance(name, str) else None
