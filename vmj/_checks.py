"""Input validation shared by every entry point.

Concrete values (Python numbers, NumPy arrays, concrete JAX arrays) are checked eagerly and
raise `ValueError` naming the parameter and its allowed range. Traced values are returned as
status codes where vmj compiles the program itself (an entry point's own trace, a sweep's
chunk: `collecting`) and raise on the host with the same message; inside the user's `jit`,
`vmap` or `grad` they are checked with `equinox.error_if`, which raises at run time.
"""

from __future__ import annotations

import contextlib
import contextvars
import inspect
import math
import warnings
from collections.abc import Callable
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "AbstractParams",
    "NotANumber",
    "validated",
    "mark_checked",
    "assume_valid",
    "guard",
    "check",
    "check_all",
    "check_int",
    "default_float",
    "scalar",
    "warn_if_float32",
]


def _is_traced(x) -> bool:
    return isinstance(x, jax.core.Tracer)


def instance_of(x, cls) -> bool:
    """`isinstance(x, cls)`, the answer kept per type: for an equinox module it goes through
    ABCMeta and costs 1.4 us (the entry points' checks of models and solvers use it)."""
    key = (type(x), cls)
    found = _INSTANCES.get(key)
    if found is None:
        found = _INSTANCES[key] = isinstance(x, cls)
    return found


_INSTANCES: dict = {}


def own_fields(x) -> dict:
    """`vars(x)` without equinox's `__getattribute__` (1.1 against 0.2 us a call)."""
    return object.__getattribute__(x, "__dict__")


def default_float() -> np.dtype:
    """JAX's default float type (float64 with x64 enabled), read off its flag:
    `jnp.result_type(float)` costs a warm single solve 2 us a call."""
    return np.dtype(np.float64 if jax.config.jax_enable_x64 else np.float32)


class NotANumber(ValueError):
    """A boolean or a string where vmj expects a number: raised by `_float`, which does not
    know the parameter's name; [`vmj.AbstractParams`][] names it."""

    def __init__(self, value, name: str | None = None, allowed: str | None = None):
        self.value = value
        head = "vmj's parameters are numbers" if name is None else f"{name} must be a number"
        rule = "" if allowed is None else f" ({allowed})"
        super().__init__(f"{head}{rule}, not {_kind_of(value)} (got {value!r})")


def _kind_of(value) -> str:
    if isinstance(value, (str, bytes)) or getattr(getattr(value, "dtype", None), "kind", "") in (
        "U",
        "S",
    ):
        return "a string"
    if isinstance(value, (list, tuple)) or np.ndim(value) > 0:
        return "an array holding booleans or strings"
    return "a boolean"


def not_a_number(x) -> bool:
    """Whether `x` is a boolean or a string, or an array or sequence holding one: `float(True)`
    and `np.asarray("5", dtype=float)` convert silently (`vmj.VariableMass(m0=True, ...)` had
    `m0 = 1.0`). Numbers, NumPy and JAX arrays of numbers and tracers are not."""
    if isinstance(x, (bool, str, bytes)):
        return True
    kind = getattr(getattr(x, "dtype", None), "kind", None)
    if kind is not None:  # NumPy scalars and arrays, JAX arrays and tracers
        return kind in "bUSV" or (kind == "O" and any(not_a_number(v) for v in np.ravel(x)))
    if isinstance(x, (list, tuple)):
        return any(not_a_number(v) for v in x)
    return False


def _float(x) -> jax.Array:
    """A float array of JAX's default float type (float64 with x64 enabled). A Python number or
    NumPy array is cast by NumPy and put on the device as it is: `jnp.asarray` would run (and,
    in a new process, load or compile) a conversion program for it. A complex value is a
    ValueError: the cast kept its real part with only a ComplexWarning (a complex-step
    derivative, `F = 14.7 + 1e-20j`, came out 0); so is a boolean or a string
    (`NotANumber`, which the modules' constructors name)."""
    dtype = default_float()
    if isinstance(x, complex) or getattr(getattr(x, "dtype", None), "kind", "") == "c":
        raise ValueError(
            f"vmj's parameters are real numbers (got the complex {x!r}); for derivatives use "
            "jax.grad, jax.jvp or jax.jacfwd"
        )
    if not_a_number(x):
        raise NotANumber(x)
    if isinstance(x, jax.Array) or _is_traced(x):
        return jnp.asarray(x, dtype=dtype)
    return jax.device_put(np.asarray(x, dtype=dtype))


