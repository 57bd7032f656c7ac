"""`vmj fit FILE ...`: identify friction and damping from a measured decay.

The command belongs to fits; the `vmj` command line names this module in its list of commands and
imports it only when `vmj fit` is run (`add_arguments(parser)`, `run(args)`).
"""

from __future__ import annotations

import argparse
import json
import sys

from vmj.cli import figure_path, input_file, number, parse_set

__all__ = ["add_arguments", "run"]

_DEFAULT_FREE = {
    "variable-mass": "FT,mu",
    "oscillator": "omega,zeta,xF,a0,offset",
    "rope": "T",
}


def _settings(text: str) -> dict:
    out = {}
    for name, value in parse_set(text).items():
        try:
            out[name] = number(value)
        except argparse.ArgumentTypeError as e:
            raise ValueError(f"--set {name}: {e}") from None
    return out


def add_arguments(p):
    p.add_argument("FILE", type=input_file,
                   help="peak-sequence CSV (k|time, amplitude|position[, crossed]) or, with "
                        "--series, a raw signal")
    p.add_argument("--model", choices=("variable-mass", "rope", "oscillator"),
                   default="variable-mass")
    p.add_argument("--fit", metavar="NAME[,NAME...]",
                   help="parameters to fit (default: variable-mass FT,mu; oscillator "
                        "omega,zeta,xF,a0,offset, without omega for records without times; rope T)")
    p.add_argument("--set", metavar="NAME=VALUE,...", default="",
                   help="fixed parameter values (SI units, or the signal's units for the "
                        "oscillator's xF, a0, offset); for fitted names, the starting value")
    p.add_argument("--series", action="store_true", help="FILE is a raw signal: extract the "
                                                         "turning points first")
    p.add_argument("--time-col", help="raw signal: time column (name or 0-based index)")
    p.add_argument("--signal-col", help="raw signal: signal column (name or 0-based index)")
    p.add_argument("--forward", choices=("exact", "smooth", "energy"), default="exact")
    p.add_argument("--loss", choices=("l2", "huber", "cauchy"), default="l2")
    p.add_argument("--optimizer", choices=("lm", "adam"), default="lm")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="PATH", type=figure_path,
                   help="write a figure (PNG) to PATH")


def run(args) -> int:
    import warnings

    import fits

    record = fits.read_record(args.FILE, series=args.series, time_col=args.time_col,
                              signal_col=args.signal_col)
    free = args.fit or _DEFAULT_FREE[args.model]
    if args.fit is None and args.model == "oscillator" and record.times is None:
        free = "zeta,xF,a0,offset"
    names = tuple(n.strip() for n in free.split(",") if n.strip())
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        result = fits.fit(record, args.model, names, _settings(args.set), forward=args.forward,
                          loss=args.loss, optimizer=args.optimizer)
    if args.plot:
        fits.plot_fit(result, args.plot)
    if args.json:
        print(json.dumps(result.to_json()))
        for w in result.warnings:
            print(f"vmj: warning: {w}", file=sys.stderr)
        if result.outliers:
            print(f"vmj: warning: outliers at k = {result.outliers}", file=sys.stderr)
    else:
        print(result.report())
    return 0
