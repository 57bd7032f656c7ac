"""Independent reference: event-driven SciPy integration of the identification oscillator

    x'' + 2 zeta omega x' + cq x'|x'| + omega^2 (r(x) + xF sign(x')) = 0,
    r(x) = x or sin(x), plus b2 x^2 + b3 x^3,

released from rest at `-a0`. Each half-swing is integrated with a fixed friction sign by
`solve_ivp` (DOP853) up to the velocity zero (a terminal event); the mass sticks at a turning
point where `|r(x)| <= xS`. Written from the equation, sharing nothing with vmj.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp


def restoring(kind: str, b2=0.0, b3=0.0, w=1.0):
    """`r(x)`: the linear law, or the sine with a share `1 - w` of the linear one, plus the
    polynomial terms."""
    if kind == "linear":
        return lambda x: x + b2 * x * x + b3 * x**3
    return lambda x: w * np.sin(x) + (1 - w) * x + b2 * x * x + b3 * x**3


def oscillator_turning_points(
    omega,
    a0,
    n,
    kind="linear",
    zeta=0.0,
    xF=0.0,
    xS=None,
    cq=0.0,
    b2=0.0,
    b3=0.0,
    w=1.0,
    rtol=1e-12,
    segments=None,
):
    """(times, positions) of the first `n` turning points (fewer if the mass sticks). A list
    `segments` receives `(t_start, t_end, dense solution)` of each half-swing."""
    xS = xF if xS is None else xS
    r = restoring(kind, b2, b3, w)
    t, x = 0.0, -a0
    out_t, out_x = [], []
    for _ in range(n):
        if abs(r(x)) <= xS:
            break
        s = -np.sign(r(x))

        def rhs(_, y, s=s):
            v = y[1]
            return [v, -2 * zeta * omega * v - cq * v * abs(v) - omega**2 * (r(y[0]) + xF * s)]

        def vel_zero(_, y, s=s):
            return y[1] * s

        vel_zero.terminal, vel_zero.direction = True, -1
        period = 2 * np.pi / omega
        sol = solve_ivp(
            rhs,
            (t, t + 20 * period),
            [x, 0.0],
            method="DOP853",
            rtol=rtol,
            atol=1e-15 * a0,
            events=vel_zero,
            first_step=1e-6 * period,
            dense_output=segments is not None,
        )
        if not sol.t_events[0].size:
            break
        if segments is not None:
            segments.append((sol.t[0], sol.t_events[0][0], sol.sol))
        t, x = sol.t_events[0][0], sol.y_events[0][0][0]
        out_t.append(t)
        out_x.append(x)
    return np.array(out_t), np.array(out_x)


def motion(segments, a0, ts, rest):
    """Positions at times `ts` from the half-swings' dense solutions (`segments`); before the
    release `-a0`, after the last half-swing `rest` (the position where the mass stuck)."""
    out = np.full(len(ts), -a0, dtype=float)
    for i, t in enumerate(ts):
        if segments and t > segments[-1][1]:
            out[i] = rest
        for t0, t1, sol in segments:
            if t0 <= t <= t1:
                out[i] = sol(t)[0]
                break
    return out
