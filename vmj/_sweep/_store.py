"""Resumable results in a Zarr store: one Zarr chunk per chunk of work, a completion marker and
a checksum per chunk and field, and the definition of the work that refuses a different one.

Layout of a store (a Zarr v3 group):

- attributes `vmj`: the format, the definition (a digest and a readable description), the
  plan (points, chunk size, number of chunks), and for a sweep its dims, shape and fields;
  `vmj_failures`: the chunks whose evaluation raised, with their status code and message;
- `vmj_status` (one `int8` per chunk: 0 not done, 1 done, 2 failed) and `vmj_checksum` (a row
  of `uint32` per chunk, the CRC-32 of each field's part of the chunk, in the order of the
  plan's `fields`; a map's one column, that of its chunk's bytes), each chunk's marker and row its
  own Zarr chunk, so that each is one atomic file; the status is written after the data and
  the checksums;
- a sweep: one array per field of the result with the points flattened in C order along
  `point` (Zarr chunks equal to the sweep's chunks, inner axes named as in
  [`vmj.SweepResult.to_xarray`][]), and the coordinates (a grid's axes, or every swept
  parameter of paired points);
- a map over items: `vmj_chunk_<c>`, the pickled results of chunk `c` as bytes.

A chunk counts as done only when its status says so and its data matches its checksums, so a
chunk half written (the process killed between its arrays) or corrupted on disk is computed
again on resuming (which reads every finished chunk once, one at a time); every write replaces
whole files atomically, so nothing finished is lost. Opening a finished store
(`SweepResult.read_zarr`, the values a sweep with a store returns) reads only its markers and
checksums (a few bytes per chunk): each chunk of a field is checked against its checksum when
it is read, and one that does not match raises, naming it (a store larger than memory opens in
the time of its markers, and a reduction over one field reads that field only).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import pickle
import re
import types
import zlib

import numpy as np

__all__ = ["digest", "ChunkStore"]

#: the layout above (format 1 had one 64-bit BLAKE2b digest per chunk, over all its fields: a
#: field could not be checked without reading all of them)
FORMAT = 2
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


def checksum(a) -> int:
    """The CRC-32 of one array's dtype, shape and bytes: it detects damage (any burst of up to
    32 bits; other damage but for one chance in 2^32), not deliberate changes, at 4.6 times
    BLAKE2b's speed (2.1 against 0.45 GB/s measured here), which checking a chunk at each read
    pays."""
    a = np.ascontiguousarray(a)
    return zlib.crc32(a, zlib.crc32(f"{a.dtype.str} {a.shape}".encode()))


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
        if not isinstance(meta, dict) or "format" not in meta:
            raise ValueError(f"store {path!r} exists and is not a vmj store: choose another path")
        _check_format(path, meta, "delete it to start over, or choose another path")
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
        _check_format(path, meta, "read it with that version (or xarray.open_zarr)")
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
        n_fields = len(plan.get("fields", [None]))  # (a map: one, its chunk's bytes)
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
            shape=(n_chunks, n_fields),
            chunks=(1, n_fields),
            dtype="uint32",
            fill_value=0,
            dimension_names=("chunk", "field"),
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
        """Write chunk `c` (one array per field, its rows only, in the order of the plan's
        fields; for a map, `names=None` and one bytes object), then its checksums, then its
        completion marker."""
        if names is None:
            blob = np.frombuffer(arrays, dtype=np.uint8)
            key = f"vmj_chunk_{c}"
            if key in self.group:
                del self.group[key]
            self.group.create_array(key, data=blob, chunks=(max(1, blob.size),))
            self._checksum[c] = np.array([checksum(blob)], dtype=np.uint32)
        else:
            self._put(c, arrays, names)
        self._status[c] = DONE
        if self._failures.pop(str(c), None) is not None:
            self.group.attrs["vmj_failures"] = self._failures

    def _put(self, c: int, arrays, names) -> None:
        """A sweep's chunk `c`: each field's rows, then the row of their checksums (one file)."""
        lo = c * self.meta["chunk"]
        sums = []
        for name, a in zip(names, arrays):
            target = self.group[name]
            a = np.asarray(a, dtype=target.dtype)  # (the checksum of what is read back)
            target[lo : lo + len(a)] = a
            sums.append(checksum(a))
        self._checksum[c] = np.array(sums, dtype=np.uint32)

    def fail(self, c: int, code: int, message: str, names=None) -> None:
        """Record that chunk `c` raised (its status code, or -1, and message); a sweep's fields
        (`names`) get NaN in the chunk's rows (0 where they are not floats), with their
        checksums (so that they read as any chunk does)."""
        if names is not None:
            lo, hi = self._rows(c)
            filled = []
            for name in names:
                a = self.group[name]
                fill = np.nan if a.dtype.kind in "fc" else 0
                filled.append(np.full((hi - lo,) + tuple(a.shape[1:]), fill, dtype=a.dtype))
            self._put(c, filled, names)
        self._status[c] = FAILED
        self._failures[str(c)] = {"code": int(code), "message": message}
        self.group.attrs["vmj_failures"] = self._failures

    def _rows(self, c: int) -> tuple[int, int]:
        """The points `lo ... hi - 1` of chunk `c`."""
        return _chunk_rows(self.meta, c)

    def status(self) -> np.ndarray:
        """The status of every chunk (a marker that cannot be read counts as not done)."""
        return _markers(self._status)

    def remaining(self, names=None, place=None) -> list:
        """The chunks still to compute (a resumed sweep or map): those not marked done or whose
        data does not match its checksums. Every finished chunk is read once, one field of one
        chunk at a time (a sweep's memory stays that of a chunk, whatever the store's size); a
        map's complete chunks are handed to `place(c, bytes)`, if given."""
        status, sums = self.status(), _markers(self._checksum)
        fields = [f[0] for f in self.meta.get("fields", [])]
        todo = []
        for c in range(self.meta["n_chunks"]):
            if status[c] != DONE:
                todo.append(c)
            elif names is None:
                blob = self._sound(c, f"vmj_chunk_{c}", slice(None), sums[c, 0])
                if blob is None:
                    todo.append(c)
                elif place is not None:
                    place(c, blob.tobytes())
            elif not all(
                self._sound(c, name, slice(*self._rows(c)), sums[c, fields.index(name)]) is not None
                for name in names
            ):
                todo.append(c)
        return todo

    def _sound(self, c: int, key: str, rows: slice, want) -> np.ndarray | None:
        """The `rows` of the array `key` if they match the checksum `want`, else None (a map's
        chunk missing too)."""
        try:
            array = self.group[key]
        except Exception:  # (missing, or its metadata cannot be decoded)
            return None
        return _checked(array, rows, want)

    def lazy(self, names) -> list:
        """A sweep's fields `names`, read lazily from the store (dask arrays with the sweep's
        shape in front, a dask chunk per chunk of work where the shape allows): only the
        checksums are read now; each chunk of work a computation touches is read whole and
        checked against its checksum (one that does not match raises a ValueError naming it);
        `np.asarray` loads one whole."""
        da = _extra("dask.array", "a sweep read from a store")
        shape = tuple(self.meta["shape"])
        n, chunk = self.meta["n"], self.meta["chunk"]
        # the checksums read once, in one Zarr call (one per chunk read cost as much Zarr
        # overhead as the chunk's data: 0.5 s of CPU more for a mean over 246 chunks)
        sums = _markers(self._checksum)
        fields = [f[0] for f in self.meta["fields"]]
        out = []
        for name in names:
            field = _CheckedField(self, name, sums[:, fields.index(name)])
            rows = (chunk,) * (n // chunk) + ((n % chunk,) if n % chunk else ())
            lazy = da.from_array(
                field,
                chunks=(rows,) + tuple((k,) for k in field.shape[1:]),
                asarray=False,
                fancy=False,
                lock=False,
                meta=np.empty((0,) * field.ndim, field.dtype),
            )
            out.append(lazy.reshape(shape + field.shape[1:]))
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


class _CheckedField:
    """One field of a sweep's store as an array for `dask.array.from_array`: a part asked for
    is cut from the chunks of work that hold it, each read whole and checked against its
    checksum (`checksums`, one per chunk, as read when the store was opened) when read (never
    the whole field); a chunk whose data does not match raises a ValueError naming it and what
    to do. Pickled with the Zarr array (a Dask cluster's workers read the store themselves)."""

    def __init__(self, store: ChunkStore, name: str, checksums: np.ndarray):
        self.path, self.name, self.meta = store.path, name, store.meta
        self.data, self.checksums = store.group[name], checksums
        self.shape = tuple(self.data.shape)
        self.ndim = len(self.shape)
        self.dtype = self.data.dtype.newbyteorder("=")

    def __dask_tokenize__(self):
        return ("vmj-store", self.path, self.meta["token"], self.name)

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        first, rest = (key[0], key[1:]) if key else (slice(None), ())
        if first is Ellipsis:
            first, rest = slice(None), key
        rows = range(self.shape[0])[first]
        if isinstance(rows, int):
            return self._points(rows, rows + 1)[(0,) + rest]
        if not len(rows):
            return np.empty((0,) + self.shape[1:], self.dtype)[(slice(None),) + rest]
        lo, hi = min(rows[0], rows[-1]), max(rows[0], rows[-1]) + 1
        local = slice(None) if rows.step == 1 else np.asarray(rows) - lo
        return self._points(lo, hi)[(local,) + rest]

    def _points(self, lo: int, hi: int) -> np.ndarray:
        """Rows `lo ... hi - 1`, from the chunks that hold them, each checked."""
        chunk = self.meta["chunk"]
        parts = []
        for c in range(lo // chunk, (hi - 1) // chunk + 1):
            start = c * chunk
            parts.append(self._chunk(c)[max(lo - start, 0) : hi - start])
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _chunk(self, c: int) -> np.ndarray:
        lo, hi = _chunk_rows(self.meta, c)
        a = _checked(self.data, slice(lo, hi), self.checksums[c])
        if a is None:
            raise ValueError(
                f"store {self.path!r}: the field {self.name!r} of chunk {c} (points {lo} to "
                f"{hi - 1}) does not match its checksum (damaged on disk, or rewritten since it "
                f"was opened): vmj.sweep(..., store={self.path!r}, resume=True) computes it again"
            )
        return _native(a)


def _chunk_rows(meta: dict, c: int) -> tuple[int, int]:
    """The points `lo ... hi - 1` of chunk `c` of a store's plan `meta`."""
    lo = c * meta["chunk"]
    return lo, min(lo + meta["chunk"], meta["n"])


def _checked(array, rows: slice, want) -> np.ndarray | None:
    """`array[rows]` if it matches the checksum `want`, else None (a data file that cannot be
    decoded too). A MemoryError is raised: it is not damage."""
    try:
        a = np.asarray(array[rows])
    except MemoryError:
        raise
    except Exception:
        return None
    return a if checksum(a) == int(want) else None


def _markers(array) -> np.ndarray:
    """A small per-chunk array (`vmj_status`, `vmj_checksum`) whole, in one read; a marker that
    cannot be decoded reads as 0 (not done; no checksum)."""
    try:
        return np.asarray(array[...])
    except Exception:
        out = np.zeros(array.shape, dtype=array.dtype)
        for c in range(array.shape[0]):
            try:
                out[c] = array[c]
            except Exception:
                pass
        return out


def _check_format(path: str, meta: dict, advice: str) -> None:
    """A vmj store of another format (written by another version of vmj) is refused."""
    if meta.get("format") != FORMAT:
        raise ValueError(
            f"store {path!r} was written by another version of vmj (store format "
            f"{meta.get('format')!r}; this version reads format {FORMAT}): {advice}"
        )


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
