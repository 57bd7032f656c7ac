"""The one diffrax wrapper of vmj, and its default ODE solver."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["dopri8", "ode_solve", "recording", "step_size_controller"]


def dopri8():
    """diffrax's `Dopri8` (Dormand and Prince's 8(7) pair, 14 stages, Bogacki and Shampine's
    dense output of order 7), its stages written out instead of looped over (diffrax runs them
    in a `while_loop`, a dozen small XLA kernels per stage, which on CPUs cost more than a
    vmapped stage's arithmetic). Same tableau, error estimate and dense output; no
    first-same-as-last reuse (one vector-field evaluation more per step, no solver state); its
    dense output a polynomial in the step's fraction whose coefficients are sums over the
    stages, written out as well.

    vmj's default for smoothed solves at its tolerances (1e-10 and tighter): against Tsit5's
    seven stages, its steps are about three times as long (the smoothed turning points of the
    benchmark grid: 202 steps per point against 625, 268 against 848 for the slowest), and an
    808-point chunk of that grid takes 0.68 x the time (Tsit5 written out the same way)."""
    return _dopri8_class()()


def _weighted(weights, stages):
    """`sum_i weights[i] * stages[i]`, written out (zero weights left out)."""
    return sum(float(w) * k for w, k in zip(weights, stages) if w != 0)


@functools.cache
def _dopri8_class():
    import diffrax as dfx  # here, not at the top: `import vmj` and the vmj command stay light

    # diffrax's weights of the dense output: stage i's is `u * polyval(eval_coeffs[i], u)`,
    # highest power first; `dense[p - 1][i]` is the coefficient of `u**p`
    coeffs = np.asarray(dfx.Dopri8.interpolation_cls.eval_coeffs)
    dense = np.stack([coeffs[:, -p] for p in range(1, coeffs.shape[1] + 1)])

    class Interpolation(dfx.Dopri8.interpolation_cls):
        """The dense output as a polynomial in the step's fraction whose coefficients are sums
        over the stages written out. diffrax's `tensordot` over the stages becomes, under
        `vmap`, a batched matrix product of its own, which on CPUs cost the smoothed turning
        points more than their steps. `k`: the stages, a tuple."""

        def __init__(self, *, t0, t1, y0, y1, k):
            del y1  # (as diffrax's: the stages hold the step's end)
            self.t0, self.t1, self.y0, self.k = t0, t1, y0, k

        def evaluate(self, t0, t1=None, left=True):  # (its derivative: diffrax's, a `jvp`)
            if t1 is not None:
                return self.evaluate(t1) - self.evaluate(t0)
            span = self.t1 - self.t0
            return self.at_fraction((t0 - self.t0) / jnp.where(span == 0, 1.0, span))

        def at_fraction(self, u):
            """The state at `t0 + u (t1 - t0)`."""

            def one(y0, *k):
                powers = [_weighted(row, k) for row in dense]
                value = powers[-1]
                for c in powers[-2::-1]:
                    value = value * u + c
                return y0 + value * u

            return jax.tree.map(one, self.y0, *self.k)

    class Dopri8(dfx.Dopri8):
        interpolation_cls = Interpolation

        def init(self, terms, t0, t1, y0, args):
            return None

        def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
            tab, control, dt = self.tableau, terms.contr(t0, t1), t1 - t0

            def combine(weights, stages):
                return jax.tree.map(lambda *k: _weighted(weights, k), *stages)

            ks = [terms.vf_prod(t0, y0, args, control)]
            for c, row in zip(tab.c, tab.a_lower):
                y = jax.tree.map(jnp.add, y0, combine(row, ks))
                ks.append(terms.vf_prod(t0 + float(c) * dt, y, args, control))
            y1 = jax.tree.map(jnp.add, y0, combine(tab.b_sol, ks))
            dense = dict(y0=y0, y1=y1, k=tuple(ks))
            return y1, combine(tab.b_error, ks), dense, None, dfx.RESULTS.successful

    return Dopri8


def recording(solver, record, memo):
    """`solver` that carries `memo` in its state through a whole solve: after every step from
    `t0` to `t1`, `record(t0, t1, y1, interpolation, memo) -> (memo, done)` updates it (the
    step's dense output as `interpolation`); from the first step with `done` True the state
    stays where that step ended (the steps to `t1` are then free of error, so the controller
    reaches it in a few). A rejected step's memo is dropped with the step. The final memo is
    `sol.solver_state[1]` with `SaveAt(solver_state=True)`.

    This is how a solve finds many events (the smoothed turning points) in one run, each lane
    of a `vmap`ped batch moving on by itself, where `diffrax.Event` stops at the first.
    (Ending the solve itself would need a result code that is not an error: diffrax replaces
    `event_occurred` from a solver by the step-size controller's.)"""
    return _recording_class()(solver, record, memo)


@functools.cache
def _recording_class():
    import diffrax as dfx

    class Recording(dfx.AbstractAdaptiveSolver, dfx.AbstractWrappedSolver):
        solver: dfx.AbstractSolver
        record: object
        memo: object
        scan_kind: None = None  # (read by diffrax.ForwardMode, which sets it for its own loops)

        @property
        def term_structure(self):
            return self.solver.term_structure

        @property
        def interpolation_cls(self):
            return self.solver.interpolation_cls

        def order(self, terms):
            return self.solver.order(terms)

        def error_order(self, terms):
            return self.solver.error_order(terms)

        def init(self, terms, t0, t1, y0, args):
            return self.solver.init(terms, t0, t1, y0, args), self.memo, jnp.array(False)

        def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
            inner, memo, done = solver_state
            y1, error, dense, inner, result = self.solver.step(
                terms, t0, t1, y0, args, inner, made_jump
            )
            interpolation = self.solver.interpolation_cls(t0=t0, t1=t1, **dense)
            new_memo, finished = self.record(t0, t1, y1, interpolation, memo)

            def stay(moved, held):  # (done: the state stays put, without error)
                return jax.tree.map(lambda a, b: jnp.where(done, b, a), moved, held)

            held = {
                k: y0 if k in ("y0", "y1") else jax.tree.map(jnp.zeros_like, v)
                for k, v in dense.items()
            }  # (a constant, for the usual dense outputs)
            y1 = stay(y1, y0)
            error = stay(error, jax.tree.map(jnp.zeros_like, error))
            dense = stay(dense, held)
            memo = stay(new_memo, memo)
            return y1, error, dense, (inner, memo, done | finished), result

        def func(self, terms, t0, y0, args):
            return self.solver.func(terms, t0, y0, args)

    return Recording


def step_size_controller(rtol, atol, limit=None, norm=None):
    """diffrax's `PIDController(rtol=rtol, atol=atol)` (integral control at its default
    coefficients: the next step is the last times `clip(safety / error**(1/order), factormin,
    factormax)`), with the power written as `exp(log(1/error)/order)`: XLA's `power` is, on
    CPUs, a call of the C library's `pow` for each lane, a scalar function in the middle of
    vectorised steps. The smoothed turning points of an 809-point chunk, compiled both ways in
    one process and run in turns: 0.92-0.95 x (three runs), the turning points the same to 5e-11
    m. No `dtmin`, `dtmax`, P or D terms (vmj uses none).

    `limit(t0, t1, y0, y1)`, if given: the longest step after an accepted step from `(t0, y0)`
    to `(t1, y1)` (the controller's own choice where it is shorter); a step limited so is
    shorter, never longer, so the error control stays as it is. `norm`: of the error estimate
    (default diffrax's RMS norm over the whole state)."""
    extra = {} if norm is None else {"norm": norm}
    return _controller_class()(rtol=rtol, atol=atol, limit=limit, **extra)


@functools.cache
def _controller_class():
    import diffrax as dfx

    class Controller(dfx.PIDController):
        limit: object = None

        def adapt_step_size(
            self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state
        ):
            prev, prev_prev, at_dtmin = controller_state

            def scaled(y, y1, error):  # as diffrax's: a candidate with a NaN counts as y
                y1 = jnp.where(jnp.isnan(y1).any(), y, y1)
                return error / (self.atol + jnp.maximum(jnp.abs(y), jnp.abs(y1)) * self.rtol)

            error = self.norm(jax.tree.map(scaled, y0, y1_candidate, y_error))
            keep = error < 1
            inverse = jax.lax.stop_gradient(1 / error)
            exponent = self.icoeff / self._get_error_order(error_order)
            factor = jnp.clip(
                self.safety * jnp.exp(exponent * jnp.log(inverse)),
                jnp.where(keep, 1, self.factormin),
                jnp.where(keep, self.factormax, self.safety),
            )
            dt = (t1 - t0) * jax.lax.stop_gradient(factor).astype(jnp.result_type(t1 - t0))
            if self.limit is not None:
                longest = jax.lax.stop_gradient(self.limit(t0, t1, y0, y1_candidate))
                dt = jnp.where(keep, jnp.minimum(dt, longest.astype(dt.dtype)), dt)
            next_t0 = jnp.where(keep, t1, t0)
            inverse = jnp.where((inverse == 0) | jnp.isinf(inverse), 1, inverse)
            state = (jnp.where(keep, inverse, prev), jnp.where(keep, prev, prev_prev), at_dtmin)
            return keep, next_t0, next_t0 + dt, False, state, dfx.RESULTS.successful

    return Controller


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
    limit=None,
    adjoint=None,
    norm=None,
):
    """`field(t, y, args)` integrated from `t0` (default 0) to `t1` with diffrax (`solver`,
    default `dopri8()`) under a PID step-size controller, stopping early at a `diffrax.Event`;
    never raises (check `sol.result`). `resume`: `(solver_state, controller_state, made_jump)`
    of a solve that ended at `t0` (saved with `SaveAt(solver_state=True,
    controller_state=True, made_jump=True)`), which this one continues with the same steps.
    `limit`, `norm`: the step-size controller's (`step_size_controller`). `adjoint`: diffrax's
    (default: its `RecursiveCheckpointAdjoint`, reverse mode)."""
    import diffrax as dfx  # here, not at the top: `import vmj` and the vmj command stay light

    solver_state, controller_state, made_jump = (None, None, None) if resume is None else resume
    return dfx.diffeqsolve(
        dfx.ODETerm(field),
        dopri8() if solver is None else solver,
        t0=t0,
        t1=t1,
        dt0=None,
        y0=y0,
        saveat=saveat,
        stepsize_controller=step_size_controller(rtol, atol, limit, norm),
        max_steps=max_steps,
        throw=False,
        event=event,
        solver_state=solver_state,
        controller_state=controller_state,
        made_jump=made_jump,
        adjoint=dfx.RecursiveCheckpointAdjoint() if adjoint is None else adjoint,
    )
