"""The one diffrax wrapper of vmj."""

from __future__ import annotations

__all__ = ["ode_solve"]


def ode_solve(field, y0, t1, saveat, *, rtol, atol, max_steps: int, solver=None):
    """`field(t, y, args)` integrated from `t = 0` to `t1` with diffrax (`solver`, default
    Tsit5) under a PID step-size controller; never raises (check `sol.result`)."""
    import diffrax as dfx  # here, not at the top: `import vmj` and the vmj command stay light
    return dfx.diffeqsolve(
        dfx.ODETerm(field), dfx.Tsit5() if solver is None else solver, t0=0.0, t1=t1, dt0=None,
        y0=y0, saveat=saveat, stepsize_controller=dfx.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps, throw=False,
    )
