"""Option helpers shared by the command modules (and by `fits._cli`, which owns `vmj fit`).

Everything here is light: argparse and the standard library only, so that `vmj --help` and
argument errors never import JAX. An argparse `type=` below runs while the arguments are parsed,
so a bad value or an unusable path is refused before any computation.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os

from .._names import name_list

__all__ = [
    "HelpFormatter",
    "Joined",
    "LARGEST",
    "number",
    "count",
    "parse_set",
    "parse_axis",
    "input_file",
    "output_path",
    "figure_path",
    "emit",
    "jsonable",
    "name_list",
    "refuse_above",
    "traced_checks",
    "FIGURE_FORMATS",
]


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Help with each option's default (or `required`) after its description; descriptions and
    epilogs are printed as written."""

    def _get_help_string(self, action):
        text = action.help or ""
        if not action.option_strings or "%(default)" in text or action.help is argparse.SUPPRESS:
            return text
        if action.required:
            return f"{text} (required)"
        if action.default not in (None, False, argparse.SUPPRESS) and action.nargs != 0:
            return f"{text} (default: %(default)s)"
        return text


class Joined(argparse.Action):
    """A comma-list option that may be given several times: `--set a=1 --set b=2` means `--set
    a=1,b=2` (argparse's default would keep the last one silently)."""

    def __call__(self, parser, namespace, values, option_string=None):
        before = getattr(namespace, self.dest, None)
        setattr(namespace, self.dest, f"{before},{values}" if before else values)


#: largest magnitude of a number on the command line: far beyond any physical parameter in SI
#: units, and small enough that the solvers' products of a few parameters stay finite
LARGEST = 1e20
#: smallest magnitude of a nonzero number on the command line (`1 / LARGEST`): products and
#: quotients of a few parameters stay normal numbers (`--k 1e-320` gave omega_c 0 and NaN)
SMALLEST = 1 / LARGEST


def number(text: str) -> float:
    """A finite float, 0 or of magnitude within `[SMALLEST, LARGEST]` (argparse type)."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"not a finite number: {text!r}")
    if abs(value) > LARGEST:
        raise argparse.ArgumentTypeError(
            f"must be a number of magnitude at most {LARGEST:g} (got {text!r})"
        )
    if 0 < abs(value) < SMALLEST:
        raise argparse.ArgumentTypeError(
            f"must be 0 or a number of magnitude at least {SMALLEST:g} (got {text!r})"
        )
    return value


def count(text: str) -> int:
    """An integer >= 1 (argparse type): a number of turning points, points per chunk."""
    try:
        value = int(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1 (got {value})")
    return value


def parse_set(text: str | None) -> dict:
    """`NAME=VALUE[,NAME=VALUE...]` of `--set` as `{name: text}`; a name given twice is an error."""
    out = {}
    for item in filter(None, (s.strip() for s in (text or "").split(","))):
        if "=" not in item:
            raise ValueError(f"--set takes NAME=VALUE pairs separated by commas (got {item!r})")
        name, value = (s.strip() for s in item.split("=", 1))
        if not name:
            raise ValueError(f"--set: a value without a name (got {item!r})")
        if name in out:
            raise ValueError(f"--set gives {name} twice")
        out[name] = value
    return out


def parse_axis(flag: str, text: str, limit: int | None = None, over: str = "") -> list[float]:
    """The values of an axis: `start:stop:count` (inclusive, evenly spaced), a comma list, or one
    number. `flag` is the option as the user spelled it (for the message); more than `limit`
    values are refused (before they are made) with the reason `over`."""

    def refuse(n):
        if limit is not None and n > limit:
            raise ValueError(f"{flag} has {n:g} values; {over}")

    def num(t):
        try:
            return number(t.strip())
        except argparse.ArgumentTypeError as e:
            raise ValueError(
                f"{flag}: {e} (an axis is start:stop:count, a comma list, or one value)"
            ) from None

    if ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise ValueError(f"{flag} must be start:stop:count (got {text!r})")
        start, stop = num(parts[0]), num(parts[1])
        try:
            n = int(parts[2])
        except ValueError:
            n = 0
        if n < 1 or (n == 1 and start != stop):
            raise ValueError(
                f"{flag}: count must be an integer >= 1, and >= 2 when start != stop (got {text!r})"
            )
        refuse(n)
        if n == 1:
            return [start]
        return [start + (stop - start) * i / (n - 1) for i in range(n)]
    parts = text.split(",")
    refuse(len(parts))
    return [num(t) for t in parts]


def input_file(text: str) -> str:
    """An existing, readable text file (argparse type): its first 64 kB must be UTF-8 text."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty file name")
    if os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text!r} is a directory; give a file")
    if not os.path.exists(text):
        raise argparse.ArgumentTypeError(f"no such file: {text!r}")
    try:
        with open(text, "rb") as fh:
            head = fh.read(65536)
    except OSError as e:
        raise argparse.ArgumentTypeError(f"cannot read {text!r} ({e.strerror})") from None
    try:
        if b"\0" in head:
            raise UnicodeError("a NUL byte")
        head.decode("utf-8")
    except UnicodeDecodeError as e:
        if len(head) < 65536 or e.start < len(head) - 3:  # not a character cut at 64 kB
            raise argparse.ArgumentTypeError(
                f"{text!r} is not a UTF-8 text file (byte {e.start}: {e.reason})"
            ) from None
    except UnicodeError as e:
        raise argparse.ArgumentTypeError(f"{text!r} is not a text file ({e})") from None
    return text


