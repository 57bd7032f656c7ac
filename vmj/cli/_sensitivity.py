"""`vmj sensitivity MODEL ... --wrt NAMES`: derivatives of a solution with respect to parameters
(`vmj.sensitivity`, forward-mode automatic differentiation through the solver).

    vmj sensitivity variable-mass --m0 5 --c 4900 --delta 3 --eps 0 --mu 2 --FT 14.7 \\
        --a0 0.06 --wrt FT,mu,eps,delta --json
    vmj sensitivity stick-slip --eps 6.3 --Omega 0.7 --wrt eps,Omega

Decay models give `d|x_k|/dp` and `dt_k/dp` for every turning point reached; stick-slip gives the
derivatives of the period, slip and stick times. Derivatives are per SI unit of the parameter.
"""

from __future__ import annotations

from .._exported import exported_jit
from ._options import Joined, count, emit, figure_path, traced_checks
from ._params import MODELS, add_options, given

__all__ = ["add_arguments", "run"]

CYCLE = ("period", "slip_time", "stick_time")  #: the stick-slip quantities differentiated


def add_arguments(p) -> None:
    from ._app import add_global_options
    from ._decay import MAX_TURNING_POINTS, _rope_args, max_substeps_arg

    sub = p.add_subparsers(dest="model", required=True, metavar="MODEL")
    for name in ("variable-mass", "rope", "stick-slip"):
        spec = MODELS[name]
        q = sub.add_parser(
            name,
            help=f"derivatives for the {name} model",
            description=f"Derivatives for the {spec.summary}.",
            formatter_class=p.formatter_class,
        )
        add_options(q, spec)
        names = ", ".join(x.name for x in spec.params)
        q.add_argument(
            "--wrt",
            metavar="NAME[,NAME...]",
            action=Joined,
            required=True,
            help=f"parameters to differentiate with respect to (of: {names})",
        )
        if name == "variable-mass":
            q.add_argument("--n", type=count, default=12, help="number of turning points")
            q.add_argument(
                "--method",
                choices=("exact", "smooth", "energy"),
                default="exact",
                help="solver differentiated",
            )
            max_substeps_arg(q, name)
        elif name == "rope":
            _rope_args(q, ("exact", "smooth"))  # the averaged envelope has no turning points
        else:
            q.add_argument(
                "--method",
                choices=("exact", "closed"),
                default="exact",
                help="solver differentiated",
            )
        if name != "stick-slip":
            q.add_argument(
                "--plot",
                metavar="PATH",
                type=figure_path,
                help="write a figure of the derivatives against k to PATH",
            )
            q.add_argument(
                "--force",
                action="store_true",
                help=f"compute more than {MAX_TURNING_POINTS} turning points",
            )
        else:
            q.add_argument("--force", action="store_true", help="accept eps above 1e4")
        q.add_argument("--json", action="store_true", help="print one JSON object")
        add_global_options(q, nested=True)


def _wrt(spec, text: str, values: dict) -> list:
    """The parameters named by `--wrt` (as spelled), each a model field of the built model or an
    initial condition."""
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise ValueError("--wrt must name at least one parameter")
    out = []
    for name in names:
        try:
            p = spec.param(name)
        except ValueError as e:
            raise ValueError(f"--wrt: {e}") from None
        if p.name not in values:
            raise ValueError(f"--wrt {name}: --{p.name} is not part of the model as given")
        if any(q is p for _, q in out):
            raise ValueError(f"--wrt names {p.name} twice")
        out.append((name, p))
    return out


def _unit(p) -> str:
    return p.help[p.help.index("[") + 1 : p.help.index("]")] if "[" in p.help else "-"


def run(args) -> int:
    spec = MODELS[args.model]
    if args.model == "rope":
        from ._decay import rope_model

        model, values, n = rope_model(args)
        a0 = values["a0"]
    else:
        values = spec.resolve(given(spec, args))
        model = spec.build(values)
        a0 = values.get("a0")
        n = getattr(args, "n", None)
        if args.model == "variable-mass":
            from ._decay import turning_point_limit

            turning_point_limit(args, n, f"--n {n} turning points")
    wrt = _wrt(spec, args.wrt, values)
    # vmj.sensitivity names a model field by its dotted path, an argument of the solve by name
    keys = [p.field if p.field is not None else p.name for _, p in wrt]
    units = {name: _unit(p) for name, p in wrt}
    if args.model == "stick-slip":
        return _cycle(args, values, model, wrt, keys, units)
    return _decay(args, model, a0, n, wrt, keys, units)


