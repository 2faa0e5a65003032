"""Shared pieces of the fuzz suites (tests/test_fuzz_*.py): hypothesis settings that are the same
on every run, the snapshot of the user's files, and the tally of outcomes."""

from __future__ import annotations

import contextlib
import hashlib
import io
from collections import Counter
from pathlib import Path

from hypothesis import HealthCheck, settings

OUTCOMES = ("ok", "error", "traceback", "modified")


def fixed(max_examples: int) -> settings:
    """Settings for a reproducible run: derandomized (a fixed seed), no example database, no deadline."""
    return settings(max_examples=max_examples, derandomize=True, database=None, deadline=None,
                    suppress_health_check=list(HealthCheck), print_blob=False)


def snapshot(root: Path) -> dict[str, str]:
    """Every file and folder under ``root`` (relative path -> sha256 of a file's bytes, "dir" for a folder)."""
    state = {}
    for path in sorted(Path(root).rglob("*")):
        rel = str(path.relative_to(root))
        state[rel] = "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
    return state


def one_line(message: str) -> bool:
    """A message a user can read: not empty, one line, no traceback."""
    return bool(message.strip()) and "\n" not in message.strip() and "Traceback" not in message


def run_cli(argv: list[str]) -> tuple[int, str]:
    """``refine.cli.main.main(argv)`` in this process: (exit status, what it wrote on stderr);
    a SystemExit (argparse) gives its code."""
    from refine.cli.main import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main(argv)
        except SystemExit as e:
            rc = e.code
    return rc, err.getvalue()


class Tally(Counter):
    """Counts of the generated inputs by outcome (see :data:`OUTCOMES`)."""

    def line(self, what: str) -> str:
        return f"fuzz {what}: {sum(self.values())} inputs: " + ", ".join(f"{k} {self[k]}" for k in OUTCOMES)
