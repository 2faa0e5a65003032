"""The 2D search (refine.diagnosis.search) and the candidate places (refine.diagnosis.candidates)
loop registries: the search asks refine.causes for the 2D causes of each stage, the candidates
come from every registered 2D source (refine.causes.sources). Toy causes of every stage and toy
sources registered here are tried, a failing one is a row with its reason, a superseding
reshape job replaces its start; the real 2D causes and sources are one file each. Fast: the fits
are fakes."""

from __future__ import annotations

import importlib
import pkgutil
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

from refine.causes import Cause, causes, register
from refine.causes import registry as reg
from refine.causes.sources import Source, register_source, sources
from refine.causes.sources import registry as src_reg
from refine.diagnosis.config import DiagnoseConfig
from refine.diagnosis.localize import Candidate


@dataclass(frozen=True, eq=False)
class _Fake:
    cause: str
    chi2_fit: float
    shapes: tuple = ()
    law: str = "neo-hookean"
    k: int = 4
    chi2_holdout: float = 50.0

    @property
    def bic(self):
        return self.chi2_fit + 10.0

    def describe(self):
        return f"{self.cause} (fake {self.chi2_fit:.0f})"


def _trials(pool, cfg=None, n_fit=10):
    from refine.diagnosis import search

    model = SimpleNamespace(experiment=SimpleNamespace(law="neo-hookean"), spacing=1.0)
    return search.Trials(model, None, None, 1.0, cfg or DiagnoseConfig(), SimpleNamespace(propagation=0.0), n_fit,
                         lambda m: None, pool)


def _candidate(rng, sign=-1, source="toy"):
    centre = rng.uniform(20.0, 80.0, 2)
    return Candidate(sign, np.arange(3), centre, rng.uniform(2.0, 6.0, 2), float(rng.uniform(0, np.pi)), 1.0, 1.0,
                     source)


@pytest.fixture()
def toys():
    """Toy 2D causes of every stage (removed after): what each was asked, the fits the place one
    made; a place job that raises, a reshape job that supersedes its start, a global job that raises."""
    from refine.diagnosis.search import Superseding

    rng = np.random.default_rng(11)
    chi2 = rng.uniform(200.0, 400.0)  # far above the noise's 10 residuals: nothing explains the data
    asked, made = [], {}

    def place(search, start):
        asked.append(("place", start, search.used))
        made["fit"] = _Fake("softer-region", chi2)
        return {"toy fit": lambda: made["fit"],
                "toy broken": lambda: (_ for _ in ()).throw(RuntimeError("the toy cannot be fitted"))}

    def reshape(search, start):
        asked.append(("reshape", start, dict(search.fits)))
        made["better"] = _Fake("softer-region", 0.5 * start.chi2_fit)
        return {"toy remeshed": Superseding(lambda: made["better"], start)}

    def glob(search, start):
        asked.append(("global", start, list(search.fitted)))
        return {"toy law": lambda: (_ for _ in ()).throw(ValueError("no such law"))}

    added = [register(Cause(f"toy-{s}", {2}, s, (f"toy-{s}-cause",), j, order=1))
             for s, j in (("place", place), ("reshape", reshape), ("global", glob))]
    yield asked, made
    for c in added:
        reg._REGISTRY.pop(c.name)


def test_the_2d_causes_are_registered_by_stage_one_file_each():
    assert [c.name for c in causes(2, "place")] == ["region", "hole"]
    assert [c.name for c in causes(2, "reshape")] == ["hole-from-region", "rectangle"]
    assert [c.name for c in causes(2, "global")] == ["law", "hole-in-law"]
    import refine.causes as package

    for c in causes(2):
        assert 2 in c.dims and c.doc and c.names
    assert causes(3, "global")[0].name == "law"  # the law cause serves both dimensions
    # every module of refine/causes is a cause file (or the sources' package), imported with the package
    for m in pkgutil.iter_modules(package.__path__):
        mod = importlib.import_module(f"refine.causes.{m.name}")
        assert m.name in ("registry", "sources") or any(isinstance(v, Cause) for v in vars(mod).values()), m.name


