"""`vmj decay MODEL`: the turning points of a free decay (variable-mass, rope)."""

from __future__ import annotations

from ._options import count, emit, number, refuse_above
from ._params import MODELS, add_options, given

__all__ = [
    "add_arguments",
    "cli_message",
    "max_substeps_arg",
    "run",
    "rope_model",
    "solver_of",
    "turning_point_limit",
    "MAX_TURNING_POINTS",
]

MAX_TURNING_POINTS = 100_000  #: turning points computed without --force (decay, sensitivity)
#: the rope's exact substeps per half-swing at most unless --max-substeps (the library's
#: default, 8, serves the variable mass)
ROPE_SUBSTEPS = 12


def add_arguments(p) -> None:
    from ._app import add_global_options

    sub = p.add_subparsers(dest="model", required=True, metavar="MODEL")
    for name, (add, run) in DECAY.items():
        q = sub.add_parser(
            name,
            help=MODELS[name].summary,
            description=MODELS[name].summary,
            formatter_class=p.formatter_class,
        )
        add_options(q, MODELS[name])
        add(q)
        q.add_argument(
            "--force",
            action="store_true",
            help=f"compute more than {MAX_TURNING_POINTS} turning points",
        )
        q.add_argument("--json", action="store_true", help="print one JSON object")
        add_global_options(q, nested=True)
        q.set_defaults(decay_run=run)


def run(args) -> int:
    return args.decay_run(args)


def max_substeps_arg(q, model: str) -> None:
    default = ROPE_SUBSTEPS if model == "rope" else 8
    q.add_argument(
        "--max-substeps",
        type=count,
        metavar="N",
        help=f"with --method exact: substeps per half-swing at most (default {default}; a mass "
        "that grows fast, or creeping motion, needs more)",
    )


def solver_of(args, method: str | None = None):
    """The solver object of `--method` (or of `method`, another solve of the same command): the
    command line's one translation of its solver names (`AbstractSolver.name`: exact, smooth,
    energy, closed) into vmj's solver objects, with their settings: `--max-substeps` of
    `vmj.Exact` (refused with another `--method`; the rope's default `ROPE_SUBSTEPS`), and the
    stick-slip command's `--smoothing` of `vmj.Smoothed`."""
    import vmj

    steps = getattr(args, "max_substeps", None)
    if steps is not None and args.method != "exact":
        raise ValueError(f"--max-substeps applies to --method exact (got --method {args.method})")
    w = getattr(args, "smoothing", None)
    if w is not None:
        if args.method != "smooth":
            raise ValueError("--smoothing applies to --method smooth")
        if not w > 0:
            raise ValueError(f"--smoothing must be finite and > 0 (got {w:g})")
    from vmj._integrate import SOLVERS

    kind = SOLVERS[method or args.method]
    if kind is vmj.Exact:
        if steps is None and getattr(args, "model", None) == "rope":
            steps = ROPE_SUBSTEPS
        return vmj.Exact(max_substeps=steps)
    if kind is vmj.Smoothed:
        return vmj.Smoothed(smoothing=w)
    return kind()


def cli_message(message: str) -> str:
    """A status message with the command's spelling of the exact solver and its step limit."""
    return message.replace("max_substeps", "--max-substeps").replace("vmj.Exact", "--method exact")


def turning_point_limit(args, n: int, what: str) -> None:
    """Refuse more than `MAX_TURNING_POINTS` unless `--force`."""
    if not args.force:
        refuse_above(what, n, MAX_TURNING_POINTS, "turning points")


# -- variable-mass -------------------------------------------------------------------------------
def _variable_mass_args(q) -> None:
    q.add_argument("--n", type=count, default=12, help="number of turning points")
    q.add_argument(
        "--method",
        choices=("exact", "smooth", "energy"),
        default="exact",
        help="exact non-smooth solver, smoothed ODE, or the paper's energy balance",
    )
    max_substeps_arg(q, "variable-mass")


def _variable_mass(args) -> int:
    import vmj

    turning_point_limit(args, args.n, f"--n {args.n} turning points")
    spec = MODELS["variable-mass"]
    values = spec.resolve(given(spec, args))
    seq = vmj.turning_points(spec.build(values), values["a0"], args.n, solver_of(args))
    got = seq.reached()
    out = {
        "model": "variable-mass",
        "method": args.method,
        "times": got["times"].tolist(),
        "amplitudes": got["amplitudes"].tolist(),
        "crossed": got["crossed"].tolist(),
        "stopped": bool(seq.stopped),
    }
    if bool(seq.failed):
        out["message"] = cli_message(seq.message)
    lines = [f"{'k':>3} {'t [s]':>12} {'|x| [m]':>14} {'crossed':>8}"]
    for k, (t, a, c) in enumerate(zip(out["times"], out["amplitudes"], out["crossed"]), 1):
        lines.append(f"{k:>3} {t:12.6f} {a:14.8f} {'yes' if c else 'no *':>8}")
    lines.append(f"status: {cli_message(seq.message)}")
    emit(out, args.json, "\n".join(lines))
    return 0


