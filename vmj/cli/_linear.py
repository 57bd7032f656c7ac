"""`vmj linear`: the linear one-degree-of-freedom oscillator (frequencies, decrement, responses)."""

from __future__ import annotations

import math

from ._options import emit
from ._params import MODELS, add_options, given

__all__ = ["add_arguments", "run", "KEYS"]

#: the JSON keys, in order (a contract)
KEYS = (
    "natural_frequency",
    "damped_frequency",
    "damping_ratio",
    "log_decrement",
    "free_amplitude",
    "free_phase",
    "forced_amplitude",
    "forced_phase",
)


def add_arguments(p) -> None:
    add_options(p, MODELS["linear"])
    p.add_argument("--json", action="store_true", help="print one JSON object")


def characteristics(osc, x0, v0, forced: bool) -> dict:
    """The quantities of `vmj linear` (the keys of `KEYS`; the forced ones only if `forced`) for
    one oscillator, NaN where one is not defined (over-damped: no damped frequency, decrement or
    free amplitude). Works under `jax.vmap` (`vmj sweep linear`)."""
    import equinox as eqx
    import jax.numpy as jnp

    under = osc.damping_ratio < 1
    # the free-vibration part of the full response (the transient when forced), computed on an
    # undamped stand-in where the oscillator is not under-damped and then masked
    stand_in = eqx.tree_at(lambda o: o.c, osc, jnp.where(under, osc.c, 0.0))
    A, alpha = stand_in.transient(x0, v0)
    masked = lambda v: jnp.where(under, v, jnp.nan)  # noqa: E731
    out = {
        "natural_frequency": osc.natural_frequency,
        "damped_frequency": masked(osc.damped_frequency),
        "damping_ratio": osc.damping_ratio,
        "log_decrement": masked(osc.log_decrement),
        "free_amplitude": masked(A),
        "free_phase": masked(alpha),
    }
    if forced:
        out["forced_amplitude"], out["forced_phase"] = osc.forced_response()
    return out


#: what a forced amplitude of `inf` means (`vmj linear` and `vmj sweep linear`)
RESONANCE = (
    "undamped resonance (c = 0, p = sqrt(k/m)): no steady state, the forced response grows as "
    "|Q| t/(2 m p); the free part is taken against it"
)


def _finite(x):
    x = float(x)
    return x if math.isfinite(x) else None


def run(args) -> int:
    spec = MODELS["linear"]
    values = spec.resolve(given(spec, args))
    forced = "F0" in values
    got = characteristics(spec.build(values), values["x0"], values["v0"], forced)
    out = {key: _finite(got[key]) if key in got else None for key in KEYS}
    A, alpha = out["free_amplitude"], out["free_phase"]
    fmt = lambda v, unit: "n/a" if v is None else f"{v:.6g} {unit}"  # noqa: E731
    lines = [
        f"natural frequency omega_c: {fmt(out['natural_frequency'], '1/s')}",
        f"damped frequency omega_3:  {fmt(out['damped_frequency'], '1/s')}",
        f"damping ratio eta:         {fmt(out['damping_ratio'], '')}",
        f"logarithmic decrement:     {fmt(out['log_decrement'], '')}",
        f"free response x = A exp(-eta omega_c t) sin(omega_3 t + alpha): "
        f"A = {fmt(A, 'm')}, alpha = {fmt(alpha, 'rad')}",
    ]
    eta = out["damping_ratio"]
    if eta is not None and eta >= 1:
        lines.append(
            f"{'critically damped (eta = 1)' if eta == 1 else 'over-damped (eta > 1)'}: the free "
            "motion does not oscillate, so it has no damped frequency, decrement or amplitude "
            "(n/a; null in --json)"
        )
    if forced:
        D = float(got["forced_amplitude"])
        lines.append(
            "forced response x = D sin(p t - beta): "
            + (f"D = {fmt(out['forced_amplitude'], 'm')}, " if math.isfinite(D) else "D = inf, ")
            + f"beta = {fmt(out['forced_phase'], 'rad')}"
        )
        if not math.isfinite(D):
            lines.append(RESONANCE)
    emit(out, args.json, "\n".join(lines))
    return 0
