"""A synthetic range sequence of the moving hand (the paper's Sec. 5 data, generated): joint angles
drawn at random under a seed, the hand solved frame by frame on a FINER mesh than any tracker's
(``examples.hand`` with its own element size; the same body), and each frame seen by one orthographic
range camera (:func:`examples.synthetic.solid_clouds.range_cloud`: rays on a grid with a fresh random
offset, the first hit of the deformed surface, Gaussian depth noise along the ray) from the back of
the hand and a little from the side, so that the palm side is never seen and the flexed thumb and
finger hide parts of each other; the forearm's proximal part lies out of the field of view. The
whole scene is placed in the scanner's frame by a random global pose. Beside the clouds, the few
marked points the paper tracked: skin points with identities, with their own localisation noise.

Units: mm, radians (degrees only in the bounds of :data:`RANGES`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from examples.hand import PAPER, HandModel, default_body, hand_mesh, skin_strain_function

from refine.exceptions import ExperimentError
from examples.synthetic.solid_clouds import range_cloud

#: the range of each joint's final angle (degrees, drawn uniformly; the wrist's with a random sign)
RANGES = {"wrist_flexion": (20.0, 40.0), "wrist_deviation": (10.0, 25.0), "thumb_1": (20.0, 45.0),
          "thumb_2": (20.0, 50.0), "index_1": (10.0, 30.0)}
SIGNED = ("wrist_flexion", "wrist_deviation")
#: depth noise (mm): a desktop structured-light scanner resolves depth to about 0.05-0.2 mm
#: at arm's length; the upper end
SCANNER_NOISE = 0.2
#: the camera's viewing direction (from the camera to the hand): down onto the back of the hand
#: (+z side), a little from the little finger's side (-x) and from the fingers' end
VIEW = (0.35, -0.2, -1.0)
#: the field of view's proximal edge: the forearm nearer the held cut than this (y, mm, reference) is not seen
VIEW_FROM_Y = -40.0
#: the marked points, each on a face of a soft-tissue volume of :func:`examples.hand.default_body`: the
#: volume's name and the point's place in its box as shares of each side (0 or 1: on that face),
#: snapped to the nearest skin node; away from the joints where the skin follows its bone: three on
#: the forearm and wrist (the global pose), three on the palm, two on each thumb phalanx, three on the
#: first finger's first phalanx (markers on volumes the hand lacks are left out)
MARKERS = {"forearm back": ("forearm", (0.5, 0.4, 1.0)), "forearm side": ("forearm", (0.0, 0.6, 0.5)),
           "wrist back": ("wrist", (0.7, 0.5, 1.0)), "palm back": ("palm", (0.5, 0.5, 1.0)),
           "palm side": ("palm", (0.0, 0.7, 0.5)), "palm back 2": ("palm", (0.8, 0.8, 1.0)),
           "thumb base back": ("thumb_1", (0.5, 0.5, 1.0)), "thumb base side": ("thumb_1", (0.5, 1.0, 0.5)),
           "thumb tip back": ("thumb_2", (0.5, 0.5, 1.0)), "thumb tip": ("thumb_2", (1.0, 0.5, 0.5)),
           "finger back": ("index_1", (0.5, 0.5, 1.0)), "finger side": ("index_1", (0.0, 0.5, 0.5)),
           "finger tip": ("index_1", (0.5, 1.0, 0.5))}
#: a marker's localisation noise (mm): a painted dot's centre found to a fraction of a pixel
MARKER_NOISE = 0.1
#: a motion that is not smooth (shares of the final angles, frames 0-4): a quarter per frame, a sudden
#: stop at frame 2, then back a quarter (velocity changes of a quarter of each angle's range per frame)
STOP_REVERSE = (0.0, 0.25, 0.5, 0.5, 0.25)


@dataclass(frozen=True, eq=False)
class HandSequence:
    """A synthetic range sequence and the truth that made it (frame 0: the hand at rest).

    Attributes:
        names: the joint angles' names ``(n_angles,)``; angles: their truth per frame
            ``(n_frames, n_angles)``, radians.
        pose: the global pose, model frame -> scanner frame: rotation vector (radians) then
            translation (mm), ``(6,)``; points ``x`` of the model are seen at ``R x + t``.
        clouds: one unlabelled range cloud per frame, ``(n_k, 3)`` mm, scanner frame.
        marker_names: ``(m,)``; marker_reference: where each marker sits on the undeformed skin
            ``(m, 3)`` mm (model frame); markers: their measured positions per frame
            ``(n_frames, m, 3)`` mm, scanner frame.
        hand: the fine data-generating :class:`examples.hand.Hand`; u: its displacements
            ``(n_frames, n_nodes, 3)`` mm; skin_strain: its skin strain per frame ``(n_frames, n_skin)``
            (largest principal Green-Lagrange strain in the skin's plane).
        noise: depth noise (mm); marker_noise: a marker's localisation noise (mm).
    """

    names: tuple
    angles: np.ndarray
    pose: np.ndarray
    clouds: tuple
    marker_names: tuple
    marker_reference: np.ndarray
    markers: np.ndarray
    hand: object
    u: np.ndarray
    skin_strain: np.ndarray
    noise: float
    marker_noise: float


def pose_matrix(pose) -> tuple[np.ndarray, np.ndarray]:
    """``(R (3, 3), t (3,))`` of a pose ``(6,)`` (rotation vector, radians; translation, mm)."""
    w = np.asarray(pose, float)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    return expm(K), w[3:]


def random_angles(rng: np.random.Generator, names) -> np.ndarray:
    """Final joint angles ``(n_angles,)`` (radians) drawn from :data:`RANGES` (0 for other names)."""
    out = []
    for n in names:
        lo, hi = RANGES.get(n, (0.0, 0.0))
        a = rng.uniform(lo, hi) * (rng.choice([-1.0, 1.0]) if n in SIGNED else 1.0)
        out.append(np.radians(a))
    return np.asarray(out)


def hand_range_sequence(seed: int = 0, frames: int = 4, h: float = 12.0, snap: float = 4.5, dims=PAPER,
                        spacing: float = 2.5, noise: float = SCANNER_NOISE, marker_noise: float = MARKER_NOISE,
                        pose_deg: float = 3.0, pose_mm: float = 5.0, view=VIEW,
                        view_from_y: float = VIEW_FROM_Y, profile=None) -> HandSequence:
    """Generate a sequence: random final angles, reached from rest in ``frames`` equal steps (or
    along ``profile``).

    Args:
        seed: seeds the angles, the pose, the rays' offsets and every noise.
        frames: deformed frames (the sequence has ``frames + 1``).
        h, snap: the data mesh's element size and face snapping (mm; the body is ``default_body(dims)``;
            a tracker's model should be coarser).
        spacing: distance between the camera's rays (mm).
        noise, marker_noise: depth noise and marker localisation noise (mm, standard deviations).
        pose_deg, pose_mm: bounds of the random global pose (each rotation component, degrees;
            each translation component, mm).
        view: the camera's viewing direction; view_from_y: the field of view's proximal edge (mm).
        profile: the share of the final angles in each frame ``(frames + 1,)`` (default equal steps
            from 0 to 1; :data:`STOP_REVERSE`: a sudden stop, then a reversal).

    Raises:
        ExperimentError: fewer than one frame, a negative noise, a profile of another length.
    """
    if frames < 1 or noise < 0 or marker_noise < 0 or spacing <= 0:
        raise ExperimentError(f"a hand sequence needs frames >= 1, noise >= 0 and spacing > 0; got frames={frames}, "
                              f"noise={noise}, marker_noise={marker_noise}, spacing={spacing}")
    share = np.linspace(0.0, 1.0, frames + 1) if profile is None else np.asarray(profile, float)
    if share.shape != (frames + 1,) or not np.isfinite(share).all():
        raise ExperimentError(f"the profile needs one finite share per frame ({frames + 1} with frames={frames}); got "
                              f"{share.tolist()}")
    rng = np.random.default_rng(seed)
    hand = hand_mesh(default_body(dims), h, snap)
    names = hand.body.angle_names
    final = random_angles(rng, names)
    pose = np.r_[np.radians(rng.uniform(-pose_deg, pose_deg, 3)), rng.uniform(-pose_mm, pose_mm, 3)]
    R, t = pose_matrix(pose)
    angles = share[:, None] * final
    model = HandModel(hand)
    strains = skin_strain_function(model)
    X = hand.mesh.nodes
    skin = np.unique(hand.skin_facets)
    vols = hand.body.volumes
    marked = {n: np.asarray(vols[v].lo) + np.asarray(share) * (np.asarray(vols[v].hi) - np.asarray(vols[v].lo))
              for n, (v, share) in MARKERS.items() if v in vols}
    ref = np.array(list(marked.values()))
    at = skin[np.argmin(np.linalg.norm(X[skin][None] - ref[:, None], axis=2), axis=1)]
    U, E, clouds, marks, start = [], [], [], [], None
    for a in angles:
        theta = model.params(dict(zip(names, a)))
        sol = model.solver.solve(theta, start=start)
        start = (sol.u.reshape(-1), {k: theta[k] for k in ("u_D", "f", "traction")})
        u = np.asarray(sol.u)
        U.append(u)
        E.append(np.asarray(strains(sol.u, theta)[0]))
        pts = range_cloud(hand.mesh, X + u, view, spacing, rng, noise)
        pts = pts[pts[:, 1] >= view_from_y]
        clouds.append(pts[rng.permutation(len(pts))] @ R.T + t)
        marks.append((X[at] + u[at]) @ R.T + t + rng.normal(0.0, marker_noise, (len(at), 3)))
    return HandSequence(names, angles, pose, tuple(clouds), tuple(marked), X[at].copy(), np.stack(marks), hand,
                        np.stack(U), np.stack(E), noise, marker_noise)