# -- rope ----------------------------------------------------------------------------------------
def _rope_args(q, methods=("exact", "smooth", "kbm")) -> None:
    q.add_argument(
        "--brake",
        type=number,
        nargs=2,
        metavar=("T_BRAKE", "T_STOP"),
        help="brake uniformly from T_BRAKE to rest at T_STOP [s] (the same as "
        "--t_brake T_BRAKE --t_stop T_STOP)",
    )
    q.add_argument("--t1", type=number, required=True, help="final time [s]")
    described = {
        "exact": "the exact non-smooth solver",
        "smooth": "the smoothed ODE",
        "kbm": "the first-order averaged envelope (kbm; constant speed only)",
    }
    q.add_argument(
        "--method",
        choices=methods,
        default="exact",
        help=", ".join(described[m] for m in methods),
    )
    max_substeps_arg(q, "rope")
    q.add_argument(
        "--units",
        choices=("si", "technical"),
        default="si",
        help="technical: m in kG s^2/m, A in cm^2, e, b, d, T in kG/cm^2, a0 in cm "
        "(the paper's units); the output is always SI",
    )


def rope_model(args, t1_flag: str = "--t1"):
    """`(model, values, n)` from the parsed options: the model, its parameters and `a0` checked
    and in SI, and `n` the number of half-swings that may occur before `--t1`."""
    from .._closed_forms._osinski import half_swings_until
    from .._models._base import check_horizon

    spec = MODELS["rope"]
    values = given(spec, args)
    if args.brake is not None:
        if "t_brake" in values or "t_stop" in values:
            raise ValueError("give --brake or --t_brake/--t_stop, not both")
        values["t_brake"] = (args.brake[0], "--brake T_BRAKE")
        values["t_stop"] = (args.brake[1], "--brake T_STOP")
    values = spec.resolve(values, technical=args.units == "technical")
    rope = spec.build(values)
    if not args.t1 > 0:
        raise ValueError(f"{t1_flag} must be finite and > 0 [s] (got {args.t1:g})")
    check_horizon(rope, args.t1, t1_flag)
    try:
        n = half_swings_until(rope, values["a0"], args.t1)
    except (OverflowError, ValueError):
        raise ValueError(
            f"the number of swings before {t1_flag} {args.t1:g} cannot be estimated "
            "(parameters out of floating-point range)"
        ) from None
    turning_point_limit(args, n, f"about {n:.3g} half-swings before {t1_flag} {args.t1:g}")
    return rope, values, n


def _rope(args) -> int:
    import jax.numpy as jnp
    import numpy as np

    import vmj

    rope, values, n = rope_model(args)
    a0 = values["a0"]
    if args.method == "kbm":
        if "t_brake" in values:
            raise ValueError("--method kbm needs a constant speed (no --brake, --t_brake)")
        failed = False
        if bool(rope.rest(0.0, -a0)[2]):  # the envelope would decay a mass that never moves
            times, amps, stopped = np.zeros(1), np.full(1, a0), True
            message = (
                "the mass does not move: |spring force| <= static friction A T at the release "
                "(no motion to average)"
            )
        else:
            times = np.linspace(0.0, args.t1, n + 1)  # at least every half period
            amps = np.asarray(vmj.kbm_amplitude(rope, a0, jnp.asarray(times)))
            stopped = bool(amps[-1] <= 0)
            message = (
                "friction stops the averaged motion" if stopped else "first-order averaged envelope"
            )
    else:
        seq = vmj.turning_points(rope, a0, n, solver_of(args))
        got = seq.reached()
        keep = got["times"] <= args.t1
        times, amps = got["times"][keep], got["amplitudes"][keep]
        stopped = bool(seq.stopped) and bool(np.all(keep))
        message, failed = cli_message(seq.message), bool(seq.failed)
        if not keep.all():  # the solve's own status is of a time after --t1
            message = f"reached --t1 {args.t1:g} s ({int(keep.sum())} turning points before it)"
        if int(seq.count) == n and not stopped and not failed and keep.all():
            raise RuntimeError("internal: the turning-point count estimate was too small")
    out = {
        "model": "rope",
        "method": args.method,
        "times": [float(t) for t in times],
        "amplitudes": [float(a) for a in amps],
        "stopped": stopped,
    }
    if failed:
        out["message"] = message
    lines = [f"{'k':>4} {'t [s]':>12} {'|x| [m]':>14} {'|x| [cm]':>10}"]
    first = 0 if args.method == "kbm" else 1
    for k, (t, a) in enumerate(zip(out["times"], out["amplitudes"]), first):
        lines.append(f"{k:>4} {t:12.6f} {a:14.8f} {100 * a:10.5f}")
    lines.append(f"status: {message}")
    emit(out, args.json, "\n".join(lines))
    return 0


#: decay models: name -> (add the model's own options, run)
DECAY = {"variable-mass": (_variable_mass_args, _variable_mass), "rope": (_rope_args, _rope)}
