"""A persistent cache of exported programs and their executables, so that a repeated `vmj`
command skips tracing, lowering and compiling.

JAX's persistent compilation cache keeps XLA's compiled code, but every new process still traces
the Python function and lowers it before it can look that code up: for `vmj fit` that tracing
is most of the run (docs/performance.md). `exported_jit` is `jax.jit` for the compiled entry
points (`vmj._integrate`, `fits._solve`, the derivatives of `vmj sensitivity`, a sweep's chunks
on one CPU); while the cache is switched on, each call with new static arguments, argument
structure or shapes looks in the cache directory for two entries:

- `NAME-KEY.xla`: XLA's executable (`jax.experimental.serialize_executable`), deserialized and
  called as it is: no tracing, no lowering, no lookup in the compilation cache. Its key also
  holds this machine's processor (the code is compiled for it). Should a loaded executable fail
  on its first call, it is compiled anew from the exported program.
- `NAME-KEY.exported`: the serialized `jax.export.Exported`, from which the executable is
  compiled where it is missing (another processor, a damaged entry).

On a miss the function is traced once, exported, compiled (by XLA itself: an executable loaded
from the compilation cache serializes without some of its code) and both entries written. A
key is a hash of the function's name, the source of vmj and of the function's package, the
versions of vmj, JAX and the libraries traced through, the x64 flag and the backend, the static
arguments and the structure and shapes of the others. An entry that cannot be read (missing,
corrupted, written by another version) is written anew; one that cannot be written (read-only
directory) costs nothing but the time. Entries are written to a temporary file and renamed into
place, so concurrent writers never leave a partial one.

The cache is off unless an entry point switches it on: the `vmj` command does, in the
subdirectory `exported` of its compilation cache (`--cache-dir`, `--no-cache`,
`VMJ_CACHE_DIR`). A script may do the same with `vmj.cli.enable_exported_cache(path)` after
configuring `jax_compilation_cache_dir`; calls inside the user's own `jit`/`vmap`/`grad` (traced
arguments) and calls with keyword arguments always take the plain `jax.jit` path.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import pickle
import re
import struct
import sys
import tempfile

from ._version import __version__

__all__ = [
    "exported_jit",
    "filter_jit",
    "split_arrays",
    "joined_leaves",
    "enable_exported_cache",
    "exported_cache_directory",
]

_MAGIC = b"vmj-exported 1\n"
_HEAD = struct.Struct("<32s32sQ")  # key digest, payload digest, skeleton length
#: distributions whose code a trace runs through (their versions are part of every key)
_LIBRARIES = ("jax", "jaxlib", "equinox", "lineax", "optimistix", "optax", "diffrax", "numpy")

_directory: list = [None]  #: the cache directory, `None` when off
_PLAIN = "plain"  #: marks an argument combination that is not exported (always plain jit)


def enable_exported_cache(path: str | os.PathLike | None) -> None:
    """Keep the exported programs of vmj's compiled entry points and their executables in the
    directory `path` (created when first written; `None` switches the cache off, the default).

    Meant for a program's entry point, after `jax.config.update("jax_compilation_cache_dir",
    ...)`: a loaded executable skips tracing, lowering and XLA's compile. The `vmj` command
    calls it with the `exported` subdirectory of its compilation cache.
    """
    _directory[0] = None if path is None else os.fspath(path)


def _top_level() -> bool:
    """Whether no JAX transformation is tracing (where `jax.jit` takes compiler options); False
    where JAX's internals do not say."""
    from jax._src import core

    ctx = getattr(core, "trace_ctx", None)
    return ctx is not None and ctx.is_top_level()


def _checked(out):
    """A top-level call's result, its program finished: a check inside it (`equinox.error_if`,
    a host callback) raises here, at the call, on every platform. On a GPU the program runs
    after the call returns, and a failed check would otherwise surface only where the result is
    first read, or as a logged error and a message at exit where it is never read (seen on an
    H200, 2026-11-28: `vmj.kbm_amplitude` over the potential barrier returned). Where JAX's
    default backend is a CPU nothing is waited for: a program with a host callback has run
    when the call returns there (also with JAX's asynchronous dispatch), and the wait would
    cost a warm `vmj.turning_points` 8 us of its 65."""
    if _default_backend_is_cpu():
        return out
    import jax

    return jax.block_until_ready(out)


@functools.cache
def _default_backend_is_cpu() -> bool:
    import jax

    return jax.default_backend() == "cpu"


def exported_cache_directory() -> str | None:
    """The directory of the exported-program cache, `None` when it is off."""
    return _directory[0]


def exported_jit(fun=None, *, static_argnums=(), compiler_options=None, one_call=True):
    """`jax.jit(fun, static_argnums=..., compiler_options=...)` that, while the exported-program
    cache is on, loads and stores the function's exported programs there (see the module's
    docstring). The plain jitted function's attributes (`lower`, ...) are those of the result.
    `compiler_options` (XLA's, as for `jax.jit`, beside `ONE_CALL` unless `one_call=False`: a
    sweep's chunk) apply where the function is compiled as a program of its own, not where it
    is traced inside another (a sweep's `jax.vmap`, the user's own `jax.jit`)."""
    if fun is None:
        return functools.partial(
            exported_jit,
            static_argnums=static_argnums,
            compiler_options=compiler_options,
            one_call=one_call,
        )
    return _ExportedJit(fun, static_argnums, compiler_options, one_call)


#: XLA's options for every program compiled here and by `filter_jit`: one call's program, whose
#: compile is most of the call's cost. XLA's CPU backend emits each fused kernel through MLIR by
#: default (`xla_cpu_use_fusion_emitters`); its older emitters write the same arithmetic in less
#: time: the first `vmj fit` of the shipped table (alternating processes, fresh caches) 7.9-9.5
#: s -> 6.1-8.3 s (12.4-13.5 -> 7.3-7.4 s on one core), the same output to the last digit; the
#: first `fits.fit` 6.3 -> 4.0 s, a warm one 5.4 -> 4.9 ms; the first `vmj.sensitivity` of the
#: README 4.0 -> 3.3 s. Their kernels run slower in bulk (a fit of 200 records in one batch 1.7
#: -> 1.8 ms per record; as the default for a whole sweep, energy balance 3.3x, exact 1.3x,
#: smoothed 1.7x slower), so `vmj.sweep` keeps XLA's default.
ONE_CALL = {"xla_cpu_use_fusion_emitters": False}


@functools.cache
def _one_call_options() -> tuple:
    """`ONE_CALL`'s items where this XLA knows them (an XLA before the option, or the
    default backend of another platform, refuses to compile with it), else none: checked once
    per process, on a program of one addition."""
    import jax

    try:
        jax.jit(lambda x: x + 1, compiler_options=ONE_CALL).lower(1.0).compile()
    except Exception:  # (XLA's error for an unknown option)
        return ()
    return tuple(ONE_CALL.items())


def split_arrays(tree):
    """`(arrays, static)`: the array leaves of `tree` and the rest of it, `(treedef, which
    leaves are arrays, the other leaves)`, hashable where those are (`joined_leaves(static,
    arrays)` gives all its leaves back): `filter_jit`'s static argument and a sweep's. A
    flattening of the tree, where `equinox.partition` and `equinox.combine` walked it in Python
    (of a sweep's fixed cost of about a millisecond, 4096 points, two such walks took about 0.1
    ms)."""
    import equinox as eqx
    import jax

    leaves, treedef = jax.tree.flatten(tree)
    is_array = tuple(eqx.is_array(x) for x in leaves)
    rest = tuple(x for x, a in zip(leaves, is_array) if not a)
    return [x for x, a in zip(leaves, is_array) if a], (treedef, is_array, rest)


def joined_leaves(static, arrays) -> list:
    """The leaves of the tree that `split_arrays` took apart into `arrays` and `static` (its
    structure: `static[0]`)."""
    _, is_array, rest = static
    arrays, rest = iter(arrays), iter(rest)
    return [next(arrays) if a else next(rest) for a in is_array]


def filter_jit(fun):
    """`jax.jit` of `fun` with its arrays traced and every other argument static (hashed), as
    `equinox.filter_jit`, whose program gets `ONE_CALL` where it is compiled on its own (no
    transformation tracing), as `exported_jit`'s: for the entry points whose arguments are no
    flat arrays (a model with a callable, a dictionary of solver settings; `vmj.sensitivity`,
    the rope's averaged laws, the linear response, the stick-slip cycle's samples). The
    function returns arrays only. The checks of values traced in its own trace are returned as
    values (`vmj._checks.collecting`): called at top level, they raise on the host, and the
    program holds no host callback for them (JAX's persistent compilation cache can store it);
    called inside another trace, they guard the result in that trace (`Failures.guard`: a
    value again where that trace collects its checks, a sweep's chunk, else
    `equinox.error_if`)."""

    @functools.cache
    def jitted(options: tuple):
        import jax

        from ._checks import collecting

        def program(arrays, static):
            args, kwargs = jax.tree.unflatten(static[0], joined_leaves(static, arrays))
            with collecting() as checks:
                out = fun(*args, **kwargs)
            return out, checks.failures()

        program.__name__ = program.__qualname__ = fun.__name__
        return jax.jit(program, static_argnums=1, compiler_options=dict(options) or None)

    @functools.wraps(fun)
    def call(*args, **kwargs):
        arrays, static = split_arrays((args, kwargs))
        if not _top_level():
            out, failures = jitted(())(arrays, static)
            return failures.guard(out)
        out, failures = jitted(_one_call_options())(arrays, static)
        failures.raise_any()
        return _checked(out)

    def lower(*args, **kwargs):
        """The program of a top-level call (`jax.stages.Lowered`: `as_text()`, ...)."""
        return jitted(_one_call_options()).lower(*split_arrays((args, kwargs)))

    call.lower = lower
    return call


class _ExportedJit:
    def __init__(self, fun, static_argnums, compiler_options=None, one_call=True):
        self.fun, self.one_call = fun, one_call
        self.static_argnums = (
            (static_argnums,) if isinstance(static_argnums, int) else tuple(sorted(static_argnums))
        )
        if any(i < 0 for i in self.static_argnums):
            raise ValueError("static_argnums must be non-negative positions")
        self.options = dict(compiler_options or {})
        self.loaded: dict = {}  # (directory, x64, static, treedef, avals) -> (call, out tree)
        functools.update_wrapper(self, fun)

    def __reduce__(self):  # pickled by reference, as the module-level function it replaces
        return self.__qualname__

    def __getattr__(self, name):  # (only for names the instance does not have)
        if name in ("jitted", "top", "__setstate__"):
            raise AttributeError(name)
        return getattr(self.jitted, name)

    def __call__(self, *args, **kwargs):
        found = None if kwargs else self._lookup(args)
        if found is None:
            return self._plain(*args, **kwargs)
        import jax

        leaves, (call, out_tree) = found
        return jax.tree.unflatten(out_tree, call(*leaves))

    def eval_shape(self, *args):
        """The output's structure and shapes (`jax.eval_shape`): read off the stored program
        where the cache has it, without tracing the function."""
        import jax

        found = self._lookup(args)
        if found is None:
            static = tuple(args[i] for i in self.static_argnums)
            dynamic = [a for i, a in enumerate(args) if i not in self.static_argnums]
            return jax.eval_shape(lambda *d: self.jitted(*self._merge(static, d)), *dynamic)
        call, out_tree = found[1]
        return jax.tree.unflatten(out_tree, list(_executable(call).out_info))

    def compiled(self, *args):
        """The compiled program for `args` (`jax.stages.Compiled`: its `memory_analysis()`, ...):
        the stored one where the cache has it."""
        found = self._lookup(args)
        if found is None:
            return (self.top if _top_level() else self.jitted).lower(*args).compile()
        return _executable(found[1][0])

    @functools.cached_property
    def jitted(self):
        """The plain `jax.jit` of the function (made at its first use: a module that defines an
        entry point imports no JAX, as the command's `--help` imports its subcommands)."""
        import jax

        return jax.jit(self.fun, static_argnums=self.static_argnums)

    @functools.cached_property
    def compiler_options(self) -> dict:
        return {**dict(_one_call_options() if self.one_call else ()), **self.options}

    @functools.cached_property
    def top(self):
        """The jitted function with its compiler options (JAX takes them for a program of its
        own only, not inside a trace)."""
        import jax

        return jax.jit(
            self.fun, static_argnums=self.static_argnums, compiler_options=self.compiler_options
        )

    def _plain(self, *args, **kwargs):
        """The jitted function, with its compiler options where no transformation traces."""
        if not _top_level():
            return self.jitted(*args, **kwargs)
        return _checked(self.top(*args, **kwargs))

    def _lookup(self, args):
        """`(leaves of the traced arguments, (call, output tree))` of the stored program for
        `args`, loaded or exported at the first call; `None` where they take the plain path
        (cache off, traced arguments, an unhashable static argument, not exportable)."""
        if _directory[0] is None:
            return None
        import jax

        static = tuple(args[i] for i in self.static_argnums)
        dynamic = tuple(a for i, a in enumerate(args) if i not in self.static_argnums)
        leaves, treedef = jax.tree.flatten(dynamic)
        typeof = getattr(jax, "typeof", None)  # (JAX >= 0.4.36; before, the plain path)
        if typeof is None or any(isinstance(x, jax.core.Tracer) for x in leaves):
            return None
        try:
            avals = tuple(typeof(x) for x in leaves)
            key = (_directory[0], jax.config.jax_enable_x64, static, treedef, avals)
            entry = self.loaded.get(key)
        except TypeError:  # a leaf that is no array, or an unhashable static argument
            return None
        if entry is None:
            entry = self.loaded[key] = self._load_or_export(static, treedef, avals)
        return None if entry is _PLAIN else (leaves, entry)

    def _merge(self, static, dynamic):
        """The positional arguments, from the static ones and the others."""
        static, dynamic = list(static), list(dynamic)
        n = len(static) + len(dynamic)
        return [static.pop(0) if i in self.static_argnums else dynamic.pop(0) for i in range(n)]

    def _load_or_export(self, static, treedef, avals):
        import jax

        text = "\n".join(
            [
                f"{self.fun.__module__}.{self.fun.__qualname__}",
                _environment(self.fun.__module__),
                f"x64={jax.config.jax_enable_x64}",
                # (no probe of the options: no XLA)
                repr(sorted({**(ONE_CALL if self.one_call else {}), **self.options}.items())),
                _stable(static),
                str(treedef),
                repr(avals),
            ]
        )
        if " at 0x" in text:  # an argument without a stable description: never cached
            return _PLAIN
        digest = hashlib.sha256(text.encode()).digest()
        path = os.path.join(_directory[0], f"{self.fun.__name__}-{digest.hex()[:40]}.exported")
        executable = _read_executable(path, digest)
        if executable is not None:
            compiled, out_tree = executable
            args = (static, treedef, avals, path, digest)
            return _Loaded(compiled, lambda: self._export_and_compile(*args)[0]), out_tree
        return self._export_and_compile(static, treedef, avals, path, digest)

    def _compile(self, exported, out_tree, path, digest, avals):
        return _compile(
            self.fun.__name__, exported, out_tree, path, digest, avals, self.compiler_options
        )

    def _export_and_compile(self, static, treedef, avals, path, digest):
        """`(compiled, output tree)` from the exported program's entry, or traced, exported
        and written there; the executable compiled and written beside it."""
        import jax

        loaded = _read(path, digest, avals)
        if loaded is not None:
            exported, out_tree = loaded
            return self._compile(exported, out_tree, path, digest, avals), out_tree
        out_trees = []

        def flat(*leaves):
            args = self._merge(static, jax.tree.unflatten(treedef, leaves))
            out_leaves, out_tree = jax.tree.flatten(self.fun(*args))
            out_trees.append(out_tree)
            return out_leaves

        flat.__name__ = flat.__qualname__ = self.fun.__name__
        specs = [jax.ShapeDtypeStruct(a.shape, a.dtype, weak_type=a.weak_type) for a in avals]
        try:
            exported = _export(jax.jit(flat), specs)
            blob = bytes(exported.serialize())
        except Exception:  # not exportable (or flatbuffers missing): the plain path
            return _PLAIN
        out_tree = out_trees[-1]
        _write(path, digest, pickle.dumps(_skeleton(out_tree)), blob)
        return self._compile(exported, out_tree, path, digest, avals), out_tree


def _executable(call):
    """The `jax.stages.Compiled` behind a stored program's call."""
    return call.compiled if isinstance(call, _Loaded) else call


class _Loaded:
    """A deserialized executable; should its first call fail (an entry that XLA cannot run),
    the program is compiled anew (`anew()`) and that one used."""

    def __init__(self, compiled, anew):
        self.compiled, self.anew, self.ran = compiled, anew, False

    def __call__(self, *leaves):
        if self.ran:
            return self.compiled(*leaves)
        import jax

        try:
            out = self.compiled(*leaves)
        except jax.errors.JaxRuntimeError:
            self.compiled = self.anew()
            out = self.compiled(*leaves)
        self.ran = True
        return out


def _executable_entry(path, digest):
    """The path and key of the executable's entry beside the exported program's: its key holds
    this machine's processor too (XLA's code is compiled for it)."""
    return path[: -len(".exported")] + ".xla", hashlib.sha256(digest + _processor().encode())


def _read_executable(path, digest):
    """`(compiled, output tree)` from the executable's entry, or `None`: loading it skips
    deserializing the exported program, lowering it and the compilation cache."""
    import jax
    from jax.experimental import serialize_executable as se

    exe_path, key = _executable_entry(path, digest)
    entry = _read_payload(exe_path, key.digest())
    if entry is None:
        return None
    try:
        in_tree, exe_out_tree, skeleton, lapack = pickle.loads(entry[1])
        if lapack and not _lapack_ready():
            return None
        compiled = se.deserialize_and_load(entry[0], in_tree, exe_out_tree)
        return compiled, jax.tree.structure(skeleton)
    except Exception:  # written by an incompatible version: compiled and written anew
        return None


def _compile(name, exported, out_tree, path, digest, avals, compiler_options):
    """XLA's executable of the exported program (lowered under the function's name), stored in
    its entry; where executables cannot be serialized, used as it is."""
    import jax
    from jax.experimental import serialize_executable as se

    def call(*leaves):
        return exported.call(*leaves)

    call.__name__ = call.__qualname__ = name
    specs = [jax.ShapeDtypeStruct(a.shape, a.dtype, weak_type=a.weak_type) for a in avals]
    lapack = b"lapack" in exported.mlir_module_serialized
    # lowered without LAPACK's set-up where the program has no LAPACK call (it imports SciPy)
    with contextlib.nullcontext() if lapack else _without_lapack_setup():
        lowered = jax.jit(call).lower(*specs)
    compiled = _compile_fresh(lowered, compiler_options)
    try:
        blob, in_tree, exe_out_tree = se.serialize(compiled)
        trees = pickle.dumps((in_tree, exe_out_tree, _skeleton(out_tree), lapack))
    except Exception:  # pragma: no cover - a backend that cannot serialize executables
        return compiled
    exe_path, key = _executable_entry(path, digest)
    _write(exe_path, key.digest(), trees, blob)
    return compiled


def _export(jitted, specs):
    """`jax.export.export(jitted)(*specs)`, with the custom calls that JAX does not promise to
    keep stable across versions allowed (LAPACK's QR in the fits' linear solves): an entry is
    only ever read by the same versions of JAX and jaxlib that wrote it (they are part of its
    key)."""
    import jax

    allowed: set = set()
    while True:
        checks = [jax.export.DisabledSafetyCheck.custom_call(t) for t in sorted(allowed)]
        try:
            return jax.export.export(jitted, disabled_checks=checks)(*specs)
        except ValueError as e:
            found = set(re.findall(r"custom_call @([\w.$-]+)", str(e))) - allowed
            if "custom calls" not in str(e) or not found:
                raise
            allowed |= found  # (the trace and the lowering are cached by `jitted`)


def _lapack_ready() -> bool:
    """Register LAPACK's custom calls for the CPU, as lowering a program that calls them does
    (an executable that calls them unregistered crashes the process); `False` where this JAX
    has no such step (the executable is then not loaded)."""
    import jax

    if jax.default_backend() != "cpu":
        return True
    try:
        from jax._src.lax import linalg

        linalg.initialize_lapack()
    except (ImportError, AttributeError):  # pragma: no cover - another layout of JAX's internals
        return False
    return True


def _compile_fresh(lowered, compiler_options):
    """`lowered.compile(compiler_options=...)` by XLA itself, never loaded from JAX's persistent
    compilation cache: an executable loaded from there serializes without the code of some of
    its kernels (jaxlib 0.10: the copy loads, and fails with "Function wrapped_rsqrt not found"
    when it runs). A compile option at its default value gives the program a cache key of its
    own, and the compile is not written to the cache (its executable is stored by the
    caller)."""
    import math

    from jax._src import config

    with config.persistent_cache_min_compile_time_secs(math.inf):
        return lowered.compile(
            compiler_options={"xla_embed_ir_in_executable": False, **compiler_options}
        )


@contextlib.contextmanager
def _without_lapack_setup():
    """Lowering a call of an exported program initializes LAPACK's custom calls for the CPU
    (jaxlib imports SciPy for them: a fifth of a `vmj table 1`); a program that has none
    skips it."""
    try:
        from jax._src.export import _export
    except ImportError:  # pragma: no cover - another layout of JAX's internals
        yield
        return
    setup = getattr(_export, "_ensure_backends_initialized", None)
    if setup is None:  # pragma: no cover
        yield
        return
    _export._ensure_backends_initialized = lambda platforms: None
    try:
        yield
    finally:
        _export._ensure_backends_initialized = setup


def _skeleton(out_tree):
    """The output structure as a picklable tree (its leaves numbered; `jax.tree.structure`
    of it gives the structure back)."""
    import jax

    return jax.tree.unflatten(out_tree, list(range(out_tree.num_leaves)))


def _read_payload(path, digest):
    """`(blob, skeleton)` of the entry at `path` for the key `digest`, or `None` (missing,
    another key's, truncated or corrupted)."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return None
    if not data.startswith(_MAGIC) or len(data) < len(_MAGIC) + _HEAD.size:
        return None
    key, check, n_skeleton = _HEAD.unpack_from(data, len(_MAGIC))
    payload = data[len(_MAGIC) + _HEAD.size :]
    if key != digest or hashlib.sha256(payload).digest() != check:
        return None
    return payload[n_skeleton:], payload[:n_skeleton]


def _read(path, digest, avals):
    """The `(Exported, output tree)` stored at `path` for the key `digest`, or `None`."""
    import jax

    try:
        entry = _read_payload(path, digest)
        if entry is None:
            return None
        blob, skeleton = entry
        out_tree = jax.tree.structure(pickle.loads(skeleton))
        exported = jax.export.deserialize(bytearray(blob))
        if [(a.shape, a.dtype) for a in exported.in_avals] != [(a.shape, a.dtype) for a in avals]:
            return None
        if jax.default_backend() not in exported.platforms:
            return None
        return exported, out_tree
    except Exception:  # unreadable, or written by an incompatible version: export anew
        return None


def _write(path, digest, skeleton, blob):
    """Write an entry atomically (temporary file, then rename); failures are ignored."""
    payload = skeleton + blob
    head = _MAGIC + _HEAD.pack(digest, hashlib.sha256(payload).digest(), len(skeleton))
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(head + payload)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
    except OSError:
        pass


def _stable(value) -> str:
    """A description of a static argument that is the same in every process (functions by
    name, dataclasses and mappings by their contents)."""
    import dataclasses

    if isinstance(value, (tuple, list)):
        return f"{type(value).__name__}({', '.join(_stable(v) for v in value)})"
    if isinstance(value, dict) or (hasattr(value, "keys") and hasattr(value, "items")):
        items = sorted((repr(k), _stable(v)) for k, v in value.items())
        return "{" + ", ".join(f"{k}: {v}" for k, v in items) + "}"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = (f"{f.name}={_stable(getattr(value, f.name))}" for f in dataclasses.fields(value))
        return f"{type(value).__module__}.{type(value).__qualname__}({', '.join(fields)})"
    if callable(value) and hasattr(value, "__qualname__"):
        if "<" in value.__qualname__:  # a lambda or a local function: no name of its own
            return repr(value)  # (with its address: never cached)
        return f"{getattr(value, '__module__', '?')}.{value.__qualname__}"
    return repr(value)


@functools.cache
def _processor() -> str:
    """This machine's processor as XLA compiles for it: its model and instruction-set
    extensions (Linux's `/proc/cpuinfo`; elsewhere what `platform` tells)."""
    import platform

    try:
        with open("/proc/cpuinfo") as f:
            lines = f.read().split("\n\n")[0].splitlines()
        wanted = ("vendor_id", "model name", "flags", "Features", "CPU implementer", "CPU part")
        return "\n".join(ln for ln in lines if ln.split(":")[0].strip() in wanted)
    except OSError:
        return f"{platform.machine()} {platform.processor()}"


@functools.cache
def _environment(module: str) -> str:
    """Versions, flags and source hashes that a trace of a function of `module` depends on."""
    import importlib.metadata

    import jax

    versions = []
    for name in _LIBRARIES:
        try:
            versions.append(f"{name}={importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            versions.append(f"{name}=-")
    packages = sorted({"vmj", module.partition(".")[0]})
    sources = [f"{p}:{_source_hash(p)}" for p in packages]
    return " ".join([f"vmj={__version__}", *versions, *sources, f"backend={jax.default_backend()}"])


@functools.cache
def _source_hash(package: str) -> str:
    """sha256 of the Python sources of an imported package (paths and contents)."""
    root = os.path.dirname(os.path.abspath(sys.modules[package].__file__))
    h = hashlib.sha256()
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith(".py"):
                full = os.path.join(folder, name)
                h.update(os.path.relpath(full, root).encode() + b"\0")
                with open(full, "rb") as f:
                    h.update(f.read())
    return h.hexdigest()
