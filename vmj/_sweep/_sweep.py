"""Sweeps: evaluate a solution at every point of a model's array-valued parameters.

`sweep(fn, model, **solver_args)` broadcasts the model's array fields together as NumPy does,
evaluates `fn(point_model, **solver_args)` at every point with `jax.vmap`, in chunks of a fixed
size (one compilation, bounded memory), sharded across the local devices when there are several,
and returns a [`vmj.SweepResult`][] whose fields carry the batch shape in front. `grid(model,
eps=..., mu=...)` builds outer products with named axes. Nothing here knows about a particular
model: any `equinox.Module` whose parameters are array fields works.
"""

from __future__ import annotations

import concurrent.futures
import math
import os
import sys
import time
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import numpy as np

from .._checks import check_int, warn_if_float32
from ._grid import Grid
from ._result import SweepResult
from ._tree import _field_paths, _get, _short_name

__all__ = ["sweep"]


class _Progress:
    def __init__(self, total: int, enabled: bool, stream=None):
        self.total, self.enabled, self.stream = total, enabled, stream or sys.stderr
        self.start = time.perf_counter()
        self.done = 0

    def update(self, k: int = 1) -> None:
        self.done += k
        if not self.enabled:
            return
        frac = self.done / self.total
        bar = "#" * int(30 * frac)
        elapsed = time.perf_counter() - self.start
        self.stream.write(f"\rsweep [{bar:<30}] {self.done}/{self.total} chunks {elapsed:6.1f} s")
        if self.done == self.total:
            self.stream.write("\n")
        self.stream.flush()


#: threads evaluating chunks on a single device
_CORES = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


@eqx.filter_jit
def _evaluate(fn, kwargs, model, swept, start, size, sharding):
    """`fn` at the points `start ... start + size` of a model whose swept leaves (flags in
    `swept`) are flat arrays over the whole sweep, already on the device(s)."""
    leaves, treedef = jax.tree.flatten(model)
    part = [jax.lax.dynamic_slice_in_dim(x, start, size) if s else x
            for x, s in zip(leaves, swept)]
    if sharding is not None:
        part = [jax.lax.with_sharding_constraint(x, sharding) if s else x
                for x, s in zip(part, swept)]

    def point(batched):
        it = iter(batched)
        return fn(jax.tree.unflatten(treedef, [next(it) if s else x for x, s in
                                               zip(part, swept)]), **kwargs)

    return jax.vmap(point)([x for x, s in zip(part, swept) if s])


def _devices(devices):
    if devices is None:
        devices = jax.local_devices()
    devices = list(devices)
    if not devices:
        raise ValueError("devices must name at least one device")
    return devices


