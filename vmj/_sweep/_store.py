"""Resumable results in a Zarr store: one Zarr chunk per chunk of work, a completion marker and
a checksum per chunk, and the definition of the work that refuses a different one.

Layout of a store (a Zarr v3 group):

- attributes `vmj`: the format, the definition (a digest and a readable description), the
  plan (points, chunk size, number of chunks), and for a sweep its dims, shape and fields;
  `vmj_failures`: the chunks whose evaluation raised, with their status code and message;
- `vmj_status` (one `int8` per chunk: 0 not done, 1 done, 2 failed) and `vmj_checksum` (one
  `uint64` per chunk, a BLAKE2b digest of the chunk's data), each entry its own Zarr chunk so
  that a marker is one atomic file; the status is written after the data and the checksum;
- a sweep: one array per field of the result with the points flattened in C order along
  `point` (Zarr chunks equal to the sweep's chunks, inner axes named as in
  [`vmj.SweepResult.to_xarray`][]), and the coordinates (a grid's axes, or every swept
  parameter of paired points);
- a map over items: `vmj_chunk_<c>`, the pickled results of chunk `c` as bytes.

A chunk counts as done only when its status says so and its data matches its checksum, so a
chunk half written (the process killed between its arrays) or corrupted on disk is computed
again; every write replaces whole files atomically, so nothing finished is lost.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import pickle
import re
import types

import numpy as np

__all__ = ["digest", "ChunkStore"]

FORMAT = 1
NOT_DONE, DONE, FAILED = 0, 1, 2


# -- digests of a definition -------------------------------------------------------------------
_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def _feed(h, obj, seen) -> None:
    import jax

    if id(obj) in seen:
        h.update(b"<cycle>")
        return
    if isinstance(obj, (np.ndarray, np.generic, jax.Array)):
        a = np.ascontiguousarray(np.asarray(obj))
        h.update(f"array {a.dtype.str} {a.shape}".encode())
        h.update(a.tobytes())
    elif obj is None or isinstance(obj, (bool, int, float, complex, str, bytes)):
        h.update(repr((type(obj).__name__, obj)).encode())
    elif isinstance(obj, (list, tuple)):
        h.update(f"{type(obj).__name__} {len(obj)}".encode())
        seen = seen | {id(obj)}
        for x in obj:
            _feed(h, x, seen)
    elif isinstance(obj, dict):
        h.update(f"dict {len(obj)}".encode())
        seen = seen | {id(obj)}
        for k in sorted(obj, key=repr):
            _feed(h, k, seen)
            _feed(h, obj[k], seen)
    elif isinstance(obj, functools.partial):
        h.update(b"partial")
        _feed(h, (obj.func, obj.args, obj.keywords), seen | {id(obj)})
    elif isinstance(obj, types.FunctionType):
        h.update(f"function {obj.__module__}.{obj.__qualname__}".encode())
        seen = seen | {id(obj)}
        _feed_code(h, obj.__code__)
        _feed(h, (obj.__defaults__, obj.__kwdefaults__), seen)
        for cell in obj.__closure__ or ():
            try:
                value = cell.cell_contents
            except ValueError:  # an empty cell
                value = None
            _feed(h, value, seen)
    elif isinstance(obj, types.MethodType):
        _feed(h, (obj.__func__, obj.__self__), seen | {id(obj)})
    elif isinstance(obj, (type, types.BuiltinFunctionType, types.ModuleType)):
        h.update(f"{getattr(obj, '__module__', '')}.{getattr(obj, '__qualname__', obj)}".encode())
    elif dataclasses.is_dataclass(obj):  # models, laws, solver objects (equinox modules)
        h.update(f"{type(obj).__module__}.{type(obj).__qualname__}".encode())
        seen = seen | {id(obj)}
        for f in dataclasses.fields(obj):
            h.update(f.name.encode())
            _feed(h, getattr(obj, f.name, None), seen)
    else:
        try:
            h.update(pickle.dumps(obj, protocol=5))
        except Exception:
            h.update(_ADDRESS.sub("", repr(obj)).encode())


def _feed_code(h, code) -> None:
    h.update(code.co_code)
    h.update(repr(code.co_names).encode())
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _feed_code(h, const)
        else:
            h.update(_ADDRESS.sub("", repr(const)).encode())


def digest(obj) -> str:
    """A hex digest of a value: arrays by dtype, shape and bytes; functions by module, name,
    code and the values they close over (so a function edited or given other constants
    differs, but line numbers and memory addresses do not count); modules (models, laws,
    solver objects) by type and fields."""
    h = hashlib.blake2b(digest_size=16)
    _feed(h, obj, frozenset())
    return h.hexdigest()


def describe_fn(fn) -> str:
    """A readable name of a function, for error messages and a sweep's `function` attribute
    (a function of vmj's own may say what it is: `_vmj_description`)."""
    own = getattr(fn, "_vmj_description", None)
    if isinstance(own, str):
        return own
    if isinstance(fn, functools.partial):
        return f"partial({describe_fn(fn.func)}, ...)"
    name = getattr(fn, "__qualname__", None) or type(fn).__qualname__
    return f"{getattr(fn, '__module__', type(fn).__module__)}.{name}"


def chunk_checksum(arrays) -> int:
    h = hashlib.blake2b(digest_size=8)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str} {a.shape}".encode())
        h.update(a.tobytes())
    return int.from_bytes(h.digest(), "little")


