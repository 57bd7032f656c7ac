"""Sweeps: evaluate a solution at every point of a model's array-valued parameters.

`sweep(fn, model, **solver_args)` broadcasts the model's array fields together as NumPy does,
evaluates `fn(point_model, **solver_args)` at every point with `jax.vmap`, in chunks (one
compilation; the chunk size bounded by the memory the compiled chunk needs), and returns a
[`vmj.SweepResult`][] whose fields carry the batch shape in front. The chunks run in threads of
this process (one per core, sharded across the local devices when there are several), or as
tasks of a Dask cluster (`client=`); with `store=` every finished chunk is written to a Zarr
store as it completes, and a rerun resumes. `grid(model, eps=..., mu=...)` builds outer products
with named axes. Nothing here knows about a particular model: any `equinox.Module` whose
parameters are array fields works.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
import os
import re
import sys
import threading
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.extend.core import ClosedJaxpr, jaxpr_as_fun

from .._checks import (
    check_int,
    check_room,
    collecting,
    mark_checked,
    validated,
    warn_if_float32,
)
from .._exported import exported_cache_directory, exported_jit, joined_leaves, split_arrays
from .._host import available_memory
from .._solution import RESULTS
from .._version import __version__
from ._engine import (
    CORES,
    Progress,
    cluster,
    failure_message,
    run_chunks,
    threads_of,
    worker_memory,
)
from ._grid import Grid
from ._result import SweepResult, export_names
from ._store import ChunkStore, check_resume, describe_fn, digest
from ._tree import _get, named_paths

__all__ = ["sweep", "SweepError"]

#: the largest chunk unless a chunk_size is given [points]: on a CPU, about what its caches hold
#: and one core evaluates in a fraction of a second; on an accelerator (one device), enough
#: lanes to fill it, so that a sweep is a few compiled calls rather than hundreds
DEFAULT_CHUNK = 16384
ACCELERATOR_CHUNK = 1 << 20
#: the share of the available memory that the chunks evaluated side by side may take
MEMORY_FRACTION = 0.25
#: on one CPU, a model's and arguments' arrays of at most this many bytes in all are handed to
#: every chunk as NumPy arrays (`jax.jit` copies them, 13 us per call for a 4096-point sweep's
#: three parameters) instead of being put on the device once (`jax.device_put`'s own cost,
#: 120-450 us for the same, was the largest part of the sweep's fixed cost of about 1 ms)
PASSED_BYTES = 1 << 18
#: traces of the chunk function in this process (each worker of a cluster should trace once)
_TRACES = 0
#: what this process knows of the compiled chunks of recent sweeps (see `_SweepJob.known`)
_KNOWN: collections.OrderedDict = collections.OrderedDict()
_KNOWN_LOCK = threading.Lock()


class SweepError(RuntimeError):
    """Some chunks of a sweep raised (e.g. `throw=True` and a solve failed, or a worker was
    lost too often); the others were evaluated (and stored, with a store).

    **Fields:** `failures` (chunk number to `(first point, last point, status code,
    message)`; the code is a [`vmj.RESULTS`][] member when the message is one of theirs, else
    -1) and `result` (the [`vmj.SweepResult`][] with the failed points' floats set to NaN and
    their other fields to 0).
    """

    def __init__(self, message: str, failures: dict, result: SweepResult):
        super().__init__(message)
        self.failures, self.result = failures, result


def _take(x, shape, idx):
    """The entries of `x` (broadcastable to `shape`) at the flat C-order indices `idx`, which
    are consecutive. A leaf of the whole shape is sliced (XLA's gathers are slow on CPUs: a
    10^6-point energy-balance sweep in 2048-point chunks on two threads, 64 -> 35 ms); a leaf
    that broadcasts (a grid's axis) is gathered from, without materialising the broadcast."""
    if tuple(x.shape) == tuple(shape) and idx.shape[0] <= x.size:  # (not a padded chunk)
        return jax.lax.dynamic_slice_in_dim(jnp.reshape(x, (-1,)), idx[0], idx.shape[0])
    full = (1,) * (len(shape) - x.ndim) + tuple(x.shape)
    flat, x_stride, out_stride = jnp.zeros_like(idx), 1, 1
    for k in range(len(shape) - 1, -1, -1):
        if full[k] > 1:
            flat = flat + (idx // out_stride) % shape[k] * x_stride
        x_stride *= full[k]
        out_stride *= shape[k]
    return jnp.reshape(x, (-1,))[flat]


def host_output(devices, sharding):
    """Where a chunk's result is written: `None` (the device's own memory) on a CPU; on an
    accelerator, its pinned host memory, which the device writes at the bus's speed and NumPy
    reads in place (measured on an H200: a 10^6 x 12 float64 result in NumPy 2.6 ms after the
    call, against 29 ms through JAX's copy of device memory into fresh host memory). `devices`:
    the sweep's (`None`: this process's default device, as a cluster's worker runs)."""
    device = devices[0] if devices else jax.local_devices()[0]
    if device.platform == "cpu":
        return None
    if "pinned_host" not in {m.kind for m in device.addressable_memories()}:
        return None  # pragma: no cover - an accelerator without host memory of its own
    return pinned_host(device, sharding)


def pinned_host(device, sharding):
    """`sharding` (the sweep's over several devices; `None`: `device` alone) with its arrays in
    pinned host memory."""
    if sharding is not None:
        return sharding.with_memory_kind("pinned_host")
    return jax.sharding.SingleDeviceSharding(device, memory_kind="pinned_host")


@functools.cache
def _avx512() -> bool:
    """Whether this machine's processor has AVX-512 (Linux's `/proc/cpuinfo`, read once; False
    where it cannot be read)."""
    try:
        with open("/proc/cpuinfo") as fh:
            return any(line.startswith("flags") and " avx512f" in line for line in fh)
    except OSError:
        return False


def chunk_options(devices) -> dict:
    """XLA's options for the compiled chunks on `devices` (`None`: this process's default
    device, as a cluster's worker runs): on a CPU with AVX-512, vectors of 512 bits (XLA's CPU
    code prefers 256 by default). Measured on the 2-core AMD EPYC (Zen 4) development machine,
    alternating processes: the exact sweep of `benchmarks/bench_exact.py` 3.2-3.3 -> 2.1-2.5
    us/point, the smoothed sweep about 8 % faster, the energy balance unchanged within its
    noise; results unchanged (the same accuracy against SciPy). `XLA_FLAGS` naming
    `--xla_cpu_prefer_vector_width` is left to decide."""
    device = devices[0] if devices else jax.local_devices()[0]
    if device.platform != "cpu" or "xla_cpu_prefer_vector_width" in os.environ.get("XLA_FLAGS", ""):
        return {}
    return {"xla_cpu_prefer_vector_width": 512} if _avx512() else {}


@dataclasses.dataclass(frozen=True)
class _Chunk:
    """What a sweep's chunk program is made of besides its arrays (hashable, its static
    argument): `fn`, the static parts of its arguments and of the model (`split_arrays`'s), the
    swept leaves (flags), the points' `shape`, the chunk's `size` and the `sharding` of a chunk
    over several devices (`None` on one)."""

    fn: Callable
    static_kwargs: tuple
    static_model: tuple
    swept: tuple
    shape: tuple
    size: int
    sharding: object


@jax.tree_util.register_pytree_node_class
class _Placed:
    """A chunk's result `out` with the axis of each of its leaves where its points are
    (`axes`, `vmap_in_place`'s), and the checks that its function's points failed (`failures`,
    `vmj._checks.Failures`, each code the failed message of any of the chunk's points): the
    axes are in the result's structure, so that they come with it from the exported-program
    cache."""

    def __init__(self, out, axes: tuple, failures):
        self.out, self.axes, self.failures = out, tuple(axes), failures

    def tree_flatten(self):
        return (self.out, self.failures), self.axes

    @classmethod
    def tree_unflatten(cls, axes, children):
        out, failures = children
        return cls(out, axes, failures)


def _chunk_program(model_arrays, kwargs_arrays, start, chunk: _Chunk) -> _Placed:
    """`chunk.fn` at the points `start ... start + chunk.size` (flat, C order; indices past the
    last point repeat it) of a model whose swept leaves broadcast to `chunk.shape`; each leaf of
    the result has its points on the axis its computation puts them on (`vmap_in_place`; on
    the first where the chunk is sharded over several devices)."""
    global _TRACES
    _TRACES += 1
    shape, swept = chunk.shape, chunk.swept
    leaves, treedef = joined_leaves(chunk.static_model, model_arrays), chunk.static_model[0]
    kwargs = jax.tree.unflatten(
        chunk.static_kwargs[0], joined_leaves(chunk.static_kwargs, kwargs_arrays)
    )
    idx = jnp.minimum(start + jnp.arange(chunk.size), math.prod(shape) - 1)
    part = [_take(x, shape, idx) if s else x for x, s in zip(leaves, swept)]
    if chunk.sharding is not None:
        part = [
            jax.lax.with_sharding_constraint(x, chunk.sharding) if s else x
            for x, s in zip(part, swept)
        ]

    def point(batched):
        it = iter(batched)
        # the sweep validated its arrays on the host: no guards (host callbacks) per point
        one = jax.tree.unflatten(treedef, [next(it) if s else x for x, s in zip(part, swept)])
        # the checks of what the function computes (its arguments, a derivative's inputs,
        # throw=True) as values: the chunk has no host callback for them (JAX's persistent
        # cache, and the exported-program cache, store it), and `compute` raises on the host
        with collecting() as checks:
            out = chunk.fn(mark_checked(one), **kwargs)
        return out, checks.failures()

    points = [x for x, s in zip(part, swept) if s]
    if chunk.sharding is None:
        (out, failures), axes = vmap_in_place(point, points)
        axes = axes[: len(jax.tree.leaves(out))]
    else:  # (a sharding over several devices splits the first axis)
        out, failures = jax.vmap(point)(points)
        axes = [0] * len(jax.tree.leaves(out))
    failures = jax.tree.map(jnp.max, failures)  # (the chunk's: a check's code, or -1)
    return _Placed(out, axes, failures)


@functools.cache
def _exported_chunk(options: tuple):
    """`_chunk_program` through the exported-program cache, compiled with XLA's `options`
    (`chunk_options`'s items; not `ONE_CALL`'s: a chunk runs in bulk)."""
    return exported_jit(
        _chunk_program, static_argnums=3, compiler_options=dict(options), one_call=False
    )


class _ChunkFunction:
    """The compiled function of a sweep's chunks, `(model arrays, kwargs arrays, start) ->
    _Placed`, its result placed by `output` (`host_output`'s), compiled with XLA's `options`
    (`chunk_options`'s). Everything else is the chunk's static `_Chunk`: a call is `jax.jit`'s
    dispatch of a few arrays (tens of microseconds less per chunk than sorting a whole model and
    its arguments into static and traced parts). While the exported-program cache is on (the
    `vmj` command), a chunk on one CPU device is stored there: a repeated `vmj sweep` loads its
    executable, untraced."""

    def __init__(self, chunk: _Chunk, output, options: dict):
        self.chunk = chunk
        self.jitted = jax.jit(
            functools.partial(_chunk_program, chunk=chunk),
            out_shardings=output,
            compiler_options=options or None,
        )
        self.exported = None
        if output is None and chunk.sharding is None and exported_cache_directory() is not None:
            self.exported = _exported_chunk(tuple(sorted(options.items())))

    def __call__(self, *args) -> _Placed:
        if self.exported is None:
            return self.jitted(*args)
        return self.exported(*args, self.chunk)

    def lower(self, *args):
        return self.jitted.lower(*args)

    def compile(self, *args):
        if self.exported is None:
            return self.jitted.lower(*args).compile()
        return self.exported.compiled(*args, self.chunk)

    def eval_shape(self, *args) -> _Placed:
        if self.exported is None:
            return jax.eval_shape(self.jitted, *args)
        return self.exported.eval_shape(*args, self.chunk)


def vmap_in_place(fn, args):
    """`(jax.vmap(fn)(args), axes)` with each leaf of the result's points on the axis where its
    computation puts them (`axes`, one per leaf), rather than moved to the front by a
    transpose: a loop's stacked outputs (`lax.scan`) come with the loop's axis first and the
    points after it. Traced once: the batched program (`jax.make_jaxpr`) is evaluated without
    the transposes that `vmap` appended to it. The energy-balance sweep of
    `benchmarks/bench_energy.py` (10^6 points x 12 swings) in turns with the points moved to the
    front, medians of 20 rounds: 54.0 -> 48.4 ms (0.90 x; one 16384-point chunk 1089 -> 956
    us), before its loop went inside a conditional (whose batched results have the points
    first: vmj/_closed_forms/_olshansky.py); the exact sweep of `bench_exact.py`, whose loop
    writes the turning points with the points first: 6.02 -> 6.04 ms (unchanged)."""
    closed, shapes = jax.make_jaxpr(jax.vmap(fn), return_shape=True)(args)
    made = {id(v): eqn for eqn in closed.jaxpr.eqns for v in eqn.outvars}
    outvars, axes = [], []
    for v in closed.jaxpr.outvars:
        eqn = made.get(id(v))
        axis = 0
        if eqn is not None and eqn.primitive.name == "transpose":
            perm = tuple(eqn.params["permutation"])  # vmap's move of axis `perm[0]` to the front
            rest = tuple(range(len(perm)))
            if perm == (perm[0], *rest[: perm[0]], *rest[perm[0] + 1 :]):
                axis, v = perm[0], eqn.invars[0]
        outvars.append(v)
        axes.append(axis)
    program = ClosedJaxpr(closed.jaxpr.replace(outvars=outvars), closed.consts)
    out = jaxpr_as_fun(program)(*jax.tree.leaves(args))
    return jax.tree.unflatten(jax.tree.structure(shapes), out), axes


def point_array(n: int, trailing: tuple, dtype, axis: int) -> np.ndarray:
    """A new `(n, *trailing)` array, a view of memory laid out with the points on `axis` (as a
    chunk's result leaf is), so that a chunk's result is copied in contiguous runs."""
    return np.moveaxis(np.empty((*trailing[:axis], n, *trailing[axis:]), dtype), axis, 0)


class _SweepJob:
    """What evaluating chunks of one sweep needs: picklable (NumPy leaves), so that it is sent
    to the workers of a cluster once; each process puts the model on its device once."""

    def __init__(
        self, fn, kwargs, model, swept, shape, chunk, token, *, devices=None, sharding=None
    ):
        self.fn, self.kwargs, self.swept, self.shape = fn, kwargs, swept, tuple(shape)
        self.model = jax.tree.map(np.asarray, model)
        self.n, self.chunk, self.token = math.prod(shape), chunk, token
        self.devices, self.sharding = devices, sharding
        self._lock = threading.Lock()
        self._on_device = None
        self._known = {}  # chunk size -> what `known` says (the shared entry, or the job's own)
        self._parted = None  # what `_parts` returns, worked out once
        self._functions = {}  # chunk size -> compiled chunk function
        self._output = None  # (host_output's answer,), worked out once

    def __getstate__(self):
        # a worker evaluates on its own default device
        state = dict(
            self.__dict__,
            devices=None,
            sharding=None,
            _on_device=None,
            _known={},
            _parted=None,
            _functions={},
            _output=None,
        )
        del state["_lock"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def _parts(self):
        """(arrays, static part) of the model and of the arguments (`split_arrays`'s)."""
        if self._parted is None:
            self._parted = (*split_arrays(self.model), *split_arrays(self.kwargs))
        return self._parted

    def on_device(self):
        """The model's and the arguments' arrays on the device(s), put there once; on one CPU,
        arrays of `PASSED_BYTES` at most in all are passed to each chunk as they are."""
        if self._on_device is not None:
            return self._on_device
        with self._lock:
            if self._on_device is None:
                devs = self.devices
                place = None
                if devs is not None and len(devs) == 1:
                    place = devs[0]
                elif devs is not None:
                    place = jax.sharding.NamedSharding(
                        self.sharding.mesh, jax.sharding.PartitionSpec()
                    )
                model_leaves, _, kwargs_leaves, _ = self._parts()
                one_cpu = len(devs or ()) == 1 and devs[0].platform == "cpu"
                if one_cpu and sum(x.nbytes for x in model_leaves + kwargs_leaves) <= PASSED_BYTES:
                    self._on_device = (tuple(model_leaves), tuple(kwargs_leaves))
                else:
                    put = lambda xs: tuple(jax.device_put(list(xs), place))  # noqa: E731
                    self._on_device = (put(model_leaves), put(kwargs_leaves))
            return self._on_device

    def output(self):
        """Where the chunks' results are written (`host_output`), worked out once."""
        if self._output is None:
            self._output = (host_output(self.devices, self.sharding),)
        return self._output[0]

    def first(self, c: int) -> int:
        """The first point evaluated by chunk `c` (the last chunk ends at the last point)."""
        return min(c * self.chunk, max(self.n - self.chunk, 0))

    def args(self, start: int):
        """The compiled chunk function's arguments for the chunk starting at point `start`."""
        return (*self.on_device(), np.int64(start))

    def definition(self, chunk: int) -> _Chunk:
        """The static part of the program of chunks of `chunk` points."""
        _, static_model, _, static_kwargs = self._parts()
        return _Chunk(
            self.fn, static_kwargs, static_model, self.swept, self.shape, chunk, self.sharding
        )

    def key(self, chunk: int):
        """What the compiled chunk depends on, hashable (None if it cannot be hashed)."""
        model_leaves, _, kwargs_leaves, _ = self._parts()
        try:
            key = (
                self.definition(chunk),
                tuple((np.shape(x), np.result_type(x).str) for x in model_leaves + kwargs_leaves),
                self.output(),
                bool(jax.config.jax_enable_x64),
                exported_cache_directory(),
            )
            hash(key)
        except TypeError:
            return None
        return key

    def known(self, chunk: int) -> dict:
        """What this process knows of the compiled chunk: its function (`"function"`),
        compiled (`"compiled"`), its memory (`"bytes"`), its result's point axes (`"axes"`)
        and output structure (`"spec"`, the points first): shared by the sweeps of the same
        definition, or this job's own where the definition cannot be hashed."""
        if chunk in self._known:
            return self._known[chunk]
        key = self.key(chunk)
        with _KNOWN_LOCK:
            if key is None:
                return self._known.setdefault(chunk, {})
            entry = _KNOWN.setdefault(key, {})
            _KNOWN.move_to_end(key)
            while len(_KNOWN) > 64:
                _KNOWN.popitem(last=False)
        return self._known.setdefault(chunk, entry)

    def function(self, chunk: int | None = None):
        """The compiled function of chunks of `chunk` points (made once per process for the
        same sweep definition, so that later sweeps reuse its executable; kept by the job too,
        so that a chunk does not look it up under the process's lock)."""
        chunk = chunk or self.chunk
        if chunk in self._functions:
            return self._functions[chunk]
        known = self.known(chunk)
        with _KNOWN_LOCK:
            if "function" not in known:
                known["function"] = _ChunkFunction(
                    self.definition(chunk), self.output(), chunk_options(self.devices)
                )
            self._functions[chunk] = known["function"]
            return known["function"]

    def compile(self, chunk: int | None = None):
        """The compiled chunk (JAX keeps it: later calls with the same shapes reuse it)."""
        compiled = self.function(chunk).compile(*self.args(0))
        self.known(chunk or self.chunk)["compiled"] = True
        return compiled

    def spec(self):
        """The output's structure (leaves with the chunk axis in front), without evaluating."""
        known = self.known(self.chunk)
        if "spec" not in known:
            placed = self.function().eval_shape(*self.args(0))
            leaves, tree = jax.tree.flatten(placed.out)
            known["axes"] = placed.axes
            known["spec"] = jax.tree.unflatten(
                tree,
                [
                    jax.ShapeDtypeStruct((s.shape[a], *s.shape[:a], *s.shape[a + 1 :]), s.dtype)
                    for s, a in zip(leaves, placed.axes)
                ],
            )
        return known["spec"]

    def compute(self, c: int) -> list:
        """The result leaves of the points `c * chunk ... (c + 1) * chunk - 1` of chunk `c`, the
        points on their first axis (views of the chunk's result)."""
        start = self.first(c)
        placed = self.function()(*self.args(start))
        placed.failures.raise_any()
        lo, hi = c * self.chunk, min((c + 1) * self.chunk, self.n)
        return [
            np.moveaxis(np.asarray(g), a, 0)[lo - start : hi - start]
            for g, a in zip(jax.tree.leaves(placed.out), placed.axes)
        ]


def _devices(devices):
    if devices is None:
        devices = jax.local_devices()
    devices = list(devices)
    if not devices:
        raise ValueError("devices must name at least one device")
    return devices


def chunk_plan(n: int, limit: int, lanes: int, multiple: int = 1) -> int:
    """The chunk size for `n` points: at most `limit`, and at least `lanes` chunks of about
    equal size (a multiple of `lanes`), so that every core has work even in a small sweep;
    rounded up to a `multiple` (the number of devices a chunk is sharded over)."""
    k = max(-(-n // limit), min(lanes, n))
    k = -(-k // lanes) * lanes if n >= lanes else k
    chunk = -(-n // k)
    return -(-chunk // multiple) * multiple


def chunk_bytes(job, chunk: int) -> int | None:
    """The memory one compiled chunk of `chunk` points needs (XLA's memory analysis of the
    compiled chunk: temporaries, outputs and arguments), or None if the backend does not say.
    Compiling here also compiles the chunks that follow (JAX caches the executable); the answer
    is remembered for the next sweep of the same function and shapes."""
    known = job.known(chunk)
    if "bytes" not in known:
        compiled = job.compile(chunk)  # a bad argument of fn raises here
        try:
            m = compiled.memory_analysis()
            need = int(m.temp_size_in_bytes + m.output_size_in_bytes + m.argument_size_in_bytes)
        except Exception:
            need = None
        known["bytes"] = need
    return known["bytes"]


def chunk_lanes(devices) -> int:
    """The fewest chunks an in-process sweep on `devices` is split into: one per core on one
    CPU device (each thread runs one), else one (a chunk fills an accelerator, or is sharded
    over the devices)."""
    return CORES if len(devices) == 1 and devices[0].platform == "cpu" else 1


def default_chunk(devices) -> int:
    """The largest chunk at the defaults on `devices` (those of the in-process sweep; None: a
    cluster's workers, planned as CPUs)."""
    if devices and all(d.platform != "cpu" for d in devices):
        return ACCELERATOR_CHUNK * len(devices)
    return DEFAULT_CHUNK


def _sized(job, n, chunk_size, lanes, multiple, memory, concurrent, limit=DEFAULT_CHUNK) -> int:
    """The chunk size: `chunk_size` points at most (default `limit`), `lanes` chunks at
    least, and small enough that `concurrent` chunks side by side need at most
    `MEMORY_FRACTION` of the `memory(enough)` bytes available (`memory`: None where the size is
    not to be checked; `enough`, the bytes that would do). An explicit `chunk_size` is kept
    unless its chunks do not fit in memory at all (refused, with the size that fits); the
    default shrinks."""
    chunk = chunk_plan(n, chunk_size or limit, lanes, multiple)
    need = chunk_bytes(job, chunk) if memory is not None else None
    if need is None:
        return chunk
    memory = memory(need * concurrent / (1.0 if chunk_size is not None else MEMORY_FRACTION))
    if not memory:
        return chunk
    per_point = need / chunk
    if chunk_size is not None:
        if need * concurrent <= memory:
            return chunk
        fits = int(memory / concurrent / per_point)
        raise ValueError(
            f"chunk_size={chunk_size} needs {need / 1e9:.3g} GB of working memory "
            f"per chunk ({per_point / 1e6:.3g} MB per point, {concurrent} chunks "
            f"side by side), more than the {memory / 1e9:.3g} GB available; use "
            f"chunk_size <= {max(fits, 1)}, or leave it at the default, which is "
            f"sized to fit"
        )
    budget = MEMORY_FRACTION * memory
    if need * concurrent <= budget:
        return chunk
    fits = int(budget / concurrent / per_point)
    if fits < multiple:
        raise ValueError(
            f"one point of this sweep needs {per_point / 1e6:.3g} MB of working "
            f"memory, more than the {budget / concurrent / 1e9:.3g} GB available "
            f"to each of its {concurrent} chunks side by side"
        )
    return chunk_plan(n, fits, lanes, multiple)


def _layout(model):
    """(dims, coords, model, shape, is a grid) of a sweep over `model` (a model or a
    `vmj.Grid`)."""
    grid = isinstance(model, Grid)
    if grid:
        dims, coords, model = model.dims, model.coords, model.model
    leaves = jax.tree.leaves(model)
    try:
        shape = tuple(np.broadcast_shapes(*(np.shape(x) for x in leaves if eqx.is_array_like(x))))
    except ValueError as e:
        raise ValueError(f"the model's parameters do not broadcast together: {e}") from None
    if not grid:
        dims = ("point",) if len(shape) == 1 else tuple(f"point_{i}" for i in range(len(shape)))
        coords = {}
        for path, name in named_paths(model):
            value = np.asarray(_get(model, path))
            if value.ndim:
                coords[name] = value
    return tuple(dims), dict(coords), model, shape, grid


def sweep(
    fn: Callable,
    model: eqx.Module | Grid,
    *,
    chunk_size: int | None = None,
    progress: bool | Callable | None = None,
    devices: Sequence[jax.Device] | None = None,
    client=None,
    store=None,
    resume: bool = False,
    **solver_args,
) -> SweepResult:
    """Evaluate `fn(point, **solver_args)` at every point of a sweep over model parameters.

    **Arguments:**

    - `fn`: a function of one model with scalar parameters, e.g. [`vmj.turning_points`][],
      [`vmj.limit_cycle`][], or your own `lambda m: ...`; it returns arrays or a pytree of
      arrays (e.g. a [`vmj.DecaySequence`][]).
    - `model`: a model whose array fields broadcast together as in NumPy (three fields of shape
      `(N,)` are `N` paired points; shapes `(N, 1)` and `(M,)` are an `N x M` product), or a
      [`vmj.Grid`][] from [`vmj.grid`][] (named axes).
    - `chunk_size`: the most points evaluated per compiled call (static). Default: 16384 on
      CPUs, 2^20 per device on accelerators (GPUs), and
      fewer when the compiled chunk would need more than a quarter of the available memory
      (host memory, or the device's) for the chunks evaluated side by side: XLA's memory
      analysis of the compiled chunk decides. A sweep is split into at least one chunk per
      core (per worker thread of a cluster), so that every core has work; the last chunk
      overlaps the one before it. An explicit `chunk_size` whose chunks do not fit in memory
      is refused with the size that fits.
    - `progress`: print chunks done / total, rate and time left to stderr (`True`), or call
      `progress(done, total)` after each chunk; default: print when stderr is a terminal and
      there is more than one chunk.
    - `devices`: devices to shard each chunk over (default: every local device); with several,
      the chunk's batch axis is split across them with `jax.sharding`. In-process only.
    - `client`: evaluate the chunks as tasks of a Dask cluster (needs `pip install
      'vmj[distributed]'`): a `dask.distributed.Client`, a scheduler address
      (`"tcp://host:8786"`), or `"local"` (a `LocalCluster` with one worker process per core
      of this machine, closed at the end). The function, model and arguments are sent to each
      worker once; each worker compiles once. Results are the same, to the last bit, as
      in-process on the same kind of machine.
    - `store`: a path of a Zarr store (`"sweep.zarr"`): every finished chunk is written to it
      as it completes (with a checksum per field and a completion marker), labelled like
      [`vmj.SweepResult.to_xarray`][], and dropped: the result is on disk, not in memory, so
      it may be larger than memory; the `values` returned are lazy (dask) arrays read from the
      store, each chunk checked against its checksums when read (`np.asarray` loads one);
      [`vmj.SweepResult.read_zarr`][] opens it again.
    - `resume`: continue the sweep already in `store`: only the chunks not yet in it (or
      whose data does not match their checksums: every finished chunk is read once, one
      field of one chunk at a time) are computed. The store must hold the same
      sweep (function, model parameters, solver arguments, shape, `chunk_size`); a different
      one is refused. Without `resume=True` an existing store is refused.
    - `**solver_args`: passed to `fn` unchanged at every point (e.g. `a0=0.06, n=12,
      solver=vmj.EnergyBalance()`); they are not swept.

    **Returns:** a [`vmj.SweepResult`][] whose `values` have the sweep's shape in front (NumPy
    arrays; with a `store`, dask arrays read from it); results are the same as calling `fn`
    point by point. Without a store, a result larger than the free memory is refused before
    anything is computed.

    **Raises:** with a `client` or a `store`, a chunk that raises (e.g. `throw=True` and a solve
    failed) does not stop the sweep: the other chunks are evaluated (and stored), and then
    [`vmj.SweepError`][] names the failed chunks and carries the rest of the result. Without
    either, the first failure is raised at once.
    """
    warn_if_float32()
    if chunk_size is not None:
        chunk_size = check_int("chunk_size", chunk_size, 1)
    check_resume(resume, store, "sweep")
    dims, coords, model, shape, is_grid = _layout(model)
    # every point's parameters checked here, once (ValueError naming the field; free for a
    # model checked at its construction); the chunks then trace each point's model as checked
    validated(model)
    n = math.prod(shape)
    leaves, treedef = jax.tree.flatten(model)
    swept = tuple(eqx.is_array_like(x) and np.ndim(x) > 0 for x in leaves)
    if not any(swept):
        raise ValueError(
            f"the {type(model).__name__} given to sweep has no array parameter, so there is "
            f"nothing to sweep: give a vmj.grid (e.g. vmj.grid(model, eps=[0, 0.5, 1])) or "
            f"array parameters (paired points), or call fn(model, ...) for one point"
        )
    model = jax.tree.unflatten(
        treedef, [np.asarray(x) if eqx.is_array_like(x) else x for x in leaves]
    )
    # what the store records and a cluster's workers key their copy on (digests of the model's
    # arrays: computed only when there is a store or a cluster)
    definition = described = None
    token = ""
    if store is not None or client is not None:
        definition, described = _definition(fn, model, solver_args, shape, dims, coords, chunk_size)
        token = digest(definition)

    with cluster(client) as cl:
        if cl is not None:
            if devices is not None:
                raise ValueError(
                    "devices applies to the in-process sweep; a cluster's workers "
                    "each use their own default device"
                )
            devs, nd, sharding = jax.local_devices()[:1], 1, None
            lanes = threads = threads_of(cl)
            # the smallest memory limit of a worker thread (else this machine's); the client
            # compiles a chunk to size it only when no chunk_size is given
            memory = None
            if chunk_size is None:
                per_worker = worker_memory(cl)
                memory = (
                    functools.partial(available_memory, devs[0])
                    if per_worker is None
                    else (lambda enough: per_worker)
                )
            concurrent = 1
        else:
            devs = _devices(devices)
            nd = len(devs)
            sharding = None
            if nd > 1:
                mesh = jax.sharding.Mesh(np.array(devs), ("batch",))
                sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))
            lanes = chunk_lanes(devs)
            threads = CORES if nd == 1 else 1
            memory = functools.partial(available_memory, devs[0])
            concurrent = threads
        job = _SweepJob(
            fn,
            solver_args,
            model,
            swept,
            shape,
            1,
            token,
            devices=devs if cl is None else None,
            sharding=sharding,
        )

        st = None
        if store is not None:
            st = ChunkStore.existing(
                store, kind="sweep", definition=definition, described=described, resume=resume
            )
        if st is not None:
            job.chunk = int(st.meta["chunk"])
        else:
            limit = default_chunk(devs if cl is None else None)
            job.chunk = _sized(job, n, chunk_size, lanes, nd, memory, concurrent, limit)
        chunk = job.chunk
        n_chunks = -(-n // chunk)

        # the output's structure, without evaluating anything
        spec = job.spec()
        spec_leaves, out_def = jax.tree.flatten(spec)
        # (worked out when asked for: 0.2-1 ms, the Python attribute lookups of equinox modules
        # and the repr of a solver object, against a warm 35-point sweep's few ms)
        provenance = functools.cache(
            functools.partial(_provenance, fn, model, solver_args, spec, set(coords) | set(dims))
        )
        axes = job.known(chunk)["axes"]
        per_point = sum(math.prod(s.shape[1:]) * np.dtype(s.dtype).itemsize for s in spec_leaves)
        names = None  # (the fields' names in a store)
        if store is None:  # the result held in this process's memory, whole
            check_room(
                f"the sweep's result, {n} points x {per_point} bytes",
                n * per_point,
                "sweep fewer points, only the fields you need (fn=lambda m, a0, n: "
                "vmj.turning_points(m, a0, n).stop_time is 8 bytes per point), or give "
                "store= (the result is then written to disk chunk by chunk and read from it)",
                jax.devices("cpu")[0],
            )
            out = [point_array(n, s.shape[1:], s.dtype, a) for s, a in zip(spec_leaves, axes)]
        else:  # each finished chunk written to the store and dropped
            names, kdims, kcoords = export_names(
                spec, 1, set(coords) | set(dims) | {"point", "vmj_status", "vmj_checksum"}
            )
            if st is None:  # (a new store: its plan)
                plan = {
                    "n": n,
                    "chunk": chunk,
                    "n_chunks": n_chunks,
                    "dims": list(dims),
                    "shape": list(shape),
                    "grid": is_grid,
                    "fields": [
                        [nm, np.dtype(s.dtype).str, list(s.shape[1:])]
                        for nm, s in zip(names, spec_leaves)
                    ],
                    "coords": list(coords),
                    "attrs": provenance(),
                }
                st = ChunkStore.create(
                    store, kind="sweep", definition=definition, described=described, plan=plan
                )
            # (also those of a resumed store whose creation was interrupted before them)
            st.create_sweep_arrays(
                [(nm, s.dtype, s.shape[1:], kd) for nm, s, kd in zip(names, spec_leaves, kdims)],
                coords,
                is_grid,
                kcoords,
                provenance()["units"],
            )

        def rows(c):
            return slice(c * chunk, min((c + 1) * chunk, n))

        def sink(c, got):
            if st is not None:
                st.write(c, got, names)
            else:
                for o, g in zip(out, got):
                    o[rows(c)] = g

        # (a resumed store's chunks are each read once, to check them against their checksum)
        todo = st.remaining(names) if st is not None and resume else list(range(n_chunks))
        resumed = n_chunks - len(todo)

        failures = {}

        def fail(c, exc):
            message = failure_message(exc)
            code = RESULTS.messages.index(message) if message in RESULTS.messages else -1
            r = rows(c)
            failures[c] = (r.start, r.stop - 1, code, message)
            if st is not None:
                st.fail(c, code, message, names)

        if cl is None and todo:
            if not job.known(chunk).get("compiled"):
                job.compile()  # here, once, before the threads share the executable
            # the model on the device here, once: put by the first thread, it held up the
            # others (4096 points of exact turning points on two threads: the second chunk
            # began 1.1-1.5 ms after the first, now 0.1-0.2 ms)
            job.on_device()
        show = progress if progress is not None else (sys.stderr.isatty() and n_chunks > 1)
        bar = Progress(n_chunks, n, show, already=resumed)
        run_chunks(
            job,
            todo,
            sink=sink,
            progress=bar,
            client=cl,
            threads=threads,
            fail=fail if (cl is not None or st is not None) else None,
            sink_in_thread=cl is None and st is None,
            store=st,
        )

    if st is not None:  # read from the store, lazily
        values = jax.tree.unflatten(out_def, st.lazy(names))
    else:
        for c in failures:
            for o in out:
                o[rows(c)] = np.nan if o.dtype.kind in "fc" else 0
        values = jax.tree.unflatten(out_def, [o.reshape(shape + o.shape[1:]) for o in out])
    result = SweepResult(
        values,
        tuple(dims),
        dict(coords),
        shape,
        nd,
        n_chunks,
        computed=len(todo) - len(failures),
        resumed=resumed,
        _attrs=provenance,
    )
    if failures:
        lo, hi, code, message = failures[min(failures)]
        text = (
            f"{len(failures)} of {n_chunks} chunks failed (the first: points {lo} to {hi}: "
            f"{message})"
        )
        if st is not None:
            text += (
                f"; the other chunks are in the store {st.path!r}: rerun with resume=True "
                f"to compute only the failed ones"
            )
        raise SweepError(text, failures, result)
    return result


def _definition(fn, model, solver_args, shape, dims, coords, chunk_size):
    """The definition of a sweep (digests) and the same in words, for the store's refusals."""
    definition = {
        "fn": digest(fn),
        "model": digest(model),
        "solver_args": digest(solver_args),
        "shape": list(shape),
        "dims": list(dims),
        "coords": digest(coords),
        "chunk_size": chunk_size,
        "vmj": __version__,
        "jax": jax.__version__,
        "x64": bool(jax.config.jax_enable_x64),
    }
    described = {
        "fn": f"{describe_fn(fn)} (code {definition['fn'][:8]})",
        # the model's kind and static parts here, each parameter below: a refusal names the
        # parameter that differs
        "model": f"{type(model).__name__} ({digest(str(jax.tree.structure(model)))[:8]})",
        **{
            f"parameter {name}": _describe_value(_get(model, path))
            for path, name in named_paths(model)
        },
        "solver arguments": f"{_describe_args(solver_args)} ({definition['solver_args'][:8]})",
        "shape": " x ".join(f"{d} {s}" for d, s in zip(dims, shape)) or "()",
        "chunk_size": "default" if chunk_size is None else str(chunk_size),
        "versions": f"vmj {definition['vmj']}, jax {definition['jax']}",
        "float64": str(definition["x64"]),
    }
    return definition, described


def _provenance(fn, model, solver_args, spec, taken) -> dict:
    """What produced a sweep, for its exports' attributes: the model's kind and laws, the
    function, the solver arguments, the fixed parameters, vmj's version, and `"units"`: the
    unit of each swept parameter (where the model declares one in its limits) and of each field
    of the result (`spec`, its output's structure) whose type declares one (`field_units`),
    by its name in the exports (`export_names`, the coordinates' names `taken`)."""
    units, fixed = {}, []
    for path, name in named_paths(model):
        owner = _get(model, path[:-1])
        unit = _unit(getattr(type(owner), "_limits", {}).get(path[-1]))
        value = np.asarray(_get(model, path))
        if value.ndim == 0:
            shown = f" {unit}" if unit and unit != "1" else ""  # (a number: eps=0)
            fixed.append(f"{name}={_number(value.item())}{shown}")
        elif unit:
            units[name] = unit
    names = export_names(spec, 1, taken)[0]
    for name, unit in zip(names, _field_units(spec, model)):
        if unit:
            units[name] = unit
    return {
        "model": _describe_model(model),
        "function": describe_fn(fn),
        "solver_arguments": _describe_args(solver_args),
        "fixed_parameters": ", ".join(fixed) or "none",
        "vmj_version": __version__,
        "units": units,
    }


def _field_units(spec, model) -> list:
    """The unit of each leaf of a result `spec` (None where none is declared): a field of a
    solution type by its `field_units(model)`, a parameter of a model or law (a result that
    carries its model) by its limits."""
    out = []
    for path, _ in jax.tree_util.tree_flatten_with_path(spec)[0]:
        node, unit = spec, None
        for key in path[:-1]:
            node = _child(node, key)
        last = getattr(path[-1], "name", None) if path else None
        if last is not None and hasattr(type(node), "field_units"):
            unit = type(node).field_units(model).get(last)
        elif last is not None:
            unit = _unit(getattr(type(node), "_limits", {}).get(last))
        out.append(unit)
    return out


def _child(node, key):
    """The child of a pytree `node` at one key of a key path."""
    if hasattr(key, "name"):
        return getattr(node, key.name)
    if hasattr(key, "key"):
        return node[key.key]
    return node[key.idx]


def _unit(limit) -> str | None:
    """The unit in a field's allowed range (`"> 0 [kg]"`: kg; `[-]`: 1, dimensionless); None
    where it names none, or only the model's position unit."""
    if limit is None:
        return None
    hit = re.search(r"\[([^\]]*)\]\s*$", limit[1])
    if hit is None or "," in hit.group(1) or "position unit" in hit.group(1):
        return None
    return "1" if hit.group(1) == "-" else hit.group(1)


def _describe_model(model) -> str:
    """A model's kind and the kinds of its laws: `VariableMass(friction=Coulomb)`."""

    def kind(v):
        if isinstance(v, (tuple, list)):
            inner = [kind(x) for x in v]
            return None if None in inner else "(" + ", ".join(inner) + ")"
        return type(v).__name__ if isinstance(v, eqx.Module) else None

    laws = []
    for f in dataclasses.fields(model):
        k = kind(getattr(model, f.name, None))
        if k is not None:
            laws.append(f"{f.name}={k}")
    return f"{type(model).__name__}({', '.join(laws)})"


def _number(x) -> str:
    """`x` in the fewest digits that give it back exactly (`5`, `14.7`, `0.1`)."""
    text = f"{x:.15g}"
    return text if float(text) == x else repr(x)


def _describe_value(value) -> str:
    """A parameter in words: a scalar exactly, an array by its size, range and digest."""
    a = np.asarray(value)
    if a.ndim == 0:
        return _number(a.item())
    return f"{a.size} values in [{np.nanmin(a):.6g}, {np.nanmax(a):.6g}] ({digest(a)[:8]})"


def _describe_args(args: dict) -> str:
    def short(v):
        text = repr(v)
        return text if len(text) <= 40 else type(v).__name__

    return ", ".join(f"{k}={short(v)}" for k, v in sorted(args.items())) or "none"
