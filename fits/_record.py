"""A measured decay as its turning points ([`fits.Record`][]), and the peak tables that hold one."""

from __future__ import annotations

import dataclasses
import os
import re
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ._signal import Signal, read_stamps, unit_of_time
from ._text import (
    ANGLE_UNIT,
    LENGTH_SPELLINGS,
    LENGTH_UNIT,
    LENGTH_UNITS,
    MAX_ROWS,
    TIME_NAME,
    TIME_UNITS,
    NotPeakTable,
    column_names,
    fail,
    line_of,
    load_text,
    parse_table,
    read_columns,
    rows_ok,
    strictly_increasing,
)

EDGE_RELEASE = "edge: at the signal's first samples, located from one side (not weighed)"
"""`Record.meta["release"]` of a record whose signal starts at its release."""
HELD_RELEASE = "held: time extrapolated from the first half-swing (not weighed)"
"""`Record.meta["release"]` of a record released from a hold."""
ROWS_AS_HALF_SWINGS = "half-swings"
"""`Record.meta["rows"]` of a peak table of amplitudes without `k`, `cycle` or `crossed`: its
rows were taken as successive half-swings (both sides' peaks in turn), which its numbers cannot
tell from one side's peaks; the fits say so in their warnings."""


@dataclass(frozen=True)
class Record:
    """A measured decay as a sequence of turning points.

    **Fields:**

    - `k`: swing index of each point (`0` is the release, the initial deflection), increasing.
    - `positions`: signed position at each turning point [signal units]. When the source gave
      amplitudes with a `crossed` column, the sides are reconstructed from it (release at
      `-a0`). When it gave amplitudes only (`sides_known` False), the sides are NOT known: the
      positions then alternate provisionally and only `amplitudes` may be trusted.
    - `times`: time of each turning point measured from the release [s], or `None`.
    - `centre`: preliminary estimate of the signal's zero [signal units]: the median of the
      local centres of successive extrema (see [`fits.sensor_start`][] for offset and asymmetry).
    - `noise`: noise estimate of the raw signal (extracted records) [signal units], else `None`.
    - `signal`: the raw [`fits.Signal`][] for extracted records (for figures), else `None`.
    - `time_origin`: absolute time of the release point [s] (times are relative to it).
    - `sides_known`: `False` for amplitude-only records (`k, amplitude` without sign or
      `crossed`): whether each swing passed the centre is for the model to decide.
    - `crossed`: the source's `crossed` flags (`True` where the swing ending at this point
      passed the centre), or `None` when the source gave none.
    """

    k: np.ndarray
    positions: np.ndarray
    times: np.ndarray | None = None
    centre: float = 0.0
    noise: float | None = None
    signal: Signal | None = None
    source: str = ""
    time_origin: float = 0.0
    meta: dict = field(default_factory=dict)
    sides_known: bool = True
    crossed: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.k)

    @property
    def orientation(self) -> float:
        """`+1` if the release point is below the centre (the models release at `-a0`), else `-1`."""
        first = self.positions[0] - self.centre
        parity = -1.0 if int(self.k[0]) % 2 else 1.0
        return 1.0 if first * parity <= 0 else -1.0

    @property
    def amplitudes(self) -> np.ndarray:
        """`|x - centre|` at each turning point."""
        return np.abs(self.positions - self.centre)

    @property
    def clock(self) -> dict | None:
        """The sample-clock report of the raw signal this record was extracted from (the fit
        JSON's `"clock"`), or `None` for peak records."""
        return None if self.signal is None else dict(self.signal.clock_report)


# -- peak sequences ----------------------------------------------------------------------------
#: the columns of a peak table by their names' first word (case-insensitive); the time column
#: by the raw signals' rule (`TIME_NAME`)
_PEAK_ROLES = {
    "k": "k",
    "cycle": "cycle",
    "amplitude": "amplitude",
    "peak": "amplitude",
    "position": "position",
    "crossed": "crossed",
}


#: words after `peak` that make a column a count of the peaks, not their amplitude
_COUNTS = {"no", "nr", "number", "num", "#", "index", "idx", "count", "n"}


