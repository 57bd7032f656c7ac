"""Every example script runs and writes its figures to `out/` (never into tracked files).

`VMJ_EXAMPLES_QUICK=1` makes the longest ones a smoke run with reduced sizes; each runs in a
scratch directory (see tests/test_docs.py).
"""

from __future__ import annotations

import sys

import pytest
from test_docs import ROOT, run, scratch

# each example is a fresh process that compiles its models (15-30 s each; the pendulum example a
# minute even as a smoke run): with the long runs (`make test-long`), for CI's 15 minutes
EXAMPLES = [
    pytest.param(p, marks=pytest.mark.long) for p in sorted((ROOT / "examples").glob("*.py"))
]


@pytest.mark.slow
@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.name)
def test_example_runs(example, tmp_path):
    run([sys.executable, str(example)], scratch(tmp_path), timeout=600, VMJ_EXAMPLES_QUICK="1")
    written = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert written and all(name.endswith(".png") for name in written), written
    assert not list(tmp_path.glob("*.png")), "figures written outside out/"
