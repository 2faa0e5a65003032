"""The project's benchmarks: one module per benchmark (``benchmarks/NAME.py`` with
``main(argv=None) -> int``, accepting ``--quick``), run by ``python -m benchmarks NAME``; each writes
one canonical results file ``benchmarks/results/NAME.json`` (with a ``targets`` section) and
``NAME.png``. Modules with a leading underscore are their helpers. See benchmarks/README.md."""