def _peak_role(name: str) -> str | None:
    """What a peak table's column holds, from its name: its first word, less a unit
    (`Amplitude [mm]`, `amplitude_mm`, `k`, `cycle`, `crossed`), and the time as a raw
    signal's time column is named (`TIME_NAME`: `Time (s)`, `time_ms`, `t/min`, `Zeit [ms]`,
    `Timestamp`, `Elapsed (s)`, `Peak time`); `None` for another column, and for a count of
    the peaks (`Peak No.`, `peak #`, `peak_index`: half-swings or periods, the name does not
    say)."""
    words = re.split(r"[\s(\[_/.]+", name.strip().lower())
    if words[0] == "peak" and len(words) > 1 and words[1] in _COUNTS:
        return None
    role = _PEAK_ROLES.get(words[0])
    if (role is None or words[0] == "peak") and TIME_NAME.search(name.strip()):
        return "time"
    return role


def _samples_of_motion(x) -> str | None:
    """What shows that a peak table's values (rows in order) are samples of an oscillation, not
    its turning points; `None` where nothing does. Both sides' turning points alternate about
    their median (successive rows cross it: gaps of one row); one side's peaks and amplitudes
    cross it where their envelope does (once, or in one band of rows where a sensor offset
    alternates them). Samples cross it twice a period all along the record, rows apart."""
    side = np.sign(x - np.median(x))
    side = side[side != 0]
    cross = np.flatnonzero(side[:-1] != side[1:])
    if cross.size < 6 or np.median(np.diff(cross)) < 2 or cross[-1] - cross[0] < side.size / 2:
        return None
    return (
        f"the values cross their median {cross.size} times in {x.size} rows, "
        f"{np.median(np.diff(cross)):.0f} rows apart"
    )


