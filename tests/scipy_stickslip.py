"""Independent reference: event-driven SciPy integration of the stick-slip rules (SYSTEMS.md 3).

Each slip phase integrates `xi'' + xi = -s` numerically (DOP853, rtol 1e-13) from the disk at
rest to the next zero of the disk velocity `u = xi' + Omega` (a terminal event); there the disk
reverses if `|xi| > 1 + margin`, otherwise it sticks until `xi` falls at rate `Omega` to `-eps`.
No closed form is used. SciPy is never imported by the library itself. `max_step` 0.02 keeps the
event detector from stepping over the shallow velocity dip of a reversal that starts just past
|xi| = 1 (the dip lasts about 2 (|xi| - 1)/Omega near the end of a full swing); reversals closer
to the threshold than about 0.01 Omega may still be missed (RuntimeError).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp


def stick_slip_cycle(eps, Omega, margin=2e-5, max_phases=64, rtol=1e-13):
    """Return (reversals, slip_intervals, slip_time, stick_time, period)."""
    xi, s = -eps, 1.0
    intervals = []
    for _ in range(max_phases):

        def rhs(t, y, s=s):
            return [y[1], -y[0] - s]

        def stop(t, y, s=s):
            return s * (y[1] + Omega)

        stop.terminal, stop.direction = True, -1
        # the phase starts at u = 0: step a little first so the event does not fire at t = 0
        sol = solve_ivp(
            rhs,
            (0.0, 4 * np.pi),
            [xi, -Omega],
            method="DOP853",
            rtol=rtol,
            atol=1e-15 * eps,
            events=stop,
            first_step=1e-6,
            max_step=0.02,
        )
        if not sol.t_events[0].size:
            raise RuntimeError("no velocity zero within two periods")
        tau, xi = sol.t_events[0][0], sol.y_events[0][0][0]
        intervals.append(tau)
        if abs(xi) > 1 + margin:
            s = -s
            continue
        slip = float(np.sum(intervals))
        stick = (xi + eps) / Omega
        return len(intervals) - 1, np.array(intervals), slip, stick, slip + stick
    raise RuntimeError("too many reversals")
