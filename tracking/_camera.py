"""The camera of a range scanner: pixels and depth to 3D points, and 3D points to pixels and depth.

Pixel coordinates are those of :class:`Tracks` (u = column, v = row, the centre of the top-left
pixel at (0, 0)). The camera's own axes: x along the columns, y along the rows, z along the
optical axis away from the camera (right-handed). A range image holds, per pixel, the depth
z (camera axis, not the distance along the ray), in mm (or the length unit of the camera).

- ``orthographic``: x = (u - cx) * scale, y = (v - cy) * scale, z = depth (``scale`` mm per px;
  a telecentric lens, or a scanner that resamples onto a regular grid).
- ``perspective`` (pinhole, no distortion): x = (u - cx) * z / fx, y = (v - cy) * z / fy,
  z = depth (``fx``, ``fy`` focal lengths in px, ``(cx, cy)`` the principal point in px).

An optional pose carries camera axes to the bundle's (world) axes: X = R x + t, with ``rotation``
R (3 x 3, orthonormal, det +1) and ``translation`` t (3,), so that the points lie on the mesh of
the body. A camera file is a small TOML file of these keys (see :func:`read_camera`).
"""

from __future__ import annotations

import difflib
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._errors import OptionError

MODELS = ("orthographic", "perspective")
_KEYS = {"orthographic": ("model", "scale", "cx", "cy", "rotation", "translation"),
         "perspective": ("model", "fx", "fy", "cx", "cy", "rotation", "translation")}


@dataclass(frozen=True)
class Camera:
    """A range camera (see the module docstring for the formulas).

    Attributes:
        model: ``"orthographic"`` or ``"perspective"``.
        scale: orthographic: length per pixel (mm/px).
        fx, fy: perspective: focal lengths, px.
        cx, cy: the pixel of the optical axis (perspective) or of x = y = 0 (orthographic), px.
        rotation: (3, 3) camera axes to world axes; identity by default.
        translation: (3,) the camera's origin in world axes, length unit.
    """

    model: str = "orthographic"
    scale: float = 1.0
    fx: float = 1.0
    fy: float = 1.0
    cx: float = 0.0
    cy: float = 0.0
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        if self.model not in MODELS:
            raise OptionError(f"camera model {self.model!r} is unknown; use one of {list(MODELS)}")
        for name in ("scale", "fx", "fy") if self.model == "perspective" else ("scale",):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise OptionError(f"camera {name} must be a positive number, got {value!r}")
        R = np.array(self.rotation, dtype=np.float64)
        t = np.array(self.translation, dtype=np.float64)
        if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise OptionError(f"camera rotation must be a 3 x 3 rotation matrix (orthonormal, det +1), got {R.tolist()}")
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise OptionError(f"camera translation must be 3 numbers, got {t.tolist()}")
        object.__setattr__(self, "rotation", R)
        object.__setattr__(self, "translation", t)

    @property
    def perspective(self) -> bool:
        return self.model == "perspective"

    def to_world(self, pixels: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """World points (..., 3) of pixels (..., 2) (u, v) at ``depth`` (...); NaN depth gives NaN."""
        pixels, depth = np.asarray(pixels, np.float64), np.asarray(depth, np.float64)
        u, v = pixels[..., 0] - self.cx, pixels[..., 1] - self.cy
        if self.perspective:
            cam = np.stack([u * depth / self.fx, v * depth / self.fy, depth], axis=-1)
        else:
            cam = np.stack([u * self.scale, v * self.scale, depth], axis=-1)
        return cam @ self.rotation.T + self.translation

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels (..., 2) and depth (...) of world points (..., 3): the inverse of :meth:`to_world`."""
        cam = (np.asarray(points, np.float64) - self.translation) @ self.rotation
        z = cam[..., 2]
        if self.perspective:
            with np.errstate(divide="ignore", invalid="ignore"):
                uv = np.stack([self.fx * cam[..., 0] / z + self.cx, self.fy * cam[..., 1] / z + self.cy], axis=-1)
        else:
            uv = np.stack([cam[..., 0] / self.scale + self.cx, cam[..., 1] / self.scale + self.cy], axis=-1)
        return uv, z

    def footprint(self, depth: float) -> float:
        """Length one pixel spans at ``depth`` (the geometric mean of its two sides)."""
        return float(self.scale if not self.perspective else depth / np.sqrt(self.fx * self.fy))

    def to_toml(self) -> dict:
        """The keys of a camera file (see :func:`read_camera`)."""
        keys = _KEYS[self.model]
        out = {k: getattr(self, k) for k in keys if k not in ("model", "rotation", "translation")}
        return {"model": self.model, **out, "rotation": self.rotation.tolist(), "translation": self.translation.tolist()}


def camera_from_table(table: dict, where: str = "camera") -> Camera:
    """A :class:`Camera` from a table of its keys (``model`` first; see :func:`read_camera`)."""
    model = table.get("model")
    if model not in MODELS:
        raise OptionError(f"{where}: model must be one of {list(MODELS)}, got {model!r}")
    unknown = sorted(set(table) - set(_KEYS[model]))
    if unknown:
        near = difflib.get_close_matches(unknown[0], _KEYS[model], n=1, cutoff=0.5)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise OptionError(f"{where}: key {unknown[0]!r} is not a key of a {model} camera{hint}; "
                          f"known keys: {list(_KEYS[model])}")
    needed = ("scale",) if model == "orthographic" else ("fx", "fy", "cx", "cy")
    missing = [k for k in needed if k not in table]
    if missing:
        raise OptionError(f"{where}: a {model} camera needs {', '.join(needed)}; {', '.join(missing)} missing")
    return Camera(**table)


def read_camera(path: str | Path) -> Camera:
    """Read a camera file: TOML with the keys of :class:`Camera`, e.g.::

        model = "perspective"      # or "orthographic" with scale = 0.05 (mm per px), cx, cy
        fx = 2400.0                # px
        fy = 2400.0
        cx = 320.0
        cy = 240.0
        rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]   # optional: camera axes to world axes
        translation = [0.0, 0.0, -150.0]              # optional: camera origin in world axes (mm)
    """
    path = Path(path)
    if not path.is_file():
        raise OptionError(f"camera file not found: {path}")
    try:
        with open(path, "rb") as f:
            table = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise OptionError(f"camera file {path} is not valid TOML: {e}") from None
    return camera_from_table(table.get("camera", table), str(path))