def output_path(text: str) -> str:
    """A path a file can be written to (argparse type): not a directory, in a directory that
    exists and is writable. The file itself is written atomically, after the computation."""
    from .._files import check_writable

    try:
        return check_writable(text, "path")
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("path ")) from None


def store_path(text: str) -> str:
    """A directory store (argparse type): an existing store, or a new one in a directory that
    exists and is writable. Whether it may be continued is decided by the store itself."""
    path = os.path.abspath(text)
    if os.path.isdir(path):
        if not os.access(path, os.W_OK):
            raise argparse.ArgumentTypeError(f"{text!r}: the store is not writable")
        return text
    if os.path.exists(path):
        raise argparse.ArgumentTypeError(f"{text!r} exists and is not a store (a directory)")
    return output_path(text)


#: figure formats matplotlib writes with its default backends (checked by the tests)
FIGURE_FORMATS = (
    "png",
    "pdf",
    "svg",
    "svgz",
    "eps",
    "ps",
    "jpg",
    "jpeg",
    "tif",
    "tiff",
    "webp",
    "pgf",
    "raw",
    "rgba",
)


def figure_path(text: str) -> str:
    """An `output_path` whose extension names a figure format (none: PNG)."""
    path = output_path(text)
    ext = os.path.splitext(path)[1].lstrip(".").lower()
    if ext and ext not in FIGURE_FORMATS:
        raise argparse.ArgumentTypeError(
            f"{text!r}: unknown figure format {ext!r} (use one of {', '.join(FIGURE_FORMATS)})"
        )
    return path


def emit(obj, as_json: bool, text: str) -> None:
    """Print `obj` as one JSON object (`jsonable`), or `text`."""
    print(json.dumps(jsonable(obj), allow_nan=False) if as_json else text)


def jsonable(obj):
    """`obj` with NumPy arrays and scalars as Python values and NaN or infinity as `None`
    (JSON's `null`: strict parsers refuse a bare `NaN`)."""
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if hasattr(obj, "tolist"):  # a NumPy array or scalar
        return jsonable(obj.tolist())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def refuse_above(what: str, amount: float, limit: float, unit: str = "") -> None:
    """Refuse work estimated above `limit` (`amount` and `limit` in `unit`); call it only when
    `--force` was not given."""
    if amount > limit:
        raise ValueError(
            f"{what}: refused above {limit:.3g}{' ' + unit if unit else ''} (give "
            "--force to run it anyway)"
        )


@contextlib.contextmanager
def traced_checks():
    """Turn a value check that fired inside compiled code into a one-line `ValueError`.

    Sweeps and sensitivities evaluate the model under `jax.vmap` and `jax.jacfwd`, where its
    fields are traced: a check that depends on several fields at once (e.g. whether a rope's
    energy map applies) is then an `equinox.error_if`, which raises `EquinoxRuntimeError` at run
    time instead of the `ValueError` a concrete check gives. Every single value was checked on
    the host before.
    """
    import equinox as eqx

    try:
        yield
    except eqx.EquinoxRuntimeError as e:
        tag = "EquinoxRuntimeError: "
        said = [ln.split(tag, 1)[1] for ln in str(e).splitlines() if tag in ln]
        raise ValueError(
            said[-1] if said else "invalid input (a check inside the computation)"
        ) from None
