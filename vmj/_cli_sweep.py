"""`vmj sweep MODEL`: a grid sweep of a decay, written to CSV, with optional figures.

    vmj sweep variable-mass --eps 0:1:11 --mu 0:10:21 --delta -3:3:7 \\
        --set m0=5,c=4900,FT=14.7,a0=0.06 --method exact --out sweep.csv --plot sweep.png
"""

from __future__ import annotations

import math
import re
import sys
import time

from ._cli import _number, command, parse_set

__all__ = ["SWEEP_MODELS", "parse_axis"]


def parse_axis(name: str, text: str):
    """`start:stop:count` (inclusive, evenly spaced), a comma list, or one number."""
    import numpy as np

    def num(t):
        try:
            return _number(t)
        except Exception as e:
            raise ValueError(f"--{name}: {e}") from None

    if ":" in text:
        parts = text.split(":")
        if len(parts) != 3:
            raise ValueError(f"--{name} must be start:stop:count (got {text!r})")
        start, stop = num(parts[0]), num(parts[1])
        try:
            count = int(parts[2])
        except ValueError:
            count = 0
        if count < 1 or (count == 1 and start != stop):
            raise ValueError(f"--{name}: count must be an integer >= 1, and >= 2 when start != stop "
                             f"(got {text!r})")
        return np.linspace(start, stop, count)
    return np.array([num(t) for t in text.split(",")])


# -- variable-mass --------------------------------------------------------------------------------
VM_PARAMS = {  # name -> help, in the order of the axes; FT (constant friction) or f and g
    "eps": "reactivity coefficient in [0, 1]", "mu": "viscous coefficient [kg/s]",
    "delta": "mass rate [kg/s]", "m0": "initial mass [kg]", "c": "stiffness [N/m]",
    "FT": "constant dry friction force [N]", "f": "friction coefficient (F = f g m(t))",
    "g": "gravity [m/s^2] for f (default 9.81)",
}
_FIELD = {"FT": "F"}  # CLI name -> model field name


def _variable_mass(values: dict):
    """Build the model from scalars (axes set to their first value; `grid` replaces them)."""
    import vmj

    for k in ("m0", "c", "delta", "eps", "mu"):
        if k not in values:
            raise ValueError(f"missing parameter {k}: give --{k} AXIS or --set {k}=VALUE")
    if ("FT" in values) == ("f" in values):
        raise ValueError("give exactly one friction law: FT (constant force [N]) or f "
                         "(coefficient, F = f g m)")
    if "FT" in values:
        if "g" in values:
            raise ValueError("g applies only to the mass-proportional law f")
        law = vmj.Coulomb(values["FT"])
    else:
        law = vmj.MassProportional(values["f"], values.get("g", 9.81))
    return vmj.VariableMass(values["m0"], values["c"], values["delta"], values["eps"],
                            values["mu"], law)


#: model name -> (parameter help dict, build(values) -> model, CLI name -> field name)
SWEEP_MODELS = {"variable-mass": (VM_PARAMS, _variable_mass, _FIELD)}


def _sweep_args(p):
    sub = p.add_subparsers(dest="model", required=True, metavar="MODEL")
    for name, (params, _, _) in SWEEP_MODELS.items():
        q = sub.add_parser(name, help=f"sweep the {name} model over a grid of parameters")
        # let an axis start with a minus sign (`--delta -3:3:7`): argparse would take it for an
        # option; none of these options looks like a number
        q._negative_number_matcher = re.compile(r"^-\d*\.?\d+([eE][-+]?\d+)?([:,].*)?$")
        for k, h in params.items():
            q.add_argument(f"--{k}", metavar="AXIS",
                           help=f"{h}: start:stop:count, a comma list, or one value")
        q.add_argument("--set", metavar="K=V,...", help="fixed parameters, and a0 (initial "
                       "deflection [m]), e.g. m0=5,c=4900,FT=14.7,a0=0.06")
        q.add_argument("--n", type=int, default=12, help="number of turning points (default 12)")
        q.add_argument("--method", choices=("exact", "energy", "smooth"), default="exact")
        q.add_argument("--out", metavar="CSV", help="write the sweep to this CSV file")
        q.add_argument("--netcdf", metavar="NC", help="also write NetCDF (needs vmj[xarray])")
        q.add_argument("--plot", metavar="PNG", help="swings until the mass sticks over "
                       "(eps, mu), one panel per delta")
        q.add_argument("--error-plot", metavar="PNG", help="energy-balance error against the "
                       "exact solution over the same grid")
        q.add_argument("--chunk-size", type=int, default=16384, help="points per compiled call")
        q.add_argument("--progress", action="store_true", help="always show the progress bar")


