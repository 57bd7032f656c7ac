"""`vmj stick-slip` and `vmj linear` (registered on import; listed in `_cli.COMMAND_MODULES`)."""

from __future__ import annotations

import math
import sys

from ._cli import _emit, _number, command


MAX_EPS = 1e4  #: largest eps the CLI accepts (its arrays grow with the number of reversals)


# -- vmj stick-slip -----------------------------------------------------------------------------
def _stick_slip_args(p):
    p.add_argument("--eps", type=_number, required=True, help="static/sliding friction M1/M0 > 1")
    p.add_argument("--Omega", type=_number, required=True,
                   help="dimensionless drive speed omega sqrt(c I)/M0 > 0")
    p.add_argument("--method", choices=("exact", "closed", "smooth"), default="exact",
                   help="exact event-driven solver (default), the paper's closed forms, or the "
                        "smoothed diffrax model")
    p.add_argument("--smoothing", type=_number, default=None,
                   help="smoothing velocity w of --method smooth (default 1e-4)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _stick_slip(args) -> int:
    import vmj

    if args.eps > MAX_EPS:
        raise ValueError(f"eps must be finite and in (1, {MAX_EPS:g}] on the command line "
                         f"(got {args.eps:g}): the cycle has about eps/2 reversals")
    model = vmj.StickSlip(args.eps, args.Omega)
    if args.method == "closed":
        cycle = vmj.stick_slip_closed_form(model, max_reversals=_bound(args.eps))
    else:
        try:
            cycle = vmj.stick_slip_cycle(model, method=args.method,
                                         max_reversals=_bound(args.eps), smoothing=args.smoothing)
        except RuntimeError as e:  # the smoothed model did not settle / diffrax failed
            print(f"vmj: error: {e}", file=sys.stderr)
            return 1
    out = cycle.reached()
    if bool(cycle.result != 0):
        out["message"] = vmj.RESULTS.messages[int(cycle.result)]
    lines = [f"stick-slip cycle (eps={args.eps:g}, Omega={args.Omega:g}, method={args.method}; "
             "dimensionless time)",
             f"reversals k*: {out['reversals']}"]
    lines += [f"  slip interval {k}: {t:.10f}" for k, t in enumerate(out["slip_intervals"], 1)]
    lines += [f"slip time:  {out['slip_time']:.10f}", f"stick time: {out['stick_time']:.10f}",
              f"period:     {out['period']:.10f}"]
    _emit(out, args.json, "\n".join(lines))
    return 0


def _bound(eps: float) -> int:
    """A static reversal bound that always suffices: k* <= (eps - 1)/2."""
    return max(1, int(math.ceil((eps - 1) / 2)) + 1)


command("stick-slip", "stick-slip limit cycle with instantaneous velocity reversal")(
    (_stick_slip_args, _stick_slip))


# -- vmj linear ---------------------------------------------------------------------------------
def _linear_args(p):
    p.add_argument("--m", type=_number, required=True, help="mass [kg] > 0")
    p.add_argument("--c", type=_number, required=True, help="viscous damping [N s/m] >= 0")
    p.add_argument("--k", type=_number, required=True, help="stiffness [N/m] > 0")
    p.add_argument("--x0", type=_number, default=0.0, help="initial displacement [m]")
    p.add_argument("--v0", type=_number, default=0.0, help="initial velocity [m/s]")
    p.add_argument("--F0", type=_number, default=None, help="harmonic force amplitude [N]")
    p.add_argument("--p", type=_number, default=None, help="forcing angular frequency [1/s]")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _finite(x):
    x = float(x)
    return x if math.isfinite(x) else None


def _linear(args) -> int:
    import vmj

    if (args.F0 is None) != (args.p is None):
        raise ValueError("--F0 and --p must be given together (force F0 sin(p t))")
    forcing = vmj.NoForcing() if args.F0 is None else vmj.HarmonicForce(args.F0, args.p)
    osc = vmj.LinearOscillator(args.m, args.c, args.k, forcing)
    under = float(osc.damping_ratio) < 1
    if under:  # the free-vibration part of the full response (the transient when forced)
        A, alpha = (_finite(v) for v in osc.transient(args.x0, args.v0))
    else:
        A = alpha = None
    out = {
        "natural_frequency": _finite(osc.natural_frequency),
        "damped_frequency": _finite(osc.damped_frequency) if under else None,
        "damping_ratio": _finite(osc.damping_ratio),
        "log_decrement": _finite(osc.log_decrement),
        "free_amplitude": A,
        "free_phase": alpha,
        "forced_amplitude": None,
        "forced_phase": None,
    }
    if args.F0 is not None:
        D, beta = osc.forced_response()
        out["forced_amplitude"], out["forced_phase"] = _finite(D), _finite(beta)
    fmt = lambda v, unit: "n/a" if v is None else f"{v:.6g} {unit}"  # noqa: E731
    lines = [
        f"natural frequency omega_c: {fmt(out['natural_frequency'], '1/s')}",
        f"damped frequency omega_3:  {fmt(out['damped_frequency'], '1/s')}",
        f"damping ratio eta:         {fmt(out['damping_ratio'], '')}",
        f"logarithmic decrement:     {fmt(out['log_decrement'], '')}",
        f"free response x = A exp(-eta omega_c t) sin(omega_3 t + alpha): "
        f"A = {fmt(A, 'm')}, alpha = {fmt(alpha, 'rad')}",
    ]
    if args.F0 is not None:
        lines.append("forced response x = D sin(p t - beta): "
                     f"D = {fmt(out['forced_amplitude'], 'm')}, "
                     f"beta = {fmt(out['forced_phase'], 'rad')}")
    _emit(out, args.json, "\n".join(lines))
    return 0


command("linear", "linear one-degree-of-freedom oscillator: frequencies, decrement, responses")(
    (_linear_args, _linear))
