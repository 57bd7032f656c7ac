"""Test configuration: float64 before any computation, hypothesis profile for a 2-core CI."""

import json
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


#: measured seconds of each test file in a run of the suite (`VMJ_TEST_DURATIONS=path` writes
#: them): the order that `pytest_xdist_make_scheduler` sends the files in
DURATIONS = os.path.join(os.path.dirname(__file__), "durations.json")
DOCUMENTATION = "tests/test_docs.py"


def file_order(files: list[str], seconds: dict[str, float]) -> list[str]:
    """`files` longest first (a file not in `seconds` counts as the median), with the
    documentation's file moved towards the end: just before the files whose seconds add up to
    its own, so that the other worker has work while the documentation runs. The pages'
    snippets run in one process of their own that compiles what they call unless the suite's
    files have compiled it into the shared cache already (tests/test_docs.py alone: 99 s in an
    empty cache, 63 s after the rest of the suite)."""
    known = sorted(seconds.values()) or [1.0]
    cost = {f: seconds.get(f, known[len(known) // 2]) for f in files}
    order = sorted((f for f in files if f != DOCUMENTATION), key=lambda f: -cost[f])
    if DOCUMENTATION in files:
        at, after = len(order), 0.0
        while at > 0 and after < cost[DOCUMENTATION]:
            at -= 1
            after += cost[order[at]]
        order.insert(at, DOCUMENTATION)
    return order


def pytest_xdist_make_scheduler(config, log):
    """`--dist loadfile` with the files in `file_order` (xdist's own order, the files with the
    most tests first, left the documentation's last: it finished alone on its worker; sent
    first, it compiled in an empty cache what the suite compiles later)."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    try:
        with open(DURATIONS, encoding="utf-8") as f:
            seconds = json.load(f)
    except (OSError, ValueError):
        seconds = {}

    class ByDuration(LoadFileScheduling):
        ordered = False

        def _assign_work_unit(self, node):
            if not self.ordered:  # (the queue is complete at the first assignment)
                self.ordered = True
                for scope in file_order(list(self.workqueue), seconds):
                    self.workqueue.move_to_end(scope)
            super()._assign_work_unit(node)

    return ByDuration(config, log)


_SECONDS: dict = {}


def pytest_runtest_logreport(report):
    """The seconds of each test file (its tests' set-up, call and tear-down), for
    `VMJ_TEST_DURATIONS`."""
    if os.environ.get("VMJ_TEST_DURATIONS"):
        name = report.nodeid.split("::")[0]
        _SECONDS[name] = _SECONDS.get(name, 0.0) + report.duration


def pytest_sessionfinish(session):
    path = os.environ.get("VMJ_TEST_DURATIONS")
    if path and _SECONDS and not hasattr(session.config, "workerinput"):  # (the controller)
        with open(path, "w", encoding="utf-8") as f:
            json.dump({k: round(v, 1) for k, v in sorted(_SECONDS.items())}, f, indent=1)
            f.write("\n")


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
