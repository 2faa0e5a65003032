"""What a hand is before it is meshed: soft-tissue volumes, bones inside them, joints between bones.

A :class:`Body` is plain data: axis-aligned boxes of soft tissue (their union is the body), bones
(boxes inside that union, each a rigid body in a kinematic tree rooted at a held bone) and the
joints that say how a bone turns against its parent (one axis for a phalanx, two for the wrist),
plus named marked points on the skin. :func:`default_body` builds the paper's simplified
hand/wrist/forearm (Sec. 5) from a few dimensions (:class:`HandDimensions`, mm).

Coordinates (mm): x across the hand (the thumb on +x), y along the arm (forearm at y < 0, fingers
at the largest y), z through the hand (palm at -z, back of the hand at +z).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from jaxfem.exceptions import MeshError, ProblemError


@dataclass(frozen=True)
class Box:
    """An axis-aligned box ``[lo, hi]`` (mm), ``lo``/``hi`` of shape ``(3,)``."""

    lo: tuple
    hi: tuple

    def __post_init__(self):
        lo, hi = np.asarray(self.lo, float), np.asarray(self.hi, float)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(hi > lo):
            raise MeshError(f"a box needs lo < hi in x, y and z (3 values each), got lo={self.lo}, hi={self.hi}")
        object.__setattr__(self, "lo", tuple(lo.tolist()))
        object.__setattr__(self, "hi", tuple(hi.tolist()))

    def contains(self, x) -> np.ndarray:
        """Whether points ``x (n, 3)`` lie inside (boundary included), ``(n,)``."""
        x = np.asarray(x, float)
        return np.all((x >= np.asarray(self.lo)) & (x <= np.asarray(self.hi)), axis=-1)


@dataclass(frozen=True)
class Joint:
    """Rotations of a bone against its parent about axes through ``pivot`` (reference coordinates,
    mm), applied in order (the first axis outermost); ``names`` names each angle (radians in the
    kinematics, degrees in a :class:`~examples.hand.motion.Motion`)."""

    pivot: tuple
    axes: tuple
    names: tuple


@dataclass(frozen=True)
class Bone:
    """A rigid bone: its box, its parent bone (``None``: the held root) and its joint to the parent."""

    name: str
    box: Box
    parent: str | None = None
    joint: Joint | None = None


@dataclass(frozen=True)
class Body:
    """Soft-tissue ``volumes`` (named boxes whose union is the body), ``bones`` (parents before
    children; the first is the held root), ``marks`` (named reference points, mm, snapped to the
    nearest skin node when meshed) and ``held`` (the name of the volume whose proximal face
    ``y = min`` is the held cut through the arm)."""

    volumes: dict
    bones: tuple
    marks: dict = field(default_factory=dict)
    held: str = "forearm"
    cover: float = 1.0  # least soft tissue around a bone, mm

    def __post_init__(self):
        _check_body(self)

    @property
    def angle_names(self) -> tuple:
        """Every joint angle's name, in the bones' order."""
        return tuple(n for b in self.bones if b.joint for n in b.joint.names)

    def inside(self, x) -> np.ndarray:
        """Whether points ``x (n, 3)`` lie in the union of the volumes, ``(n,)``."""
        return np.any([v.contains(x) for v in self.volumes.values()], axis=0)


def _check_body(body: Body) -> None:
    """Raise a clear error for a joint without an axis, a bone outside the body, a broken tree."""
    if body.held not in body.volumes:
        raise MeshError(f"the held volume {body.held!r} is not one of the volumes {sorted(body.volumes)}")
    seen = set()
    for k, bone in enumerate(body.bones):
        if bone.name in seen:
            raise ProblemError(f"two bones are called {bone.name!r}; give each bone its own name")
        if k == 0 and (bone.parent is not None or bone.joint is not None):
            raise ProblemError(f"the first bone ({bone.name!r}) is the held root: it takes no parent and no joint")
        if k > 0 and (bone.parent not in seen or bone.joint is None):
            raise ProblemError(f"bone {bone.name!r} needs a joint and a parent among the bones listed before it "
                               f"({sorted(seen)}), got parent={bone.parent!r}")
        if bone.joint is not None:
            _check_joint(bone)
        _check_inside(body, bone)
        seen.add(bone.name)
    names = body.angle_names
    if len(set(names)) != len(names):
        raise ProblemError(f"joint angle names repeat: {names}; give each rotation its own name")


def _check_joint(bone: Bone) -> None:
    j = bone.joint
    if np.shape(j.pivot) != (3,):
        raise ProblemError(f"joint of bone {bone.name!r}: the pivot needs 3 coordinates, got {j.pivot}")
    if len(j.axes) not in (1, 2) or len(j.names) != len(j.axes):
        raise ProblemError(f"joint of bone {bone.name!r}: give one or two axes (a hinge, or a universal joint "
                           f"like the wrist) and one name per axis; got {len(j.axes)} axes, names {j.names}")
    for name, axis in zip(j.names, j.axes):
        a = np.asarray(axis, float)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-12:
            raise ProblemError(f"joint angle {name!r} of bone {bone.name!r} has no axis ({axis!r}): give its "
                               "rotation axis as a nonzero 3-vector, e.g. (0, 1, 0)")


def _check_inside(body: Body, bone: Bone) -> None:
    """The bone, grown by ``cover`` mm, must lie in the union of the volumes (sampled on a lattice)."""
    lo, hi = np.asarray(bone.box.lo) - body.cover, np.asarray(bone.box.hi) + body.cover
    g = np.stack(np.meshgrid(*[np.linspace(a, b, 9) for a, b in zip(lo, hi)], indexing="ij"), -1).reshape(-1, 3)
    out = ~body.inside(g)
    if out.any():
        raise MeshError(f"bone {bone.name!r} ({bone.box.lo} .. {bone.box.hi} mm) is not inside the body with "
                        f"{body.cover} mm of soft tissue around it (e.g. {g[out][0].round(2).tolist()} is "
                        "outside every volume); move or shrink the bone, or enlarge the volumes")


@dataclass(frozen=True)
class HandDimensions:
    """The simplified hand of :func:`default_body` (mm). Tuples are (width x, length y, thickness z)
    for the forearm, wrist and palm; fingers and thumb have a width, thickness and phalanx lengths.
    ``bone`` is the bone's share of a segment's width, ``bone_thickness`` its thickness (one for all
    bones, so that their faces share grid planes); ``gap`` the soft tissue left between a bone's end
    and its joint. :data:`PAPER` is a coarser hand of about the paper's size."""

    forearm: tuple = (50.0, 60.0, 30.0)
    wrist: tuple = (46.0, 16.0, 30.0)
    palm: tuple = (80.0, 80.0, 26.0)
    fingers: int = 4
    finger: tuple = (16.0, 16.0)  # width, thickness
    phalanges: tuple = (40.0, 25.0, 20.0)
    thumb: tuple = (20.0, 18.0)
    thumb_phalanges: tuple = (30.0, 25.0)
    thumb_at: float = 12.0  # the thumb's base edge, from the palm's proximal end (y)
    bone: float = 0.45
    bone_thickness: float = 9.0
    gap: float = 5.0