def check(name: str, value, ok: Callable, allowed: str):
    """Return `value` after checking it is finite and satisfies `ok` elementwise.

    `ok` must work on Python numbers, NumPy and JAX arrays alike. `allowed` is the human
    description of the range, e.g. `"> 0"` or `"in [0, 1]"`.
    """
    if (
        isinstance(value, (float, int))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and ok(value)
    ):
        return value  # the common case, without building arrays
    return check_all([(name, value, ok, allowed)])[0]


def scalar(name: str, value):
    """A checked scalar argument as an array of JAX's default float type: a NumPy array for
    concrete values (a compiled entry point takes it without a device round trip or a
    recompilation for Python floats), traced values unchanged but cast. An array of any other
    shape is a `ValueError` naming the argument (the solvers' arrays have one lane: an array
    of `a0` broke the results' shapes; a sweep or `jax.vmap` maps over several)."""
    if not isinstance(value, float) and not_a_number(value):
        raise NotANumber(value, name)
    if not isinstance(value, float) and np.ndim(value) != 0:
        raise ValueError(
            f"{name} must be a scalar (got shape {np.shape(value)}); "
            "for several values use jax.vmap or vmj.sweep"
        )
    if _is_traced(value):
        return jnp.asarray(value, dtype=default_float())
    return np.asarray(value, dtype=default_float())


def check_all(items) -> list:
    """`check` for several `(name, value, ok, allowed)` at once: the traced values share one
    `equinox.error_if` (one host callback per call, however many parameters), which names the
    first parameter out of range."""
    items = list(items)
    out = [value for _, value, _, _ in items]
    traced = []
    for i, (name, value, ok, allowed) in enumerate(items):
        message = f"{name} must be finite and {allowed}"
        if not_a_number(value):
            raise NotANumber(value, name, allowed)
        if _is_traced(value):
            if _ASSUMED.get():
                continue
            traced.append((i, jnp.logical_not(jnp.all(jnp.isfinite(value) & ok(value))), message))
            continue
        if np.iscomplexobj(value):
            raise ValueError(f"{message}, a real number (got {value!r})")
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{message}, a number (got {value!r})") from None
        if not (np.all(np.isfinite(arr)) and np.all(ok(arr))):
            shown = arr.item() if arr.ndim == 0 else arr
            raise ValueError(f"{message} (got {shown})")
    if traced:
        bad = jnp.stack([b for _, b, _ in traced])
        guarded = fail_branched(
            tuple(out[i] for i, _, _ in traced),
            jnp.any(bad),
            jnp.argmax(bad),
            [m for _, _, m in traced],
        )
        for (i, _, _), g in zip(traced, guarded):
            out[i] = g
    return out


#: memory needs from this size on are checked against the memory free for them [bytes] (a
#: warm solve makes no system call)
ROOM_CHECKED_FROM = 1 << 26


def check_room(what: str, need: int, advice: str, device=None) -> None:
    """`ValueError` where `what` needs `need` bytes, more than `device` (JAX's default device
    if None) has free: the process was killed for want of memory instead (`vmj.turning_points`
    with `n = 10**9` on a 24 GiB machine; a sweep's result, whose `np.empty` succeeds where the
    operating system overcommits memory). `advice` says what to ask for instead."""
    if need < ROOM_CHECKED_FROM:
        return
    from ._host import available_memory

    device = jax.devices()[0] if device is None else device
    free = available_memory(device, need)
    if free is not None and need > free:
        raise ValueError(
            f"{what}: about {need / 1e9:.3g} GB, more than the {free / 1e9:.3g} GB free on "
            f"{device.platform}; {advice}"
        )


