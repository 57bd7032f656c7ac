"""The result of a sweep with named axes, and its export (CSV, xarray, NetCDF)."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from typing import Any

import jax
import numpy as np

from .._checks import check_room
from .._files import replacing

__all__ = ["SweepResult"]

#: points written per block by `SweepResult.to_csv`
CSV_ROWS = 1 << 16


def _lazy(x) -> bool:
    """Whether `x` is a lazy array (dask's, as a sweep with a store returns): computed when
    asked, and read part by part."""
    return hasattr(x, "dask") and hasattr(x, "compute")


def _loaded(leaf):
    """`leaf` in memory: a lazy one read block by block into one array (never its blocks and
    their concatenation side by side, as `np.asarray` holds them)."""
    if not _lazy(leaf):
        return leaf
    out = np.empty(leaf.shape, leaf.dtype)
    leaf.store(out, lock=False)
    return out


def _leaf_names(tree) -> list[str]:
    def name(path):
        parts = []
        for k in path:
            parts.append(str(getattr(k, "name", getattr(k, "key", getattr(k, "idx", k)))))
        return ".".join(parts) or "value"

    return [name(p) for p, _ in jax.tree_util.tree_flatten_with_path(tree)[0]]


def export_names(values, lead: int, taken=()):
    """Names for the fields of `values` (leaves with `lead` leading sweep axes) in an export:
    `(names, inner dims per field, inner coordinates)`. A field's name is its path with `_`
    for `.` (and `_value` after it where it would be one of the names `taken` by the
    coordinates); inner axes are named `k` (1-based, the turning point index) when all fields
    agree on their length, else `NAME_k`."""
    names = _leaf_names(values)
    shapes = [tuple(np.shape(v)) for v in jax.tree.leaves(values)]
    shared_k = len({s[lead] for s in shapes if len(s) > lead}) == 1
    out, dims, coords = [], [], {}
    for name, s in zip(names, shapes):
        kdims = []
        for j in range(len(s) - lead):
            kd = ("k" if shared_k else f"{name}_k") + (f"{j}" if j else "")
            kdims.append(kd)
            coords[kd] = np.arange(1, s[lead + j] + 1)
        name = name.replace(".", "_")
        out.append(name + "_value" if name in taken else name)
        dims.append(tuple(kdims))
    return out, dims, coords


@dataclass(frozen=True)
class SweepResult:
    """Values of a solution over a sweep, with named axes.

    **Fields:**

    - `values`: what the swept function returns (e.g. a [`vmj.DecaySequence`][]), with NumPy
      leaves whose leading axes are the sweep's `shape` (e.g. `values.positions[i, j, l, k]`).
      A leaf that the function computes with the points on another axis (a loop's stacked
      output, such as the 12 turning points of the energy balance) is a view of memory laid
      out that way, as NumPy's `.T` is (`np.ascontiguousarray` gives a C-ordered copy). A
      sweep with a store (and `read_zarr`) gives dask arrays read lazily from the store instead:
      `np.asarray` loads one, `.compute()` a part or a reduction of one.
    - `dims`: the names of the leading axes (`("eps", "mu", "delta")` for a grid, `("point",)`
      for paired points).
    - `coords`: parameter values: for a grid one 1-D array per axis; for paired points every
      swept parameter broadcast to `shape`.
    - `shape`: the sweep's shape (the broadcast shape of the model's parameters).
    - `devices`: number of devices the evaluation was sharded over.
    - `chunks`: number of chunks the points were evaluated in; `computed` of them in this call,
      `resumed` read back from a store.
    - `attrs`: what produced it (strings: `model`, e.g. `VariableMass(friction=Coulomb)`,
      `function`, `solver_arguments`, `fixed_parameters` with their units, `vmj_version`), and
      `units`: the unit of each swept parameter that the model declares (`{"mu": "kg/s", "eps":
      "1"}`) and of each field whose type declares one (`{"times": "s", "positions": "m"}`);
      the exports carry them (xarray's and NetCDF's attributes, each variable's `units`).
    """

    values: Any
    dims: tuple
    coords: dict
    shape: tuple
    devices: int = 1
    chunks: int = field(default=1, compare=False)
    computed: int = field(default=0, compare=False)
    resumed: int = field(default=0, compare=False)
    #: `attrs`, or the function that makes them when first asked for
    _attrs: Any = field(default_factory=dict, compare=False, repr=False)

    @property
    def attrs(self) -> dict:
        if callable(self._attrs):
            object.__setattr__(self, "_attrs", self._attrs())
        return self._attrs

    def __getstate__(self):  # (pickled with its attrs made: the function may be a lambda)
        return {**self.__dict__, "_attrs": self.attrs}

    def columns(self) -> dict[str, np.ndarray]:
        """Flat columns, one row per point (C order): the parameters, then every field of
        `values`; a field with inner axes gives one column per entry, `name_1 ... name_n`
        (1-based, as the turning points k). Loads the whole result: lazy values (read from a
        store) are read chunk by chunk into their columns. Where the columns need more than
        the free memory, they are refused before anything is read, with their size (see
        `to_csv`, which writes them block by block, or compute a part or a reduction of
        `values`)."""
        n = math.prod(self.shape)
        index = 8 * (len(self.shape) + 1)  # (np.unravel_index of np.arange(n))
        params = sum(
            np.asarray(self.coords[k]).dtype.itemsize
            for k in (self.dims if self._is_grid else self.coords)
        )
        # the fields' bytes made anew: lazy ones read, in-memory ones copied where their
        # points are not laid out in C order
        fields = sum(
            leaf.nbytes // n
            for leaf in jax.tree.leaves(self.values)
            if _lazy(leaf) or not np.asarray(leaf).flags.c_contiguous
        )
        check_room(
            f"SweepResult.columns() of {n} points x {index + params + fields} bytes",
            n * (index + params + fields),
            "write them to a file block by block with to_csv(path), or compute only what you "
            "need from values (lazy with a store: values['count'].sum().compute(), "
            "values['positions'][..., 0].compute())",
            jax.devices("cpu")[0],
        )
        return self._columns(0, n, [(name, _loaded(leaf)) for name, leaf in self._flat()])

    def _flat(self) -> list:
        """`(name, leaf)` for every field, each leaf with its points flattened on the first
        axis (a lazy leaf stays lazy)."""
        n = math.prod(self.shape)
        return [
            (name, leaf.reshape((n,) + tuple(np.shape(leaf)[len(self.shape) :])))
            if _lazy(leaf)
            else (name, np.asarray(leaf).reshape((n,) + np.shape(leaf)[len(self.shape) :]))
            for name, leaf in zip(_leaf_names(self.values), jax.tree.leaves(self.values))
        ]

    def _columns(self, lo: int, hi: int, flat: list) -> dict[str, np.ndarray]:
        """`columns()` of the points `lo ... hi - 1` only, from `_flat()`'s leaves (of a lazy
        result, only those rows are read)."""
        idx = np.unravel_index(np.arange(lo, hi), self.shape)
        cols = {}
        if self._is_grid:
            for i, d in enumerate(self.dims):
                cols[d] = np.asarray(self.coords[d])[idx[i]]
        else:
            for name, c in self.coords.items():
                cols[name] = np.broadcast_to(c, self.shape)[idx]
        for name, leaf in flat:
            leaf = np.asarray(leaf[lo:hi])
            if leaf.ndim == 1:
                cols[name] = leaf
            else:
                for k in np.ndindex(*leaf.shape[1:]):
                    cols[name + "".join(f"_{i + 1}" for i in k)] = leaf[(slice(None),) + k]
        return cols

    @property
    def _is_grid(self) -> bool:
        return all(d in self.coords and np.ndim(self.coords[d]) == 1 for d in self.dims) and tuple(
            len(self.coords[d]) for d in self.dims
        ) == tuple(self.shape)

    def to_csv(self, path: str) -> None:
        """Write the `columns()` to `path`, `CSV_ROWS` points at a time (a result read lazily
        from a store is never loaded whole); a first comment line records the axes, so that
        [`vmj.SweepResult.read_csv`][] restores the result's shape. Floats are written with 17
        significant digits (exact round trip)."""
        leaves = dict(zip(_leaf_names(self.values), jax.tree.leaves(self.values)))
        meta = {
            "dims": list(self.dims),
            "shape": list(self.shape),
            "grid": self._is_grid,
            "fields": {
                k: [str(np.dtype(v.dtype)), list(np.shape(v)[len(self.shape) :])]
                for k, v in leaves.items()
            },
            "coords": [k for k in self.coords],
            "attrs": self.attrs,
        }
        n, flat = math.prod(self.shape), self._flat()
        with replacing(path) as tmp, open(tmp, "w", newline="") as fh:
            fh.write("# vmj-sweep " + json.dumps(meta) + "\n")
            for lo in range(0, max(n, 1), CSV_ROWS):
                cols = self._columns(lo, min(lo + CSV_ROWS, n), flat)
                if lo == 0:
                    fh.write(",".join(cols) + "\n")
                data = list(cols.values())
                fmts = ["%d" if c.dtype.kind in "biu" else "%.17g" for c in data]
                table = np.empty((len(data[0]), len(data)), dtype=object)
                for j, c in enumerate(data):
                    table[:, j] = c.astype(np.int64) if c.dtype.kind == "b" else c
                np.savetxt(fh, table, fmt=fmts, delimiter=",")

    @staticmethod
    def read_csv(path: str) -> SweepResult:
        """Read a file written by `to_csv`; `values` becomes a dict of field name to array."""
        with open(path, newline="") as fh:
            first = fh.readline()
            if not first.startswith("# vmj-sweep "):
                raise ValueError(f"{path} is not a CSV written by vmj.SweepResult.to_csv")
            meta = json.loads(first[len("# vmj-sweep ") :])
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
            conv = (
                flat.astype(np.int64).astype(kind)
                if kind.kind in "biu"
                else flat.astype(float).astype(kind)
            )
            values[name] = conv.reshape(shape + tuple(inner))
        return SweepResult(values, tuple(meta["dims"]), coords, shape, _attrs=meta.get("attrs", {}))

    def to_xarray(self):
        """An `xarray.Dataset` with one variable per field of `values` (needs the optional
        extra: `pip install 'vmj[xarray]'`). Inner axes are named `k` (1-based, the turning
        point index) when all fields agree on their length, else `NAME_k`."""
        try:
            import xarray as xr
        except ImportError:  # pragma: no cover - exercised only without the extra
            raise ImportError(
                "SweepResult.to_xarray needs xarray: pip install 'vmj[xarray]'"
            ) from None
        names, kdims, extra_coords = export_names(
            self.values, len(self.shape), set(self.coords) | set(self.dims)
        )
        # (lazy arrays stay lazy: `to_netcdf` then writes them chunk by chunk)
        leaves = [v if _lazy(v) else np.asarray(v) for v in jax.tree.leaves(self.values)]
        data_vars = {name: (tuple(self.dims) + kd, v) for name, kd, v in zip(names, kdims, leaves)}
        if self._is_grid:
            coords = {d: self.coords[d] for d in self.dims}
        else:
            coords = {
                k: (tuple(self.dims), np.broadcast_to(c, self.shape))
                for k, c in self.coords.items()
            }
        data = xr.Dataset(data_vars, coords={**coords, **extra_coords})
        for name, unit in self.attrs.get("units", {}).items():
            if name in data.variables:
                data[name].attrs["units"] = unit
        data.attrs.update({k: v for k, v in self.attrs.items() if k != "units"})
        return data

    def to_netcdf(self, path: str) -> None:
        """Write `to_xarray()` to a NetCDF file (needs the optional extra `vmj[xarray]`)."""
        data = self.to_xarray()
        with replacing(path, seekable=True) as tmp:
            data.to_netcdf(tmp)

    @staticmethod
    def read_zarr(path: str) -> SweepResult:
        """Open the sweep in a Zarr store written by [`vmj.sweep`][] with `store=` (needs the
        optional extra `vmj[distributed]`); `values` becomes a dict of field name to a lazy
        (dask) array read from the store, as `vmj.sweep(..., store=...)` returns them:
        `np.asarray` loads a field, `.compute()` a part of one, and the exports stream them.
        Every chunk must be marked complete (an unfinished sweep is refused: resume it with
        `vmj.sweep(..., store=path, resume=True)`); opening reads only these markers and the
        chunks' checksums, and each chunk of a field is checked against its checksum when it
        is read (one that does not match raises a ValueError naming it), so a store larger
        than memory opens in the time of its markers."""
        from ._store import DONE, ChunkStore

        st = ChunkStore.read_only(path, kind="sweep")
        meta = st.meta
        names = [f[0] for f in meta["fields"]]
        missing = int(np.sum(st.status() != DONE))
        if missing:
            raise ValueError(
                f"store {path!r} holds an unfinished sweep: {missing} of "
                f"{meta['n_chunks']} chunks are missing or failed; resume it with "
                f"vmj.sweep(..., store={path!r}, resume=True)"
            )
        return SweepResult(
            dict(zip(names, st.lazy(names))),
            tuple(meta["dims"]),
            st.coords(),
            tuple(meta["shape"]),
            1,
            meta["n_chunks"],
            resumed=meta["n_chunks"],
            _attrs=meta.get("attrs", {}),
        )
