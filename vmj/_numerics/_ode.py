"""The one diffrax wrapper of vmj."""

from __future__ import annotations

__all__ = ["ode_solve"]


def ode_solve(
    field,
    y0,
    t1,
    saveat,
    *,
    rtol,
    atol,
    max_steps: int,
    solver=None,
    t0=0.0,
    event=None,
    resume=None,
):
    """`field(t, y, args)` integrated from `t0` (default 0) to `t1` with diffrax (`solver`,
    default Tsit5) under a PID step-size controller, stopping early at a `diffrax.Event`;
    never raises (check `sol.result`). `resume`: `(solver_state, controller_state, made_jump)`
    of a solve that ended at `t0` (saved with `SaveAt(solver_state=True,
    controller_state=True, made_jump=True)`), which this one continues with the same steps."""
    import diffrax as dfx  # here, not at the top: `import vmj` and the vmj command stay light

    solver_state, controller_state, made_jump = (None, None, None) if resume is None else resume
    return dfx.diffeqsolve(
        dfx.ODETerm(field),
        dfx.Tsit5() if solver is None else solver,
        t0=t0,
        t1=t1,
        dt0=None,
        y0=y0,
        saveat=saveat,
        stepsize_controller=dfx.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps,
        throw=False,
        event=event,
        solver_state=solver_state,
        controller_state=controller_state,
        made_jump=made_jump,
    )
