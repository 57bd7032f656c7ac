"""`vmj fit FILE [FILE ...] ...`: identify friction and damping from measured decays.

The command belongs to fits; the `vmj` command line names this module in its list of commands and
imports it only when `vmj fit` is run (`add_arguments(parser)`, `run(args)`). Nothing here
imports JAX before `run` (`vmj fit --help` stays fast).
"""

from __future__ import annotations

import argparse
import math
import os
import sys

from vmj.cli import Joined, count, emit, figure_path, input_file, number, parse_set

__all__ = ["add_arguments", "run", "MODELS", "TIME_UNITS", "MAX_ROWS"]

#: the model families (kept equal to `fits._models.SPACES` by a test)
MODELS = ("variable-mass", "rope", "oscillator", "pendulum")

_DEFAULT_FREE = {
    "variable-mass": "FT,mu",
    "oscillator": "omega,zeta,xF,a0,offset",
    "rope": "T",
    "pendulum": "omega,zeta,xF,cq,b2,a0,offset,asym",  # fits._pendulum.FREE (a test checks)
}
_ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180}
#: a raw signal's time units (kept equal to `fits.TIME_UNITS`' keys by a test)
TIME_UNITS = ("s", "ms", "us", "ns", "min")
#: the default limit on a file's data rows (kept equal to `fits.MAX_ROWS` by a test)
MAX_ROWS = 2_000_000


def _record_file(text: str) -> str:
    """A FILE of `vmj fit` (argparse type): `vmj.cli.input_file`'s checks of the path (missing,
    a directory, unreadable), not its UTF-8 check: the content is `fits.read_record`'s to
    judge, which reads UTF-16 with a byte-order mark and Windows-1252 as well (a spreadsheet's
    `Winkel [°]`) and names the line of a bad cell or binary data. (Until 2026-11-28 such a
    file was refused: "not a UTF-8 text file".)"""
    if os.path.isfile(text) and os.access(text, os.R_OK):
        return text
    return input_file(text)


def _settings(text: str) -> dict:
    out = {}
    for name, value in parse_set(text).items():
        try:
            out[name] = number(value)
        except argparse.ArgumentTypeError as e:
            raise ValueError(f"--set {name}: {e}") from None
    return out


class _Order(ValueError):
    """`LO:HI` with `LO >= HI`."""


def _span(text: str) -> tuple:
    """`LO:HI` as floats, an empty or infinite end open (+-inf); `ValueError` saying what is
    wrong (`_Order` for ends in the wrong order)."""
    lo_t, colon, hi_t = text.partition(":")
    if not colon:
        raise ValueError("must be LO:HI")
    try:
        lo = -math.inf if lo_t.strip() in ("", "-inf") else float(lo_t)
        hi = math.inf if hi_t.strip() in ("", "inf", "+inf") else float(hi_t)
    except ValueError:
        raise ValueError("LO and HI must be numbers") from None
    if math.isnan(lo) or math.isnan(hi) or not lo < hi:
        raise _Order("need LO < HI")
    return lo, hi


def _bounds(text: str | None) -> dict:
    """`NAME=LO:HI[,NAME=LO:HI...]` of `--bounds` as `{name: (lo, hi)}` (`LO`/`HI` may be
    empty or `inf` for an open end)."""
    out = {}
    for item in filter(None, (s.strip() for s in (text or "").split(","))):
        name, sep, rng = item.partition("=")
        name = name.strip()
        if not sep or ":" not in rng or not name:
            raise ValueError(f"--bounds takes NAME=LO:HI pairs separated by commas (got {item!r})")
        try:
            out_range = _span(rng)
        except ValueError as err:
            raise ValueError(f"--bounds {name}: {err} (got {rng!r})") from None
        if name in out:
            raise ValueError(f"--bounds gives {name} twice")
        out[name] = out_range
    return out


def _rate(text: str) -> float:
    """`--rate`: a sampling rate [Hz] > 0 (argparse type)."""
    value = number(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a sampling rate > 0 [Hz] (got {text!r})")
    return value


def _window(text: str) -> tuple:
    """`--window START:END` [s from the first sample] (argparse type; an empty end is open)."""
    try:
        return _span(text)
    except _Order:
        raise argparse.ArgumentTypeError(f"needs START < END (got {text!r})") from None
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"must be START:END in seconds from the first sample, an end may be empty "
            f"(got {text!r})"
        ) from None


def _count_or(word: str, least: int):
    """An argparse type: an integer >= `least`, or `word` (returned as `None` for "none")."""

    def parse(text: str):
        if text.strip().lower() == word:
            return None if word == "none" else word
        try:
            value = int(text)
        except ValueError:
            value = least - 1
        if value < least:
            raise argparse.ArgumentTypeError(
                f"must be an integer >= {least} or '{word}' (got {text!r})"
            )
        return value

    return parse


