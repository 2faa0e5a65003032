"""The refined model as input: ``nonrigid diagnose BUNDLE --out OUT`` writes ``OUT/refined/``, a
bundle whose initial model is the model the diagnosis chose, so that ``nonrigid simulate`` and
``nonrigid diagnose`` can be run on it (the paper's loop: "newly acquired geometry information is
then incorporated into a global model").

``OUT/refined/`` holds:

- ``experiment.toml``: the bundle's experiment plus the chosen finding: a region of other stiffness
  as a known region (``[[model.regions]]``: its fitted shape and relative elasticity, and the
  cell ``tag`` it has in the mesh below), a hole as an ellipse in ``model.domain.holes``, another
  material law as ``[material]`` (law, fitted nu and the law's fitted parameters); where measured
  forces made the moduli absolute, ``material.E`` is the measured background modulus. Its name
  is the bundle's with ``-refined``; comment lines at its top say where it came from.
- ``mesh.vtu`` (``model.mesh``) where something was found: the chosen model's own mesh (its
  fitted geometry, quadratic triangles), so that simulating the refined bundle reproduces the
  chosen model's predictions to the solver's tolerance; ``simulate --h`` remeshes instead, and a
  diagnosis's hypotheses remesh the domain, which describes the same geometry.
- ``points.csv``, ``displacements.csv`` (and ``forces.csv``): copies of the bundle's
  observations, so that the folder is a bundle of its own that can be moved.

Where nothing was found, ``experiment.toml`` is the bundle's own (the initial model stands).
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from jaxfem.io import write_vtu
from jaxfem.materials import get_material

from refine.bundle.experiment import Experiment, MeshDomain
from refine.bundle.io import Bundle, write_bundle
from refine.bundle.regions import KnownRegion
from refine.bundle.shapes import EllipseShape, RectangleShape
from refine.diagnosis.atomic import folder
from refine.exceptions import ExperimentError
from refine.model.known import region_tag

MESH = "mesh.vtu"


def _free_names(taken, n: int) -> list[str]:
    """``n`` region names ``region1, region2, ...`` not among ``taken``."""
    out, k = [], 1
    while len(out) < n:
        if f"region{k}" not in taken:
            out.append(f"region{k}")
        k += 1
    return out


def _shape(s):
    """A fitted diagnosis shape (``RegionShape`` or ``Hole``) as a bundle shape."""
    cls = RectangleShape if s.kind == "rectangle" else EllipseShape
    return cls(tuple(map(float, s.centre)), tuple(map(float, s.axes)), float(s.angle))


def refined_experiment(d) -> Experiment:
    """The bundle's experiment extended by ``d``'s chosen finding (see the module docstring);
    the bundle's own experiment where the initial model stands.

    Raises:
        refine.exceptions.ExperimentError: a region or hole was found in a bundle whose domain is
            a mesh file (known regions need a rectangle or polygon domain).
    """
    ex, chosen = d.bundle.experiment, d.chosen
    if chosen.cause == "none":
        return ex
    mesh = chosen.model.mesh
    names = {name: tag for tag, name in mesh.region_names.items()}
    regions = [replace(r, tag=names.get(region_tag(r.name), r.tag)) for r in ex.regions]
    E, scale = ex.E, 1.0
    if d.absolute:  # one factor on every modulus explains the measured forces
        E, scale = d.background_modulus, d.background_modulus / ex.E
        regions = [r if r.modulus is None else replace(r, modulus=r.modulus * scale) for r in regions]
    changes = {"name": f"{ex.name}-refined", "E": E, "mesh": MESH}
    if chosen.cause == "material-law":
        theta = chosen.theta
        changes.update(law=chosen.law, nu=float(np.asarray(theta["nu"])[0]),
                       parameters={q.name: float(np.asarray(theta[q.name])[0]) for q in get_material(chosen.law).extra})
    elif chosen.cause == "hole":
        holes = (*ex.domain.holes, *(_shape(s) for s in chosen.shapes))
        changes["domain"] = replace(ex.domain, holes=holes)
    else:
        new = _free_names({r.name for r in regions}, len(chosen.shapes))
        regions += [KnownRegion(_shape(s), relative_elasticity=float(s.ratio), name=name, tag=k + 1)
                    for k, (s, name) in enumerate(zip(chosen.shapes, new))]
    if isinstance(ex.domain, MeshDomain) and chosen.cause != "material-law":
        raise ExperimentError("a region or hole found in a bundle whose domain is a mesh file cannot be written as a "
                              "known region or hole; give the domain as a rectangle or polygon")
    return replace(ex, regions=tuple(regions), **changes)


def write(d, out: str | Path) -> Path | None:
    """Write ``OUT/refined/`` for the diagnosis ``d`` (see the module docstring); return it, or
    None (with a warning that says why) where the finding cannot be written as a bundle."""
    root = Path(out) / "refined"
    try:
        ex = refined_experiment(d)
    except ExperimentError as e:
        warnings.warn(f"{root} not written: {e}", stacklevel=2)
        return None
    with folder(root) as tmp:  # the folder appears whole or not at all (refine.diagnosis.atomic)
        write_bundle(tmp, Bundle(ex, d.bundle.observations, root=d.bundle.root))
        if ex is not d.bundle.experiment:
            chosen = d.chosen
            mesh = chosen.model.mesh.with_nodes(np.asarray(chosen.theta["X"]))
            write_vtu(tmp / MESH, mesh)
        path = tmp / "experiment.toml"
        head = (f"# written by nonrigid diagnose from bundle {d.bundle.experiment.name!r}"
                f"{'' if d.bundle.root is None else f' ({d.bundle.root})'}\n"
                f"# chosen: {d.chosen.describe()}\n")
        path.write_text(head + path.read_text(encoding="utf-8"), encoding="utf-8")
    return root
