"""``nonrigid simulate BUNDLE --out DIR``: drive the bundle's initial model with its boundary points."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``simulate`` sub-command to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    p = subparsers.add_parser("simulate", help="drive the bundle's initial model with its boundary points")
    p.add_argument("bundle")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--h", type=float, default=None, help="element size (default: half the point spacing)")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Carry out ``nonrigid simulate`` (``args`` from the parser of :func:`add_parser`); 0 on success."""
    simulate(args.bundle, args.out, h=args.h)
    return 0


def simulate(bundle, out: str | Path, h: float | None = None, quiet: bool = False) -> dict:
    """Solve the bundle's initial model in every frame, driven by the measured boundary points.

    Frames are solved in order, each starting from the previous solution.

    Args:
        bundle: a bundle directory (str or Path) or a :class:`refine.bundle.Bundle`.
        out: output directory (created if missing). Written there: ``displacements.csv`` (the
            model's displacement of every point in every frame, the bundle's format and length
            unit), ``strain_frameNN.png`` (the model's strain map per frame; a 3D model:
            ``model_frameNN.vtu`` with displacement and equivalent strain instead) and, for ParaView,
            ``paraview/model.pvd`` (the model per frame: displacement, strains, modulus, regions;
            :func:`refine.model.paraview.write_model_series`) and ``paraview/points.pvd`` (the
            tracked points with their measured and predicted displacements and residuals).
        h: element size in the bundle's length unit; None: half the point spacing.
        quiet: do not print the summary.

    Returns:
        ``frames``, ``points``, ``cells``, ``newton_iterations`` and ``seconds`` (wall time), and
        where the bundle has such points ``guide_error`` and ``validate_error`` (mean distance
        between predicted and measured points, length unit) and ``tracking_error`` (on the
        validation points; see :func:`refine.measures.tracking_error`).

    Raises:
        refine.exceptions.BundleError: the bundle directory is malformed.
        jaxfem.exceptions.SolverError: a load step does not converge (the message names it).
    """
    from matplotlib.figure import Figure

    import jaxfem as jf

    from refine.bundle.io import read_bundle, write_displacements_csv
    from refine.measures import mean_position_error, tracking_error
    from refine.model.measured import MeasuredModel
    from refine.model.paraview import write_model_series, write_points_series

    t0 = time.perf_counter()
    if isinstance(bundle, (str, Path)):
        bundle = read_bundle(bundle)
    model = MeasuredModel(bundle.experiment, bundle.observations, h=h, root=bundle.root)
    theta = model.params()
    obs = bundle.observations
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    U, start, preds = [], None, []
    for f in range(obs.n_frames):
        th = {**theta, "u_D": model.prescribed(f)}
        sol = model.solver.solve(th, start=start)  # raises SolverError naming the load step
        start = (sol.u.reshape(-1), {"u_D": th["u_D"], "f": th["f"], "traction": th["traction"]})
        U.append(sol)
        preds.append(np.asarray(model.probe(sol.u)))
        if model.mesh.dim == 3:  # no 2D map: the model for ParaView (displacement, equivalent strain per cell)
            jf.write_vtu(out_dir / f"model_frame{f + 1:02d}.vtu", model.mesh, {"displacement": np.asarray(sol.u)},
                         {"equivalent_strain": np.asarray(jf.equivalent_strain(model.solver, sol.u, th))})
            continue
        ax = Figure(figsize=(7, 4.5)).subplots()
        jf.plot.strain_map(model.solver, sol.u, th, ax=ax, points=obs.reference + np.nan_to_num(obs.displacements[f]),
                           title=f"{bundle.experiment.name}: frame {f + 1}, initial model")
        ax.figure.savefig(out_dir / f"strain_frame{f + 1:02d}.png", dpi=120, bbox_inches="tight")
    pred = np.stack(preds)
    write_displacements_csv(out_dir / "displacements.csv", obs.ids, pred)
    write_model_series(out_dir / "paraview", "model", model, theta, [s.u for s in U])
    write_points_series(out_dir / "paraview", "points", obs, {"model": pred})
    summary = {"frames": obs.n_frames, "points": obs.n_points, "cells": model.mesh.n_cells,
               "newton_iterations": int(sum(int(s.info["iterations"]) for s in U)),
               "seconds": time.perf_counter() - t0}
    for role in ("guide", "validate"):
        m = obs.mask(role)
        if m.any():
            summary[f"{role}_error"] = mean_position_error(pred[:, m], obs.displacements[:, m]).value
    if obs.mask("validate").any():
        m = obs.mask("validate")
        summary["tracking_error"] = tracking_error(pred[:, m], obs.displacements[:, m]).value
    if not quiet:
        print(f"simulated {summary['frames']} frames of {bundle.experiment.name!r} on {summary['cells']} cells "
              f"({summary['newton_iterations']} Newton iterations, {summary['seconds']:.1f} s)")
        for k in ("guide_error", "validate_error", "tracking_error"):
            if k in summary:
                print(f"  {k.replace('_', ' ')}: {summary[k]:.4g}")
        print(f"  wrote {out_dir / 'displacements.csv'} and {obs.n_frames} "
              f"{'strain maps' if model.mesh.dim == 2 else 'model VTU files'}")
        print(f"  ParaView: open {out_dir / 'paraview' / 'model.pvd'} and {out_dir / 'paraview' / 'points.pvd'}")
    return summary