def _names(text: str | None, option: str) -> tuple:
    names = tuple(n.strip() for n in (text or "").split(",") if n.strip())
    if len(set(names)) != len(names):
        raise ValueError(f"{option}: a name is listed twice ({text!r})")
    return names


def add_arguments(p):
    p.add_argument(
        "FILE",
        type=_record_file,
        nargs="+",
        help="peak-sequence CSV (k|cycle|time, amplitude|position[, crossed]) or a raw "
        "signal (see --series); several files are fitted jointly (see --shared)",
    )
    p.add_argument(
        "--model",
        choices=MODELS,
        help="model family (default: variable-mass; a record of unknown mass and stiffness: "
        "oscillator)",
    )
    p.add_argument(
        "--fit",
        metavar="NAME[,NAME...]",
        action=Joined,
        help="parameters to fit (default: variable-mass FT,mu; oscillator "
        "omega,zeta,xF,a0,offset, without omega for records without times; rope T;"
        " pendulum omega,zeta,xF,cq,b2,a0,offset,asym; without the names given with --set, "
        "and without offset for a table of one side's peaks or of amplitudes)",
    )
    p.add_argument(
        "--set",
        metavar="NAME=VALUE,...",
        action=Joined,
        default="",
        help="fixed parameter values (SI units: FT N, mu and delta kg/s, m0 kg, c N/m, "
        "g m/s^2, omega rad/s; the signal's units for xF, a0, offset, and per "
        "second for drift, the sensor zero's drift); for names given with --fit, the "
        "starting value. A parameter neither fitted nor set takes its physical default "
        "(friction terms and drift 0, g 9.81, a0 the first point, offset the "
        "record's centre) or is an error",
    )
    p.add_argument(
        "--bounds",
        metavar="NAME=LO:HI,...",
        action=Joined,
        help="bounds of parameters, in their units (an empty LO or HI is open); a "
        "fitted value at a bound set here is not flagged",
    )
    p.add_argument(
        "--shared",
        metavar="NAME[,NAME...]",
        action=Joined,
        help="several FILEs: fitted parameters with one value for all records (the "
        "others, e.g. offset and a0, one per record)",
    )
    p.add_argument(
        "--series",
        action="store_true",
        help="FILE is a raw signal: extract the turning points first (default: decided from "
        "the file: a raw signal where it has no header line, no amplitude or position column, "
        "or values that are samples of an oscillation, or where a raw-signal option is given)",
    )
    p.add_argument(
        "--residuals",
        choices=("turning-points", "series"),
        default="turning-points",
        help="what the fit compares: the turning points (default) or, for a raw signal, every "
        "sample of the raw signal against the exact motion between the turning points (the "
        "turning-point fit starts it; the release's time shift t0 is fitted)",
    )
    p.add_argument("--time-col", help="raw signal: time column (name or 0-based index)")
    p.add_argument("--signal-col", help="raw signal: signal column (name or 0-based index)")
    p.add_argument(
        "--rate",
        metavar="HZ",
        type=_rate,
        help="raw signal: sampling rate [Hz], > 0; needed for a file without a time column, "
        "and with one it puts the samples on a uniform clock at that rate",
    )
    p.add_argument(
        "--time-unit",
        choices=TIME_UNITS,
        help="raw signal: unit of the time column (default: the unit its name ends with, as in "
        "time_ms or 't [ms]', else s)",
    )
    p.add_argument(
        "--window",
        metavar="START:END",
        type=_window,
        help="raw signal: keep the samples from START to END [s from the first sample; an "
        "empty end is open], e.g. one decay of several in a file",
    )
    p.add_argument(
        "--decay",
        metavar="N|all",
        type=_count_or("all", 0),
        help="raw signal of several free decays (repeated taps or releases): fit the N-th, "
        "from 0 in time order (default: the one of the largest swing), or all of them jointly "
        "(with --shared for the parameters they share, e.g. omega,zeta,xF)",
    )
    p.add_argument(
        "--max-rows",
        metavar="N",
        type=_count_or("none", 1),
        default=MAX_ROWS,
        help=f"refuse files of more data rows than N, or 'none' for no limit (default: "
        f"{MAX_ROWS:,}, about 2 hours at 259 Hz)",
    )
    p.add_argument(
        "--angle-unit",
        choices=tuple(_ANGLE_UNITS),
        help="unit of an angle signal, for models with an angle_unit parameter (default: the "
        "unit the signal column's name ends with, as in 'Angle(rad)' or angle_deg, else deg)",
    )
    p.add_argument(
        "--forward",
        choices=("exact", "smooth", "energy"),
        default="exact",
        help="forward model (default: %(default)s)",
    )
    p.add_argument(
        "--loss",
        choices=("l2", "huber", "cauchy"),
        default="l2",
        help="loss (default: %(default)s)",
    )
    p.add_argument(
        "--optimizer", choices=("lm", "adam"), default="lm", help="optimizer (default: %(default)s)"
    )
    p.add_argument(
        "--adam-steps",
        type=count,
        metavar="N",
        help="with --optimizer adam: its steps (default 3000; converged where the step that "
        "remains is below 0.1 standard errors)",
    )
    p.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object: model, params, stderr, stderr_gn, intervals, "
        "correlation, converged, iterations, rms, diagnostics, "
        "model_comparison, residuals_of[, records, clock], units",
    )
    p.add_argument("--plot", metavar="PATH", type=figure_path, help="write a figure (PNG) to PATH")