def read_peaks(path: str | os.PathLike, *, max_rows: int | None = MAX_ROWS) -> Record:
    """Read a peak sequence from a CSV file with a header line.

    Columns, by the first word of their names (case-insensitive), the time column as a raw
    signal's is named (`Time (ms)`, `time_ms`, `Zeit [ms]`, `Timestamp`; a unit at the end of
    its name is read, and times are converted to seconds): `k` (the
    half-swing index, `0` the initial deflection: successive rows of a table of both sides'
    peaks are `k`, `k + 1`) or `cycle` (full periods, for a table of one side's peaks as a
    logarithmic-decrement table lists them: `k = 2 cycle`), and/or `time` (or `t`);
    `amplitude` (or `peak`: `|x| >= 0`) or `position` (signed `x`); optional `crossed` (`0`
    where the swing did not pass `x = 0`, the tables' `*`). Other columns are ignored. Signed
    positions and amplitudes with `crossed` fix the sides; amplitudes alone give a record
    whose sides are unknown (`sides_known` False). Without `k` or `cycle`, rows are
    half-swings `0, 1, 2, ...` (both sides' peaks in turn); times are then measured from the
    first row. One side's peaks read as successive half-swings would give half the frequency
    and twice the damping, and nothing in the numbers tells the two apart: such a table needs
    its `cycle` (an amplitude table without `k`, `cycle` or `crossed` is marked,
    [`fits.ROWS_AS_HALF_SWINGS`][], and its fits warn).

    Raises `ValueError` naming the file (and the line and column where there is one) for a
    missing, unreadable, binary or empty file, a directory, a header without data, a single
    row, missing columns, two columns of one kind, non-numeric, empty or non-finite cells,
    non-increasing `k` or `time`, negative amplitudes, and more than `max_rows` rows.
    """
    text, source = load_text(path, max_rows)
    tab = parse_table(text, source, need_header=True)
    names, times_at = {}, []
    for i, h in enumerate(tab.header):
        role = _peak_role(h)
        if role == "time":  # several: the finest, as a raw signal's (below)
            times_at.append(i)
            continue
        if role in names:
            fail(
                source,
                f"columns {tab.header[names[role]]!r} and {h!r} both name the {role} "
                f"(found {tab.header})",
            )
        if role is not None:
            names[role] = i
    if "amplitude" not in names and "position" not in names:
        fail(
            source,
            f"missing column: need 'amplitude' or 'position' (found {tab.header})",
            ValueError if {"k", "cycle", "crossed"} & set(names) else NotPeakTable,
        )
    if "k" in names and "cycle" in names:
        fail(source, "give 'k' (half-swings) or 'cycle' (full periods), not both")
    if len(times_at) == 1:
        names["time"] = times_at[0]
    elif times_at:  # (`Timestamp`, `Time_Elapsed(s)`)
        columns = column_names(tab)
        names["time"] = columns.index(read_stamps(tab, times_at, columns)[1])
    wanted = [c for c in ("k", "cycle", "time", "amplitude", "position", "crossed") if c in names]
    values = dict(zip(wanted, read_columns(tab, [names[c] for c in wanted])))
    n = len(values[wanted[0]])
    rows_ok(n, source, max_rows, 2, "a decay")
    label = {c: tab.header[names[c]].strip() for c in wanted}
    value = "position" if "position" in values else "amplitude"
    if not {"k", "cycle", "crossed"} & set(values):  # nothing says the rows are turning points
        samples = _samples_of_motion(values[value])
        if samples:
            fail(
                source,
                f"column {label[value]!r}: {samples}: these are samples of a motion, not its "
                "turning points: read the file as a raw signal (fits.read_record(path) "
                "decides by itself, or series=True; a 'k' column makes it a peak table)",
                NotPeakTable,
            )
    if "k" not in names and "cycle" not in names and "time" not in names:
        fail(source, f"missing column: need 'k', 'cycle' or 'time' (found {tab.header})")

    def check(column, bad, what):
        rows = np.nonzero(bad)[0]
        if rows.size:
            fail(
                source,
                f"line {line_of(tab, int(rows[0]))}, column {label[column]!r}: "
                f"{values[column][rows[0]]:g}: {what}",
            )

    index = "k" if "k" in values else "cycle" if "cycle" in values else None
    if index is not None:
        k = values[index]
        check(index, (k != np.round(k)) | (k < 0), f"{index} must hold integers >= 0")
        strictly_increasing(k, tab, label[index])
        k = k.astype(int) * (2 if index == "cycle" else 1)
    else:
        k = np.arange(n)
    times = values.get("time")
    if times is not None:
        strictly_increasing(times, tab, label["time"])
        times = times * TIME_UNITS[unit_of_time(label["time"]) or "s"]
    crossed = values.get("crossed")
    if crossed is not None:
        check("crossed", ~np.isin(crossed, (0.0, 1.0)), "crossed must hold 0 or 1")
    if "position" in values:
        record = record_from_sequence(positions=values["position"], k=k, times=times, source=source)
        record.meta["value_name"] = label[value]
        return record
    amplitudes = values["amplitude"]
    check(
        "amplitude",
        amplitudes < 0,
        "an amplitude must be >= 0 (use a 'position' column for signed values)",
    )
    record = record_from_sequence(
        amplitudes=amplitudes, crossed=crossed, k=k, times=times, source=source
    )
    record.meta["value_name"] = label[value]
    if index is None and crossed is None:  # nothing says the rows are half-swings
        record.meta["rows"] = ROWS_AS_HALF_SWINGS
    return record


def value_name(record: Record) -> str:
    """The name of the column the record's values were read from (the raw signal's, or the
    peak table's amplitude or position column), `""` where it came from arrays."""
    return (
        record.signal.signal_name
        if record.signal is not None
        else record.meta.get("value_name", "")
    )