#: a hand of about the paper's 1,947 elements (2,412 tet10 at h = 24 mm, snap = 4.5 mm): one finger
#: block (the four fingers as a mitten with one bone), a shorter forearm, forearm and wrist equally wide
PAPER = HandDimensions(forearm=(48.0, 40.0, 28.0), wrist=(48.0, 16.0, 28.0), palm=(80.0, 70.0, 26.0), fingers=1,
                       finger=(80.0, 22.0), phalanges=(80.0,), thumb=(20.0, 22.0), thumb_at=10.0)

FINGER_NAMES = ("index", "middle", "ring", "little")


def default_body(d: HandDimensions = HandDimensions()) -> Body:
    """The hand/wrist/forearm of the paper's Sec. 5 as boxes: forearm (its bone held), wrist (soft
    tissue only: its two rotations, flexion about x and deviation about z, turn the palm's bone),
    palm, a thumb of two phalanges (hinges about y at its base and between them) and ``d.fingers``
    fingers of three phalanges (hinges about -x). Marks: ``"thumb tip"`` and each finger's tip
    (``"middle tip"``...), at the middle of the distal face."""
    if not 0 <= d.fingers <= 4:
        raise MeshError(f"a hand has 0 to 4 fingers besides the thumb, got {d.fingers}")
    (fw, fl, ft), (ww, wl, wt), (pw, pl, pt) = d.forearm, d.wrist, d.palm
    vol, bones, marks = {}, [], {}

    def seg(name, x0, x1, y0, y1, z0, z1):
        vol[name] = Box((x0, y0, z0), (x1, y1, z1))

    def bone_in(name, box, along, parent=None, joint=None):
        lo, hi = np.array(box.lo), np.array(box.hi)
        c, s = 0.5 * (lo + hi), 0.5 * (hi - lo) * d.bone
        s[2] = 0.5 * d.bone_thickness
        blo, bhi = c - s, c + s
        blo[along], bhi[along] = lo[along] + d.gap, hi[along] - d.gap
        bones.append(Bone(name, Box(tuple(blo), tuple(bhi)), parent, joint))

    seg("forearm", -fw / 2, fw / 2, -wl - fl, -wl, -ft / 2, ft / 2)
    seg("wrist", -ww / 2, ww / 2, -wl, 0.0, -wt / 2, wt / 2)
    seg("palm", -pw / 2, pw / 2, 0.0, pl, -pt / 2, pt / 2)
    bone_in("radius", vol["forearm"], 1)
    wrist = Joint((0.0, -wl / 2, 0.0), ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)), ("wrist_flexion", "wrist_deviation"))
    bone_in("metacarpals", vol["palm"], 1, "radius", wrist)
    # the thumb along +x from the palm's radial side; flexion turns its tip to the palm (-z)
    tw, tt = d.thumb
    x, y0 = pw / 2, d.thumb_at
    parent = "metacarpals"
    for k, length in enumerate(d.thumb_phalanges):
        name = f"thumb_{k + 1}"
        seg(name, x, x + length, y0, y0 + tw, -tt / 2, tt / 2)
        bone_in(name, vol[name], 0, parent, Joint((x, y0 + tw / 2, 0.0), ((0.0, 1.0, 0.0),), (f"thumb_{k + 1}",)))
        parent, x = name, x + length
    marks["thumb tip"] = (x, y0 + tw / 2, 0.0)
    fw_, ft_ = d.finger
    centres = np.linspace(pw / 2, -pw / 2, 2 * max(d.fingers, 1) + 1)[1::2]
    for name, cx in zip(FINGER_NAMES, centres[: d.fingers]):
        y, parent = pl, "metacarpals"
        for k, length in enumerate(d.phalanges):
            seg(f"{name}_{k + 1}", cx - fw_ / 2, cx + fw_ / 2, y, y + length, -ft_ / 2, ft_ / 2)
            bone_in(f"{name}_{k + 1}", vol[f"{name}_{k + 1}"], 1, parent,
                    Joint((cx, y, 0.0), ((-1.0, 0.0, 0.0),), (f"{name}_{k + 1}",)))
            parent, y = f"{name}_{k + 1}", y + length
        marks[f"{name} tip"] = (cx, y, 0.0)
    return Body(vol, tuple(bones), marks)
