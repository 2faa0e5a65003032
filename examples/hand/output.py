"""A motion's results out: ParaView series of the volume and the skin, and the strain curves as a PNG."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np

from jaxfem.io import write_pvd, write_vtu
from .motion import MotionResult


def write_motion_series(result: MotionResult, hand, folder, E=None) -> tuple[Path, Path]:
    """Write one VTU per frame of the volume (point data ``displacement`` mm; cell data
    ``equivalent_strain``, ``skin_strain`` on the cells under the skin (0 inside), ``E`` MPa if given)
    and of the skin surface (``triangle6``, cell data ``skin_strain``), and a PVD for each (time =
    the share of the full range). Returns the two PVD paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    stem = result.motion.name.replace(" ", "_") + ("_scar" if result.scar is not None else "")
    vol, skin = [], []
    X = np.asarray(hand.mesh.nodes)
    for k in range(len(result.fraction)):
        on_skin = np.zeros(hand.mesh.n_cells)
        np.maximum.at(on_skin, hand.skin_cells, result.skin_strain[k])
        cd = {"equivalent_strain": result.equivalent[k], "skin_strain": on_skin}
        if E is not None:
            cd["E"] = np.asarray(E)
        vol.append(folder / f"{stem}_{k:03d}.vtu")
        write_vtu(vol[-1], hand.mesh, {"displacement": result.u[k]}, cd)
        skin.append(folder / f"{stem}_skin_{k:03d}.vtu")
        meshio.Mesh(X, [("triangle6", hand.skin_facets)], point_data={"displacement": result.u[k]},
                    cell_data={"skin_strain": [result.skin_strain[k]]}).write(skin[-1], file_format="vtu")
    return (write_pvd(folder / f"{stem}.pvd", vol, result.fraction),
            write_pvd(folder / f"{stem}_skin.pvd", skin, result.fraction))


def plot_curves(results, path, labels=None) -> Path:
    """Plot max skin strain (over the area of interest where one was given) vs the marked point's
    displacement for each result into the PNG ``path``: one colour per motion, scars dashed (then
    dash-dotted, dotted), a strain limit as a thin line, a threshold (a ``threshold`` with
    ``"motion"`` and ``"interval"`` in the displacement's unit, as refine.threshold's ``to_json``)
    as a marker with its interval. ``labels``: one per result (default: the motion's name, "with
    scar"); a restricted motion's reachable share is added to its label."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    colours, scarred = {}, {}
    for i, r in enumerate(results):
        c = colours.setdefault(r.motion.name, f"C{len(colours)}")
        style = "-"
        if r.scar is not None:
            scarred[r.motion.name] = scarred.get(r.motion.name, -1) + 1
            style = ("--", "-.", ":")[scarred[r.motion.name] % 3]
        label = labels[i] if labels is not None else r.motion.name + (" with scar" if r.scar is not None else "")
        if r.restricted:
            label += f" (restricted at {100 * r.reached:.0f} %: {r.limited_by})"
        ax.plot(r.displacement, r.area_max_strain, style, color=c, marker=".", label=label)
        if r.strain_limit is not None:
            ax.axhline(r.strain_limit, color=c, lw=0.6, ls=":")
        t = r.threshold
        if isinstance(t, dict) and "motion" in t and "interval" in t:
            y = np.interp(t["motion"], r.displacement, r.area_max_strain)
            ax.errorbar([t["motion"]], [y], xerr=[[t["motion"] - t["interval"][0]], [t["interval"][1] - t["motion"]]],
                        color=c, marker="D", ms=5, capsize=3)
    ax.set_xlabel("displacement of the marked point (mm)")
    where = " (area of interest)" if any(r.area is not None for r in results) else ""
    ax.set_ylabel("max skin strain (principal, Green-Lagrange)" + where, fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
