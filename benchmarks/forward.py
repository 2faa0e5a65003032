"""Forward-solve benchmark of jaxfem: neo-Hookean stretch of a sheet (2D) and a block (3D).

For a sweep of mesh sizes it measures, on this machine and in one run:

- jaxfem with each of its linear solvers (``superlu``, ``klu``, ``pardiso``; ``cg`` and ``dense`` at
  the smallest size): compile seconds (first call minus warm call), warm solve seconds (best of 3),
  Newton iterations (linear solves including the predictor), load steps, seconds per iteration;
- one factor + solve of the same tangent (jaxfem's tangent at the solution, constrained as the
  solver does) by every sparse direct solver installed here: SciPy SuperLU (its default COLAMD, and
  jaxfem's symmetric-mode options), KLU (klujax), MKL PARDISO (pypardiso, fresh solver object each
  time), CHOLMOD (scikit-sparse, when importable); each row's ``per_iteration_ratio`` spells out
  the ratio of the target (best jaxfem seconds per Newton iteration over the fastest of these
  complete factor + solves) and, for reference, the same over the numeric phases alone;
- where the time of one Newton iteration goes (the jitted residual + tangent assembly alone);
- peers: scikit-fem on the same triangle mesh in plane strain (against jaxfem in plane strain),
  and torch-fem on the same hexahedral block and on its own neo-Hookean benchmark
  (benchmarks/hyperelasticity.py of torch-fem: a unit cube stretched to 20x its length).

It writes benchmarks/results/forward.json (all numbers, the targets with pass/fail) and forward.png.

    python -m benchmarks forward           # ~25 min on a loaded 2-core machine: 2D to 51k, 3D to 10k DOFs
    python -m benchmarks forward --full    # adds 2D 102k-406k and 3D 29k-103k DOFs (an hour or more)
    python -m benchmarks forward --quick   # smoke test, tiny sizes

A combination predicted to take more than --budget seconds (60) for one solve is skipped and
recorded as skipped. The machine may be shared: every timing is a best-of-N and carries the load
average when it was taken.

This file holds the command line and the run's metadata; the work is in its helper modules:
``_forward_problems`` (the problems and size sweeps), ``_forward_measure`` (everything measured at
one size), ``_forward_sweeps`` (the sweeps, --reuse and the partial writes), ``_forward_report``
(targets, load flags, plot), ``_direct`` (the standalone sparse direct solves), ``_peers``
(scikit-fem, torch-fem) and ``_timing``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent

import jax  # noqa: E402

from jaxfem.linsolve import AUTO_KLU_MAX_DOFS_2D, available  # noqa: E402

from benchmarks import _direct  # noqa: E402
from benchmarks._forward_measure import log  # noqa: E402
from benchmarks._forward_problems import BLOCK, E_SHEET, NU, SHEET, STRETCH  # noqa: E402
from benchmarks._forward_report import _json_default, plot, targets  # noqa: E402
from benchmarks._forward_sweeps import RESULTS, REUSE, sweep_block, sweep_documented, sweep_sheet, write_partial  # noqa: E402
from benchmarks._timing import loadavg  # noqa: E402
from benchmarks._cli import QUICK, quick  # noqa: E402


def versions():
    out = {}
    for pkg in ("jax", "jaxlib", "numpy", "scipy", "scikit-fem", "klujax", "pypardiso", "mkl", "scikit-sparse",
                "torch", "torch-fem", "pyamg"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = None
    return out



def memory_watchdog(limit_gb):
    """Abort (with every thread's stack) if this process's resident memory passes ``limit_gb``: the
    machine may be shared, and a sparse factorisation with bad fill can take it all."""
    import faulthandler
    import threading

    def rss_gb():
        return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e9

    def watch():
        while True:
            if rss_gb() > limit_gb:
                log(f"resident memory {rss_gb():.1f} GB > {limit_gb:.1f} GB: aborting")
                faulthandler.dump_traceback(all_threads=True)
                os._exit(3)
            time.sleep(0.25)

    threading.Thread(target=watch, daemon=True).start()


def mem_available_gb():
    for line in open("/proc/meminfo"):
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) / 1e6
    return 8.0


def main(argv=None) -> int:
    argv = quick(argv, ["--quick", "--out", str(QUICK / "forward.json")])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--full", action="store_true", help="add the large sizes (2D to 406k, 3D to 103k DOFs)")
    ap.add_argument("--quick", action="store_true", help="tiny sizes, one repeat: a smoke test")
    ap.add_argument("--budget", type=float, default=60.0, help="skip a jaxfem solve predicted over this (s)")
    ap.add_argument("--peer-budget", type=float, default=None, help="same for one peer solve (s)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--solvers", default=None, help="comma-separated jaxfem linear solvers to run (default: all)")
    ap.add_argument("--torchfem-threads", default="1,2",
                    help="thread counts for torch-fem at the smallest size (larger sizes: 1); on a loaded "
                         "machine a 2-thread run mostly measures the contention")
    ap.add_argument("--only", choices=["sheet", "block", "documented"], action="append")
    ap.add_argument("--out", default=str(HERE / "results" / "forward.json"))
    ap.add_argument("--max-dofs", type=int, default=10**9, help="leave out the sheet and block sizes above this")
    ap.add_argument("--min-dofs", type=int, default=0, help="... and below this (unless --reuse has them)")
    ap.add_argument("--max-memory-gb", type=float, default=None,
                    help="abort past this resident memory (default: 75 %% of what is available at the start)")
    ap.add_argument("--reuse", default=None, help="an earlier forward.json: keep its rows of the same sizes "
                    "and measure only the others (e.g. --full after a default run)")
    ap.add_argument("--remeasure", action="store_true", help="with --reuse: measure the sizes within "
                    "--min-dofs .. --max-dofs again, keep the reused rows of the others")
    args = ap.parse_args(argv)
    args.torchfem_threads = tuple(int(t) for t in args.torchfem_threads.split(","))
    args.solvers = args.solvers.split(",") if args.solvers else None
    if args.reuse:
        REUSE.update(json.loads(Path(args.reuse).read_text()))
    memory_watchdog(args.max_memory_gb or min(0.75 * mem_available_gb(), 12.0))
    mode = "quick" if args.quick else "full" if args.full else "default"
    if args.quick:
        args.repeats = 1
    if args.peer_budget is None:
        args.peer_budget = 180.0 if args.full else 60.0
    png = Path(args.out).with_suffix(".png")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    os.environ.pop("PYPARDISO_MKL_RT", None)
    pinit = _direct.pardiso_construction_seconds() if "pardiso" in available() else None
    args.pardiso_init_s = pinit["seconds_without_PYPARDISO_MKL_RT"] if pinit else 0.0
    RESULTS.clear()
    RESULTS["meta"] = {
        "mode": mode, "date": time.strftime("%Y-%m-%d %H:%M:%S"), "cpu": f"{os.cpu_count()} cores, {platform.machine()}",
        "platform": platform.platform(), "python": platform.python_version(), "versions": versions(),
        "jax_devices": [str(d) for d in jax.devices()], "load_start": loadavg(),
        "budget_s": args.budget, "peer_budget_s": args.peer_budget, "repeats": args.repeats,
        "command_line": sys.argv[1:], "torchfem_threads": list(args.torchfem_threads),
        "reused_rows_from": None if not args.reuse else {"file": args.reuse, "date": REUSE.get("meta", {}).get("date"),
                                                          "load_start": REUSE.get("meta", {}).get("load_start"),
                                                          "command_line": REUSE.get("meta", {}).get("command_line"),
                                                          "reused_rows_from": REUSE.get("meta", {}).get("reused_rows_from")},
        "auto_klu_max_dofs_2d_without_pardiso": AUTO_KLU_MAX_DOFS_2D, "linear_solvers_available": available(),
        "direct_solvers_available": _direct.available_direct(),
        "problems": {
            "sheet": f"{SHEET[0]:g} x {SHEET[1]:g} rectangle, tri3 (square cells split in two), neo-Hookean "
                     f"E={E_SHEET}, nu={NU}, plane stress; left edge u_x = 0, right edge u_x = {STRETCH} L, "
                     "u_y = 0 at the bottom-left node",
            "block": f"{BLOCK[0]:g} x {BLOCK[1]:g} x {BLOCK[2]:g} block, hex8 (2n x n x n cubes), same law; left face "
                     f"u_x = 0, right face u_x = {STRETCH} L, u_y = u_z = 0 at (0,0,0), u_z = 0 at (0,L_y,0)",
            "torchfem_documented": "torch-fem benchmarks/hyperelasticity.py: unit cube, (N-1)^3 hex8, E=1000, nu=0.3, "
                                   "right face stretched to 20x the length (u_x = 19) in 20 geometric increments, "
                                   "symmetry planes y = z = 0.5; forward pass timed (parameters declared differentiable, as there)",
        },
        "timing": "warm = best of N (3, fewer where they would pass the budget) calls after the first; compile = first - warm; iterations = linear solves incl. "
                  "the predictor (failed, cut-back attempts included); factor+solve = one solve of the constrained "
                  "tangent at the solution, from the CSR values to x, best of N; each timing carries the 1-min "
                  "load average when it was taken (the machine may be shared)",
    }
    RESULTS["pardiso_construction"] = pinit
    RESULTS["install"] = {
        "scikit-sparse": "plain `pip install scikit-sparse` fails here (0.5.0 builds from source: no cholmod.h; "
                         "with Debian's libsuitesparse-dev 5.12 its C code needs SuiteSparse 7). Works: "
                         "`apt-get install libsuitesparse-dev && pip install scikit-sparse==0.4.16` (~45 s).",
        "torch-fem": "`pip install torch==2.13.0` (local CPU wheel), `pip install torch-fem --no-deps pyamg`; "
                     "pyvista (VTK, plotting only) is stubbed out in the child process.",
    }
    only = set(args.only or ["sheet", "block", "documented"])
    for part, kinds in (("sheet", ("sheet_plane_stress", "sheet_plane_strain")), ("block", ("block",)),
                        ("documented", ("torchfem_documented",))):
        if part not in only:  # parts not measured now: carried over from --reuse
            for k in kinds:
                if k in REUSE:
                    RESULTS[k] = REUSE[k]
    if "sheet" in only:
        RESULTS["sheet_plane_stress"], RESULTS["sheet_plane_strain"] = [], []
        sweep_sheet(args, mode)
    if "block" in only:
        RESULTS["block"] = []
        sweep_block(args, mode)
    if "documented" in only:
        RESULTS["torchfem_documented"] = []
        sweep_documented(args, mode)
    RESULTS["targets"] = targets(RESULTS)
    RESULTS["fastest_linear_solver_by_size"] = [
        {"problem": kind, "dofs": r["dofs"], "fastest_jaxfem": r.get("fastest_jaxfem"),
         "warm_s": {k: round(v["warm_s"], 4) for k, v in r["jaxfem"].items() if "warm_s" in v},
         "fastest_factor_solve": r.get("fastest_factor_solve")}
        for kind in ("sheet_plane_stress", "block") for r in RESULTS.get(kind, [])]
    RESULTS["meta"]["wall_seconds"] = time.time() - t_start
    write_partial(args)
    plot(RESULTS, png)
    log(f"wrote {args.out} and {png} in {RESULTS['meta']['wall_seconds']:.0f} s")
    print(json.dumps(RESULTS["targets"], indent=1, default=_json_default))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
