"""The data side of the sensor model: starting values of a sensor's offset and side-dependent gain
from the turning points of a record.

The sensor model reads a deflection `x` as

    y = offset + (1 + asym) x   (x > 0),        y = offset + (1 - asym) x   (x < 0),

so a positive extremum of true amplitude `A` reads `offset + (1 + asym) A` and a negative one
`offset - (1 - asym) A`. Half their sum is `offset + asym A`, half their difference `A`: the
centre of a pair of successive extrema moves linearly with their amplitude, with slope `asym`
and intercept `offset`. Successive extrema are not at the same amplitude (the motion decays),
so each extremum `x_k` is paired with the opposite-side extremum interpolated to the same swing
index from its neighbours,

    x̄_k = (-x_{k-3} + 9 x_{k-1} + 9 x_{k+1} - x_{k+3}) / 16

(cubic interpolation; `(x_{k-1} + x_{k+1}) / 2` next to the ends), which is exact for an
amplitude that is a cubic in `k` and within `delta^4` for a geometric decay of logarithmic
decrement `delta`. With the local centre `c_k = (x_k + x̄_k) / 2` and amplitude
`d_k = |x_k - x̄_k| / 2`, [`fits.sensor_start`][] fits the line `c = offset + asym d` robustly
(Theil-Sen: the median of the pairwise slopes, then the median intercept).

Caveat: an even restoring term (`x^2` in the restoring force) also moves the centre with the
amplitude, as `A^2`; over a decay from large amplitudes the line then takes up part of it. The
values are starting values for the fit, which separates the two by the shape of the motion.
"""

from __future__ import annotations

import numpy as np

from ._extract import extract_turning_points
from ._record import Record
from ._signal import Signal

__all__ = ["sensor_start"]


def _opposite(x: np.ndarray) -> np.ndarray:
    """The opposite-side extremum interpolated at every interior swing index."""
    n = x.size
    out = np.full(n, np.nan)
    out[1:-1] = (x[:-2] + x[2:]) / 2
    if n >= 7:
        out[3:-3] = (-x[:-6] + 9 * x[2:-4] + 9 * x[4:-2] - x[6:]) / 16
    return out


def _theil_sen(d: np.ndarray, c: np.ndarray, max_pairs: int = 500_000) -> tuple[float, float]:
    n = d.size
    i, j = np.triu_indices(n, 1)
    if i.size > max_pairs:  # long records: an evenly spread subset of the pairs
        keep = np.linspace(0, i.size - 1, max_pairs).astype(int)
        i, j = i[keep], j[keep]
    dd = d[j] - d[i]
    ok = np.abs(dd) > 1e-12 * max(float(np.max(np.abs(d))), 1e-300)
    if not np.any(ok):
        return 0.0, float(np.median(c))
    slope = float(np.median((c[j] - c[i])[ok] / dd[ok]))
    return slope, float(np.median(c - slope * d))


def sensor_start(data: Record | Signal) -> dict:
    """Starting values of the sensor offset and asymmetry from the alternation of successive
    extrema (the estimator is described in this module's text).

    **Arguments:**

    - `data`: a [`fits.Record`][] with signed turning points (extracted from a signal, or read
      with signs), or a raw [`fits.Signal`][] (its turning points are extracted first).

    **Returns** a dict: `offset` [signal units], `asym` [-] (a positive swing is read
    `1 + asym` times, a negative one `1 - asym` times), `offset_stderr`, `asym_stderr`
    (approximate: neighbouring centres share turning points, so treat them as scales, not
    intervals; `None` where they cannot be estimated), `n` (the number of local centres used),
    and a one-line `message`. With fewer than 5 local centres, or amplitudes that barely change,
    the asymmetry is not identifiable: `asym` is then 0 and `offset` the median centre.

    Raises `ValueError` for a record whose sides are unknown (amplitudes only), or with fewer
    than 3 turning points.
    """
    record = extract_turning_points(data) if isinstance(data, Signal) else data
    if not isinstance(record, Record):
        raise ValueError(
            f"sensor_start needs a fits.Record or fits.Signal, got {type(data).__name__}"
        )
    src = f"{record.source}: " if record.source else ""
    if not record.sides_known:
        raise ValueError(
            f"{src}the record holds amplitudes without sides: the sensor's offset "
            "and asymmetry need signed turning points"
        )
    k = np.asarray(record.k)
    x = np.asarray(record.positions, dtype=float)
    # runs of consecutive swings (a record may skip swing indices)
    runs = np.split(np.arange(k.size), np.nonzero(np.diff(k) != 1)[0] + 1)
    c_all, d_all = [], []
    for run in runs:
        if run.size < 3:
            continue
        xr = x[run]
        xo = _opposite(xr)[1:-1]
        c_all.append((xr[1:-1] + xo) / 2)
        d_all.append(np.abs(xr[1:-1] - xo) / 2)
    if not c_all:
        raise ValueError(
            f"{src}need at least 3 consecutive turning points for the sensor's "
            f"offset (got {k.size})"
        )
    c, d = np.concatenate(c_all), np.concatenate(d_all)
    n = c.size
    spread = float(np.max(d) / max(float(np.min(d)), 1e-300)) if n else 1.0
    if n < 5 or spread < 1.2:
        offset = float(np.median(c))
        resid = c - offset
        scale = 1.4826 * float(np.median(np.abs(resid)))
        return {
            "offset": offset,
            "asym": 0.0,
            "offset_stderr": float(scale / np.sqrt(n)) if n > 1 else None,
            "asym_stderr": None,
            "n": int(n),
            "message": f"offset {offset:.6g} from the median of {n} local centres; the "
            "asymmetry is not identifiable (too few swings or too little decay), "
            "taken as 0",
        }
    asym, offset = _theil_sen(d, c)
    resid = c - offset - asym * d
    scale = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    # neighbouring centres share turning points: about a third of them are independent
    ssd = float(np.sum((d - d.mean()) ** 2))
    inflate = np.sqrt(3.0)
    asym_se = float(inflate * scale / np.sqrt(ssd)) if ssd > 0 else None
    offset_se = float(inflate * scale * np.sqrt(1 / n + d.mean() ** 2 / ssd)) if ssd > 0 else None
    return {
        "offset": offset,
        "asym": asym,
        "offset_stderr": offset_se,
        "asym_stderr": asym_se,
        "n": int(n),
        "message": f"offset {offset:.6g}, asym {asym:+.4g} from a Theil-Sen line through "
        f"{n} local centres against their amplitudes "
        f"({float(np.min(d)):.3g} to {float(np.max(d)):.3g})",
    }