def run(args) -> int:
    import warnings

    import fits
    from fits._fit import MissingParameters
    from fits._models import SPACES
    from fits._result import outliers_at

    model = args.model or "variable-mass"
    space = SPACES[model]
    given = _settings(args.set)
    bounds = _bounds(args.bounds)
    shared = _names(args.shared, "--shared")
    if shared and len(args.FILE) < 2 and args.decay != "all":
        raise ValueError("--shared needs several FILEs (or --decay all)")
    if args.adam_steps is not None and args.optimizer != "adam":
        raise ValueError("--adam-steps applies to --optimizer adam")
    if "angle_unit" in space.names:
        if args.angle_unit is not None:  # else the signal column's name, or degrees
            given["angle_unit"] = _ANGLE_UNITS[args.angle_unit]
    elif args.angle_unit is not None:
        raise ValueError(
            f"--angle-unit applies only to models with an angle_unit parameter "
            f"(the {model} model has none)"
        )
    series = True if args.series else None  # None: the file decides (fits.read_record)
    reading = {
        "time_col": args.time_col,
        "signal_col": args.signal_col,
        "time_unit": args.time_unit,
        "rate": args.rate,
        "window": args.window,
        "max_rows": args.max_rows,
    }
    if args.decay == "all":  # every decay of every file, fitted jointly
        records = [rec for path in args.FILE for rec in fits.read_decays(path, **reading)]
    else:
        records = [
            fits.read_record(path, series=series, decay=args.decay, **reading) for path in args.FILE
        ]
    free = _DEFAULT_FREE[model] if args.fit is None else args.fit  # (`--fit ""`: no names)
    if args.fit is None and model == "oscillator" and any(r.times is None for r in records):
        free = "zeta,xF,a0,offset"
    names = _names(free, "--fit")
    note = None  # printed once the fit has run: an error is one line
    if args.fit is None:  # the default set: without what --set fixed
        names = tuple(n for n in names if n not in given)
        why = None
        if any(len({int(k) % 2 for k in r.k}) == 1 for r in records):
            # one side's peaks: an offset o shifts every peak alike, which the decay takes as
            # dry friction (xF - o (1 - r)/(1 + r) per half-swing ratio r): not both
            why = "one side's peaks only, where a sensor offset cannot be told from dry friction"
        elif any(not r.sides_known for r in records):
            # amplitudes: distances from the centre, compared with the model's |y|, which no
            # offset changes (fitted, it had no standard error: not converged)
            why = "amplitudes only (distances from its centre), which an offset does not change"
        if "offset" in names and why:
            names = tuple(n for n in names if n != "offset")
            note = (
                f"vmj: note: offset not fitted: the record holds {why} (held at its default, "
                "the record's centre; --set offset=VALUE holds another value)"
            )
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        try:
            result = fits.fit(
                records if len(records) > 1 else records[0],
                model,
                names,
                given,
                shared=shared,
                bounds=bounds,
                forward=args.forward,
                loss=args.loss,
                optimizer=args.optimizer,
                residuals=args.residuals,
                **({} if args.adam_steps is None else {"adam_steps": args.adam_steps}),
            )
        except MissingParameters as err:
            if args.model is not None:
                raise
            raise ValueError(
                f"{err}; or choose the model (--model): oscillator for a decay of unknown mass "
                "and stiffness (omega, zeta, xF in the signal's units), pendulum for an "
                "angle, rope for a hoisting rope"
            ) from None
    if note:
        print(note, file=sys.stderr)
    if args.plot:
        fits.plot_fit(result, args.plot)
    if args.json:
        emit(result.to_json(), True, "")
        for w in result.warnings:
            print(f"vmj: warning: {w}", file=sys.stderr)
        if result.outliers:
            print(f"vmj: warning: outliers {outliers_at(result)}", file=sys.stderr)
    else:
        print(result.report())
    return 0
