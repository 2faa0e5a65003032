"""benchmarks/diagnose_speed.py's same-machine verdict (``--baseline-tree``) on made-up rows."""

import numpy as np


def test_the_same_machine_target_pairs_the_two_codes_rows_on_one_bundle():
    """diagnose_speed.py --baseline-tree: the verdict compares the medians of this code's and the
    baseline's rows of one label, only over cases both diagnosed on the same bundle and hidden
    effect; drawn seconds under a seed, so the verdict is computed, not assumed."""
    from benchmarks import diagnose_speed as ds

    rng = np.random.default_rng(2311)
    rows, truth = [], [[80.0, 45.0, 8.0, 8.0, 0.0, 7.0]]
    for k, case in enumerate(("a", "b", "c", "d")):
        base_wall, base_cpu = rng.uniform(60, 120), rng.uniform(100, 200)
        f = rng.uniform(0.5, 1.5)
        bundle = "x" if case != "d" else "y"  # case d: the codes saw different bundles, left out
        rows.append({"label": "s", "role": "baseline", "code": "old", "case": case, "bundle": "x", "truth": truth,
                     "wall": base_wall, "cpu": base_cpu, "load": [1, 1], "passed": True})
        rows.append({"label": "s", "role": "main", "code": "new", "case": case, "bundle": bundle, "truth": truth,
                     "wall": f * base_wall, "cpu": f * base_cpu, "load": [1, 1], "passed": True})
    rows.append({"label": "quiet", "case": "a", "code": "new", "wall": 40.0, "cpu": 70.0, "load": [1, 1], "passed": True})
    t = ds.baseline_target(rows)
    same = [r for r in rows if r["label"] == "s" and r["case"] != "d"]
    med = {role: {x: float(np.median([r[x] for r in same if r["role"] == role])) for x in ("wall", "cpu")}
           for role in ("main", "baseline")}
    assert t["cases"] == ["a", "b", "c"]
    assert t["median_wall_s"] == med["main"]["wall"] and t["baseline_median_cpu_s"] == med["baseline"]["cpu"]
    assert t["pass"] == (med["main"]["wall"] < med["baseline"]["wall"] and med["main"]["cpu"] < med["baseline"]["cpu"])
    np.testing.assert_allclose(t["median_wall_on_48s_scale_s"], 48 * med["main"]["wall"] / med["baseline"]["wall"])
    # the absolute 48 s target reads this code's rows only, of the label asked for
    assert ds.median_target(rows, "s")["median_wall_s"] == float(np.median([r["wall"] for r in rows[1::2]]))
    assert ds.baseline_target([r for r in rows if r.get("role") != "baseline"]) is None
    # the issue's verdict reads the issue's code's rows only; another baseline is a before/after pair
    assert ds.baseline_target(rows, issue=True) is None and ds.baseline_target(rows, issue=False) == t
