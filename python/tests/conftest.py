"""Shared fixtures: the repository, and the ``phenomena`` command the module is
compared with (``PHENOMENA_BIN``, else the workspace's debug or release build)."""

import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def cli():
    """Run the ``phenomena`` command; fails (never skips) when it is not built."""
    candidates = [os.environ.get("PHENOMENA_BIN"), REPO / "target/debug/phenomena", REPO / "target/release/phenomena"]
    binary = next((Path(c) for c in candidates if c and Path(c).is_file()), None)
    if binary is None:
        pytest.fail("no phenomena binary: build it (cargo build -p phenomena) or set PHENOMENA_BIN")

    def run(*args) -> str:
        done = subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True)
        assert done.returncode == 0, f"phenomena {' '.join(map(str, args))} failed:\n{done.stderr}"
        return done.stdout

    return run
