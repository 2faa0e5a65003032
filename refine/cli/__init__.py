"""The ``nonrigid`` command line: one module per command, each with a public function."""

from refine.cli.main import main

__all__ = ["main"]
