"""Test configuration: float64 before any computation, hypothesis profile for a 2-core CI."""

import os
import sys

import pytest

#: The suite's programs are compiled for a short compile rather than for fast code: XLA's
#: older kernel emitters (those vmj compiles every single call with, `vmj._exported.ONE_CALL`)
#: and LLVM's lightest optimisation, the same operations (docs/performance.md: the suite on 2
#: cores in an empty cache 730 -> 614 s; unoptimised, 517 s, put one exact decay 1.3e-6 off
#: where the optimised code is within 4e-16). Tests marked `production_compile` (properties
#: of XLA's optimised code, such as two programs agreeing to the last bit or taking the same
#: adaptive steps, and the paper's tables) are left out here and run by
#: tests/test_production_compile.py in a process of their own with the flags as given, as the
#: `vmj` command compiles. `VMJ_TEST_COMPILE=production` runs the whole suite that way.
FAST_COMPILE = ("--xla_cpu_use_fusion_emitters=false", "--xla_backend_optimization_level=1")
PRODUCTION = os.environ.get("VMJ_TEST_COMPILE") == "production"
if not PRODUCTION:
    os.environ["XLA_FLAGS"] = " ".join((os.environ.get("XLA_FLAGS", ""), *FAST_COMPILE)).strip()

import vmj  # noqa: E402

# as the vmj command runs: XLA's small loops (a single solve's) as one kernel each, set before
# JAX starts its backend (the suite's own compiling takes as long either way: tests/test_rope.py
# and tests/test_decay_trajectory.py in an empty cache, 105 s with it, 114 s without)
vmj.one_kernel_loops()
import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
# as the vmj command runs single solves (its `fit` runs asynchronously: docs/fits.md); the
# suite takes as long either way (209 s)
jax.config.update("jax_cpu_enable_async_dispatch", False)
# share compiled programs between the pytest workers and test files of one run; the `vmj`
# command run in-process or as a subprocess uses the same directory (not the user's cache).
# Every program, however quick its compile, as the `vmj` command keeps them: the documentation's
# snippets and the commands' processes compile many small ones that the suite has compiled
# already (the suite on 2 cores, the same tree, one run each: 570 s with programs of 1 s of
# compiling and more kept, 500 s with all kept)
# (VMJ_CACHE_DIR, where set, names another directory: an empty one measures a fresh clone's run)
CACHE = os.environ.setdefault(
    "VMJ_CACHE_DIR", os.path.join(os.path.dirname(__file__), "..", ".pytest_cache", "jax")
)
jax.config.update("jax_compilation_cache_dir", CACHE)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile(
    "vmj", deadline=None, max_examples=25, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile("vmj")

sys.path.insert(0, os.path.dirname(__file__))  # tests/scipy_reference.py


def pytest_xdist_make_scheduler(config, log):
    """`--dist loadfile`, the documentation's file sent first: tests/test_docs.py runs every
    page in one process (a minute and more of a cold run, from a file of few tests), and xdist
    sends the files with the most tests first, so that it came last and finished last on its
    worker."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class DocumentationFirst(LoadFileScheduling):
        def _assign_work_unit(self, node):
            if "tests/test_docs.py" in self.workqueue:
                self.workqueue.move_to_end("tests/test_docs.py", last=False)
            super()._assign_work_unit(node)

    return DocumentationFirst(config, log)


_PRODUCTION_TESTS = pytest.StashKey[list]()


def pytest_collection_modifyitems(config, items):
    """At the suite's compile settings, the tests marked `production_compile` are deselected
    (`production_tests` runs them)."""
    if PRODUCTION:
        return
    kept, chosen = [], []
    for item in items:
        (chosen if item.get_closest_marker("production_compile") else kept).append(item)
    config.stash[_PRODUCTION_TESTS] = [item.nodeid for item in chosen]
    config.hook.pytest_deselected(items=chosen)
    items[:] = kept


@pytest.fixture
def production_tests(request) -> tuple[list, dict]:
    """The deselected `production_compile` tests' ids (none where the suite runs at the
    production settings) and the environment that runs them so: `XLA_FLAGS` without
    `FAST_COMPILE`."""
    flags = [f for f in os.environ.get("XLA_FLAGS", "").split() if f not in FAST_COMPILE]
    env = dict(os.environ, VMJ_TEST_COMPILE="production", XLA_FLAGS=" ".join(flags))
    return request.config.stash.get(_PRODUCTION_TESTS, []), env