def test_the_search_tries_every_registered_2d_cause_and_failures_are_rows(toys, monkeypatch):
    from refine.diagnosis import search

    asked, made = toys
    real = search.causes
    monkeypatch.setattr(search, "causes", lambda dim, stage: [c for c in real(dim, stage) if c.name.startswith("toy")])
    rng = np.random.default_rng(12)
    cand = _candidate(rng)
    with ThreadPoolExecutor(2) as pool:
        trials = _trials(pool)
        out = search._try_hypotheses(trials, [cand])
    assert [a[0] for a in asked] == ["place", "reshape", "global"]
    assert asked[0][1] is cand and asked[0][2] == ()  # the first region: nothing used before it
    assert asked[1][1] is made["fit"] and asked[1][2] == {"toy fit": made["fit"], "toy broken": None}
    assert asked[2][1] is None
    # the superseding job replaced its start: listed once, as the better fit
    assert out == [made["better"]] and asked[2][2] == [made["better"]]
    rows = [f.row() for f in trials.failed]
    assert {r["tried"]: r["cause"] for r in rows} == {"toy broken": "toy-place-cause", "toy law": "toy-global-cause"}
    assert {r["tried"]: r["failed"]["message"] for r in rows} == {"toy broken": "the toy cannot be fitted",
                                                                  "toy law": "no such law"}
    assert all(r["bic"] is None for r in rows)


def test_a_cause_that_cannot_say_its_jobs_or_does_not_apply(monkeypatch):
    """A cause whose jobs raise is a row named after it; one whose ``applies`` gives a reason is
    not asked for jobs; global causes only where no fit explains the data."""
    from refine.diagnosis import search

    rng = np.random.default_rng(13)
    asked = []

    def broken(search_, start):
        raise KeyError("the toy's start is missing")

    def glob(search_, start):
        asked.append("global")
        return {}

    good = _Fake("stiffer-region", 1.0)  # 1 over 10 residuals: explains the data
    added = [register(Cause("toy-broken", {2}, "place", ("toy-region",), broken, order=1)),
             register(Cause("toy-fine", {2}, "place", ("toy-region",), lambda s, c: {"toy good": lambda: good},
                            order=2)),
             register(Cause("toy-refused", {2}, "reshape", ("toy-region",), lambda s, c: asked.append("refused"),
                            applies=lambda s: "the toy says no", order=1)),
             register(Cause("toy-global", {2}, "global", ("toy-law",), glob, order=1))]
    real = search.causes
    try:
        monkeypatch.setattr(search, "causes",
                            lambda dim, stage: [c for c in real(dim, stage) if c.name.startswith("toy")])
        with ThreadPoolExecutor(2) as pool:
            trials = _trials(pool)
            out = search._try_hypotheses(trials, [_candidate(rng), _candidate(rng)])
    finally:
        for c in added:
            reg._REGISTRY.pop(c.name)
    assert out == [good] and asked == []  # explained at the first candidate: no second, no global cause
    [row] = [f.row() for f in trials.failed]
    assert row["tried"] == "toy-broken" and row["cause"] == "toy-region" and "missing" in row["failed"]["message"]


def test_the_2d_sources_are_registered_one_file_each():
    names = [s.name for s in sources(2)]
    assert names == ["gaps", "soft-gaps", "field", "strain"]
    assert [s.reads for s in sources(2)] == [False, True, False, False]
    assert all(s.doc and 2 in s.dims for s in sources(2))


def test_data_candidates_lists_every_registered_source_in_order(monkeypatch):
    """Toy sources (the real ones left out): listed in their order, one that reads the others
    sees those found before it, a place seen twice (same sign, centre inside a kept one) kept once."""
    from refine.diagnosis.candidates import data_candidates

    rng = np.random.default_rng(14)
    first, other = _candidate(rng, -1, "toy-a"), _candidate(rng, 1, "toy-b")
    twice = Candidate(-1, np.arange(2), first.centroid + 0.1, first.axes, first.angle, 0.5, 0.5, "toy-c")
    seen = {}

    def reading(look, found):
        seen.update(found)
        return [twice]

    added = [register_source(Source("toy-b", {2}, lambda look, found: [other], order=3, doc="b")),
             register_source(Source("toy-c", {2}, reading, order=1, reads=True, doc="c")),
             register_source(Source("toy-a", {2}, lambda look, found: [first], order=2, doc="a")),
             register_source(Source("toy-3d", {3}, lambda look, found: [other], order=0, doc="3d"))]
    real = src_reg.sources
    try:
        monkeypatch.setattr(src_reg, "sources", lambda dim=None: [s for s in real(dim) if s.name.startswith("toy")])
        look = SimpleNamespace()
        got = data_candidates(look, None, None, None, 0.01, DiagnoseConfig())
    finally:
        for s in added:
            src_reg._REGISTRY.pop(s.name)
    assert seen == {"toy-a": [first], "toy-b": [other]}  # found before it, in their order; no 3D source
    assert got == [twice, other]  # toy-c first (order 1); toy-a's is the same place, kept once
