"""Independent reference: event-driven SciPy integration of the variable-mass oscillator.

Each half-swing is integrated with a fixed friction sign by `solve_ivp` (DOP853) up to the
velocity zero (a terminal event), then the stick rule is applied. Used by the tests and the
benchmarks; SciPy is never imported by the library itself.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp


def variable_mass_turning_points(
    m0, c, delta, eps, mu, a0, n, F=None, f=None, g=9.81, rtol=1e-12, segments=None
):
    """Return (times, positions, crossed) of the first `n` turning points (fewer if it stops).
    A list `segments` receives `(t_start, t_end, dense solution)` of each half-swing."""
    b = delta * eps + mu

    def friction(t):
        return F if F is not None else f * g * (m0 + delta * t)

    t, x = 0.0, -a0
    t_end = m0 / -delta if delta < 0 else np.inf
    out_t, out_x, out_c = [], [], []
    for _ in range(n):
        spring, Ft = c * abs(x), friction(t)
        if spring <= Ft:
            if f is not None and delta < 0:  # friction decreases with the mass: release later
                t = t + (Ft - spring) / (-f * g * delta)
            else:
                break
        s = -np.sign(x)

        def rhs(tt, y, s=s):
            return [y[1], -(b * y[1] + c * y[0] + s * friction(tt)) / (m0 + delta * tt)]

        def vel_zero(tt, y, s=s):
            return y[1] * s

        vel_zero.terminal, vel_zero.direction = True, -1
        period = np.pi * np.sqrt((m0 + delta * t) / c)
        horizon = min(t + 20 * period, t + 0.999 * (t_end - t))
        # the start has v = 0 exactly: nudge past it so the event does not fire at t0
        y0 = [x, 0.0]
        sol = solve_ivp(
            rhs,
            (t, horizon),
            y0,
            method="DOP853",
            rtol=rtol,
            atol=1e-14 * a0,
            events=vel_zero,
            first_step=1e-6 * period,
            dense_output=segments is not None,
        )
        if not sol.t_events[0].size:
            break
        if segments is not None:
            segments.append((sol.t[0], sol.t_events[0][0], sol.sol))
        t, x_new = sol.t_events[0][0], sol.y_events[0][0][0]
        out_c.append(bool(x_new * s > 0))
        x = x_new
        out_t.append(t)
        out_x.append(x)
    return np.array(out_t), np.array(out_x), np.array(out_c, dtype=bool)
