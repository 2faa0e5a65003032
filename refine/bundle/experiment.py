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
from dataclasses import dataclass, field
from typing import Any

from refine.bundle.regions import KnownRegion, check_layout, check_parameters, regions_from_toml
from refine.bundle.shapes import PolygonShape
from refine.exceptions import ExperimentError, nearest_key

from refine.bundle.domains import (RECTANGLE_EDGES, Domain, FromPointsDomain, MeshDomain,  # noqa: F401
                                   PolygonDomain, RectangleDomain, _number, _outline)


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
        subset: side of the square DIC subset (or tracker window) centred on each tracked point,
            length unit (> 0; ``measurement.subset``); None if unknown. A tracked point's whole
            subset lay on material, so a hole hypothesis keeps half a subset away from it.
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
    subset: float | None = None

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
        if self.subset is not None:
            object.__setattr__(self, "subset", _number(self.subset, "measurement.subset", positive=True))
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
            subset=meas.pop("subset", None),
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
        if self.subset is not None:
            data.setdefault("measurement", {})["subset"] = self.subset
        _merge(data, copy.deepcopy(self.extra))
        return data


def _domain_from_toml(table: Any) -> Domain:
    if not isinstance(table, dict):
        raise ExperimentError(f"model.domain must be a table, e.g. {{ rectangle = [0, 0, 100, 60] }}; got {table!r}")
    table = dict(table)
    holes = table.pop("holes", [])
    sides = table.pop("sides", {})
    max_edge = table.pop("max_edge", None)
    faces, boundary_faces = table.pop("faces", {}), table.pop("boundary_faces", [])
    if len(table) != 1:
        raise ExperimentError(
            "model.domain must hold exactly one of rectangle = [xmin, ymin, xmax, ymax], "
            "polygon = [[x, y], ...], from_points = \"concave\" or mesh = \"FILE\" (and optionally "
            f"holes = [[[x, y], ...], ...] and sides = {{ NAME = [[x0, y0], [x1, y1]] }}; a mesh may name faces = "
            f"{{ NAME = {{ box = [...] }} }} and boundary_faces = [NAME, ...]); got {table!r}"
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
        raise ExperimentError("domain.sides goes with a rectangle, a polygon or from_points; a mesh domain names "
                              "faces: domain = { mesh = ..., faces = { NAME = { box = [...] } } }")
    if (faces or boundary_faces) and kind != "mesh":
        raise ExperimentError("domain.faces and domain.boundary_faces go with a mesh domain (domain = { mesh = ... }); "
                              "a rectangle, polygon or from_points domain names sides = { ... }")
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
        return MeshDomain(value, faces, boundary_faces)
    raise ExperimentError(f"model.domain kind {kind!r} is unknown; use rectangle, polygon, from_points or mesh")


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
              "material": ("law", "E", "nu"), "measurement": ("noise_std", "subset")}
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
