"""Timing helpers shared by the benchmarks: repeated measurements summarised as a median with
the range, ratios of medians, whole-process runs, and a line describing the machine."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import time

import numpy as np

REPEAT = 5  #: repetitions on each side of a comparison (at least)
#: `interleaved(..., warm_up=True)`: each turn's untimed calls last this long [s] (one call at
#: least; `VMJ_BENCH_WARM=0` in the environment: one call, as before the twenty-first stop)
WARM_UP_S = float(os.environ.get("VMJ_BENCH_WARM", "0.1"))


def set_up_jax() -> bool:
    """JAX as the `vmj` command runs it, before anything is computed: XLA's loops as one kernel
    each (`vmj.one_kernel_loops`), float64 and synchronous CPU dispatch. `--float32` on the
    command line turns float64 off (and silences vmj's warning that its accuracy figures assume
    float64: it was asked for); `--async-dispatch` keeps JAX's default dispatch. Returns
    whether JAX runs in float32."""
    import warnings

    import vmj

    vmj.one_kernel_loops()
    import jax

    float32 = "--float32" in sys.argv
    jax.config.update("jax_enable_x64", not float32)
    if float32:
        warnings.filterwarnings("ignore", "vmj: JAX is running in float32")
    if "--async-dispatch" not in sys.argv:
        jax.config.update("jax_cpu_enable_async_dispatch", False)
    return float32


class Timing:
    """Repeated wall times of one measurement [s]."""

    def __init__(self, times):
        self.times = np.asarray(times, dtype=float)

    @property
    def median(self) -> float:
        return float(np.median(self.times))

    def __str__(self) -> str:
        return f"{_fmt(self.median)} (min {_fmt(self.times.min())}, max {_fmt(self.times.max())})"

    def per(self, count: int) -> Timing:
        return Timing(self.times / count)


def _fmt(seconds: float) -> str:
    if seconds >= 1.0:
        return f"{seconds:.2f} s"
    if seconds >= 1e-3:
        return f"{seconds * 1e3:.1f} ms"
    if seconds >= 1e-6:
        return f"{seconds * 1e6:.1f} us"
    return f"{seconds * 1e9:.0f} ns"


def repeat(fn, times: int = REPEAT, number: int = 1, block=None) -> Timing:
    """Wall time of `number` calls of `fn`, `times` times, per call (`block(out)` waits for an
    asynchronous result)."""
    out = []
    for _ in range(times):
        t0 = time.perf_counter()
        for _ in range(number):
            result = fn()
            if block is not None:
                block(result)
        out.append((time.perf_counter() - t0) / number)
        del result
    return Timing(out)


def interleaved(*measurements, rounds: int = REPEAT, warm_up: bool = False) -> list[Timing]:
    """Wall times of several measurements taken in turns, so that a change of the machine's speed
    during the run (on the shared development machine, up to 2 x within minutes) reaches each of
    them alike: each of `rounds` rounds makes `calls` calls of every `(fn, calls)`, one
    measurement after the other. With `warm_up`, each measurement's turn starts with calls that
    are not timed, for `WARM_UP_S` seconds (one call at least), so that every timed call finds
    the machine as its own calls left it, as in a run of `repeat`: the energy-balance sweep
    straight after the NumPy version, whose arrays had taken the caches, took 50-69 ms against
    47-52 ms; on this 2-core virtual machine the 4096-point exact sweep (4-5 ms a call) took
    1.4-1.7 us per point in its first four calls after the 0.45 s single-threaded SciPy loop
    and the multiply-add kernel, 0.9-1.2 us from the fifth on (five turns, medians per call).
    Returns one `Timing` per measurement, of every timed call."""
    times = [[] for _ in measurements]
    for _ in range(rounds):
        for out, (fn, calls) in zip(times, measurements):
            if warm_up:
                t_warm = time.perf_counter()
                fn()
                while time.perf_counter() - t_warm < WARM_UP_S:
                    fn()
            for _ in range(calls):
                t0 = time.perf_counter()
                result = fn()
                out.append(time.perf_counter() - t0)
                del result
    return [Timing(t) for t in times]


def run_process(argv, env=None, cwd=None) -> tuple[float, str]:
    """Wall time of a whole process [s] and its standard output (raises if it fails)."""
    t0 = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=cwd)
    elapsed = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed:\n{done.stderr}")
    return elapsed, done.stdout


def ratio(label: str, numerator: Timing, denominator: Timing, goal: str = "") -> float:
    """Print and return the ratio of two medians."""
    r = numerator.median / denominator.median
    print(f"  {label}: {r:.3g}" + (f"  (goal {goal})" if goal else ""))
    return r


def _processor() -> str:
    """The processor's model name (`/proc/cpuinfo` on Linux), else the architecture: figures
    taken on different processors are not compared."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> str:
    import jax

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return (
        f"{_processor()}, {cores} cores, load average "
        f"{os.getloadavg()[0]:.1f}; python {sys.version.split()[0]}, jax {jax.__version__}, "
        f"{jax.devices()[0].platform}; medians of {REPEAT} or more runs (min, max)"
    )
