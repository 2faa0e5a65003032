"""The overlay images of ``nonrigid track``: each frame with its tracked points coloured by role."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from refine.bundle.experiment import RectangleDomain
from refine.bundle.io import Bundle

ROLE_COLOURS = {"boundary": "tab:orange", "guide": "tab:green", "validate": "tab:blue"}


def write_overlays(stack: np.ndarray, tracks, bundle: Bundle, scale: float, origin, directory: Path,
                   roi=None) -> list[Path]:
    """One PNG per frame, ``frame_000.png`` ...: the image with the tracked points coloured by role.

    Frame 0 also shows the ROI (dashed) and the bundle's domain (black); in later frames a lost
    point is a red x where its neighbours' motion would put it.

    Args:
        stack: images ``(n_frames, rows, cols)``.
        tracks: the :class:`tracking.Tracks` in pixels; ``bundle`` the bundle made of them, in mm
            with ``scale`` (mm/px) and ``origin`` (px); ``scale`` None: a 3D bundle (range images),
            whose domain (a mesh) is not drawn.
        directory: where the PNGs go (created if missing).
        roi: the tracked region ``(x0, y0, x1, y1)`` in pixels, drawn on frame 0; None: not drawn.

    Returns:
        The paths written, one per frame.
    """
    from matplotlib.figure import Figure  # not pyplot: the caller's backend (a notebook's) stays as it is
    from scipy.spatial import cKDTree

    directory.mkdir(parents=True, exist_ok=True)
    role = dict(zip(bundle.observations.ids.tolist(), bundle.observations.roles.tolist()))
    colours = np.array([ROLE_COLOURS.get(role.get(int(i)), "0.5") for i in tracks.ids])
    rows, cols = stack.shape[1:]
    zoom = float(np.clip(900.0 / cols, 1.0, 4.0))
    marker = 2.0 + zoom
    paths = []
    for k, image in enumerate(stack):
        fig = Figure(figsize=(zoom * cols / 100, zoom * rows / 100), dpi=100)
        ax = fig.add_axes([0, 0, 1, 1])
        ax.imshow(image, cmap="gray", interpolation="nearest")
        ok = ~tracks.lost[k]
        xy = tracks.positions[k]
        ax.scatter(xy[ok, 0], xy[ok, 1], s=marker ** 2, c=colours[ok], linewidths=0)
        if k == 0:
            if scale is not None:  # a 3D bundle (range images) has a mesh, no outline in pixels
                outline_px = _domain_outline(bundle.experiment.domain) / scale + np.asarray(origin)
                ax.plot(*np.vstack([outline_px, outline_px[:1]]).T, "k-", lw=1)
                for hole in getattr(bundle.experiment.domain, "holes", ()):
                    hole_px = np.asarray(hole) / scale + np.asarray(origin)
                    ax.plot(*np.vstack([hole_px, hole_px[:1]]).T, "k--", lw=1)
            if roi is not None:
                x0, y0, x1, y1 = roi
                ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "y--", lw=1)
        elif (~ok).any():
            found = np.flatnonzero(ok)
            guess = tracks.reference[~ok].copy()
            if found.size:
                _, near = cKDTree(tracks.reference[found]).query(guess, k=min(4, found.size))
                near = found[near.reshape(len(guess), -1)]
                guess += tracks.displacements()[k][near].mean(axis=1)
            ax.scatter(guess[:, 0], guess[:, 1], s=(2.5 * marker) ** 2, c="red", marker="x", linewidths=1.5)
        ax.text(4, 4, f"frame {k}: {int(ok.sum())} tracked, {int((~ok).sum())} lost", color="yellow",
                va="top", fontsize=8 + zoom, bbox={"facecolor": "black", "alpha": 0.5, "lw": 0})
        ax.set_xlim(-0.5, cols - 0.5)
        ax.set_ylim(rows - 0.5, -0.5)
        ax.axis("off")
        path = directory / f"frame_{k:03d}.png"
        fig.savefig(path)
        paths.append(path)
    return paths


def _domain_outline(domain) -> np.ndarray:
    if isinstance(domain, RectangleDomain):
        return np.array([[domain.xmin, domain.ymin], [domain.xmax, domain.ymin],
                         [domain.xmax, domain.ymax], [domain.xmin, domain.ymax]])
    return np.asarray(domain.vertices)
