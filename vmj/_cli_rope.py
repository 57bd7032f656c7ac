"""`vmj decay rope`: turning points of the mass on a rope of varying length."""

from __future__ import annotations

from ._cli import DECAY_MODELS, _emit, _number


def _args(p):
    p.add_argument("--m", type=_number, required=True, help="mass [kg] (technical: kG s^2/m)")
    p.add_argument("--A", type=_number, required=True, help="rope cross-section [m^2] (cm^2)")
    p.add_argument("--e", type=_number, required=True, help="linear modulus [Pa] (kG/cm^2)")
    p.add_argument("--b", type=_number, default=0.0, help="quadratic coefficient [Pa] (kG/cm^2)")
    p.add_argument("--d", type=_number, default=0.0, help="cubic coefficient [Pa] (kG/cm^2)")
    p.add_argument("--T", type=_number, required=True, help="wire friction stress [Pa] (kG/cm^2)")
    p.add_argument("--l0", type=_number, required=True, help="initial rope length [m]")
    p.add_argument("--u", type=_number, required=True,
                   help="hoisting speed [m/s] (> 0 hoisting, < 0 lowering)")
    p.add_argument("--brake", type=_number, nargs=2, metavar=("T_BRAKE", "T_STOP"),
                   help="brake uniformly from t_brake to rest at t_stop [s]")
    p.add_argument("--a0", type=_number, required=True, help="initial deflection [m] (cm)")
    p.add_argument("--t1", type=_number, required=True, help="final time [s]")
    p.add_argument("--method", choices=("exact", "smooth", "kbm"), default="exact")
    p.add_argument("--units", choices=("si", "technical"), default="si",
                   help="technical: m in kG s^2/m, A in cm^2, e, b, d, T in kG/cm^2, a0 in cm "
                        "(the paper's units); the output is always SI")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _run(args) -> int:
    import jax.numpy as jnp
    import numpy as np

    import vmj

    from ._checks import check, positive
    from ._models._base import check_horizon
    from ._closed_forms._osinski import half_swings_until

    if args.brake is not None:
        length = vmj.Braking(args.l0, args.u, *args.brake)
    else:
        length = vmj.ConstantSpeed(args.l0, args.u)
    params = (args.m, args.A, args.e, args.b, args.d, args.T, length)
    if args.units == "technical":
        rope = vmj.Rope.from_technical(*params)
        a0 = args.a0 * 1e-2
    else:
        rope = vmj.Rope(*params)
        a0 = args.a0
    check("a0", a0, positive, "> 0")
    check("t1", args.t1, positive, "> 0 [s]")
    check_horizon(rope, args.t1)
    n = half_swings_until(rope, a0, args.t1)
    if args.method == "kbm":
        if args.brake is not None:
            raise ValueError("method kbm needs a constant speed (no --brake)")
        times = np.linspace(0.0, args.t1, n + 1)  # at least every half period
        amps = np.asarray(vmj.kbm_amplitude(rope, a0, jnp.asarray(times)))
        stopped = bool(amps[-1] <= 0)
        message = ("friction stops the averaged motion" if stopped
                   else "first-order averaged envelope")
        failed = False
    else:
        seq = vmj.turning_points(rope, jnp.asarray(a0), n, method=args.method, max_substeps=12)
        got = seq.reached()
        keep = got["times"] <= args.t1
        times, amps = got["times"][keep], got["amplitudes"][keep]
        stopped = bool(seq.stopped) and bool(np.all(keep))
        message, failed = seq.message, bool(seq.failed)
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
    for k, (t, a) in enumerate(zip(out["times"], out["amplitudes"]), 0 if args.method == "kbm"
                               else 1):
        lines.append(f"{k:>4} {t:12.6f} {a:14.8f} {100 * a:10.5f}")
    lines.append(f"status: {message}")
    _emit(out, args.json, "\n".join(lines))
    return 0


DECAY_MODELS["rope"] = (_args, _run)
