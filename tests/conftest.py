"""Test configuration: float64 before any computation, hypothesis profile for a 2-core CI."""

import os
import sys

import vmj

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