def _sweep(args) -> int:
    import numpy as np

    import vmj

    params, build, field = SWEEP_MODELS[args.model]
    fixed = parse_set(args.set)
    a0 = fixed.pop("a0", None)
    if a0 is None:
        raise ValueError("missing a0: give --set a0=VALUE (initial deflection [m])")
    a0 = float(parse_axis("set a0", a0)[0])
    values, axes = {}, {}
    for k, v in fixed.items():
        if k not in params:
            raise ValueError(f"--set: unknown parameter {k!r} (known: a0, {', '.join(params)})")
        arr = parse_axis(f"set {k}", v)
        if arr.size != 1:
            raise ValueError(f"--set {k} takes one value; give --{k} for an axis")
        values[k] = float(arr[0])
    for k in params:
        text = getattr(args, k)
        if text is None:
            continue
        if k in values:
            raise ValueError(f"{k} is given both as --{k} and in --set")
        arr = parse_axis(k, text)
        values[k] = float(arr[0])
        axes[k] = arr
    if not axes:
        raise ValueError("give at least one axis, e.g. --eps 0:1:11")
    if args.n < 1:
        raise ValueError(f"--n must be an integer >= 1 (got {args.n})")
    if (args.plot or args.error_plot) and (list(axes)[:2] != ["eps", "mu"] or len(axes) > 3):
        raise ValueError("--plot and --error-plot need the axes --eps and --mu, and optionally "
                         f"--delta (got {', '.join('--' + k for k in axes)})")
    model = build(values)
    # validate every axis value (ValueError naming the parameter), then build the grid
    g = vmj.grid(model, **{field.get(k, k): v for k, v in axes.items()})
    progress = True if args.progress else None
    t = time.perf_counter()

    def run(method):
        return vmj.sweep(vmj.turning_points, g, a0=a0, n=args.n, method=method,
                         chunk_size=args.chunk_size, progress=progress)

    result = run(args.method)
    elapsed = time.perf_counter() - t
    if args.out:
        result.to_csv(args.out)
    if args.netcdf:
        result.to_netcdf(args.netcdf)
    if args.plot or args.error_plot:
        from .plot import plot_energy_error, plot_swings

        cli_names = {v: k for k, v in field.items()}
        for r in [result]:
            r.coords.update({cli_names.get(d, d): r.coords[d] for d in r.dims})
        if args.plot:
            plot_swings(result, args.plot, title=f"{args.method}: ")
        if args.error_plot:
            exact = result if args.method == "exact" else run("exact")
            energy = result if args.method == "energy" else run("energy")
            plot_energy_error(exact, energy, a0, args.error_plot)
    seq = result.values
    shape = " x ".join(f"{d} {len(result.coords[d])}" for d in result.dims)
    stopped = int(np.sum(seq.stopped))
    failed = int(np.sum(vmj.RESULTS.failed(np.asarray(seq.result))))
    n_points = math.prod(result.shape)
    print(f"sweep: {n_points} points ({shape}), method {args.method}, {args.n} swings, "
          f"{elapsed:.2f} s; stopped within {args.n} swings: {stopped}; failed: {failed}"
          + (f"; wrote {args.out}" if args.out else ""), file=sys.stdout)
    if failed:
        codes, counts = np.unique(np.asarray(seq.result)[vmj.RESULTS.failed(np.asarray(seq.result))],
                                  return_counts=True)
        for code, cnt in zip(codes, counts):
            print(f"  {cnt} points: {vmj.RESULTS.messages[int(code)]}")
    return 0


command("sweep", "sweep a decay over a grid of parameters (CSV, figures)")((_sweep_args, _sweep))
