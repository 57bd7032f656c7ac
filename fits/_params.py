"""Parameter transforms of the fits: named bijections between an unconstrained coordinate `p`
(what the least-squares solver moves) and a parameter value `theta` inside its bounds.

Each transform is a small class with `forward(p)` (NumPy or JAX arrays) and `inverse(theta)`
(NumPy, for starting values), its bounds `lo`, `hi` and an integer `code`. The compiled solve
does not see these classes: every free slot carries `(code, lo, hi, scale)` as array data and
[`apply`][fits._params.apply] evaluates all slots at once, so ONE compiled solve serves every
bound set (user bounds, physical bounds, a slot held at a value).

| class            | range       | `theta(p)`                    |
|------------------|-------------|-------------------------------|
| `Real()`         | (-inf, inf) | `scale p`                     |
| `LowerBound(lo)` | [lo, inf)   | `lo + scale p^2`              |
| `UpperBound(hi)` | (-inf, hi]  | `hi - scale p^2`              |
| `Interval(lo,hi)`| [lo, hi]    | `lo + (hi - lo) sin(p)^2`     |
| `Positive()`     | [0, inf)    | `LowerBound(0)`               |

A slot with code `HELD` is not moved by `p`: it keeps its held value (a parameter that ran
into a bound, or a profile-likelihood point).
"""

from __future__ import annotations

import math
import warnings

import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "check_value",
    "warn_if_float32",
    "Transform",
    "Real",
    "LowerBound",
    "UpperBound",
    "Interval",
    "Positive",
    "transform_for",
    "apply",
    "derivative",
    "HELD",
]

REAL, LOWER, UPPER, INTERVAL, HELD = 0, 1, 2, 3, 4

_warned = False


def check_value(name: str, value, ok, allowed: str) -> float:
    """`value` as a float after checking that it is a finite number satisfying `ok`; else a
    `ValueError` "NAME must be finite and ALLOWED (got VALUE)"."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number (got {value!r})") from None
    if isinstance(value, bool) or not math.isfinite(v) or not ok(v):
        raise ValueError(f"{name} must be finite and {allowed} (got {value!r})")
    return v


def warn_if_float32() -> None:
    """Warn once when JAX runs in float32: the fits' accuracy statements assume float64."""
    global _warned
    if not _warned and not jax.config.jax_enable_x64:
        _warned = True
        warnings.warn(
            "fits: JAX is running in float32; accuracy figures assume float64. Enable it with "
            "jax.config.update('jax_enable_x64', True) before any computation.",
            stacklevel=3,
        )


_INSIDE = 1e-3  #: starting values are kept this fraction of the range inside a bound


class Transform:
    """Base of the bijections: `lo`, `hi` [parameter units], `code` (the compiled slot code)."""

    code = REAL

    def __init__(self, lo: float = -math.inf, hi: float = math.inf):
        self.lo, self.hi = float(lo), float(hi)

    def forward(self, p, scale=1.0):
        """The parameter value [its units] at the unconstrained coordinate `p` [-]."""
        return apply(self.code, self.lo, self.hi, scale, p)

    def inverse(self, theta: float, scale: float = 1.0) -> float:
        """The coordinate `p` [-] of the value `theta`, moved a little inside the bounds (a
        start ON a bound of a squared coordinate has zero gradient)."""
        return inverse(self.code, self.lo, self.hi, scale, theta)

    def contains(self, theta: float) -> bool:
        return self.lo <= theta <= self.hi

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.lo}, {self.hi})"

    def __eq__(self, other) -> bool:
        return type(self) is type(other) and (self.lo, self.hi) == (other.lo, other.hi)

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.lo, self.hi))


class Real(Transform):
    """Any real value: `theta = scale p`."""

    code = REAL

    def __init__(self):
        super().__init__()


class LowerBound(Transform):
    """`theta >= lo`: `theta = lo + scale p^2`."""

    code = LOWER

    def __init__(self, lo: float):
        super().__init__(lo, math.inf)