def check_int(name: str, value, minimum: int) -> int:
    """Check a static integer (an array shape, an iteration count). A concrete 0-d integer
    array is taken; a traced one is refused with how to keep it static."""
    if type(value) is int and value >= minimum:
        return value  # the common case, first: a warm solve costs tens of microseconds
    if _is_traced(value):
        raise ValueError(
            f"{name} must be a static integer >= {minimum} (it sets an array shape), not a "
            "traced value: pass a Python int, e.g. with jax.jit(..., static_argnums=...) or "
            "equinox.filter_jit"
        )
    if (
        isinstance(value, (np.ndarray, jax.Array))
        and value.ndim == 0
        and np.issubdtype(value.dtype, np.integer)
    ):
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum} (got {value!r})")
    return int(value)


positive = lambda x: x > 0  # noqa: E731
nonnegative = lambda x: x >= 0  # noqa: E731
anything = lambda x: x == x  # noqa: E731
unit_interval = lambda x: (x >= 0) & (x <= 1)  # noqa: E731

_warned = False


def warn_if_float32() -> None:
    """Warn once when JAX runs in float32: vmj's accuracy statements assume float64."""
    global _warned
    if not _warned and not jax.config.jax_enable_x64:
        _warned = True
        warnings.warn(
            "vmj: JAX is running in float32; accuracy figures assume float64. Enable it with "
            "jax.config.update('jax_enable_x64', True) before any computation.",
            stacklevel=3,
        )


# -- parameterised modules ----------------------------------------------------------------------
class _ParamsMeta(type(eqx.Module)):
    """Names the parameter of a `NotANumber` that a converter raised: the converters see a
    value only. Costs nothing unless it raises."""

    def __call__(cls, *args, **kwargs):
        try:
            return super().__call__(*args, **kwargs)
        except NotANumber as error:
            if error.value is None:
                raise
            name = _argument_named(cls, error.value, args, kwargs)
            if name is None:
                raise
            allowed = cls._limits.get(name, (None, None))[1]
            raise NotANumber(error.value, name, allowed) from None


def _argument_named(cls, value, args, kwargs) -> str | None:
    """The name of the constructor's argument that is `value` (the first in order)."""
    try:
        bound = inspect.signature(cls.__init__).bind(None, *args, **kwargs)
    except TypeError:
        return None
    names = list(bound.arguments)[1:]
    return next((n for n in names if bound.arguments[n] is value), None)


class AbstractParams(eqx.Module, metaclass=_ParamsMeta):
    """Base of every model and law: `_limits` maps a field name to `(predicate, allowed range)`;
    `_relations` maps a field name to `(predicate of the module, allowed range)` for a range
    that depends on other fields (e.g. a static friction level at least the kinetic one).

    Concrete values are checked once, at construction (`ValueError` naming the field and its
    range); the entry points call `validated` on the whole model tree, which guards traced
    values (inside `jit`, `vmap`, `grad`) with one `equinox.error_if` and re-checks concrete
    values that bypassed construction (`eqx.tree_at`, `jax.tree.unflatten`).
    """

    _limits: ClassVar[dict] = {}
    _relations: ClassVar[dict] = {}

    def __check_init__(self):
        problems = _problems(self, traced=False)
        _raise_concrete(problems)
        if not any(traced for *_, traced in problems):
            # Checked here, once. The mark lives on this instance only: every other way to make
            # a module (tree_at, unflatten inside jit/vmap) builds a new instance without it.
            object.__setattr__(self, _CHECKED, True)


#: attribute marking a module whose limited fields were concrete and checked at construction
_CHECKED = "_vmj_checked"
#: attribute marking a module whose whole tree `validated` has found valid
_TREE_CHECKED = "_vmj_tree_checked"
_ASSUMED = contextvars.ContextVar("vmj_assume_valid", default=False)


@contextlib.contextmanager
def assume_valid():
    """Within this block, vmj compiles no runtime checks of traced parameters and arguments.

    Inside `jax.jit`/`jax.vmap` vmj's entry points guard traced values (model parameters,
    `a0`, ...) with `equinox.error_if`, a host callback: it makes the compiled program
    synchronous and keeps it out of JAX's persistent compilation cache. Code that keeps its
    values in range by construction (a fit's transformed parameters, a sweep over arrays that
    were checked) can trace its solves inside this block instead. Concrete values are still
    checked; what is traced here is compiled without the guards, also when it runs later.

        with vmj.assume_valid():
            fitted = jax.jit(residuals)(theta)
    """
    token = _ASSUMED.set(True)
    try:
        yield
    finally:
        _ASSUMED.reset(token)


