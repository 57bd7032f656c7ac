"""`vmj stick-slip`: the limit cycle of the torsional stick-slip model."""

from __future__ import annotations

import math

from ._decay import solver_of
from ._options import emit, number, refuse_above
from ._params import MODELS, add_options, given

__all__ = ["add_arguments", "run", "MAX_EPS", "reversal_bound"]

MAX_EPS = 1e4  #: largest eps computed without --force (a cycle has about eps/2 reversals)


def add_arguments(p) -> None:
    add_options(p, MODELS["stick-slip"])
    p.add_argument(
        "--method",
        choices=("exact", "closed", "smooth"),
        default="exact",
        help="exact event-driven solver, the paper's closed forms, or the smoothed diffrax model",
    )
    p.add_argument(
        "--smoothing",
        type=number,
        default=None,
        help="smoothing velocity w of --method smooth [-] (default 1e-4)",
    )
    p.add_argument("--force", action="store_true", help=f"accept eps above {MAX_EPS:g}")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def reversal_bound(eps: float) -> int:
    """A static reversal bound that always suffices: k* <= (eps - 1)/2."""
    return max(1, int(math.ceil((eps - 1) / 2)) + 1)


def eps_limit(args, eps: float, flag: str = "--eps") -> None:
    if not args.force:
        refuse_above(
            f"{flag} {eps:g} means about {eps / 2:.3g} reversals per cycle (arrays of that length)",
            eps,
            MAX_EPS,
            "for eps",
        )


def run(args) -> int:
    import vmj

    spec = MODELS["stick-slip"]
    values = spec.resolve(given(spec, args))
    eps_limit(args, values["eps"])
    solver = solver_of(args)
    model = spec.build(values)
    cycle = vmj.limit_cycle(model, solver, max_reversals=reversal_bound(values["eps"]))
    out = cycle.reached()
    if bool(cycle.failed):
        out["message"] = vmj.RESULTS(int(cycle.result)).message
    lines = [
        f"stick-slip cycle (eps={values['eps']:g}, Omega={values['Omega']:g}, "
        f"method={args.method}; dimensionless time)",
        f"reversals k*: {out['reversals']}",
    ]
    lines += [f"  slip interval {k}: {t:.10f}" for k, t in enumerate(out["slip_intervals"], 1)]
    lines += [
        f"slip time:  {out['slip_time']:.10f}",
        f"stick time: {out['stick_time']:.10f}",
        f"period:     {out['period']:.10f}",
    ]
    if "message" in out:
        lines.append(f"status: {out['message']}")
    emit(out, args.json, "\n".join(lines))
    return 0
