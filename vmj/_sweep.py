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
import csv
import dataclasses
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import equinox as eqx
import jax
import numpy as np

from ._checks import check_int, warn_if_float32
from ._models import _float, validated

__all__ = ["Grid", "SweepResult", "grid", "sweep", "resolve_field"]


# -- naming the parameters of a model -----------------------------------------------------------
def _field_paths(model, prefix=()):
    """Paths (tuples of attribute names) to every array field of a module tree."""
    out = []
    if isinstance(model, eqx.Module):
        for name in (f.name for f in dataclasses.fields(model)):
            out += _field_paths(getattr(model, name), prefix + (name,))
    elif eqx.is_array_like(model) and not isinstance(model, (str, bytes)):
        out.append(prefix)
    return out


def resolve_field(model, name: str) -> tuple[str, ...]:
    """The path of the array field `name` of `model`: a field name (`"eps"`), unique among the
    nested modules (`"F"` is `friction.F`), or a dotted path (`"friction.F"`)."""
    paths = _field_paths(model)
    want = tuple(name.split("."))
    hits = [p for p in paths if p[-len(want):] == want]
    if len(hits) != 1:
        known = ", ".join(sorted(".".join(p) for p in paths))
        why = "is ambiguous" if hits else "is not a parameter"
        raise ValueError(f"{name!r} {why} of {type(model).__name__} (parameters: {known})")
    return hits[0]


def _short_name(paths, path) -> str:
    """The shortest dotted suffix of `path` that names it uniquely among `paths`."""
    for k in range(1, len(path) + 1):
        if sum(p[-k:] == path[-k:] for p in paths) == 1:
            return ".".join(path[-k:])
    return ".".join(path)


def _get(model, path):
    for p in path:
        model = getattr(model, p)
    return model


def _set_fields(model, paths, values):
    """Replace the fields at `paths` by float arrays and re-validate (ValueError on bad values)."""
    values = [_float(v) for v in values]
    model = eqx.tree_at(lambda m: [_get(m, p) for p in paths], model, values)
    return validated(model)


# -- grids ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Grid:
    """An outer product of parameter axes, made by [`vmj.grid`][].

    **Fields:** `model` (its swept fields shaped for broadcasting: axis `i` has shape
    `(1, ..., n_i, ..., 1)`), `dims` (the axis names, e.g. `("eps", "mu", "delta")`), `coords`
    (the axis values, one 1-D array per name).
    """

    model: Any
    dims: tuple
    coords: dict


def grid(model, **axes) -> Grid:
    """Outer product of parameter axes, e.g. `vmj.grid(model, eps=np.linspace(0, 1, 11), mu=...)`.

    **Arguments:**

    - `model`: a model with scalar parameters (e.g. [`vmj.VariableMass`][]); its other fields
      stay fixed.
    - `**axes`: parameter name (a field name such as `eps`, `F` for `friction.F`, or a dotted
      path) to a 1-D sequence of values in the parameter's unit. The order of the keywords is the
      order of the axes.

    **Returns:** a [`vmj.Grid`][] for [`vmj.sweep`][]; the result's axes are named after the
    keywords.
    """
    if not axes:
        raise ValueError("grid needs at least one axis, e.g. grid(model, eps=[0, 0.5, 1])")
    for leaf in jax.tree.leaves(model):
        if np.ndim(leaf) != 0:
            raise ValueError("grid takes a model with scalar parameters; the swept ones are the "
                             "keyword axes")
    names = list(axes)
    paths = [resolve_field(model, n) for n in names]
    if len(set(paths)) != len(paths):
        raise ValueError("each parameter may be given once in grid")
    coords, shaped = {}, []
    for i, (name, values) in enumerate(axes.items()):
        arr = np.asarray(values, dtype=float)
        if arr.ndim != 1 or arr.size == 0:
            raise ValueError(f"grid axis {name} must be a non-empty 1-D sequence (got shape "
                             f"{arr.shape})")
        _set_fields(model, [paths[i]], [arr])  # ValueError naming the parameter and range
        coords[name] = arr
        shape = [1] * len(names)
        shape[i] = arr.size
        shaped.append(arr.reshape(shape))
    return Grid(_set_fields(model, paths, shaped), tuple(names), coords)