def guard(x, bad, message: str):
    """`fail_if(x, bad, message)` for a check of an input, unless inside `assume_valid`."""
    return x if _ASSUMED.get() else fail_if(x, bad, message)


# -- checks of traced values, as host callbacks or as values -----------------------------------
#: the collector of the program being traced at top level (`collecting`), or None
_COLLECTOR = contextvars.ContextVar("vmj_collector", default=None)


def _current_trace():
    from jax._src import core

    return core.trace_ctx.trace


def fail_if(x, bad, message: str, error: type = ValueError):
    """`x`, failing with `message` where `bad` (any entry) holds: at once (`error`) for a
    concrete `bad`; for a traced one, collected as a value where a compiled entry point or a
    sweep's chunk traces it (`collecting`), else `equinox.error_if` (a host callback: inside
    the user's `jit`/`vmap`, or a loop's body)."""
    return fail_branched(x, jnp.any(bad), 0, (message,), error)


def fail_branched(x, bad, index, messages, error: type = ValueError):
    """`fail_if` with the message `messages[index]` (`equinox.branched_error_if`'s form): one
    check however many parameters it covers."""
    messages = tuple(messages)
    if not _is_traced(bad):
        if bool(np.any(bad)):
            raise error(messages[int(index)])
        return x
    collector = _COLLECTOR.get()
    if collector is not None and collector.trace is _current_trace():
        code = jnp.where(jnp.any(bad), jnp.asarray(index, jnp.int32), -1)
        collector.found.append((code, messages, error))
        return x
    return eqx.branched_error_if(x, jnp.any(bad), index, messages)


class Failures(eqx.Module):
    """The checks that a compiled program traced at top level returns as values
    (`collecting`): per check the index of its failed message (`-1`: passed), its messages
    and the exception it raises on the host."""

    codes: tuple
    messages: tuple = eqx.field(static=True)
    errors: tuple = eqx.field(static=True)

    def raise_any(self) -> None:
        """Raise the first failed check's exception, its message (concrete codes, of one
        call or of a sweep's chunk of points: any that failed); its `check_message` attribute
        is the message alone (a sweep's record of a failed chunk)."""
        for code, messages, error in zip(self.codes, self.messages, self.errors):
            code = int(np.max(np.asarray(code)))
            if code >= 0:
                failed = error(messages[code])
                failed.check_message = messages[code]
                raise failed

    def guard(self, x):
        """`x` guarded by the same checks in the trace that is current (`fail_branched`): for
        checks collected inside a transformation and returned out of it (`jax.jacfwd`'s
        auxiliary output)."""
        for code, messages, error in zip(self.codes, self.messages, self.errors):
            x = fail_branched(x, code >= 0, jnp.maximum(code, 0), messages, error)
        return x


class _Collector:
    def __init__(self):
        self.trace, self.found = _current_trace(), []

    def failures(self) -> Failures:
        codes, messages, errors = zip(*self.found) if self.found else ((), (), ())
        return Failures(tuple(codes), tuple(messages), tuple(errors))


@contextlib.contextmanager
def collecting():
    """Within this block, checks of values traced at the trace that is current (not deeper:
    inside a `vmap`, a loop's body or a derivative's trace their values cannot leave) are
    collected instead of compiled as host callbacks; yields the collector, whose `failures()`
    the traced function returns: the compiled program stays free of host callbacks (JAX's
    persistent compilation cache stores no program that has one), and the caller raises
    (`Failures.raise_any`) on the host with the same message. Used by `filter_jit` (a
    call's own trace; a call inside another trace hands its failures on to that one,
    `Failures.guard`) and by a sweep's chunk (the trace of its `jax.vmap` over the points)."""
    collector = _Collector()
    token = _COLLECTOR.set(collector)
    try:
        yield collector
    finally:
        _COLLECTOR.reset(token)


