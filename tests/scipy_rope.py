"""Independent reference for the rope model: event-driven SciPy integration (DOP853).

Each half-swing is integrated with a fixed friction sign up to the velocity zero (a terminal
event), then the stick rule `|spring force| <= A T` is applied. Constant-speed profile only.
SciPy is never imported by the library itself.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp


def rope_turning_points(m, A, e, b, d, T, l0, u, a0, n, rtol=1e-12):
    """Return (times, positions) of the first `n` turning points (fewer if it sticks)."""

    def spring(t, x):
        s = x / (l0 - u * t)
        return A * s * (e + s * (b + s * d))

    t, x = 0.0, -a0
    out_t, out_x = [], []
    for _ in range(n):
        f = spring(t, x)
        if abs(f) <= A * T:
            break
        s = -np.sign(f)

        def rhs(tt, y, s=s):
            return [y[1], -(spring(tt, y[0]) + A * T * s) / m]

        def vel_zero(tt, y, s=s):
            return y[1] * s

        vel_zero.terminal, vel_zero.direction = True, -1
        l = l0 - u * t
        k = A * (e + 3 * d * (x / l) ** 2) / l
        period = 2 * np.pi * np.sqrt(m / k)
        horizon = t + 5 * period
        sol = solve_ivp(
            rhs,
            (t, horizon),
            [x, 0.0],
            method="DOP853",
            rtol=rtol,
            atol=1e-15 * a0,
            events=vel_zero,
            first_step=1e-6 * period,
        )
        if not sol.t_events[0].size:
            break
        t, x = sol.t_events[0][0], sol.y_events[0][0][0]
        out_t.append(t)
        out_x.append(x)
    return np.array(out_t), np.array(out_x)
