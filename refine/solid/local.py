"""The paper's local model of a cup holder's observed bottom, and the hypothesis of a hole through it.

The local model is the bottom slab alone (:func:`jaxfem.wall.disc_wall`, the disk under the whole
cup, ``0 <= z <= bottom``), in the cup's frame (origin at the bottom face's centre): its outer
face's nodes under the ``boundary`` points (the ring under the wall) follow them, its face inside
carries the measured squeeze force as a uniform pressure (:class:`~refine.solid.loaded.LoadedModel`),
the rest is free. The wall above is left out: the driven ring holds the floor as the wall does.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from types import SimpleNamespace

import numpy as np

import jaxfem as jf
from jaxfem.wall import ExtrudedWall, disc_wall, rimmed_wall

from refine.bundle.experiment import Experiment
from refine.bundle.observations import Observations
from refine.bundle.roles import point_spacing
from refine.diagnosis.fitted import NotApplicable
from refine.diagnosis.holes import HoleShape, hole_hypothesis
from refine.diagnosis.shapes import Hole
from refine.model.objective import Compiled
from refine.model.parametrize import Combined, RegionModuli, UniformParameter
from refine.solid.cup import CupShape, bottom_points
from refine.solid.edge import EdgeEvidence, EdgeGeometry
from refine.solid.global_model import fixture_nodes, held_by_fixture
from refine.solid.loaded import LoadedModel
from refine.solid.morph import ExtrudedMorph


HOLE_HEADROOM = 1.2
"""The padding of a model without a hole (the local model's first fit, the global null test's
models), as for a mesh this many times larger: a hole's meshes at the same element size have up
to about 12 % more cells (graded along its curve; h 1.65: 2790 cells without, 2856-3114 with), so
each compiled a bucket of its own (Newton, tangents: 25-35 s of compile on 2 cores under load),
which they now find made (:meth:`jaxfem.program.Program.sizes_for`); the padding's cells cost the
hole-free model's few solves a share of the assembly alone. Not enough everywhere: the fine
benchmark's global meshes at h 1.2 had 30 % more cells with the hole (6282 against 4836) and still
compile a bucket of their own."""


@dataclass(frozen=True, eq=False)
class Local:
    """How to build the local model: the cup's ``shape``, the bundle's ``experiment``, the bottom
    face's points ``obs`` in the cup's frame, the squeeze ``force (n_frames, 3)``, the element
    size ``h`` (length unit), the linear solver, ``layers`` of elements through the bottom (None:
    ``bottom / h`` rounded, :func:`jaxfem.wall.rimmed_wall`), ``hole_ratio``: elements along a hole's
    curve of at most that many times its smallest radius of curvature (:meth:`hole_h`; None: ``h``
    there too), ``floor_h``: the element size inside the floor ``r < r_in`` (None: ``h``)."""

    shape: CupShape
    experiment: Experiment
    obs: Observations
    force: np.ndarray
    h: float
    linear_solver: str = "auto"
    layers: int | None = None
    hole_ratio: float | None = None
    floor_h: float | None = None

    def hole_h(self, hole: jf.Ellipse | None) -> float | None:
        """The element size (length unit) along ``hole``'s curve: ``hole_ratio`` times its smallest
        radius of curvature (an ellipse's at the major axis's ends, b^2 / a), at most the floor's
        size (``floor_h`` or ``h``); None without a hole or a ratio."""
        if hole is None or self.hole_ratio is None:
            return None
        return min(self.floor_h or self.h, self.hole_ratio * hole.min_radius_of_curvature)

    def coarser(self, h: float) -> Local:
        """The same recipe at element size ``h`` everywhere, the hole's and the floor's included
        (``hole_ratio`` and ``floor_h`` scaled by ``h / self.h``): a mesh uniformly coarser or finer."""
        k = h / self.h
        return replace(self, h=h, hole_ratio=None if self.hole_ratio is None else self.hole_ratio * k,
                       floor_h=None if self.floor_h is None else self.floor_h * k)

    def model(self, hole: jf.Ellipse | None = None, headroom: float = 1.0) -> tuple[LoadedModel, ExtrudedWall]:
        """The local model (``tet10``) with ``hole`` cut through it, and its slab mesh;
        ``headroom``: its solver padded as for a mesh that many times larger (:data:`HOLE_HEADROOM`)."""
        s = self.shape
        slab = disc_wall(s.r_in, s.r_out, s.bottom, self.h, hole, layers=self.layers, hole_h=self.hole_h(hole),
                          floor_h=self.floor_h)
        model = LoadedModel(self.experiment, self.obs, slab.mesh, slab.facets, self.force, h=self.h,
                            linear_solver=self.linear_solver, headroom=headroom)
        return model, slab

    def hole_from(self, shape) -> jf.Ellipse:
        """A hole started at ``shape`` (a :class:`Hole` or region shape, cup frame): shrunk until
        no point lies inside it (:func:`refine.diagnosis.holes.hole_hypothesis`), then until it
        keeps half an element from the inner wall. Raises :class:`NotApplicable` where points were
        seen near its middle."""
        xy = self.obs.reference[:, :2]
        base = SimpleNamespace(experiment=self.experiment, spacing=point_spacing(xy), obs=SimpleNamespace(reference=xy))
        e = hole_hypothesis(base, shape).hole
        reach = self.shape.r_in - 0.5 * self.h
        for _ in range(40):
            ring = np.linspace(0, 2 * np.pi, 181)
            c, s_ = np.cos(e.angle), np.sin(e.angle)
            x = e.cx + e.rx * np.cos(ring) * c - e.ry * np.sin(ring) * s_
            y = e.cy + e.rx * np.cos(ring) * s_ + e.ry * np.sin(ring) * c
            if np.hypot(x, y).max() < reach:
                return e
            e = jf.Ellipse(0.95 * e.cx, 0.95 * e.cy, 0.95 * e.rx, 0.95 * e.ry, e.angle)
        raise NotApplicable(f"no hole at ({shape.centre[0]:.1f}, {shape.centre[1]:.1f}) fits inside the floor")


@dataclass(frozen=True, eq=False)
class Whole(Local):
    """How to build the global model in the cup's frame: the whole cup holder (``tet10``), held
    where its ``boundary`` points are (``obs``: every point, those of the bottom's ring made
    ``guide``: :func:`refine.solid.global_model.held_by_fixture`), squeezed by ``force``. A hole
    found by the local model is refitted in it (:class:`SolidHole` takes either recipe): the local
    model leaves the wall out, which bends the floor's edge as the wall does not (its hole came
    out 23 % small on noise-free data)."""

    @classmethod
    def of(cls, local: Local, obs: Observations, h: float | None = None) -> tuple[Whole, np.ndarray]:
        """The global model of ``local``'s cup holder, held by the fixture's points among the
        bundle's observations ``obs`` (moved into the cup's frame), at element size ``h`` (length
        unit; None: ``local.h``; otherwise :meth:`Local.coarser`), and which of its points lie on
        the bottom (``(n,)`` bool)."""
        tol = 0.05 * point_spacing(obs.reference)
        held = held_by_fixture(obs, local.shape, tol)
        on = bottom_points(local.shape, held.reference, tol)
        held = replace(held, reference=held.reference - local.shape.offset)
        whole = replace(local, obs=held) if h is None else replace(local.coarser(h), obs=held)
        return cls(**{f.name: getattr(whole, f.name) for f in fields(Local)}), on

    def model(self, hole: jf.Ellipse | None = None, headroom: float = 1.0) -> tuple[LoadedModel, ExtrudedWall]:
        s = self.shape
        cup = rimmed_wall(s.r_in, s.r_out, s.bottom, s.height, self.h, hole=hole, layers=self.layers,
                            hole_h=self.hole_h(hole), floor_h=self.floor_h)
        driven = fixture_nodes(cup.mesh, self.obs, max(4 * (self.experiment.noise_std or 0.0), 0.05 * self.h))
        model = LoadedModel(self.experiment, self.obs, cup.mesh, cup.facets, self.force, h=self.h,
                            linear_solver=self.linear_solver, driven=driven, headroom=headroom)
        return model, cup


@dataclass(frozen=True)
class ModulusHole(Hole):
    """A hole fitted with a uniform modulus ``E`` beside it (the experiment's unit): a remesh at it
    starts from that modulus (:meth:`SolidHole.at`)."""

    E: float | None = None
    wall: float | None = None


@dataclass(frozen=True, eq=False)
class WithModulus(Combined):
    """A hole's geometry (:class:`~refine.solid.edge.EdgeGeometry`, the first unknowns) and a
    uniform modulus (next; then, where given, the wall's modulus relative to it): the geometry's
    :meth:`~refine.solid.edge.EdgeGeometry.constraints` on its unknowns, so the fit's steps slide
    along them."""

    def constraints(self, z) -> np.ndarray:
        return self.parts[0].constraints(np.asarray(z, float)[:self.parts[0].size])


@dataclass(frozen=True, eq=False)
class WallModulus(RegionModuli):
    """The cup wall's modulus relative to the uniform one (a factor exp(z) on the wall's cells),
    started at ``start``."""

    start: float = 1.0

    @property
    def z0(self):
        return np.array([np.log(self.start)])


@dataclass(frozen=True, eq=False)
class SolidHole(HoleShape):
    """The hypothesis of an elliptic hole through the bottom at ``hole`` (cup frame): the local
    (or global, ``local`` a :class:`Whole`) model with the hole cut, its centre, axes and
    orientation fitted through an extruded morph
    (:class:`~refine.solid.morph.ExtrudedMorph`), remeshed at fitted shapes by
    :func:`refine.diagnosis.fitted.refit`. ``free_modulus``: a uniform modulus is fitted too (the
    last unknown; between half and twice the experiment's E, started at ``E_start``, by default E,
    and after a remesh where the fit left it). ``edge``: the painted grid's
    evidence of the hole (:class:`~refine.solid.edge.EdgeEvidence`): every missing crossing of its
    gap is kept within the evidence's slack of the hole (:class:`~refine.solid.edge.EdgeGeometry`).
    ``h``: the element size (length unit) in place of the recipe's (None: ``local.h``; set by
    :func:`refine.diagnosis.uncertainty.discretisation_bias`'s refit on a coarser mesh)."""

    local: Local
    hole: jf.Ellipse
    free_modulus: bool = False
    edge: EdgeEvidence | None = None
    E_start: float | None = None
    h: float | None = None
    wall_modulus: bool = False
    wall_start: float | None = None
    remeshable = True

    @property
    def law(self) -> str:
        return self.local.experiment.law

    def build(self) -> tuple[Compiled, None]:
        local = self.local if self.h is None else self.local.coarser(self.h)
        model, slab = local.model(self.hole)
        sp = model.spacing
        slack = 0.0 if self.edge is None else max(self.edge.slack, self.edge.missing_outside(self.hole.params) + 1e-9)
        param = EdgeGeometry(ExtrudedMorph.of(slab), self.hole.params[None], scale=0.5 * sp, rotate=True,
                             mesh=slab.mesh, outside=self.local.obs.reference[:, :2], min_axis=0.1 * sp,
                             edge=self.edge, slack=slack)
        if self.free_modulus:
            E = float(self.local.experiment.E)
            start = float(np.clip(self.E_start or E, 0.55 * E, 1.9 * E))  # inside the bounds' sigmoid
            parts = (param, UniformParameter("E", start, 0.5 * E, 2.0 * E))
            if self.wall_modulus and model.mesh.region_names.get(1) == "rim":
                wall = (np.asarray(model.mesh.regions) == 1)[None].astype(float)
                parts += (WallModulus(wall, E, ("wall",), start=float(self.wall_start or 1.0)),)
            param = WithModulus(parts)
        return Compiled(model, param), None

    def shapes_at(self, compiled: Compiled, z):
        if self.free_modulus:
            z = np.asarray(z)
            g = compiled.param.parts[0].size
            s = super().shapes_at(SimpleNamespace(param=compiled.param.parts[0]), z[:g])[0]
            E = float(compiled.param.parts[1].value(z[g:g + 1]))
            wall = float(np.exp(z[g + 1])) if len(compiled.param.parts) > 2 else None
            return (ModulusHole(s.centre, s.axes, s.angle, E, wall),)
        return super().shapes_at(compiled, z)

    def at(self, shapes, element: str = "tet10") -> SolidHole:
        s = shapes[0]
        return SolidHole(self.local, jf.Ellipse(*s.centre, *s.axes, s.angle), self.free_modulus, self.edge,
                         getattr(s, "E", None), self.h, self.wall_modulus, getattr(s, "wall", None))
