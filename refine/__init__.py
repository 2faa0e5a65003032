"""refine: joins measured motion (``tracking``) and finite-element models (``jaxfem``).

Rooms, each with a short public ``__init__`` that is its API (import from the room, not from
this package, which imports nothing so that ``import refine`` stays light):

- :mod:`refine.bundle`: the measurement bundle (experiment, observations, roles) and its I/O;
- :mod:`refine.model`: the model driven by measured boundary points, its parametrisations and
  the misfit a fit minimises;
- :mod:`refine.optimize`: the optimisers, one method per module (LM / Gauss-Newton, L-BFGS-B,
  Pade steps, the tensor method, the paper's Brent and cubic searches);
- :mod:`refine.diagnosis`: show / decide / name / extend / measure, and the report;
- :mod:`refine.demo_data`: the demo's data, a sheet with a hidden effect solved on a finer mesh;
- :mod:`refine.cli`: the ``nonrigid`` command line, one module per command.

:mod:`refine.exceptions` is the error hierarchy and :mod:`refine.measures` the error measures.

The entry point, for every body: ``refine.diagnose(bundle, config) -> refine.Diagnosis``, then
``Diagnosis.write(out)`` (:mod:`refine.api`); ``refine.read_report(path)`` reads any report.json
as schema 2 (:mod:`refine.reports`). They load on first use, so ``import refine`` stays light
(and the package has no ``__all__``: the reference documents them in their modules).
"""

_ENTRY = {"diagnose": "refine.api", "Diagnosis": "refine.api", "read_report": "refine.reports",
          "upgrade": "refine.reports"}


def __getattr__(name: str):
    """The entry point's names (:data:`_ENTRY`), imported on first use (PEP 562)."""
    if name in _ENTRY:
        import importlib

        return getattr(importlib.import_module(_ENTRY[name]), name)
    raise AttributeError(f"module 'refine' has no attribute {name!r}")
