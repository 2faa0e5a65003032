"""Active contours (snakes) on the grid lines, after Kass, Witkin & Terzopoulos (1988).

Every run of two or more neighbouring crossings in a grid row (or column) becomes an open snake
through them, sampled ``subdivisions`` times per pitch. A snake moves up the ridge of the
smoothed ink image (its image force, taken along the snake's normal so the samples do not slide)
and resists bending (rigidity; no tension, so open snakes do not shrink). The semi-implicit
update (I + rigidity * D2' D2) X_new = X + F(X) is stable for any rigidity. Evolving first on a
coarse scale (a quarter pitch: capture range about half a pitch) then on a fine scale (the
line width) brings every snake onto its own line; crossings of row and column snakes give the
grid points with their identity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse.linalg import splu


@dataclass(frozen=True)
class SnakeOptions:
    """Snake settings.

    Attributes:
        subdivisions: samples per grid pitch along a snake.
        rigidity: weight of the bending energy against the image force (dimensionless).
        step: largest move of a sample per iteration from the image force (px).
        iterations: iterations per scale.
        coarse_scale: smoothing of the coarse stage as a fraction of the pitch (0 skips it).
    """

    subdivisions: int = 4
    rigidity: float = 0.3
    step: float = 0.3
    iterations: int = 40
    coarse_scale: float = 0.25


@dataclass(frozen=True)
class _Family:
    samples: np.ndarray   # (m, 2)
    blocks: np.ndarray    # (k, 2) [start, stop) of every snake in samples
    node_sample: np.ndarray  # (R, C) index of the node's sample, -1 without a snake
    node_block: np.ndarray   # (R, C) index of the node's snake, -1 without


def _family(nodes: np.ndarray, valid: np.ndarray, subdivisions: int) -> _Family:
    """Snakes along axis 1 of ``nodes`` (grid rows); transpose the inputs for columns."""
    samples, blocks = [], []
    node_sample = -np.ones(valid.shape, dtype=np.int64)
    node_block = -np.ones(valid.shape, dtype=np.int64)
    count = 0
    fractions = np.arange(subdivisions) / subdivisions
    for i in range(valid.shape[0]):
        j = 0
        while j < valid.shape[1]:
            if not valid[i, j]:
                j += 1
                continue
            end = j
            while end + 1 < valid.shape[1] and valid[i, end + 1]:
                end += 1
            if end > j:
                run = nodes[i, j:end + 1]
                dense = run[:-1, None, :] + fractions[None, :, None] * np.diff(run, axis=0)[:, None, :]
                dense = np.concatenate([dense.reshape(-1, 2), run[-1:]], axis=0)
                node_sample[i, j:end + 1] = count + subdivisions * np.arange(end + 1 - j)
                node_block[i, j:end + 1] = len(blocks)
                blocks.append((count, count + len(dense)))
                samples.append(dense)
                count += len(dense)
            j = end + 1
    samples = np.concatenate(samples) if samples else np.zeros((0, 2))
    return _Family(samples, np.array(blocks, dtype=np.int64).reshape(-1, 2), node_sample, node_block)


def _system(blocks: np.ndarray, size: int, rigidity: float):
    pieces = []
    for start, stop in blocks:
        n = stop - start
        ones = np.ones(n - 2)
        d2 = sparse.diags([ones, -2 * ones, ones], [0, 1, 2], shape=(n - 2, n))
        pieces.append(sparse.identity(n) + rigidity * (d2.T @ d2))
    return splu(sparse.block_diag(pieces, format="csc")) if pieces else None


def _normals(samples: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    prev = np.arange(len(samples)) - 1
    nxt = np.arange(len(samples)) + 1
    prev[blocks[:, 0]] = blocks[:, 0]
    nxt[blocks[:, 1] - 1] = blocks[:, 1] - 1
    tangent = samples[nxt] - samples[prev]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True) + 1e-12
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)


def _force_field(ink: np.ndarray, sigma: float):
    gy, gx = np.gradient(ndimage.gaussian_filter(ink, sigma, mode="nearest"))
    scale = np.percentile(np.hypot(gx, gy), 90) + 1e-12
    return gx / scale, gy / scale


def _evolve(samples, blocks, solver, field, options: SnakeOptions) -> np.ndarray:
    if len(samples) == 0:
        return samples
    gx, gy = field
    x = samples.copy()
    for _ in range(options.iterations):
        coords = np.stack([x[:, 1], x[:, 0]])
        force = np.stack([ndimage.map_coordinates(g, coords, order=1, mode="nearest")
                          for g in (gx, gy)], axis=1)
        normal = _normals(x, blocks)
        push = np.clip(np.sum(force * normal, axis=1), -1.0, 1.0) * options.step
        new = solver.solve(x + push[:, None] * normal)
        moved = np.max(np.abs(new - x))
        x = new
        if moved < 1e-3:
            break
    return x


def _local_lines(family: _Family, samples: np.ndarray, half: int):
    """Straight line (point, unit direction) fitted through the samples around every node."""
    shape = family.node_sample.shape
    point = np.full(shape + (2,), np.nan)
    direction = np.full(shape + (2,), np.nan)
    has = family.node_sample >= 0
    if not has.any():
        return point, direction
    centre = family.node_sample[has]
    block = family.blocks[family.node_block[has]]
    index = np.clip(centre[:, None] + np.arange(-half, half + 1)[None, :], block[:, :1], block[:, 1:] - 1)
    window = samples[index]                                   # (n, w, 2)
    mean = window.mean(axis=1)
    centred = window - mean[:, None, :]
    cov = np.einsum("nwi,nwj->nij", centred, centred)
    _, vectors = np.linalg.eigh(cov)
    point[has] = mean
    direction[has] = vectors[:, :, 1]
    return point, direction


def snake_crossings(ink: np.ndarray, nodes: np.ndarray, valid: np.ndarray, pitch: float,
                    line_width: float, fallback_steps, options: SnakeOptions = SnakeOptions()):
    """Move row and column snakes onto the grid lines of ``ink`` and intersect them.

    Args:
        ink: (rows, cols) image where lines are positive ridges.
        nodes: (R, C, 2) initial crossing positions (NaN where there is none).
        valid: (R, C) nodes to use.
        pitch, line_width: grid pitch and line width in pixels.
        fallback_steps: (col_step, row_step) directions for nodes without a snake.

    Returns:
        crossings (R, C, 2), row-line directions (R, C, 2) and column-line directions (R, C, 2),
        all unit vectors oriented towards +x and +y; NaN for invalid nodes.
    """
    rows = _family(nodes, valid, options.subdivisions)
    cols = _family(nodes.transpose(1, 0, 2), valid.T, options.subdivisions)
    scales = [options.coarse_scale * pitch] if options.coarse_scale > 0 else []
    scales.append(max(1.0, 0.5 * line_width))
    fields = [_force_field(ink, sigma) for sigma in scales]
    moved = []
    for family in (rows, cols):
        x = family.samples
        solver = _system(family.blocks, len(x), options.rigidity)
        for field in fields:
            x = _evolve(x, family.blocks, solver, field, options)
        moved.append(x)
    half = max(1, options.subdivisions // 2)
    row_point, row_dir = _local_lines(rows, moved[0], half)
    col_point, col_dir = _local_lines(cols, moved[1], half)
    col_point, col_dir = col_point.transpose(1, 0, 2), col_dir.transpose(1, 0, 2)
    default_row = np.asarray(fallback_steps[0], float) / np.linalg.norm(fallback_steps[0])
    default_col = np.asarray(fallback_steps[1], float) / np.linalg.norm(fallback_steps[1])
    row_missing = ~np.isfinite(row_dir[..., 0])
    col_missing = ~np.isfinite(col_dir[..., 0])
    row_dir[row_missing] = default_row
    col_dir[col_missing] = default_col
    row_point[row_missing] = nodes[row_missing]
    col_point[col_missing] = nodes[col_missing]
    row_dir *= np.sign(np.sum(row_dir * default_row, axis=-1, keepdims=True))
    col_dir *= np.sign(np.sum(col_dir * default_col, axis=-1, keepdims=True))
    crossing = intersect_lines(row_point, row_dir, col_point, col_dir)
    crossing[~valid] = np.nan
    return crossing, row_dir, col_dir


def intersect_lines(p: np.ndarray, d: np.ndarray, q: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Intersection of the lines p + s d and q + t e (arrays (..., 2)); NaN for parallel lines."""
    det = d[..., 0] * (-e[..., 1]) - d[..., 1] * (-e[..., 0])
    rhs = q - p
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (rhs[..., 0] * (-e[..., 1]) - rhs[..., 1] * (-e[..., 0])) / det
    out = p + s[..., None] * d
    out[np.abs(det) < 1e-9] = np.nan
    return out
