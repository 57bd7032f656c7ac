"""`vmj sweep MODEL`: a model over a grid of parameters, written to CSV/NetCDF, with figures for the
variable-mass model.

    vmj sweep variable-mass --eps 0:1:11 --mu 0:10:21 --delta -3:3:7 \\
        --set m0=5,c=4900,FT=14.7,a0=0.06 --method exact --out sweep.csv --plot sweep.png
    vmj sweep rope --T 0:8:9 --u -3,0,3 --set m=2,A=1.74,e=0.8e6,d=0.8e11,l0=10,a0=1 \\
        --units technical --n 20 --out rope.csv
    vmj sweep stick-slip --eps 2:20:37 --Omega 0.1:2:20 --out cycles.csv
    vmj sweep linear --c 0:40:41 --set m=1,k=14.5,v0=0.1 --out linear.csv

Every axis is `--NAME start:stop:count` (inclusive, evenly spaced), a comma list, or one value;
`--set NAME=VALUE,...` fixes the others (and the initial conditions). The work is estimated
before anything is computed and refused above the limits below unless `--force` is given.
"""

from __future__ import annotations

import importlib.util
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

from ._app import on_cpu_if_small
from ._decay import cli_message, max_substeps_arg, solver_of
from ._options import (
    Joined,
    count,
    figure_path,
    output_path,
    parse_axis,
    parse_set,
    refuse_above,
    store_path,
    traced_checks,
)
from ._params import MODELS, add_options

__all__ = ["add_arguments", "run", "SWEEPS", "MAX_BYTES", "MAX_SECONDS", "MAX_AXIS"]

MAX_BYTES = 2**30  #: results held in memory without --force (no --store) [bytes]
MAX_SECONDS = 600.0  #: estimated run time without --force [s]
MAX_AXIS = 10**7  #: values of one axis without --force


@dataclass(frozen=True)
class Sweep:
    """How a model is swept: its methods (the first is the default), the cost of one point
    (`bytes`, `seconds` as functions of the method, the number of turning points `n` and the
    largest magnitudes of the parameters), `evaluate(args, grid, scalars)`, which runs
    `vmj.sweep` and returns its result, and an example of `--set` for the help."""

    methods: tuple
    bytes: Callable
    seconds: Callable
    evaluate: Callable
    example: str
    turning_points: bool = True


# -- cost of one point, measured roughly on the 2-core development machine -----------------------
#: seconds per turning point, about 5 times the warm sweeps' (the 1617-point grid, 12 turning
#: points: exact 4.4 ms, smoothed 70 ms since its turning points are found in one solve)
_PER_SWING = {"exact": 1e-6, "energy": 1e-8, "smooth": 2e-5}
_SWING_BYTES = 17  #: time, position (float64) and crossed flag of one turning point


def _decay_cost(per_swing_scale: float = 1.0):
    return (
        lambda method, n, top: n * _SWING_BYTES + 64,
        lambda method, n, top: n * _PER_SWING[method] * per_swing_scale,
    )


def _turning_points(args, g, scalars, method=None):
    import vmj

    return vmj.sweep(
        vmj.turning_points,
        g,
        a0=scalars["a0"],
        n=args.n,
        solver=solver_of(args, method),
        **_engine(args),
    )


def _failures(codes) -> tuple:
    """`(count of failed points, one line per failure status with its count)`."""

    import vmj

    counts = _bincount(codes, len(vmj.RESULTS))
    failed = [(c, int(k)) for c, k in enumerate(counts) if k and vmj.RESULTS.failed(c)]
    lines = [f"  {k} points: {cli_message(vmj.RESULTS(c).message)}" for c, k in failed]
    return sum(k for _, k in failed), lines


def _bincount(codes, length: int):
    """How many of `codes` (non-negative integers) there are of each value below `length`;
    a result read lazily from a store (`--store`) is counted chunk by chunk, never loaded."""
    import numpy as np

    if hasattr(codes, "compute"):
        import dask.array as da

        return da.bincount(codes.ravel(), minlength=length).compute()[:length]
    return np.bincount(np.asarray(codes).ravel(), minlength=length)[:length]


def _decay_summary(args, result) -> tuple:
    """`(summary items, lines below the summary)` of a turning-point sweep."""

    seq = result.values
    failed, lines = _failures(seq.result)
    stopped = int(seq.stopped.sum())  # (a lazy result: summed chunk by chunk)
    return [f"stopped within {args.n} swings: {stopped}", f"failed: {failed}"], lines


