"""What the diagnosis's search runs on, so that its cost does not grow with the data: a mesh
whose size comes from the domain (not from the number of tracked points), and a few frames.

A diagnosis compiles one program per hypothesis and solves every frame in every evaluation; with
a mesh at half the point spacing, 3,000 points meant ~25,000 cells, and 11 frames meant 11
nonlinear solves per evaluation of a field fit of 80 iterations. The search (the null test, the
modulus field, every hypothesis) runs on the frames that carry the most motion; the chosen model
is then refitted on every frame (:mod:`refine.diagnosis.pipeline`). A hyperelastic model has no
history, so the frames left out of the search only add evidence of the same kind (motion of the
same points, scaled), which the final fit uses.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from refine.bundle.experiment import MeshDomain, PolygonDomain, RectangleDomain
from refine.bundle.observations import Observations
from refine.diagnosis.fitted import Fitted
from refine.model.measured import MeasuredModel
from refine.model.objective import Compiled


def _polygon_area(vertices) -> float:
    v = np.asarray(vertices, float)
    x, y = v[:, 0], v[:, 1]
    return float(abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 2.0)


def domain_area(domain) -> float | None:
    """Area of a 2-D domain (length unit squared), its known holes removed; None for a mesh file."""
    if isinstance(domain, RectangleDomain):
        outer = (domain.xmax - domain.xmin) * (domain.ymax - domain.ymin)
    elif isinstance(domain, PolygonDomain):
        outer = _polygon_area(domain.vertices)
    else:
        return None
    return outer - sum(_polygon_area(h) for h in getattr(domain, "holes", ()))


def mesh_size(domain, spacing: float, max_cells: int) -> float | None:
    """Element size of the diagnosis's models (length unit): half the point spacing (finer cannot
    be resolved by the points), but never so fine that linear triangles of this size would
    exceed ``max_cells`` over the domain (two triangles per square of side h). None where the
    domain is a mesh file (its own cells)."""
    if isinstance(domain, MeshDomain):
        return None
    area = domain_area(domain)
    return float(max(0.5 * spacing, np.sqrt(2.0 * area / max_cells))) if area else 0.5 * spacing


def search_frames(obs: Observations, n: int) -> tuple[int, ...]:
    """The ``n`` frames (0-based, in order) the search uses: the frame of largest median motion,
    then frames whose median motion is closest to evenly spaced fractions of it (1/2 for two
    frames: a second load level shows a nonlinear law). All frames when ``n`` is 0 or at least
    their number."""
    if n <= 0 or n >= obs.n_frames:
        return tuple(range(obs.n_frames))
    motion = np.nanmedian(np.linalg.norm(obs.displacements, axis=2), axis=1)
    motion = np.nan_to_num(motion, nan=-1.0)
    top = int(np.argmax(motion))
    chosen = {top}
    for fraction in np.arange(1, n)[::-1] / n:
        rest = [f for f in range(obs.n_frames) if f not in chosen]
        chosen.add(min(rest, key=lambda f: abs(motion[f] - fraction * motion[top])))
    return tuple(sorted(chosen))


def at_frames(obs: Observations, frames) -> Observations:
    """The observations of the given frames only (0-based), points and roles unchanged."""
    frames = list(frames)
    if frames == list(range(obs.n_frames)):
        return obs
    forces = None if obs.forces is None else replace(obs.forces, values=obs.forces.values[frames])
    return Observations(obs.ids, obs.reference, obs.roles, obs.displacements[frames], forces)


def drives_alike(search: MeasuredModel, full: MeasuredModel) -> bool:
    """Whether ``search`` is ``full`` on fewer frames of the same mesh with every frame driven
    alike (the same boundary points tracked in all: a lost point changes its frame's drive), so
    that :func:`every_frame` can predict ``full``'s frames with ``search``'s compiled solve."""
    if search is full or search.mesh is not full.mesh or not np.array_equal(search.obs.ids, full.obs.ids):
        return False
    drive = search.drives[0].matrix
    return all(np.array_equal(d.matrix, drive) for d in (*search.drives, *full.drives))


def every_frame(search: MeasuredModel, full: MeasuredModel, theta) -> np.ndarray:
    """Predictions of ``full`` on every frame, ``(n_frames, n_points, dim)``, at ``theta`` from
    the search model's compiled solve (:func:`drives_alike` must hold), run on the frames in
    chunks of its own length (the last chunk padded with its last frame): the initial model on
    every frame then costs no compilation of its own (several CPU seconds; its solves cost a
    fraction of one). Each chunk is solved from the undeformed state, so every prediction is
    the equilibrium of its frame's boundary motion, as ``full.predict`` gives it (a hyperelastic
    model has no history)."""
    n, B = search.obs.n_frames, full.measured_boundary()
    out = []
    for start in range(0, len(B), n):
        chunk = B[start:start + n]
        padded = np.concatenate([chunk, np.repeat(chunk[-1:], n - len(chunk), axis=0)])
        out.append(np.asarray(search.predict(theta, boundary=padded))[:len(chunk)])
    return np.concatenate(out)


def on_frames(f: Fitted, full: MeasuredModel) -> Fitted:
    """A hypothesis fitted on the search's frames moved onto ``full`` (every frame): its
    hypothesis rebuilt on ``full`` (for remeshing), its compiled model the same mesh and
    parametrisation driven on every frame. Its misfits are those of the search until refitted."""
    if f.model.obs is full.obs:
        return f
    model = MeasuredModel(f.model.experiment, full.obs, mesh=f.model.mesh, h=f.model.h)
    hypothesis = replace(f.hypothesis, base=full) if hasattr(f.hypothesis, "base") else f.hypothesis
    return replace(f, hypothesis=hypothesis, model=model, compiled=Compiled(model, f.compiled.param))
