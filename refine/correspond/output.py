"""What a followed sequence leaves on disk: the dense correspondences (CSV), the summary (JSON) and
the prediction error against the frame (PNG)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np


def write_correspondences(path: str | Path, nodes: np.ndarray, positions: np.ndarray) -> Path:
    """Every model node's position in every frame: ``frame,node,X,Y,x,y`` (reference coordinates
    X, Y; position x, y in that frame; frame 0 the reference). ``nodes (n, 2)``,
    ``positions (n_frames + 1, n, 2)``."""
    path = Path(path)
    dim = nodes.shape[1]
    axes = "xyz"[:dim]
    with open(path, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f, lineterminator="\n")
        out.writerow(["frame", "node", *(a.upper() for a in axes), *axes])
        for k, xk in enumerate(positions):
            for i, (X, x) in enumerate(zip(nodes, xk)):
                out.writerow([k, i, *(f"{v:.6g}" for v in X), *(f"{v:.6g}" for v in x)])
    return path


def write_summary(path: str | Path, summary: dict) -> Path:
    """The summary of a followed sequence as JSON."""
    path = Path(path)
    path.write_text(json.dumps(summary, indent=2, default=float), encoding="utf-8")
    return path


def plot_errors(path: str | Path, records, null_level: float, baseline=None) -> Path:
    """Prediction error before and after refinement against the frame, the null level, and
    optionally the errors of a run without refinement (``baseline``: a list of records)."""
    from matplotlib.figure import Figure  # the object API: no pyplot, no backend switched

    frames = [r.frame for r in records]
    fig = Figure(figsize=(6, 3.6))
    ax = fig.subplots()
    ax.plot(frames, [r.error_before for r in records], "o-", label="predicted (before refinement)")
    ax.plot(frames, [r.error_after for r in records], "s--", label="after refinement")
    if baseline is not None:
        ax.plot([r.frame for r in baseline], [r.error_before for r in baseline], "x:", color="grey",
                label="initial model, never refined")
    for r in records:
        if r.refined:
            ax.axvline(r.frame, color="tab:red", alpha=0.3)
    ax.axhline(null_level, color="k", lw=0.8, label="null level")
    ax.set_xlabel("frame")
    ax.set_ylabel("held-out outline error (length)")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return Path(path)