def _stick_slip_eval(args, g, scalars):
    import numpy as np

    import vmj

    from ._stick_slip import reversal_bound

    top = float(np.max(np.asarray(g.model.eps)))
    return vmj.sweep(
        vmj.limit_cycle,
        g,
        solver=solver_of(args),
        max_reversals=reversal_bound(top),
        **_engine(args),
    )


def _linear_eval(args, g, scalars):
    import vmj

    from ._linear import characteristics

    return vmj.sweep(
        characteristics,
        g,
        x0=scalars["x0"],
        v0=scalars["v0"],
        forced="F0" in scalars,
        **_engine(args),
    )


def _cycle_summary(args, result):
    """`(summary items, lines below the summary)` of a limit-cycle or closed-form sweep."""
    import numpy as np

    if not hasattr(result.values, "result"):  # the linear oscillator's closed forms
        from ._linear import RESONANCE

        D = result.values.get("forced_amplitude")
        k = 0 if D is None else int(np.isinf(D).sum())
        if not k:
            return [], []
        return [f"forced_amplitude inf: {k}"], [f"  forced_amplitude inf: {RESONANCE}"]
    failed, lines = _failures(result.values.result)
    return [f"failed: {failed}"], lines


SWEEPS = {
    "variable-mass": Sweep(
        ("exact", "energy", "smooth"),
        *_decay_cost(),
        _turning_points,
        "m0=5,c=4900,FT=14.7,a0=0.06",
    ),
    "rope": Sweep(
        ("exact", "smooth", "energy"),
        *_decay_cost(3.0),
        _turning_points,
        "m=2,A=1.74,e=0.8e6,d=0.8e11,l0=10,u=0,a0=1",
    ),
    "stick-slip": Sweep(
        ("exact", "closed"),
        lambda method, n, top: 40 * (top["eps"] / 2 + 2) + 64,
        lambda method, n, top: 3e-6 * (top["eps"] / 2 + 1),
        _stick_slip_eval,
        "Omega=0.7",
        turning_points=False,
    ),
    "linear": Sweep(
        ("closed",),
        lambda method, n, top: 64,
        lambda method, n, top: 1e-7,
        _linear_eval,
        "m=1,k=14.5,v0=0.1",
        turning_points=False,
    ),
}


def add_arguments(p) -> None:
    from ._app import add_global_options

    sub = p.add_subparsers(dest="model", required=True, metavar="MODEL")
    for name, how in SWEEPS.items():
        spec = MODELS[name]
        q = sub.add_parser(
            name,
            help=f"sweep the {name} model: {spec.summary}",
            description=f"{spec.summary}. Axes: start:stop:count (inclusive), a "
            "comma list, or one value.",
            formatter_class=p.formatter_class,
        )
        add_options(q, spec, axes=True)
        initial = [x.name for x in spec.params if x.field is None]
        q.add_argument(
            "--set",
            metavar="NAME=VALUE,...",
            action=Joined,
            help="fixed parameters"
            + (f" and the initial conditions ({', '.join(initial)})" if initial else "")
            + f", e.g. {how.example}",
        )
        if how.turning_points:
            q.add_argument("--n", type=count, default=12, help="number of turning points")
        if len(how.methods) > 1:
            q.add_argument("--method", choices=how.methods, help="solver")
        q.set_defaults(method=how.methods[0])
        if how.turning_points:
            max_substeps_arg(q, name)
        if name == "rope":
            q.add_argument(
                "--units",
                choices=("si", "technical"),
                default="si",
                help="technical: m in kG s^2/m, A in cm^2, e, b, d, T in kG/cm^2, a0 "
                "in cm; the results and their coordinates are SI",
            )
        q.add_argument(
            "--out", metavar="CSV", type=output_path, help="write the sweep to this CSV file"
        )
        q.add_argument(
            "--netcdf",
            metavar="NC",
            type=output_path,
            help="also write NetCDF (needs the extra vmj[xarray])",
        )
        if name == "variable-mass":
            q.add_argument(
                "--plot",
                metavar="PNG",
                type=figure_path,
                help="swings until the mass sticks over (eps, mu), one panel per delta",
            )
            q.add_argument(
                "--error-plot",
                metavar="PNG",
                type=figure_path,
                help="energy-balance error against the exact solution over the same grid",
            )
        q.add_argument(
            "--chunk-size",
            type=count,
            default=None,
            help="points per compiled call (default: 16384 on CPUs, 2^20 on a GPU; "
            "fewer where the chunks would not fit in memory)",
        )
        q.add_argument(
            "--scheduler",
            metavar="ADDRESS",
            help="run the chunks on a Dask cluster: tcp://HOST:8786 (a running "
            "`dask scheduler`), or `local` (a cluster of this machine's cores); "
            "needs the extra vmj[distributed]",
        )
        q.add_argument(
            "--store",
            metavar="PATH.zarr",
            type=store_path,
            help="write every finished chunk to this Zarr store as it completes "
            "(needs vmj[distributed]); a rerun with --resume computes only the "
            "missing chunks",
        )
        q.add_argument(
            "--resume",
            action="store_true",
            help="continue the sweep in an existing --store (the same definition)",
        )
        q.add_argument("--progress", action="store_true", help="always show the progress bar")
        q.add_argument(
            "--force",
            action="store_true",
            help=f"run a sweep estimated above {MAX_BYTES / 2**30:g} GiB of results in memory "
            "(without --store) or "
            f"{MAX_SECONDS:g} s, or an axis of more than {MAX_AXIS:.0e} values",
        )
        add_global_options(q, nested=True)


