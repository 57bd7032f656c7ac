"""One reader for any file of a measured decay: a peak table, or a raw signal whose turning
points are extracted ([`fits.read_record`][], [`fits.read_decays`][]).
"""

from __future__ import annotations

import os

from ._extract import extract_record, extract_turning_points, find_decays, naming_other_columns
from ._record import Record, read_peaks
from ._signal import Signal, read_signal
from ._text import MAX_ROWS, PEAK_TABLE_ROWS, Loaded, NotPeakTable, load_text


def read_record(
    path: str | os.PathLike,
    *,
    series: bool | None = None,
    time_col: str | int | None = None,
    signal_col: str | int | None = None,
    clock: str = "auto",
    rate: float | None = None,
    time_unit: str | None = None,
    max_rows: int | None = MAX_ROWS,
    angle_unit: float | None = None,
    window: tuple | None = None,
    decay: int | None = None,
) -> Record:
    """A [`fits.Record`][] from a file: a peak sequence ([`fits.read_peaks`][]) or the turning
    points extracted from a raw signal ([`fits.read_signal`][] for `time_col`, `signal_col`,
    `clock`, `rate`, `time_unit`, `window`, and [`fits.extract_turning_points`][] for `decay`).

    `series`: `True` for a raw signal, `False` for a peak table, `None` (default) to decide
    from the file: a raw signal where one of the raw signal's arguments is given, or where the
    file is no peak table (no header line, no amplitude or position column, or values that
    cross their median all along the file, rows apart, as samples of an oscillation do;
    a peak table's rows alternate about it or follow its envelope), else a peak table.
    """
    raw = dict(
        time_col=time_col,
        signal_col=signal_col,
        rate=rate,
        time_unit=time_unit,
        window=window,
        decay=decay,
    )
    raw_given = any(v is not None for v in raw.values()) or clock != "auto"
    not_peaks = None
    if series is None and not raw_given:
        path = Loaded(*load_text(path, max_rows))
        try:
            return read_peaks(path, max_rows=max_rows)
        except NotPeakTable as err:
            not_peaks = str(err).removeprefix(f"{path.source}: ")
    if series or series is None:
        try:
            return extract_turning_points(
                read_signal(
                    path,
                    time_col,
                    signal_col,
                    clock,
                    rate=rate,
                    time_unit=time_unit,
                    max_rows=max_rows,
                    window=window,
                ),
                angle_unit=angle_unit,
                decay=decay,
            )
        except ValueError as err:
            if series is None and raw_given and _reads_as_peaks(path, max_rows):
                named = [n for n, v in raw.items() if v is not None]
                _peaks_with_raw_options(path, named, clock)
            if not_peaks is None or path.text.count("\n") > PEAK_TABLE_ROWS:
                raise
            raise ValueError(
                f"{err} (read as a raw signal; as a peak table: {not_peaks})"
            ) from None
    if raw_given:
        raise ValueError(
            "time_col, signal_col, clock, rate, time_unit, window and decay apply to raw "
            "signals (series=True)"
        )
    return read_peaks(path, max_rows=max_rows)


def _peaks_with_raw_options(path, named: list, clock: str = "auto"):
    """Raise the error for a peak table read with the raw-signal options `named` (and `clock`
    where it is not `"auto"`)."""
    named = [n for n in named if n != "clock"] + (["clock"] if clock != "auto" else [])
    flags = ", ".join("--" + n.replace("_", "-") for n in named)
    several = len(named) > 1
    source = path.source if isinstance(path, Loaded) else os.fspath(path)
    raise ValueError(
        f"{source}: a table of turning points, but the raw-signal option"
        f"{'s' if several else ''} {', '.join(named)} ({flags} on the command line) "
        f"{'were' if several else 'was'} given: leave {'them' if several else 'it'}"
        " out to read the table"
    ) from None


def _reads_as_peaks(path, max_rows) -> bool:
    """Whether `path` reads as a peak table (`read_peaks` without an error)."""
    try:
        read_peaks(path, max_rows=max_rows)
    except (ValueError, NotPeakTable):
        return False
    return True


def read_decays(path: str | os.PathLike, **kwargs) -> list:
    """Every free decay of a raw signal (repeated taps or releases in one file), one
    [`fits.Record`][] each, in time order: fitted together with shared parameters
    (`fits.fit(records, ..., shared=("omega", "zeta", "xF"))`), each keeps its own release
    amplitude and offset. `kwargs` as [`fits.read_record`][]'s for raw signals (not
    `series`, not `decay`)."""
    for name in ("series", "decay"):
        if name in kwargs:
            raise ValueError(f"read_decays reads raw signals, every decay: no {name}=")
    angle_unit = kwargs.pop("angle_unit", None)
    try:
        return _every_decay(read_signal(path, **kwargs), angle_unit)
    except ValueError:
        if _reads_as_peaks(path, kwargs.get("max_rows", MAX_ROWS)):
            named = [n for n, v in kwargs.items() if v is not None and n != "max_rows"]
            _peaks_with_raw_options(path, ["decay", *named], kwargs.get("clock", "auto"))
        raise


@naming_other_columns
def _every_decay(signal: Signal, angle_unit) -> list:
    """`extract_turning_points` of every decay of `signal`, the signal searched once."""
    found = find_decays(signal, None)
    first = extract_record(signal, found, None, angle_unit, None)
    decays = first.meta.get("decays")
    if decays is None:
        return [first]
    return [
        first if i == decays["index"] else extract_record(signal, found, None, angle_unit, i)
        for i in range(len(decays["starts"]))
    ]