def in_metres(record: Record, model: str = "this") -> Record:
    """`record` with its positions in metres, for models whose lengths are SI: where its value
    column's name ends with another length unit (`amplitude_mm`, `x [um]`), the positions, the
    centre, the noise and the raw signal scaled to metres, `meta["length_unit"]` the unit
    converted from; else `record` itself (a name without a unit is read in metres). A column
    named in an angle unit is a `ValueError` naming `model`."""
    name = value_name(record).strip()
    if ANGLE_UNIT.search(name):
        fail(
            record.source,
            f"the column {name!r} holds an angle, and the {model} model's positions are "
            "lengths [m] (an angle record: --model pendulum, or oscillator in the signal's "
            "units)",
        )
    m = LENGTH_UNIT.search(name)
    unit = LENGTH_SPELLINGS.get(m.group(1).lower(), m.group(1).lower()) if m else "m"
    scale = LENGTH_UNITS[unit]
    if scale == 1.0:
        return record
    signal = record.signal
    if signal is not None:
        signal = dataclasses.replace(signal, y=signal.y * scale)
    return dataclasses.replace(
        record,
        positions=record.positions * scale,
        centre=record.centre * scale,
        noise=None if record.noise is None else record.noise * scale,
        signal=signal,
        meta={**record.meta, "length_unit": unit},
    )


def record_from_sequence(
    *,
    amplitudes: ArrayLike | None = None,
    positions: ArrayLike | None = None,
    crossed: ArrayLike | None = None,
    k: ArrayLike | None = None,
    times: ArrayLike | None = None,
    source: str = "",
) -> Record:
    """A [`fits.Record`][] from arrays: signed `positions`, or `amplitudes` (`|x|`) with optional
    `crossed` flags (`1` where the swing ending at that point passed `x = 0`); swing indices `k`
    (default `0, 1, ...`) and optional `times` [s], measured from the `k = 0` row if there is
    one, else taken as given (a fit aligns the record's clock with the model's by a fitted
    shift, so their origin need not be the release).

    Amplitudes without `crossed` give a record with `sides_known = False`: its positions
    alternate provisionally (as if every swing crossed), and a fit must let the model decide
    which swings passed zero."""
    if (amplitudes is None) == (positions is None):
        raise ValueError("give exactly one of amplitudes or positions")
    values = np.asarray(amplitudes if positions is None else positions, dtype=float).ravel()
    name = "amplitudes" if positions is None else "positions"
    if values.size == 0:
        fail(source, f"{name} is empty")
    if not np.all(np.isfinite(values)):
        fail(source, f"{name} must be finite (NaN and infinity are not allowed)")
    k = np.arange(values.size) if k is None else np.asarray(k).astype(int).ravel()
    if k.shape != values.shape:
        fail(source, "k and the values must have the same length")
    if np.any(np.diff(k) <= 0) or np.any(k < 0):
        fail(source, "k must be strictly increasing integers >= 0")
    sides_known, flags = True, None
    if positions is None:
        if np.any(values < 0):
            fail(source, "amplitudes must be >= 0")
        flips = np.ones(int(k[-1]) + 1, dtype=bool)  # swing j (ending at k = j) crossed x = 0
        if crossed is not None:
            flags = np.asarray(crossed, dtype=float).ravel()
            if flags.shape != values.shape:
                fail(source, "crossed and the amplitudes must have the same length")
            if not np.all(np.isin(flags, (0.0, 1.0))):
                fail(source, "crossed must hold 0 or 1")
            flags = flags.astype(bool)
            flips[k] = flags
        else:
            sides_known = False
        flips[0] = False
        side = -np.cumprod(np.where(flips, -1.0, 1.0))
        values = side[k] * values
    elif crossed is not None:
        raise ValueError("crossed applies to amplitudes (positions carry their sides)")
    origin = 0.0
    if times is not None:
        times = np.asarray(times, dtype=float).ravel()
        if times.shape != values.shape:
            fail(source, "times and the values must have the same length")
        if not np.all(np.isfinite(times)):
            fail(source, "times must be finite (NaN and infinity are not allowed)")
        if np.any(np.diff(times) <= 0):
            fail(source, "times must be strictly increasing")
        if k[0] == 0:
            origin = float(times[0])
            times = times - origin
    return Record(
        k=k,
        positions=values,
        times=times,
        source=source,
        time_origin=origin,
        sides_known=sides_known,
        crossed=flags,
    )