def _engine(args) -> dict:
    """Where the chunks run and where they are kept: `vmj.sweep`'s `client`, `store`,
    `resume` and `progress`."""
    return {
        "client": args.scheduler,
        "store": args.store,
        "resume": args.resume,
        "chunk_size": args.chunk_size,
        "progress": True if (args.progress or args.scheduler) else None,
    }


def gather(spec, args, force: bool):
    """`(scalars, axes)` from `--NAME AXIS` options and `--set`: every value checked
    against its range with the user's spelling; `scalars` are SI values of every parameter (an
    axis at its first value), `axes` maps each swept parameter to its SI values."""
    technical = getattr(args, "units", "si") == "technical"
    raw, axes = {}, {}
    for name, text in parse_set(args.set).items():
        try:
            p = spec.param(name)
        except ValueError as e:
            raise ValueError(f"--set: {e}") from None
        if p.name in raw:
            raise ValueError(f"--set gives {p.name} twice")
        axis = (
            f"give --{p.name} for an axis"
            if p.field is not None
            else "an initial condition is not swept"  # (there is no --a0 axis)
        )
        values = parse_axis(f"--set {name}", text, 1, f"--set takes one value; {axis}")
        raw[p.name] = (values[0], f"--set {name}")
    for p in spec.fields:  # the axes in the order of the table
        text = getattr(args, p.name)
        if text is None:
            continue
        flag = f"--{p.name}"
        if p.name in raw:
            raise ValueError(f"{p.name} is given both as {flag} and in --set")
        values = parse_axis(
            flag,
            text,
            None if force else MAX_AXIS,
            f"refused above {MAX_AXIS:.0e} (give --force to run it anyway)",
        )
        axes[p.name] = [p.check(v, flag, technical) for v in values]
        raw[p.name] = (values[0], flag)
    if not axes:
        example = next(p.name for p in spec.fields)
        raise ValueError(f"give at least one axis, e.g. --{example} START:STOP:COUNT")
    scalars = spec.resolve(
        raw,
        technical,
        spell=lambda n: f"--set {n}=" if spec.param(n).field is None else f"--{n}/--set {n}=",
        axes=axes,
    )
    return scalars, axes


def _distinct_outputs(args) -> None:
    """Refuse two outputs that name the same file: the one written last replaced the other
    (a device such as /dev/null may take several)."""
    import os

    from .._files import _special

    seen = {}
    for flag in ("--out", "--netcdf", "--plot", "--error-plot", "--store"):
        path = getattr(args, flag[2:].replace("-", "_"), None)
        if path is None or _special(path):
            continue
        key = os.path.realpath(path)
        if key in seen:
            raise ValueError(f"{seen[key]} and {flag} name the same file {path!r}; give two paths")
        seen[key] = flag


