"""The experiment's known regions and holes in a model: which cells each region holds, the
material law that covers them all, and the per-cell parameters of the initial model.

A mesh made by :func:`refine.model.measured.domain_mesh` follows every known region and tags it
``known:NAME`` (:func:`region_tag`); a mesh from a file that has no such tags (a 2-D
``domain = { mesh = ... }``) gets a region's modulus on the cells whose centroid lies inside it.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Bool

import jaxfem as jf
from jaxfem.materials import get_material, mixture, share

from refine.bundle.experiment import Experiment


def region_tag(name: str) -> str:
    """The region name a mesh gives the cells of the known region ``name``."""
    return f"known:{name}"


def hole_geometry(hole) -> jf.Polygon | jf.Ellipse | jf.Rect:
    """The ``jaxfem`` shape of a known hole (a polygon's vertex tuple, or a bundle shape)."""
    return hole.geometry() if hasattr(hole, "kind") else jf.Polygon(np.asarray(hole, float))


def known_inclusions(experiment: Experiment) -> dict:
    """The known regions as ``jaxfem`` shapes to mesh, ``{region_tag(name): shape}``."""
    return {region_tag(r.name): r.shape.geometry() for r in experiment.regions}


def region_cells(mesh: jf.Mesh, experiment: Experiment) -> Bool[np.ndarray, "regions cells"]:
    """``(n_regions, n_cells)``: the cells of each known region: those the mesh names
    ``known:NAME`` (a mesh made by the model), else those of the region's ``tag`` (a mesh file),
    else those whose centroid lies in its shape (a mesh that does not follow it)."""
    tags = {name: tag for tag, name in mesh.region_names.items()}
    out = np.zeros((len(experiment.regions), mesh.n_cells), bool)
    centroids = None
    for k, r in enumerate(experiment.regions):
        tag = tags.get(region_tag(r.name), r.tag)
        if tag is not None:
            out[k] = mesh.regions == tag
        else:
            centroids = mesh.nodes[mesh.cells].mean(axis=1) if centroids is None else centroids
            out[k] = r.shape.contains(centroids)
    return out


def model_material(experiment: Experiment) -> jf.Material:
    """The law of the background, or, where a known region has another law, a
    :func:`jaxfem.materials.mixture` of them (the background's first)."""
    laws = list(dict.fromkeys([experiment.law, *(r.law for r in experiment.regions if r.law)]))
    if len(laws) == 1:
        return get_material(laws[0])
    return mixture(tuple(get_material(law) for law in laws))


def cell_parameters(mesh: jf.Mesh, experiment: Experiment, E: float) -> dict:
    """Per-cell material parameters of the initial model, ``{name: (n_cells,)}``: ``E`` (the
    background's modulus ``E``, a known region's relative elasticity times it or its absolute
    modulus), the laws' extra parameters (the experiment's, then each region's) and, for a
    mixture of laws, each law's share."""
    material = model_material(experiment)
    cells = region_cells(mesh, experiment)
    out = {"E": np.full(mesh.n_cells, float(E))}
    for q in material.extra:
        out[q.name] = np.full(mesh.n_cells, experiment.parameters.get(q.name, q.default))
    for r, inside in zip(experiment.regions, cells):
        out["E"][inside] = r.modulus_over(E)
        if r.law and r.law != experiment.law:
            out[share(experiment.law)][inside] = 0.0
            out[share(r.law)][inside] = 1.0
        for key, value in r.parameters.items():
            out[key][inside] = value
    return out
