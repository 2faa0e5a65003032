"""Where one diagnosis's CPU seconds go (``diagnose_scale.py --profile``): the diagnosis run with
its thread pool made synchronous (every job in the calling thread, so that cProfile sees all of
it; the CPU seconds are those of the threaded run, the wall seconds longer), XLA compilations
counted with their seconds and the name of the function compiled (``jax.monitoring``), the
shared programs' Newton solves and their iterations (every :class:`jaxfem.program.Program`'s
``newton`` counted), and the CPU seconds between the diagnosis's log lines (its stages). Writes
``OUT/diagnose_profile_SIZE.json`` (stages with their compilations and Newton solves,
compilations by name, the top functions by cumulative and own time) and the raw ``.prof``
beside it.
"""

from __future__ import annotations

import cProfile
import io
import json
import os
import pstats
import resource
import time
from concurrent.futures import Future
from pathlib import Path


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class SyncExecutor:
    """An executor that runs every job at submission, in the calling thread."""

    def __init__(self, *args, **kwargs):
        pass

    def submit(self, fn, *args, **kwargs):
        f = Future()
        try:
            f.set_result(fn(*args, **kwargs))
        except BaseException as e:  # noqa: BLE001 - handed to the caller as the future's exception
            f.set_exception(e)
        return f

    def shutdown(self, *args, **kwargs):
        pass


def _by_name(names: list[str], seconds: list[float]) -> dict:
    """``{name: [compilations, seconds]}``, most seconds first."""
    out = {}
    for n, d in zip(names, seconds):
        c, t = out.get(n, (0, 0.0))
        out[n] = (c + 1, t + d)
    return {n: [c, round(t, 2)] for n, (c, t) in sorted(out.items(), key=lambda kv: -kv[1][1])}


def _top(stats: pstats.Stats, key: str, n: int = 40) -> list[dict]:
    stats.sort_stats(key)
    out = []
    for func in stats.fcn_list[:n]:
        cc, nc, tt, ct, _ = stats.stats[func]
        out.append({"function": f"{Path(func[0]).name}:{func[1]}({func[2]})", "calls": nc,
                    "own_s": round(tt, 2), "cumulative_s": round(ct, 2)})
    return out


def count_newton() -> dict:
    """Count every shared program's Newton solves and iterations from now on (the returned
    dict's ``solves`` and ``iterations``): :class:`jaxfem.program.Program`'s ``newton`` read
    through a wrapper (programs made before included; the counters read after the solve has
    finished, the same results)."""
    import jax

    import jaxfem.program as jp

    counts = {"solves": 0, "iterations": 0}

    def get(self):
        newton = self.__dict__["newton"]

        def counted(*a, **k):
            out = newton(*a, **k)
            counts["solves"] += 1
            counts["iterations"] += int(jax.device_get(out[1]["iterations"]))
            return out

        return counted

    def put(self, value):
        self.__dict__["newton"] = value

    jp.Program.newton = property(get, put)  # a data descriptor: read before the instance's own
    return counts


def profile_case(bundle, config, label: str, out_dir: Path) -> dict:
    """Diagnose ``bundle`` under cProfile (synchronously) and write the profile's JSON."""
    import jax

    import refine.diagnosis.pipeline as pipeline

    compiles, names = [], []

    def listen(event, duration, **kw):
        if event.endswith("backend_compile_duration"):
            compiles.append(round(duration, 3))
            names.append(str(kw.get("fun_name", "?")))

    jax.monitoring.register_event_duration_secs_listener(listen)
    newton = count_newton()
    stages, c0, w0 = [], _cpu(), time.perf_counter()

    def log(msg):
        done = {"compiles": sum(s.get("new_compiles", 0) for s in stages)}
        new = names[done["compiles"]:]
        by_name = {}
        for n, d in zip(new, compiles[done["compiles"]:]):
            by_name[n] = [by_name.get(n, [0, 0.0])[0] + 1, round(by_name.get(n, [0, 0.0])[1] + d, 2)]
        stages.append({"cpu_s": round(_cpu() - c0, 2), "wall_s": round(time.perf_counter() - w0, 2),
                       "compiles": len(compiles), "compile_s": round(sum(compiles), 1),
                       "newton_solves": newton["solves"], "newton_iterations": newton["iterations"],
                       "new_compiles": len(new), "new_compiles_by_name": dict(sorted(by_name.items(),
                                                                                      key=lambda kv: -kv[1][1])),
                       "line": msg[:160]})

    pipeline.ThreadPoolExecutor = SyncExecutor
    prof = cProfile.Profile()
    load0 = os.getloadavg()[0]
    prof.enable()
    d = pipeline.diagnose(bundle, config, log=log)
    prof.disable()
    out_dir.mkdir(parents=True, exist_ok=True)
    prof.dump_stats(str(out_dir / f"diagnose_profile_{label}.prof"))
    stats = pstats.Stats(prof, stream=io.StringIO())
    row = {"label": label, "cpu_s": round(_cpu() - c0, 1), "wall_s": round(time.perf_counter() - w0, 1),
           "load": [round(load0, 2), round(os.getloadavg()[0], 2)],
           "compiles": len(compiles), "compile_s": round(sum(compiles), 1),
           "large_compiles": sorted((c for c in compiles if c > 1.0), reverse=True),
           "compiles_by_name": _by_name(names, compiles),
           "newton_solves": newton["solves"], "newton_iterations": newton["iterations"],
           "stages": stages, "chosen": d.chosen.describe(),
           "top_cumulative": _top(stats, "cumulative"), "top_own": _top(stats, "tottime", 25)}
    (out_dir / f"diagnose_profile_{label}.json").write_text(json.dumps(row, indent=1))
    return row
