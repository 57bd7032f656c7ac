"""The one diffrax wrapper of vmj, and its default ODE solver."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["ode_solve", "recording", "step_size_controller", "tsit5"]


def tsit5():
    """diffrax's `Tsit5`, its seven stages written out instead of looped over (diffrax runs them
    in a `while_loop`, a dozen small XLA kernels per stage, which on CPUs cost more than a
    vmapped stage's arithmetic: the smoothed sweep of the 1617-point grid 930 -> 338 ms, the
    turning points the same to 1e-14 m). Same tableau, error estimate and dense output; no
    first-same-as-last reuse (one vector-field evaluation more per step, no solver state); its
    dense output's sum over the stages written out as well."""
    return _tsit5_class()()


def _expand(scale, *factors):
    """The power-series coefficients (ascending, from the first power) of `scale` times the
    product of polynomials given by their ascending coefficients."""
    product = functools.reduce(np.polynomial.polynomial.polymul, factors, np.array([scale]))
    return np.pad(product, (0, 5 - len(product)))[1:]


#: Tsit5's dense-output weights (Tsitouras 2011, as diffrax writes them, factored) multiplied
#: out: `_TSIT5_DENSE[p - 1][i]` is the coefficient of `u**p` in the weight of stage `i`
_TSIT5_DENSE = np.stack(
    [
        _expand(
            -1.0530884977290216,
            [0, 1],
            [-1.3299890189751412, 1],
            [0.7139816917074209, -1.4364028541716351, 1],
        ),
        _expand(0.1017, [0, 0, 1], [1.2949852507374631, -2.1966568338249754, 1]),
        _expand(2.490627285651252793, [0, 0, 1], [1.57803468208092486, -2.38535645472061657, 1]),
        _expand(
            -16.54810288924490272, [-1.21712927295533244, 1], [-0.61620406037800089, 1], [0, 0, 1]
        ),
        _expand(
            47.37952196281928122, [-1.203071208372362603, 1], [-0.658047292653547382, 1], [0, 0, 1]
        ),
        _expand(-34.87065786149660974, [-1.2, 1], [-0.666666666666666667, 1], [0, 0, 1]),
        _expand(2.5, [-1, 1], [-0.6, 1], [0, 0, 1]),
    ],
    axis=1,
)


def _weighted(weights, stages):
    """`sum_i weights[i] * stages[i]`, written out (zero weights left out)."""
    return sum(float(w) * k for w, k in zip(weights, stages) if w != 0)


@functools.cache
def _tsit5_class():
    import diffrax as dfx  # here, not at the top: `import vmj` and the vmj command stay light

    class Interpolation(dfx.Tsit5.interpolation_cls):
        """Tsit5's dense output, a quartic in the step's fraction whose coefficients are sums
        over the stages written out (`_TSIT5_DENSE`). diffrax's `tensordot` over the stages
        becomes, under `vmap`, a batched matrix product of its own, which on CPUs cost the
        smoothed turning points more than their steps. `k`: the seven stages, a tuple."""

        def evaluate(self, t0, t1=None, left=True):
            if t1 is not None:
                return self.evaluate(t1) - self.evaluate(t0)
            return self.at_fraction(self._fraction(t0)[0])

        def derivative(self, t, left=True):
            u, span = self._fraction(t)
            slope = jax.jvp(self.at_fraction, (u,), (jnp.ones_like(u),))[1]
            return jax.tree.map(lambda d: d / span, slope)

        def _fraction(self, t):
            """`(u, span)`: `t` as the fraction `u` of the step, and the step's length (1 for
            an empty step)."""
            span = self.t1 - self.t0
            span = jnp.where(span == 0, 1.0, span)
            return (t - self.t0) / span, span

        def at_fraction(self, u):
            """The state at `t0 + u (t1 - t0)`."""

            def one(y0, *k):
                powers = [_weighted(row, k) for row in _TSIT5_DENSE]
                value = powers[-1]
                for c in powers[-2::-1]:
                    value = value * u + c
                return y0 + value * u

            return jax.tree.map(one, self.y0, *self.k)

    class Tsit5(dfx.Tsit5):
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

    return Tsit5


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


def step_size_controller(rtol, atol, limit=None):
    """diffrax's `PIDController(rtol=rtol, atol=atol)` (integral control at its default
    coefficients: the next step is the last times `clip(safety / error**(1/order), factormin,
    factormax)`), with the power written as `exp(log(1/error)/order)`: XLA's `power` is, on
    CPUs, a call of the C library's `pow` for each lane, a scalar function in the middle of
    vectorised steps. The smoothed turning points of an 809-point chunk, compiled both ways in
    one process and run in turns: 0.92-0.95 x (three runs), the turning points the same to 5e-11
    m. No `dtmin`, `dtmax`, P or D terms (vmj uses none).

    `limit(t0, t1, y0, y1)`, if given: the longest step after an accepted step from `(t0, y0)`
    to `(t1, y1)` (the controller's own choice where it is shorter); a step limited so is
    shorter, never longer, so the error control stays as it is."""
    return _controller_class()(rtol=rtol, atol=atol, limit=limit)


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
):
    """`field(t, y, args)` integrated from `t0` (default 0) to `t1` with diffrax (`solver`,
    default `tsit5()`) under a PID step-size controller, stopping early at a `diffrax.Event`;
    never raises (check `sol.result`). `resume`: `(solver_state, controller_state, made_jump)`
    of a solve that ended at `t0` (saved with `SaveAt(solver_state=True,
    controller_state=True, made_jump=True)`), which this one continues with the same steps.
    `limit`: the step-size controller's (`step_size_controller`)."""
    import diffrax as dfx  # here, not at the top: `import vmj` and the vmj command stay light

    solver_state, controller_state, made_jump = (None, None, None) if resume is None else resume
    return dfx.diffeqsolve(
        dfx.ODETerm(field),
        tsit5() if solver is None else solver,
        t0=t0,
        t1=t1,
        dt0=None,
        y0=y0,
        saveat=saveat,
        stepsize_controller=step_size_controller(rtol, atol, limit),
        max_steps=max_steps,
        throw=False,
        event=event,
        solver_state=solver_state,
        controller_state=controller_state,
        made_jump=made_jump,
    )
