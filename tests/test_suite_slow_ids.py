"""Every check that tests/conftest.py moves out of the default suite still exists: a renamed test
would otherwise rejoin the default suite unnoticed (and a removed one leave a dead entry)."""

import re
from pathlib import Path

from conftest import SLOW_IN_CI

ROOT = Path(__file__).resolve().parent.parent


def test_every_slow_in_ci_id_names_an_existing_test_function():
    missing = []
    for nodeid in sorted(SLOW_IN_CI):
        path, _, name = nodeid.partition("::")
        function = name.split("[")[0]
        source = ROOT / path
        if not source.exists() or not re.search(rf"^def {re.escape(function)}\(", source.read_text(), re.M):
            missing.append(nodeid)
    assert not missing, f"SLOW_IN_CI names tests that do not exist: {missing}"
