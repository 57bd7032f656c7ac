"""Host settings of a program's start-up (the allocator for large sweeps on the CPU, XLA's CPU
loops for single solves), and the memory free for new buffers (`available_memory`: a sweep's
chunk size, the room for an entry point's results).

XLA:CPU takes every compiled call's output and temporary buffers from `malloc`. glibc serves
blocks above its mmap threshold with fresh `mmap`s and gives freed memory back to the operating
system above its trim threshold, so a sweep that runs hundreds of chunks page-faults the same
few megabytes into existence again for every chunk, and its result array (96 MB for 10^6 points
x 12 amplitudes) once more for every sweep. On the 2-core development machine that was a fifth
to a third of a 10^6-point energy-balance sweep (docs/performance.md). `retain_host_memory`
raises both thresholds, so that freed blocks are reused instead.

XLA's CPU backend runs a `while` loop operation by operation, a kernel launch each per
iteration, unless the loop's buffers come to less than its option
`xla_cpu_small_while_loop_byte_threshold` (1 kB by default): then the whole loop is one
compiled kernel. A single solve is loops of scalar operations (swings, substeps, Newton
iterations), whose cost is the number of launches, not the arithmetic; `one_kernel_loops`
raises the threshold.

Both change the whole process, so vmj never calls them on import or inside a solver: the `vmj`
command line, the benchmarks and the test suite call them at start-up, and a script of your own
may do the same.
"""

from __future__ import annotations

import ctypes
import math
import os
import platform

__all__ = ["retain_host_memory", "one_kernel_loops", "available_memory"]

_M_TRIM_THRESHOLD = -1  # glibc <malloc.h>
_M_MMAP_THRESHOLD = -3
_INT_MAX = 2**31 - 1  # mallopt takes a C int


def retain_host_memory(limit: int = 2**30) -> bool:
    """Keep freed host memory for reuse instead of returning it to the operating system
    (glibc's `mallopt`; a process-wide setting, meant for a program's entry point).

    **Arguments:**

    - `limit`: bytes, in `[0, 2**31 - 1]`. Blocks up to this size are served from the heap
      rather than from fresh `mmap`s, and up to this much freed memory at the top of the heap
      is kept rather than trimmed. The price is that the process may hold up to `limit` bytes
      of freed memory it is not using.

    **Returns:** `True` if the setting was applied; `False` where the C library is not glibc
    (macOS, Windows, musl), where it does nothing.

    Measured on the 2-core development machine (docs/performance.md): a 10^6-point x 12-swing
    energy-balance sweep of the amplitudes, best (median) of 10 in separate processes, took
    64-75 (74-85) ms with it and 69-87 (76-136) ms without it; one `jax.jit(jax.vmap(...))` of
    the same over all points, whose 96 MB output is allocated anew on every call, 76-94 (91-102)
    ms with it and 156-165 (183-187) ms without it.
    """
    if isinstance(limit, bool) or not isinstance(limit, int) or not 0 <= limit <= _INT_MAX:
        raise ValueError(
            f"limit must be an integer number of bytes in [0, {_INT_MAX}], got {limit!r}"
        )
    if platform.libc_ver()[0] != "glibc":
        return False
    mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
    if mallopt is None:  # pragma: no cover - glibc always has it
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, limit)) and bool(mallopt(_M_TRIM_THRESHOLD, limit))


#: XLA's option, and the loops' bytes up to which `one_kernel_loops` makes a loop one kernel
LOOP_OPTION, LOOP_BYTES = "xla_cpu_small_while_loop_byte_threshold", 2**16


def one_kernel_loops(limit: int = LOOP_BYTES) -> bool:
    """Have XLA's CPU backend compile each `while` loop whose buffers come to less than `limit`
    bytes into one kernel, instead of a kernel launch per operation and iteration (sets its
    option `xla_cpu_small_while_loop_byte_threshold` in the `XLA_FLAGS` environment variable,
    which XLA reads when JAX starts its backend: call it before the first computation).

    **Arguments:**

    - `limit`: bytes, an integer in `[0, 2**63 - 1]` (XLA's default: 1024).

    **Returns:** `True` if the setting will apply (or `XLA_FLAGS` names the option already: it
    is left as given); `False` if JAX's backend has started already, when nothing is changed.

    At the default every loop of a single exact, smoothed or rope solve is one kernel and a
    sweep's chunks (16384 lanes) stay above the limit: one warm exact solve takes about 0.7 of
    its time at XLA's default, sweeps and compiling as long (docs/performance.md).
    """
    if isinstance(limit, bool) or not isinstance(limit, int) or not 0 <= limit < 2**63:
        raise ValueError(
            f"limit must be an integer number of bytes in [0, 2**63 - 1], got {limit!r}"
        )
    flags = os.environ.get("XLA_FLAGS", "")
    if LOOP_OPTION in flags:
        return True
    try:
        from jax._src import xla_bridge

        if xla_bridge.backends_are_initialized():
            return False
    except (ImportError, AttributeError):  # pragma: no cover - another JAX: set it regardless
        pass
    option = f"{LOOP_OPTION}={limit}"
    words = flags.split()
    for i, word in enumerate(words):  # (XLA takes one map of extra options: extend it)
        if word.startswith("--xla_backend_extra_options="):
            words[i] = f"{word},{option}"
            break
    else:
        words.append(f"--xla_backend_extra_options={option}")
    os.environ["XLA_FLAGS"] = " ".join(words)
    return True


def available_memory(device, enough: float = math.inf) -> int | None:
    """Bytes of memory free for new buffers on `device` (the host's available memory for a
    CPU), or None if unknown. On a CPU, the host's free memory (less than what it has available)
    when that is `enough` already (one system call: reading `/proc/meminfo` is a file's
    opening, 17-140 us of a sweep's fixed cost)."""
    if device.platform != "cpu":
        try:
            stats = device.memory_stats() or {}
            return int(stats["bytes_limit"] - stats.get("bytes_in_use", 0))
        except Exception:
            return None
    try:
        free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        if free >= enough:
            return free
    except (ValueError, OSError, AttributeError):
        pass
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None