def sweep(
    fn: Callable,
    model: eqx.Module | Grid,
    *,
    chunk_size: int = 16384,
    progress: bool | None = None,
    devices: Sequence[jax.Device] | None = None,
    **solver_args,
) -> SweepResult:
    """Evaluate `fn(point, **solver_args)` at every point of a sweep over model parameters.

    **Arguments:**

    - `fn`: a function of one model with scalar parameters, e.g. [`vmj.turning_points`][],
      [`vmj.energy_balance`][], or your own `lambda m: ...`; it returns arrays or a pytree of
      arrays (e.g. a [`vmj.DecaySequence`][]).
    - `model`: a model whose array fields broadcast together as in NumPy (three fields of shape
      `(N,)` are `N` paired points; shapes `(N, 1)` and `(M,)` are an `N x M` product), or a
      [`vmj.Grid`][] from [`vmj.grid`][] (named axes).
    - `chunk_size`: points evaluated per compiled call (static; the last chunk overlaps the one
      before it, and a sweep smaller than one chunk is padded, so there is one compilation).
      Working memory is proportional to it (times the number of cores, whose threads evaluate
      chunks side by side); the swept parameters themselves (8 bytes per point each) are put on
      the device once.
    - `progress`: print a progress bar to stderr; default: when stderr is a terminal and there is
      more than one chunk.
    - `devices`: devices to shard each chunk over (default: every local device); with several,
      the chunk's batch axis is split across them with `jax.sharding`.
    - `**solver_args`: passed to `fn` unchanged at every point (e.g. `a0=0.06, n=12,
      method="exact"`); they are not swept.

    **Returns:** a [`vmj.SweepResult`][] whose `values` have the sweep's shape in front; results
    are the same as calling `fn` point by point.
    """
    warn_if_float32()
    chunk_size = check_int("chunk_size", chunk_size, 1)
    if isinstance(model, Grid):
        dims, coords, model = model.dims, model.coords, model.model
    else:
        dims = coords = None
    leaves, treedef = jax.tree.flatten(model)
    try:
        shape = tuple(np.broadcast_shapes(*(np.shape(x) for x in leaves
                                            if eqx.is_array_like(x))))
    except ValueError as e:
        raise ValueError(f"the model's parameters do not broadcast together: {e}") from None
    if dims is None:
        dims = ("point",) if len(shape) == 1 else tuple(f"point_{i}" for i in range(len(shape)))
        coords = {}
        paths = _field_paths(model)
        for path in paths:
            value = np.asarray(_get(model, path))
            if value.ndim:
                coords[_short_name(paths, path)] = value
    n = math.prod(shape)
    devs = _devices(devices)
    nd = len(devs)
    chunk = min(chunk_size, n)
    chunk = -(-chunk // nd) * nd
    n_chunks = -(-n // chunk)
    sharding = None
    if nd > 1:
        mesh = jax.sharding.Mesh(np.array(devs), ("batch",))
        sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))
    # the swept parameters flattened once (C order) and put on the device(s) once; the compiled
    # chunk slices them (no copy per chunk). The last chunk ends at the last point and overlaps
    # the one before it; only a sweep smaller than one chunk is padded (with its last point).
    swept = tuple(eqx.is_array_like(x) and np.ndim(x) > 0 for x in leaves)
    size = max(n, chunk)
    place = devs[0] if nd == 1 else jax.sharding.NamedSharding(
        mesh, jax.sharding.PartitionSpec())
    on_device = []
    for x, s in zip(leaves, swept):
        if s:
            f = np.broadcast_to(np.asarray(x), shape).reshape(n)
            if size > n:
                f = np.concatenate([f, np.repeat(f[-1:], size - n)])
            x = jax.device_put(f, place)
        elif eqx.is_array_like(x):
            x = jax.device_put(np.asarray(x), place)
        on_device.append(x)
    model = jax.tree.unflatten(treedef, on_device)

    def first(c):  # the first point evaluated by chunk c
        return min(c * chunk, size - chunk)

    def evaluate(c):
        start = np.asarray(first(c), dtype=np.int64)
        return jax.tree.flatten(_evaluate(fn, solver_args, model, swept, start, chunk, sharding))

    def store(c, got_leaves):
        lo, stop = c * chunk, min((c + 1) * chunk, n)
        for o, g in zip(out_leaves, got_leaves):
            o[lo:stop] = np.asarray(g)[lo - first(c):stop - first(c)]

    show = progress if progress is not None else (sys.stderr.isatty() and n_chunks > 1)
    bar = _Progress(n_chunks, bool(show))
    got_leaves, out_def = evaluate(0)  # compiles; fixes the output structure
    out_leaves = [np.empty((n,) + g.shape[1:], dtype=g.dtype) for g in got_leaves]
    store(0, got_leaves)
    bar.update()
    # A compiled chunk runs synchronously (its runtime checks call back to the host), so on a
    # single device the chunks run in threads, one per core; results go straight into place.
    workers = max(1, min(_CORES, n_chunks - 1)) if nd == 1 else 1
    with concurrent.futures.ThreadPoolExecutor(workers) as pool:
        jobs = [pool.submit(lambda c: store(c, evaluate(c)[0]), c) for c in range(1, n_chunks)]
        for job in concurrent.futures.as_completed(jobs):
            job.result()
            bar.update()
    values = jax.tree.unflatten(out_def, [o.reshape(shape + o.shape[1:]) for o in out_leaves])
    return SweepResult(values, tuple(dims), dict(coords), shape, nd, n_chunks)