# -- results --------------------------------------------------------------------------------------
def _leaf_names(tree) -> list[str]:
    def name(path):
        parts = []
        for k in path:
            parts.append(str(getattr(k, "name", getattr(k, "key", getattr(k, "idx", k)))))
        return ".".join(parts) or "value"

    return [name(p) for p, _ in jax.tree_util.tree_flatten_with_path(tree)[0]]


@dataclass(frozen=True)
class SweepResult:
    """Values of a solution over a sweep, with named axes.

    **Fields:**

    - `values`: what the swept function returns (e.g. a [`vmj.DecaySequence`][]), with NumPy
      leaves whose leading axes are the sweep's `shape` (e.g. `values.positions[i, j, l, k]`).
    - `dims`: the names of the leading axes (`("eps", "mu", "delta")` for a grid, `("point",)`
      for paired points).
    - `coords`: parameter values: for a grid one 1-D array per axis; for paired points every
      swept parameter broadcast to `shape`.
    - `shape`: the sweep's shape (the broadcast shape of the model's parameters).
    - `devices`: number of devices the evaluation was sharded over.
    """

    values: Any
    dims: tuple
    coords: dict
    shape: tuple
    devices: int = 1
    chunks: int = field(default=1, compare=False)

    def columns(self) -> dict[str, np.ndarray]:
        """Flat columns, one row per point (C order): the parameters, then every field of
        `values`; a field with inner axes gives one column per entry, `name_1 ... name_n`
        (1-based, as the turning points k)."""
        n = math.prod(self.shape)
        cols = {}
        if self._is_grid:
            mesh = np.meshgrid(*(self.coords[d] for d in self.dims), indexing="ij")
            for d, g in zip(self.dims, mesh):
                cols[d] = g.reshape(n)
        else:
            for name, c in self.coords.items():
                cols[name] = np.broadcast_to(c, self.shape).reshape(n)
        for name, leaf in zip(_leaf_names(self.values), jax.tree.leaves(self.values)):
            leaf = np.asarray(leaf).reshape((n,) + np.shape(leaf)[len(self.shape):])
            if leaf.ndim == 1:
                cols[name] = leaf
            else:
                for idx in np.ndindex(*leaf.shape[1:]):
                    cols[name + "".join(f"_{i + 1}" for i in idx)] = leaf[(slice(None),) + idx]
        return cols

    @property
    def _is_grid(self) -> bool:
        return all(d in self.coords and np.ndim(self.coords[d]) == 1 for d in self.dims) and \
            tuple(len(self.coords[d]) for d in self.dims) == tuple(self.shape)

    def to_csv(self, path: str) -> None:
        """Write the `columns()` to `path`; a first comment line records the axes, so that
        [`vmj.SweepResult.read_csv`][] restores the result's shape. Floats are written with 17
        significant digits (exact round trip)."""
        cols = self.columns()
        leaves = dict(zip(_leaf_names(self.values), jax.tree.leaves(self.values)))
        meta = {
            "dims": list(self.dims),
            "shape": list(self.shape),
            "grid": self._is_grid,
            "fields": {k: [str(np.asarray(v).dtype), list(np.shape(v)[len(self.shape):])]
                       for k, v in leaves.items()},
            "coords": [k for k in self.coords],
        }
        header = list(cols)
        data = [np.asarray(c) for c in cols.values()]
        fmts = ["%d" if c.dtype.kind in "biu" else "%.17g" for c in data]
        table = np.empty((len(data[0]), len(data)), dtype=object)
        for j, c in enumerate(data):
            table[:, j] = c.astype(np.int64) if c.dtype.kind == "b" else c
        with open(path, "w", newline="") as fh:
            fh.write("# vmj-sweep " + json.dumps(meta) + "\n")
            fh.write(",".join(header) + "\n")
            np.savetxt(fh, table, fmt=fmts, delimiter=",")

    @staticmethod
    def read_csv(path: str) -> "SweepResult":
        """Read a file written by `to_csv`; `values` becomes a dict of field name to array."""
        with open(path, newline="") as fh:
            first = fh.readline()
            if not first.startswith("# vmj-sweep "):
                raise ValueError(f"{path} is not a CSV written by vmj.SweepResult.to_csv")
            meta = json.loads(first[len("# vmj-sweep "):])
            reader = csv.reader(fh)
            header = next(reader)
            raw = np.array([row for row in reader], dtype=object).reshape(-1, len(header))
        col = {h: raw[:, j] for j, h in enumerate(header)}
        shape = tuple(meta["shape"])
        if meta["grid"]:
            coords = {}
            for i, d in enumerate(meta["dims"]):
                full = col[d].astype(float).reshape(shape)
                coords[d] = full[tuple(slice(None) if k == i else 0 for k in range(len(shape)))]
        else:
            coords = {k: col[k].astype(float).reshape(shape) for k in meta["coords"]}
        values = {}
        for name, (dtype, inner) in meta["fields"].items():
            kind = np.dtype(dtype)
            if inner:
                keys = [name + "".join(f"_{i + 1}" for i in idx) for idx in np.ndindex(*inner)]
                flat = np.stack([col[k] for k in keys], axis=-1)
            else:
                flat = col[name]
            conv = flat.astype(np.int64).astype(kind) if kind.kind in "biu" else \
                flat.astype(float).astype(kind)
            values[name] = conv.reshape(shape + tuple(inner))
        return SweepResult(values, tuple(meta["dims"]), coords, shape)

    def to_xarray(self):
        """An `xarray.Dataset` with one variable per field of `values` (needs the optional
        extra: `pip install 'vmj[xarray]'`). Inner axes are named `k` (1-based, the turning
        point index) when all fields agree on their length, else `NAME_k`."""
        try:
            import xarray as xr
        except ImportError:  # pragma: no cover - exercised only without the extra
            raise ImportError("SweepResult.to_xarray needs xarray: pip install 'vmj[xarray]'") \
                from None
        names = _leaf_names(self.values)
        leaves = [np.asarray(v) for v in jax.tree.leaves(self.values)]
        inner_lengths = {v.shape[len(self.shape)] for v in leaves if v.ndim > len(self.shape)}
        shared_k = len(inner_lengths) == 1
        data_vars, extra_coords = {}, {}
        for name, v in zip(names, leaves):
            inner = v.ndim - len(self.shape)
            kdims = []
            for j in range(inner):
                kd = ("k" if shared_k else f"{name}_k") + (f"{j}" if j else "")
                kdims.append(kd)
                extra_coords[kd] = np.arange(1, v.shape[len(self.shape) + j] + 1)
            data_vars[name.replace(".", "_")] = (tuple(self.dims) + tuple(kdims), v)
        if self._is_grid:
            coords = {d: self.coords[d] for d in self.dims}
        else:
            coords = {k: (tuple(self.dims), np.broadcast_to(c, self.shape))
                      for k, c in self.coords.items()}
        return xr.Dataset(data_vars, coords={**coords, **extra_coords})

    def to_netcdf(self, path: str) -> None:
        """Write `to_xarray()` to a NetCDF file (needs the optional extra `vmj[xarray]`)."""
        self.to_xarray().to_netcdf(path)


# -- evaluation -----------------------------------------------------------------------------------
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
    model,
    *,
    chunk_size: int = 16384,
    progress: bool | None = None,
    devices=None,
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