def _problems(m, traced: bool = True) -> list:
    """`(message, field value, ok, traced)` of each check of the module `m` itself: `ok` is a
    boolean array (all True when the check passes); for a traced value only a placeholder
    unless `traced`."""
    out = []
    for n, (ok, allowed) in type(m)._limits.items():
        value = getattr(m, n)
        if _is_traced(value):
            out.append(
                (
                    f"{n} must be finite and {allowed}",
                    value,
                    jnp.isfinite(value) & ok(value) if traced else None,
                    True,
                )
            )
        else:
            if not_a_number(value):  # (set without the converter: eqx.tree_at)
                raise NotANumber(value, n, allowed)
            arr = np.asarray(value, dtype=float)
            out.append(
                (f"{n} must be finite and {allowed}", arr, np.isfinite(arr) & ok(arr), False)
            )
    for n, (ok, allowed) in type(m)._relations.items():
        if not traced and any(_is_traced(x) for x in jax.tree.leaves(m)):
            out.append((f"{n} must be {allowed}", getattr(m, n), None, True))
            continue
        flags = ok(m)
        out.append((f"{n} must be {allowed}", getattr(m, n), flags, _is_traced(flags)))
    return out


def _raise_concrete(problems) -> None:
    for message, value, ok, traced in problems:
        if not traced and not np.all(ok):
            raise ValueError(f"{message} (got {_bad_entries(np.asarray(value), ok)})")


def _bad_entries(arr: np.ndarray, ok) -> str:
    """The value that failed a check, for its message: a scalar itself; an array's first bad
    entry with its index, and how many are bad (NumPy's summary of a long array, `[0. 0.0002
    ... 1.]`, left the bad value out)."""
    if arr.ndim == 0:
        return str(arr.item())
    if np.shape(ok) != arr.shape:  # (a relation whose other fields broadcast further)
        return str(arr)
    bad = np.argwhere(~np.asarray(ok, dtype=bool))
    first = tuple(int(i) for i in bad[0])
    where, of = (first[0], arr.size) if arr.ndim == 1 else (first, arr.shape)
    more = f"; {len(bad)} bad" if len(bad) > 1 else ""
    return f"{arr[first]} at index {where} of {of}{more}"


def _modules(tree):
    """Every module of a model tree (the models and the laws, tuples of laws included),
    parents before their children."""
    if instance_of(tree, AbstractParams):
        yield tree
        for v in own_fields(tree).values():
            yield from _modules(v)
    elif isinstance(tree, (tuple, list)):  # a tuple of laws
        for v in tree:
            yield from _modules(v)


def mark_checked(model):
    """Mark every module of `model` as checked, so that [`validated`][] passes it without
    guards: for a model rebuilt from values that were validated elsewhere. A sweep validates
    its parameter arrays on the host once; each point's model, rebuilt inside the compiled
    chunk, is marked, so the chunk checks nothing of it again (arguments the chunk's function
    computes are still checked, as values the chunk returns: `collecting`). Returns `model`."""
    for m in _modules(model):
        object.__setattr__(m, _CHECKED, True)
    return model


def validated(model):
    """Check every limited field (and relation) of `model` and of the modules inside it; return
    the model guarded by one `equinox.error_if` over all its traced checks (concrete ones raise
    `ValueError` now). Modules checked at their construction, or by an earlier call with
    concrete values (and not rebuilt since), are not checked again; a whole tree found valid
    is not walked again either (its modules are immutable: 4.8 -> 0.9 us per warm solve)."""
    if instance_of(model, AbstractParams) and own_fields(model).get(_TREE_CHECKED, False):
        return model
    problems = []
    concrete = []  # modules whose own checks are all concrete: marked once they pass
    for m in _modules(model):
        if not own_fields(m).get(_CHECKED, False):
            own = _problems(m)
            problems.extend(own)
            if not any(traced for *_, traced in own):
                concrete.append(m)
    _raise_concrete(problems)
    for m in concrete:
        object.__setattr__(m, _CHECKED, True)
    traced = [(message, ok) for message, _, ok, is_traced in problems if is_traced]
    if not traced and instance_of(model, AbstractParams):
        object.__setattr__(model, _TREE_CHECKED, True)
    if not traced or _ASSUMED.get():
        return model
    bad = jnp.stack([jnp.logical_not(jnp.all(ok)) for _, ok in traced])
    return fail_branched(model, jnp.any(bad), jnp.argmax(bad), [message for message, _ in traced])