# -- the store ---------------------------------------------------------------------------------
def _extra(module: str, what: str):
    """`module` of the optional extra `vmj[distributed]`, or an ImportError saying that `what`
    needs it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:  # pragma: no cover - exercised only without the extra
        raise ImportError(
            f"{what} needs the optional extra: pip install 'vmj[distributed]'"
        ) from None


def _opened(zarr, path: str, mode: str):
    """`path`'s Zarr group opened with `mode` and its vmj metadata (`None` where it is no
    readable group or has none)."""
    try:
        group = zarr.open_group(path, mode=mode)
        return group, group.attrs.get("vmj")
    except Exception:
        return None, None


def check_resume(resume, store, work: str) -> None:
    """`resume=` of `vmj.sweep` and `vmj.map_chunks` (`work` names what a store continues)."""
    if not isinstance(resume, bool):
        raise ValueError(f"resume must be True or False (got {resume!r})")
    if resume and store is None:
        raise ValueError(f"resume=True needs a store (the path of the {work} to continue)")


class ChunkStore:
    """A Zarr group holding the chunks of one definition of work (see the module text)."""

    def __init__(self, group, path: str, meta: dict):
        self.group, self.path, self.meta = group, path, meta
        self._status = group["vmj_status"]
        self._checksum = group["vmj_checksum"]
        # this process is the store's one writer: the failures are kept here and written whole
        self._failures = dict(group.attrs.get("vmj_failures", {}))

    # -- opening -------------------------------------------------------------------------------
    @classmethod
    def existing(
        cls, path, *, kind: str, definition: dict, described: dict, resume: bool
    ) -> ChunkStore | None:
        """The store at `path` if there is one (None otherwise). It must hold work of `kind`
        (`"sweep"` or `"map"`) with the same `definition` (a dict of digests; `described` says
        the same in words), and `resume=True` is needed to continue it; its stored plan (chunk
        size, number of chunks) is the one used."""
        zarr = _extra("zarr", "a store")
        path = os.fspath(path)
        if not os.path.exists(path):
            return None
        group, meta = _opened(zarr, path, "r+")
        if meta is None and group is not None and "vmj_status" in group:
            raise ValueError(
                f"store {path!r} is incomplete: its creation was interrupted, or another "
                f"process is creating it now; delete it to start over, or choose another path"
            )
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise ValueError(f"store {path!r} exists and is not a vmj store: choose another path")
        if meta.get("kind") != kind or meta.get("token") != digest(definition):
            raise ValueError(
                f"store {path!r} holds a different {meta.get('kind', 'sweep')}: "
                f"{_differences(meta.get('described', {}), described)}. Use another "
                f"store path, or delete this one to start over"
            )
        if not resume:
            raise ValueError(
                f"store {path!r} already holds this {kind}: pass resume=True to "
                f"continue it (only the chunks not yet in it are computed), or "
                f"choose another path"
            )
        return cls(group, path, meta)

    @classmethod
    def read_only(cls, path, *, kind: str) -> ChunkStore:
        """An existing store opened for reading."""
        zarr = _extra("zarr", "a store")
        path = os.fspath(path)
        group, meta = _opened(zarr, path, "r")
        if not isinstance(meta, dict) or meta.get("kind") != kind:
            raise ValueError(f"{path!r} is not a vmj {kind} store")
        return cls(group, path, meta)

    @classmethod
    def create(
        cls, path, *, kind: str, definition: dict, described: dict, plan: dict
    ) -> ChunkStore:
        """A new store at `path` for work of `kind` with `plan` (`n`, `chunk`, `n_chunks`, and
        for a sweep its `dims`, `shape`, `grid`, `fields`)."""
        zarr = _extra("zarr", "a store")
        path = os.fspath(path)
        meta = {
            "format": FORMAT,
            "kind": kind,
            "token": digest(definition),
            "described": described,
            **plan,
        }
        try:
            group = zarr.open_group(path, mode="w-", zarr_format=3)
        except FileExistsError:  # (it did not exist when `existing` looked)
            raise ValueError(
                f"store {path!r} was created by another process meanwhile: rerun with "
                f"resume=True to continue it, or choose another path"
            ) from None
        n_chunks = plan["n_chunks"]
        group.create_array(
            "vmj_status",
            shape=(n_chunks,),
            chunks=(1,),
            dtype="int8",
            fill_value=NOT_DONE,
            dimension_names=("chunk",),
        )
        group.create_array(
            "vmj_checksum",
            shape=(n_chunks,),
            chunks=(1,),
            dtype="uint64",
            fill_value=0,
            dimension_names=("chunk",),
        )
        group.attrs.update({"vmj_failures": {}, "vmj": meta})  # the definition last
        return cls(group, path, meta)

    # -- sweeps --------------------------------------------------------------------------------
    def create_sweep_arrays(
        self, fields, coords: dict, grid: bool, inner_coords: dict, units: dict
    ):
        """The arrays of a sweep's fields (`[(name, dtype, inner shape, inner dims)]`) and its
        coordinates: a grid's axes, each along its own dimension; paired points' parameters
        along `point`, as the fields are (named in each field's `coordinates` attribute, so that
        `xarray.open_zarr` attaches them). `units` (by name) become each array's attribute
        `units`. Created once (a resumed store has them)."""
        n, chunk = self.meta["n"], self.meta["chunk"]
        paired = "" if grid else " ".join(coords)
        for name, dtype, inner, kdims in fields:
            if name not in self.group:
                attributes = {"units": units[name]} if name in units else {}
                if paired:
                    attributes["coordinates"] = paired
                self.group.create_array(
                    name,
                    shape=(n,) + tuple(inner),
                    chunks=(chunk,) + tuple(inner),
                    dtype=dtype,
                    fill_value=np.zeros((), dtype).item(),
                    dimension_names=("point",) + tuple(kdims),
                    attributes=attributes or None,
                )
        for name, value in {**coords, **inner_coords}.items():
            if name in self.group:
                continue
            value = np.asarray(value)
            attributes = {"units": units[name]} if name in units else None
            if grid or name in inner_coords:
                self.group.create_array(
                    name,
                    data=value,
                    chunks=value.shape or (1,),
                    dimension_names=(name,),
                    attributes=attributes,
                )
                continue
            # a paired parameter, broadcast to the points and flattened as the fields are
            # (written chunk by chunk: never the whole broadcast in memory)
            full = np.broadcast_to(value, tuple(self.meta["shape"]))
            array = self.group.create_array(
                name,
                shape=(n,),
                chunks=(chunk,),
                dtype=value.dtype,
                dimension_names=("point",),
                attributes=attributes,
            )
            for lo in range(0, n, chunk):
                array[lo : lo + chunk] = full.flat[lo : min(lo + chunk, n)]

    def write(self, c: int, arrays, names=None) -> None:
        """Write chunk `c` (one array per field, its rows only; for a map, `names=None` and one
        bytes object), then its checksum, then its completion marker."""
        if names is None:
            blob = np.frombuffer(arrays, dtype=np.uint8)
            key = f"vmj_chunk_{c}"
            if key in self.group:
                del self.group[key]
            self.group.create_array(key, data=blob, chunks=(max(1, blob.size),))
            total = chunk_checksum([blob])
        else:
            lo = c * self.meta["chunk"]
            for name, a in zip(names, arrays):
                self.group[name][lo : lo + len(a)] = a
            total = chunk_checksum(arrays)
        self._checksum[c] = np.uint64(total)
        self._status[c] = DONE
        if self._failures.pop(str(c), None) is not None:
            self.group.attrs["vmj_failures"] = self._failures

    def fail(self, c: int, code: int, message: str, names=None) -> None:
        """Record that chunk `c` raised (its status code, or -1, and message); a sweep's fields
        (`names`) get NaN in the chunk's rows (0 where they are not floats)."""
        if names is not None:
            lo = c * self.meta["chunk"]
            hi = min(lo + self.meta["chunk"], self.meta["n"])
            for name in names:
                a = self.group[name]
                a[lo:hi] = np.nan if a.dtype.kind in "fc" else 0
        self._status[c] = FAILED
        self._failures[str(c)] = {"code": int(code), "message": message}
        self.group.attrs["vmj_failures"] = self._failures

    def status(self) -> np.ndarray:
        """The status of every chunk (a marker that cannot be read counts as not done)."""
        try:
            return np.asarray(self._status[:])
        except Exception:
            out = np.zeros(self.meta["n_chunks"], dtype=np.int8)
            for c in range(len(out)):
                try:
                    out[c] = self._status[c]
                except Exception:
                    pass
            return out

    def remaining(self, names=None, place=None) -> list:
        """The chunks still to compute (a resumed sweep): those not marked done or whose data
        does not match its checksum (each read once, chunk by chunk); each complete one is
        handed to `place(c, data)`, if given."""
        status = self.status()
        todo = []
        for c in range(self.meta["n_chunks"]):
            data = self.read(c, names) if status[c] == DONE else None
            if data is None:
                todo.append(c)
            elif place is not None:
                place(c, data)
        return todo

    def lazy(self, names) -> list:
        """A sweep's fields `names`, read lazily from the store (dask arrays with the sweep's
        shape in front, a dask chunk per chunk of work where the shape allows): nothing is read
        until they are computed, `np.asarray` loads one whole."""
        da = _extra("dask.array", "a sweep read from a store")
        shape = tuple(self.meta["shape"])
        out = []
        for name in names:
            a = self.group[name]
            lazy = _native(da.from_zarr(a))
            out.append(lazy.reshape(shape + tuple(a.shape[1:])))
        return out

    def coords(self) -> dict:
        """A sweep's coordinates: a grid's axes; paired points' parameters with the sweep's
        shape (read whole: 8 bytes per point and parameter)."""
        shape, n = tuple(self.meta["shape"]), self.meta["n"]
        out = {}
        for k in self.meta["coords"]:
            value = np.asarray(self.group[k][...])
            value = _native(value)
            if not self.meta["grid"] and value.size == n:
                value = value.reshape(shape)
            out[k] = value
        return out

    def read(self, c: int, names=None):
        """The data of chunk `c` (marked done) if it matches its checksum, else None."""
        try:
            want = int(self._checksum[c])
            if names is None:
                blob = np.asarray(self.group[f"vmj_chunk_{c}"][:])
                return blob.tobytes() if chunk_checksum([blob]) == want else None
            lo = c * self.meta["chunk"]
            hi = min(lo + self.meta["chunk"], self.meta["n"])
            arrays = [np.asarray(self.group[name][lo:hi]) for name in names]
        except Exception:  # a marker or data file that cannot be decoded
            return None
        return arrays if chunk_checksum(arrays) == want else None


def _differences(stored: dict, now: dict) -> str:
    keys = [k for k in now if stored.get(k) != now[k]] + [k for k in stored if k not in now]
    if not keys:
        return "its definition differs"
    parts = []
    for k in keys:
        was, new = stored.get(k), now.get(k)
        if isinstance(was, str) and isinstance(new, str) and len(was) + len(new) < 120:
            parts.append(f"{k} (stored {was}, now {new})")
        else:
            parts.append(f"{k} differ" if k.endswith("s") else f"{k} differs")
    return "; ".join(parts)


def _native(a):
    """`a` (a NumPy or Dask array) in the native byte order spelled `=`: Zarr spells it out,
    `'<f8'`, the same memory on a little-endian machine, about whose every variable netCDF4
    warns (a view then; converted where the store's order is the other)."""
    native = a.dtype.newbyteorder("=")
    return a.view(native) if a.dtype.isnative else a.astype(native)
