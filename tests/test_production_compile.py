"""The tests marked `production_compile`, run at the `vmj` command's compile settings: the rest
of the suite compiles for a short compile (tests/conftest.py, `FAST_COMPILE`), which keeps the
operations but not their last bits where two differently built programs are compared."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_the_production_compile_tests_pass_as_the_command_compiles(production_tests):
    ids, env = production_tests
    if not ids:
        pytest.skip("the suite runs at the production settings: those tests ran in it")
    got = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *ids],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert got.returncode == 0 and f"{len(ids)} passed" in got.stdout, (
        f"{got.stdout[-6000:]}\n{got.stderr[-3000:]}"
    )