def _cycle(args, values, model, wrt, keys, units) -> int:
    """Derivatives of the stick-slip period, slip and stick times."""
    import vmj

    from ._decay import solver_of
    from ._stick_slip import eps_limit, reversal_bound

    eps_limit(args, values["eps"])
    solver = solver_of(args)
    bound = reversal_bound(values["eps"])

    def cycle(m):
        c = vmj.limit_cycle(m, solver, max_reversals=bound)
        return {k: getattr(c, k) for k in CYCLE}

    got = vmj.limit_cycle(model, solver, max_reversals=bound)
    with traced_checks():
        d = vmj.sensitivity(cycle, model, keys)
    out = {"model": "stick-slip", "method": args.method, "wrt": [w for w, _ in wrt], "units": units}
    out.update({k: float(getattr(got, k)) for k in CYCLE})
    for k in CYCLE:
        out[f"d_{k}"] = {w: float(d[key][k]) for (w, _), key in zip(wrt, keys)}
    if bool(got.failed):
        out["message"] = vmj.RESULTS(int(got.result)).message
    lines = [
        f"stick-slip cycle (eps={values['eps']:g}, Omega={values['Omega']:g}, "
        f"method={args.method}; dimensionless time)",
        f"{'':12}{'value':>16}" + "".join(f"{'d/d' + w:>16}" for w, _ in wrt),
    ]
    for k in CYCLE:
        lines.append(
            f"{k:<12}{out[k]:16.8g}" + "".join(f"{out[f'd_{k}'][w]:16.8g}" for w, _ in wrt)
        )
    emit(out, args.json, "\n".join(lines))
    return 0


@exported_jit(static_argnums=(2, 4, 5))
def _decay_derivatives(model, a0, n, solver, keys, mode):
    """`vmj.sensitivity` of the amplitudes and times of `n` turning points by `solver` with
    respect to `keys` in `mode`."""
    import vmj

    def decay(m, a0, n):
        seq = vmj.turning_points(m, a0, n, solver)
        return {"times": seq.times, "amplitudes": seq.amplitudes}

    return vmj.sensitivity(decay, model, keys, mode=mode, a0=a0, n=n)


def _decay(args, model, a0, n, wrt, keys, units) -> int:
    """Derivatives of the turning points' amplitudes and times."""
    import numpy as np

    import vmj

    from ._decay import cli_message, solver_of

    method = args.method
    solver = solver_of(args)

    seq = vmj.turning_points(model, a0, n, solver)
    got = seq.reached()
    keep = len(got["times"])
    if args.model == "rope":  # the turning points up to --t1
        keep = int(np.sum(got["times"] <= args.t1))
    if method == "smooth":  # forward mode (a few parameters, many outputs)
        solver = vmj.Smoothed(smoothing=solver.smoothing, derivatives="forward")
    # that concrete solve checked the model and a0 on the host (a failed check raised there):
    # the derivatives are traced without guards, so that the program is exported and a
    # repeated command loads it (vmj/_exported.py)
    with vmj.assume_valid():
        d = _decay_derivatives(model, a0, n, solver, tuple(keys), "forward")
    out = {
        "model": args.model,
        "method": method,
        "wrt": [w for w, _ in wrt],
        "units": units,
        "times": got["times"][:keep].tolist(),
        "amplitudes": got["amplitudes"][:keep].tolist(),
        "d_amplitudes": {
            w: np.asarray(d[key]["amplitudes"])[:keep].tolist() for (w, _), key in zip(wrt, keys)
        },
        "d_times": {
            w: np.asarray(d[key]["times"])[:keep].tolist() for (w, _), key in zip(wrt, keys)
        },
        "stopped": bool(seq.stopped),
    }
    if bool(seq.failed):
        out["message"] = cli_message(seq.message)
    bad = [w for w, _ in wrt if not np.all(np.isfinite(out["d_amplitudes"][w] + out["d_times"][w]))]
    if bad:
        raise ValueError(
            f"the derivatives with respect to {', '.join(bad)} are not finite here "
            "(a turning point at a stick or release boundary)"
        )
    if args.plot:
        from vmj.plot import plot_sensitivity

        plot_sensitivity(out, args.plot)
    from vmj.plot import per

    header = f"{'k':>3} {'t [s]':>10} {'|x| [m]':>12}" + "".join(
        f" {'d|x|/d' + w + ' [' + per('m', units[w]) + ']':>24}" for w, _ in wrt
    )
    lines = [header]
    for k in range(keep):
        lines.append(
            f"{k + 1:>3} {out['times'][k]:10.5f} {out['amplitudes'][k]:12.8f}"
            + "".join(f" {out['d_amplitudes'][w][k]:24.10g}" for w, _ in wrt)
        )
    lines.append(f"status: {cli_message(seq.message)}; dt_k/dp in the JSON output (--json)")
    emit(out, args.json, "\n".join(lines))
    return 0