def run(args) -> int:
    import numpy as np

    import vmj

    spec, how = MODELS[args.model], SWEEPS[args.model]
    scalars, axes = gather(spec, args, args.force)
    if args.model == "rope" and args.method == "energy":
        speeds = [u for u in axes.get("u", [scalars.get("u", 0.0)]) if u != 0]
        if speeds:
            raise ValueError(
                "--method energy is the energy map of a rope of fixed length: it needs --u 0 "
                f"(got {speeds[0]:g})"
            )
    _distinct_outputs(args)
    plots = getattr(args, "plot", None) or getattr(args, "error_plot", None)
    if plots and (list(axes)[:2] != ["eps", "mu"] or len(axes) > 3):
        raise ValueError(
            "--plot and --error-plot need the axes --eps and --mu, and optionally "
            f"--delta (got {', '.join('--' + k for k in axes)})"
        )
    if (args.scheduler or args.store) and importlib.util.find_spec("dask") is None:
        raise ValueError(
            "--scheduler and --store need Dask and Zarr: pip install 'vmj[distributed]'"
        )
    if args.resume and not args.store:
        raise ValueError("--resume needs --store PATH.zarr (the store to continue)")
    if args.store and plots:
        raise ValueError(
            "--store cannot be combined with --plot/--error-plot (write the store, "
            "then draw from it)"
        )
    if args.netcdf and importlib.util.find_spec("xarray") is None:
        raise ValueError("--netcdf needs xarray and netCDF4: pip install 'vmj[xarray]'")
    if plots and min(len(axes["eps"]), len(axes["mu"])) < 2:
        raise ValueError("--plot and --error-plot need at least 2 values of --eps and of --mu")
    # the work, estimated before anything is built
    points = math.prod(len(v) for v in axes.values())
    top = {name: max(abs(x) for x in axes.get(name, [scalars.get(name, 0.0)])) for name in scalars}
    n = getattr(args, "n", 1)
    runs = (
        1
        + bool(getattr(args, "error_plot", None) and args.method != "exact")
        + bool(getattr(args, "error_plot", None) and args.method != "energy")
    )
    size = points * how.bytes(args.method, n, top) * runs
    seconds = points * how.seconds(args.method, n, top) * runs
    shape = " x ".join(f"{name} {len(v)}" for name, v in axes.items())
    if not args.force and not args.store:  # (with --store the results are on disk)
        refuse_above(
            f"the sweep of {points:.4g} points ({shape}) holds about {size / 2**30:.3g} "
            "GiB of results in memory (--store PATH.zarr writes them to disk instead)",
            size / 2**30,
            MAX_BYTES / 2**30,
            "GiB",
        )
        refuse_above(
            f"the sweep of {points:.4g} points ({shape}) takes about {seconds:.3g} s "
            f"with --method {args.method}",
            seconds,
            MAX_SECONDS,
            "s",
        )
    if seconds > 10:
        print(f"vmj: sweep of {points} points, estimated {seconds:.0f} s", file=sys.stderr)
    on_cpu_if_small(args, seconds)

    model = spec.build(scalars)
    short = {p.name: p.field.rsplit(".", 1)[-1] for p in spec.fields}
    g = vmj.grid(model, **{short[name]: np.asarray(v) for name, v in axes.items()})
    t = time.perf_counter()
    try:
        with traced_checks():
            result = how.evaluate(args, g, scalars)
    except ValueError as e:  # the store's and the cluster's messages name the Python argument
        message = str(e).replace("resume=True", "--resume").replace("chunk_size", "--chunk-size")
        if args.scheduler is not None and message.startswith("client "):
            message = "--scheduler " + message.removeprefix("client ")
        raise ValueError(message) from None
    except vmj.SweepError as e:  # some chunks raised; the others are in the store, if any
        print(f"vmj: error: {e}", file=sys.stderr)
        return 1
    elapsed = time.perf_counter() - t
    if args.out:
        result.to_csv(args.out)
    if args.netcdf:
        result.to_netcdf(args.netcdf)
    if plots:
        from vmj.plot import plot_energy_error, plot_swings

        if args.plot:
            plot_swings(result, args.plot, title=f"{args.method}: ")
        if args.error_plot:
            with traced_checks():
                other = {
                    m: result if args.method == m else _turning_points(args, g, scalars, m)
                    for m in ("exact", "energy")
                }
            plot_energy_error(other["exact"], other["energy"], scalars["a0"], args.error_plot)
    summary, lines = (_decay_summary if how.turning_points else _cycle_summary)(args, result)
    head = f"sweep: {points} points ({shape}), method {args.method}"
    if how.turning_points:
        head += f", {args.n} swings"
    paths = (args.out, args.netcdf, getattr(args, "plot", None), getattr(args, "error_plot", None))
    written = [f"wrote {p}" for p in dict.fromkeys(p for p in paths if p)]
    if args.store:
        written.append(f"stored in {args.store}")
        if result.resumed:
            written[-1] += f" ({result.resumed} of {result.chunks} chunks were in it already)"
    if not written:
        written = ["nothing written (--out CSV, --netcdf NC, --plot PNG or --store keep it)"]
    print("; ".join([f"{head}, {elapsed:.2f} s", *summary, *written]))
    for line in lines:
        print(line)
    return 0