class UpperBound(Transform):
    """`theta <= hi`: `theta = hi - scale p^2`."""

    code = UPPER

    def __init__(self, hi: float):
        super().__init__(-math.inf, hi)


class Interval(Transform):
    """`lo <= theta <= hi`: `theta = lo + (hi - lo) sin(p)^2`."""

    code = INTERVAL

    def __init__(self, lo: float, hi: float):
        if not lo < hi:
            raise ValueError(f"an interval needs lo < hi (got {lo}, {hi})")
        super().__init__(lo, hi)


class Positive(LowerBound):
    """`theta >= 0`."""

    def __init__(self):
        super().__init__(0.0)


def transform_for(lo: float, hi: float) -> Transform:
    """The transform of the range `[lo, hi]` (infinite ends allowed)."""
    lo_f, hi_f = math.isfinite(lo), math.isfinite(hi)
    if lo_f and hi_f:
        return Interval(lo, hi)
    if lo_f:
        return LowerBound(lo)
    if hi_f:
        return UpperBound(hi)
    return Real()


def apply(code, lo, hi, scale, p, held=None):
    """Values of slots (arrays broadcast together; NumPy or JAX): `code` per slot, bounds `lo`,
    `hi`, `scale` and coordinates `p`; slots coded `HELD` take `held`."""
    xp = _namespace(p)
    lo_s = xp.where(xp.isfinite(lo), lo, 0.0)
    hi_s = xp.where(xp.isfinite(hi), hi, 0.0)
    width = xp.where(code == INTERVAL, hi_s - lo_s, 1.0)
    val = xp.where(
        code == REAL,
        scale * p,
        xp.where(
            code == LOWER,
            lo_s + scale * p * p,
            xp.where(code == UPPER, hi_s - scale * p * p, lo_s + width * xp.sin(p) ** 2),
        ),
    )
    if held is not None:
        val = xp.where(code == HELD, held, val)
    return val


def derivative(code, lo, hi, scale, p):
    """`d theta / d p` of every slot (0 for held slots)."""
    xp = _namespace(p)
    width = xp.where(
        code == INTERVAL,
        xp.where(xp.isfinite(hi), hi, 0.0) - xp.where(xp.isfinite(lo), lo, 0.0),
        1.0,
    )
    dv = xp.where(
        code == REAL,
        scale,
        xp.where(
            code == LOWER,
            2 * scale * p,
            xp.where(code == UPPER, -2 * scale * p, width * xp.sin(2 * p)),
        ),
    )
    return xp.where(code == HELD, 0.0, dv)


def inverse(code: int, lo: float, hi: float, scale: float, theta: float) -> float:
    """The coordinate of `theta` (NumPy scalar), kept `_INSIDE` of the range off a bound."""
    if code == REAL:
        return theta / scale
    if code == LOWER:
        return math.sqrt(max(theta - lo, _INSIDE * scale) / scale)
    if code == UPPER:
        return math.sqrt(max(hi - theta, _INSIDE * scale) / scale)
    if code == INTERVAL:
        u = min(max((theta - lo) / (hi - lo), _INSIDE), 1 - _INSIDE)
        return math.asin(math.sqrt(u))
    return 0.0


def at_bound(code, lo, hi, scale, p, near):
    """Which slots sit at a bound (their coordinate within `near` of it), and the bound."""
    code, p = np.asarray(code), np.asarray(p)
    sin2 = np.sin(p) ** 2
    sq = p * p
    lower = ((code == LOWER) & (sq < near)) | ((code == INTERVAL) & (sin2 < near))
    upper = ((code == UPPER) & (sq < near)) | ((code == INTERVAL) & (sin2 > 1 - near))
    value = np.where(lower, np.where(np.isfinite(lo), lo, 0.0), np.where(np.isfinite(hi), hi, 0.0))
    return lower | upper, value


def _namespace(x):
    return jnp if isinstance(x, jax.Array) else np
