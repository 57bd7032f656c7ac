"""The compiled solve of the fits: residuals of a job's records, their Jacobian, the
Levenberg-Marquardt and Adam solvers over a batch of jobs (in turn on a CPU, `jax.vmap` on an
accelerator: `_over_jobs`), and the profile-likelihood batch.

A *job* is one least-squares problem (`fits._fit`): R records of N points, P parameters and q
free slots, all array data (`_Data`), so one compiled solve serves every fit of a model family,
forward method and record shape (and, on an accelerator, batch size). The residual vmaps over
the records; a slot's value is its coordinate through `fits._params.apply` (bounds per slot);
the Jacobian is materialised in one forward-mode pass and handed to the solvers through a
`custom_jvp`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import optimistix as optx
from jax.extend.core import jaxpr_as_fun

import vmj
from vmj.cli import exported_jit

from ._params import HELD, apply, derivative
from ._space import theta_dict

__all__ = []

_LM_RTOL, _LM_ATOL = 1e-10, 1e-12
#: Bates and Watts' relative offset at which a Levenberg-Marquardt solve has converged, and
#: the part of a Jacobian column's norm that must remain, orthogonal to the columns before it,
#: for it to count as one more dimension
_OFFSET_RTOL, _RANK_RTOL = 1e-4, 1e-10
#: Adam's end, converged, in the same relative offset: a first-order method's 3000 steps end
#: within hundredths of a standard error, not Levenberg-Marquardt's 1e-4
_ADAM_OFFSET = 0.1
#: Adam's learning rate (in the slots' coordinates, `fits._params`), cosine-decayed to 1e-3 of
#: it, after a linear warm-up over the first 1/`_ADAM_WARMUP` of the steps. Adam's first steps
#: are about the rate in every coordinate whatever the gradient (its moment estimates start
#: empty): without the warm-up a solve started at an optimum (every pass after the first,
#: `fits._fit._passes`) moved omega by 4 % (its standard error 2e-6 of it), sent xF to 0,
#: where its coordinate's gradient vanishes, and ended with twice the residual sum of
#: squares (the Huber fit of `tests/test_fits_engine.py`'s record with outliers). With a
#: warm-up of 30, 100 or 300 steps of 3000 it ended at the same optimum to 1e-11.
_ADAM_RATE, _ADAM_WARMUP = 0.02, 30
#: no progress: accepted steps in a row that lowered the residual sum of squares by less than
#: this many residual variances together
_STALL_STEPS, _STALL_DEVIANCE = 10, 1e-5
_CHI2_95 = 3.841458820694124  #: 95 % quantile of chi-square with 1 degree of freedom
#: 90 % quantile of chi-square with 1 degree of freedom: the deviance of a 95 % one-sided limit
#: of a parameter whose estimate lies on its bound (the deviance is then 0 with probability 1/2,
#: else chi-square with 1 degree of freedom: Self and Liang 1987)
_CHI2_90 = 2.705543454095404
_PROFILE_STEPS = 8  #: root-finding iterations of a profile-likelihood end
_PROFILE_TOL = 0.02  #: relative tolerance on the deviance at an interval end


# -- the compiled core -------------------------------------------------------------------------
class _Data(eqx.Module):
    """One job's arrays (a leading batch axis when stacked): R records of N points, P
    parameters, q free slots."""

    k: jax.Array  # (R, N) swing index of each point
    x: jax.Array  # (R, N) measured positions (amplitudes for amplitude-only records)
    t: jax.Array  # (R, N) measured times from the release
    wx: jax.Array  # (R, N) weights of the position residuals (0 = ignored / padding)
    wt: jax.Array  # (R, N) weights of the time residuals
    orient: jax.Array  # (R,) +1 if the release is below the centre
    absval: jax.Array  # (R,) 1 for amplitude-only records
    fixed: jax.Array  # (R, P) parameter values
    M: jax.Array  # (q, R, P) 1 where slot s sets parameter p of record r
    E: jax.Array  # (R, qr, q) 1 where record r's local slot j is slot s (`_record_slots`)
    code: jax.Array  # (q,) transform code of each slot (fits._params), HELD: not moved
    lo: jax.Array  # (q,) bounds of each slot
    hi: jax.Array
    scale: jax.Array  # (q,) scale of each slot's transform
    held: jax.Array  # (q,) value of a held slot


def _place(d: _Data, val):
    """Parameter values (R, P) with the slots set to `val` (q,)."""
    mask = jnp.sum(d.M, axis=0)
    return d.fixed * (1 - mask) + jnp.einsum("q,qrp->rp", val, d.M)


def _values(d: _Data, p):
    return apply(d.code, d.lo, d.hi, d.scale, p, d.held)


def _align_clocks(r, J, wt):
    """The time residuals `r` and their Jacobian `J` on each record's clock shifted to align
    best with the model's: the weighted mean time residual removed, `r_t - wt (wt . r_t) /
    (wt . wt)` per record (a projection off the weights' direction; `J` likewise), nothing
    for a record without timed points. `r` `(R * 2N,)` and `J` `(R * 2N, q)` as `_residual_and_jacobian_impl`
    makes them, `wt` `(R, N)` the times' weights.

    A record's times are measured from its release, but the release's time is no better known
    than the turning points' (or worse: an extracted release at the signal's first samples is
    located from one side, one from a hold is extrapolated, and neither is weighed; a peak
    file's first row need not be the release): taken as exact, its error shifts every time
    and biases the frequency (a clean synthetic signal released at its first sample: the
    release 2.4 ms late, `omega` 10 Gauss-Newton standard errors off, the times' residuals
    flagged as structured). The shift is a nuisance parameter per timed record, profiled out
    in closed form (the residuals are linear in it) and counted in the degrees of freedom
    (`fits._result`). Applied to the residuals and the Jacobian after the forward-mode pass,
    not inside it: the shift inside took each Levenberg-Marquardt step of the pendulum fit of
    `fits/data/80P.txt` from 59-65 to 150 ms (XLA then ran the batched solve's loops
    differently)."""
    R, N = wt.shape
    total = jnp.sum(wt * wt, axis=1, keepdims=True)
    unit = wt / jnp.sqrt(jnp.where(total > 0, total, 1.0))  # 0 for a record without times
    both = jnp.concatenate([J, r[:, None]], axis=1).reshape(R, 2, N, -1)  # (one projection)
    times = both[:, 1]
    times = times - unit[..., None] * jnp.einsum("rn,rnq->rq", unit, times)[:, None, :]
    both = both.at[:, 1].set(times).reshape(R * 2 * N, -1)
    return both[:, -1], both[:, :-1]


def _record_residual(space, forward, n, th_row, k, x, t, wx, wt, orient, absval):
    """One record's weighted residuals `(2N,)`: its positions, then its times (from the
    record's release; `_align_clocks` aligns the clocks), at parameter values `th_row` (P,).
    A series space compares the motion at the sample times `t` (shifted by `t0`) with the
    samples `x`; its time residuals are zero."""
    th = theta_dict(space, th_row)
    if space.series:
        y = space.motion(th, t - th["t0"], n, forward)
    else:
        times, y = space.predict(th, n, forward)
        y, tk = y[k], times[k]
    oy = orient * y
    gain = orient * (1 + th["asym"] * jnp.sign(oy)) if "asym" in th else orient
    dev = gain * y
    offset = th["offset"] if "offset" in th else 0.0
    if "drift" in th:  # the sensor's zero drifting, on the record's clock
        offset = offset + th["drift"] * t
    px = jnp.where(absval > 0, jnp.abs(dev), offset + dev)
    if space.series:
        dt = jnp.zeros_like(t)
    else:
        if "drift" in th:  # the reading turns where drift + gain y' = 0, not where y' = 0
            slope = th["drift"] / jnp.where(gain != 0, gain, 1.0)
            tk = tk + space.extremum_shift(th, tk, y, slope)
        dt = tk - t
    return jnp.concatenate([wx * (px - x), wt * dt])


def _residual_and_jacobian_impl(space, forward, n, p, d):
    """Residuals `(R * 2N,)` at `p` and their Jacobian `(R * 2N, q)` with respect to the slot
    values (in the parameters' units), from one forward-mode pass, the records' clocks
    aligned (`_align_clocks`). Wrapping it as a `custom_jvp` whose tangent is that
    materialised Jacobian keeps the solvers from tracing (and compiling) the forward model
    again for linearisation and transposition: one compiled Jacobian serves the
    Levenberg-Marquardt steps, Adam's gradients and the standard errors.

    Each record's pass carries a tangent per slot that sets one of its parameters (`d.E`, qr
    of them: the shared slots and its own), not one per slot of the job: a joint fit's
    records, each with its own sensor and release, otherwise each differentiated their
    forward model along every other record's slots too, whose columns are zero (three
    pendulum records on their samples, 9 slots each of 17: 17 tangents a record where 9
    matter)."""
    theta = _place(d, _values(d, p))  # (R, P)
    local = jnp.einsum("rjs,srp->rjp", d.E, d.M)  # (R, qr, P): a record's slots' parameters

    def one(th_row, loc, *row):
        def r_of(u):
            r = _record_residual(space, forward, n, th_row + u @ loc, *row)
            return r, r

        return jax.jacfwd(r_of, has_aux=True)(jnp.zeros(loc.shape[0], th_row.dtype))

    rows = (theta, local, d.k, d.x, d.t, d.wx, d.wt, d.orient, d.absval)
    if theta.shape[0] == 1:  # one record: no `vmap` over a batch of one (a batching pass of
        J, r = one(*(a[0] for a in rows))  # the whole forward model, about 0.5 s of tracing)
        J, r = J[None], r[None]
    else:
        J, r = jax.vmap(one)(*rows)  # (R, 2N, qr), (R, 2N)
    J = jnp.einsum("rnj,rjs->rns", J, d.E).reshape(-1, d.E.shape[2])
    return _align_clocks(r.reshape(-1), J, d.wt)


# (an inner `jit`, called in one trace context (`_NO_MESH` in `_solve_lm`): every call of it
# in a solve, the optimiser's shape evaluation included, shares one trace and one batching)
_residual_and_jacobian = jax.custom_jvp(
    jax.jit(_residual_and_jacobian_impl, static_argnums=(0, 1, 2)), nondiff_argnums=(0, 1, 2)
)


@_residual_and_jacobian.defjvp
def _residual_and_jacobian_jvp(space, forward, n, primals, tangents):
    p, d = primals
    dp, _ = tangents  # never differentiated with respect to the data
    r, J = _residual_and_jacobian(space, forward, n, p, d)
    dv = derivative(d.code, d.lo, d.hi, d.scale, p)
    return (r, J), (J @ (dv * dp), jnp.zeros_like(J))


_NO_MESH = jax.sharding.AbstractMesh((), ())


def _offset_and_scale(r, J):
    """Bates and Watts' relative offset at `(r, J)` (squared): the residuals' projection on
    the Jacobian's column space against their orthogonal part, `(|P r|^2 / p) / (|r - P
    r|^2 / (n - p))`, and the residual variance `|r - P r|^2 / (n - p)` (n, p: the rows and
    the independent columns that count; padding rows and held slots are zero).

    The projection by Gram-Schmidt, each column orthogonalised twice against those before it
    and kept where more than `_RANK_RTOL` of its norm remains: matrix products only. With
    LAPACK's factorisations inside the solve's loop (a singular-value decomposition, then a QR
    factorisation) fits hung in XLA: two pendulum fits solved at once in threads, and then a
    single oscillator fit of `tests/test_fits_coverage.py`, each waiting for its result."""
    r, J = jnp.asarray(r), jnp.asarray(J)
    norms = jnp.sqrt(jnp.sum(J * J, axis=0))

    def column(j, basis):
        v = J[:, j]
        v = v - basis @ (basis.T @ v)
        v = v - basis @ (basis.T @ v)
        left = jnp.sqrt(jnp.sum(v * v))
        keep = left > _RANK_RTOL * norms[j]
        return basis.at[:, j].set(jnp.where(keep, v / jnp.where(keep, left, 1.0), 0.0))

    basis = jax.lax.fori_loop(0, J.shape[1], column, jnp.zeros_like(J))
    along = jnp.sum((basis.T @ r) ** 2)
    p = jnp.sum(jnp.any(basis != 0, axis=0))
    dof = jnp.sum(jnp.any(J != 0, axis=1) | (r != 0)) - p
    s2 = (jnp.sum(r * r) - along) / jnp.maximum(dof, 1)
    return jnp.where(dof > 0, along / jnp.maximum(p, 1) / s2, jnp.inf), s2


class _LevenbergMarquardt(optx.AbstractLeastSquaresSolver):
    """optimistix's Levenberg-Marquardt with two more ends, both converged, for fits of
    measured data:

    - Bates and Watts' relative offset (`_offset_and_scale`) below `_OFFSET_RTOL`: the
      Gauss-Newton step that remains would move the parameters by about that fraction of
      their standard errors;
    - no progress: `_STALL_STEPS` accepted steps in a row lowered the residual sum of
      squares by less than `_STALL_DEVIANCE` residual variances together (SciPy's
      `least_squares` ends on the same kind of test, its `ftol`). In a long, curved valley
      (a law set that misfits the record) the solver otherwise crawls on to its step limit,
      each step lowering the loss by a few parts in 1e9, and holds up the whole batch it is
      solved in; at a kink of the loss (a mass that sticks or not) the trust region shrinks
      until this test or optimistix's own ends the solve.

    optimistix's own test (every slot and every residual changed by less than
    `atol + rtol |value|` in an accepted step) still ends fits without noise, whose offset
    is rounding over rounding. Not converged: the step limit, or values that are not
    finite. `fn` returns `(r, J, dv)` as its auxiliary output: the residuals, their Jacobian
    in the parameters' units and the parameters' derivatives in the solver's coordinates
    (zero for a held slot: a profile's point is not a minimum in its direction)."""

    rtol: float
    atol: float
    norm: object = optx.max_norm

    @property
    def _lm(self):
        return optx.LevenbergMarquardt(self.rtol, self.atol, self.norm)

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        inner = self._lm.init(fn, y, args, options, f_struct, aux_struct, tags)
        return (
            inner,
            jnp.asarray(jnp.inf, f_struct.dtype),
            jnp.asarray(0),
            jnp.zeros((), f_struct.dtype),
        )

    def step(self, fn, y, args, options, state, tags):
        inner, ref, quiet, _ = state
        accepted = inner.num_accepted_steps
        y, inner, aux = self._lm.step(fn, y, args, options, inner, tags)
        r, J, dv = aux  # at the last accepted point
        offset2, s2 = _offset_and_scale(r, J * dv)  # (held slots: dv = 0)
        rss = jnp.sum(r * r)
        progress = ref - rss > _STALL_DEVIANCE * s2
        quiet = jnp.where(progress, 0, quiet + (inner.num_accepted_steps > accepted))
        return y, (inner, jnp.where(progress, rss, ref), quiet, offset2), aux

    def terminate(self, fn, y, args, options, state, tags):
        inner, _, quiet, offset2 = state
        done, result = self._lm.terminate(fn, y, args, options, inner, tags)
        offset = (inner.num_accepted_steps > 0) & (offset2 < _OFFSET_RTOL**2)
        return done | offset | (quiet >= _STALL_STEPS), result

    def postprocess(self, fn, y, aux, args, options, state, tags, result):
        return self._lm.postprocess(fn, y, aux, args, options, state[0], tags, result)


def _in_turn() -> bool:
    """Whether the fit's arrays go to a CPU (JAX's default device, as `jax.default_device`
    sets it, else the first device), where `_solve` solves the jobs in turn, `CPU_JOBS` a
    call. (Read from the configuration, 1 us: placing an array to ask its device took 130 us
    of every `_solve`.)"""
    device = jax.config.jax_default_device or jax.devices()[0]
    return (device if isinstance(device, str) else device.platform) == "cpu"


#: jobs per compiled solve on a CPU, whatever the fit: its padding is skipped (`_over_jobs`)
CPU_JOBS = 32


def _over_jobs(one, d, p0, real, in_turn: bool):
    """`one(d, p0)` for every job of the batch: in turn (`lax.map`, on a CPU), the jobs whose
    `real` is False (a chunk's padding) skipped, their outputs zero; or all at once
    (`jax.vmap`, on an accelerator, whose lanes run in parallel; padding solved as well).

    On a CPU, one job after another is faster to trace, to compile and to run. Batched, a
    while loop needs its carries' batching found by tracing its body again (JAX's fixpoint),
    and the fit's loops are four deep (the solver's steps, the swings, the substeps, Newton's
    iterations); each lane then runs until the batch's slowest has converged. The pendulum fit
    of `fits/data/80P.txt` took 95-98 s batched, 44-45 s in turn (a fresh cache, 2 cores; the
    other figures in docs/fits.md). (`one` is traced once, into a jaxpr that the conditional's
    branch evaluates: the skipping branch needs only its outputs' shapes.)"""
    if not in_turn:
        return jax.vmap(one)(d, p0)

    def job(args):
        d, p0, real = args
        closed, shapes = jax.make_jaxpr(one, return_shape=True)(d, p0)
        skip = lambda *_: [jnp.zeros(s.shape, s.dtype) for s in jax.tree.leaves(shapes)]  # noqa: E731
        out = jax.lax.cond(real, jaxpr_as_fun(closed), skip, *jax.tree.leaves((d, p0)))
        return jax.tree.unflatten(jax.tree.structure(shapes), out)

    return jax.lax.map(job, (d, p0, real))


@exported_jit(static_argnums=(0, 1, 2, 3, 4))  # a repeated `vmj fit` loads it untraced
def _solve_lm(space, forward, n, max_steps, in_turn, d, p0, real):
    def one(d, p0):
        def fn(p, d):
            # one trace context for every call: optimistix first calls `fn` under
            # `eval_shape` (no mesh set), then inside the solve's trace (an empty one); the
            # inner jit's traces are then shared, not made twice
            with jax.sharding.use_abstract_mesh(_NO_MESH):
                r, J = _residual_and_jacobian(space, forward, n, p, d)
            return r, (r, J, derivative(d.code, d.lo, d.hi, d.scale, p))

        sol = optx.least_squares(
            fn,
            _LevenbergMarquardt(_LM_RTOL, _LM_ATOL),
            p0,
            d,
            has_aux=True,
            max_steps=max_steps,
            throw=False,
        )
        r, J, _ = sol.aux  # at the returned point: no second compiled copy of the Jacobian
        ok = sol.result == optx.RESULTS.successful
        return sol.value, _place(d, _values(d, sol.value)), J, r, ok, sol.stats["num_steps"]

    return _over_jobs(one, d, p0, real, in_turn)


@exported_jit(static_argnums=(0, 1, 2, 3, 4))
def _solve_adam(space, forward, n, steps, in_turn, d, p0, real):
    """Adam (optax) on the weighted residual sum of squares, `steps` steps from `p0`: the
    problem Levenberg-Marquardt solves. A robust loss is the weights' concern (`fits._fit`'s
    iteratively reweighted passes, weights psi(u)/u), not the objective's: both solvers then
    reach the same M-estimate. (Until 2026-11-28 Adam minimised the robust loss of the already
    reweighted residuals, the robustness applied twice: its Huber and Cauchy estimates ended
    0.03-0.07 standard errors from Levenberg-Marquardt's on a 30-point record with three
    outliers, and more elsewhere, both "converged".)"""

    def one(d, p0):
        def objective(p):  # (its gradient from the forward-mode Jacobian)
            r, _ = _residual_and_jacobian(space, forward, n, p, d)
            return 0.5 * jnp.sum(r * r)

        rate = optax.warmup_cosine_decay_schedule(
            0.0, _ADAM_RATE, steps // _ADAM_WARMUP, steps, 1e-3 * _ADAM_RATE
        )
        opt = optax.adam(rate)
        grad = jax.value_and_grad(objective)

        def body(carry, _):
            p, state = carry
            _, g = grad(p)
            updates, state = opt.update(g, state, p)
            return (optax.apply_updates(p, updates), state), None

        (p, _), _ = jax.lax.scan(body, (p0, opt.init(p0)), None, length=steps)
        r, J = _residual_and_jacobian(space, forward, n, p, d)
        # converged where the Gauss-Newton step that remains is below `_ADAM_OFFSET` standard
        # errors (Bates and Watts' relative offset, as the Levenberg-Marquardt solver's end).
        # Until 2026-11-28 the test was the gradient against 1e-4 of the loss, which Adam's
        # 3000 steps never met on well-posed records that it had solved to 0.01-0.08 standard
        # errors of the Levenberg-Marquardt optimum.
        dv = derivative(d.code, d.lo, d.hi, d.scale, p)  # (held slots: 0)
        offset2, _ = _offset_and_scale(r, J * dv)
        ok = jnp.all(jnp.isfinite(p)) & (offset2 < _ADAM_OFFSET**2)
        return p, _place(d, _values(d, p)), J, r, ok, jnp.asarray(steps)

    return _over_jobs(one, d, p0, real, in_turn)


# -- batched solves ----------------------------------------------------------------------------
@dataclass
class _Shape:
    N: int  # points per record (bucketed)
    q: int  # slots
    n_model: int  # turning points predicted
    B: int  # jobs per compiled solve
    settings: dict
    qr: int | None = None  # slots per record, its own and the shared (`_record_slots`; None: q)


def _job_arrays(job, prob, shape) -> dict:
    R, N, q = len(prob.records), shape.N, shape.q
    space = job.space
    P = len(space.names)
    k = np.zeros((R, N), dtype=int)
    x = np.zeros((R, N))
    t = np.zeros((R, N))
    fixed = np.zeros((R, P))
    M = np.zeros((q, R, P))
    for r, rec in enumerate(prob.records):
        m = len(rec)
        k[r, :m] = rec.k
        signs = None if job.signs is None else job.signs[r]
        x[r, :m] = (
            rec.positions
            if rec.sides_known
            else rec.amplitudes
            if signs is None
            else signs * rec.amplitudes
        )
        if rec.times is not None:
            t[r, :m] = rec.times
        for i, name in enumerate(space.names):
            fixed[r, i] = job.fixed[r].get(name, job.start[r].get(name, 0.0))
    for s, (name, r) in enumerate(job.slots):
        i = space.index(name)
        if r is None:
            M[s, :, i] = 1.0
        else:
            M[s, r, i] = 1.0
    pad = q - len(job.slots)
    lo = np.array([t_.lo for t_ in job.transforms] + [-np.inf] * pad)
    hi = np.array([t_.hi for t_ in job.transforms] + [np.inf] * pad)
    return dict(
        k=k,
        x=x,
        t=t,
        wx=np.stack(prob.wx),
        wt=np.stack(prob.wt),
        orient=np.array([rec.orientation for rec in prob.records]),
        absval=np.array(
            [0.0 if rec.sides_known or job.signs is not None else 1.0 for rec in prob.records]
        ),
        fixed=fixed,
        M=M,
        E=_record_slots(job, R, shape),
        code=np.concatenate([job.code, np.full(pad, HELD)]),
        lo=lo,
        hi=hi,
        scale=np.concatenate([job.scale, np.ones(pad)]),
        held=np.concatenate([job.held, np.zeros(pad)]),
        p=np.concatenate([job.p, np.zeros(pad)]),
    )


def _record_slots(job, R, shape) -> np.ndarray:
    """`(R, qr, q)`: row `j` of record `r` picks the slot that is the record's `j`-th own or
    shared one (held slots too: their columns give a bound's one-sided limit; rows past the
    record's slots are zero)."""
    q = shape.q
    qr = q if shape.qr is None else shape.qr
    E = np.zeros((R, qr, q))
    for r in range(R):
        mine = [s for s, (_, rr) in enumerate(job.slots) if rr is None or rr == r]
        E[r, np.arange(len(mine)), mine] = 1.0
    return E


def _solve(space, items, shape, optimizer=None):
    """Solve the jobs `items` (dicts of `_job_arrays`) of one space in chunks (the last one
    padded with copies); returns per item a dict of numpy outputs.

    A chunk is `CPU_JOBS` jobs on a CPU (`_in_turn`), whose padding the solve skips, whatever
    the fit: one compiled solve (and one stored) serves fits of any number of jobs. Until
    2026-12-02 a CPU's chunks were `shape.B` jobs, the most that one round of the fit solves,
    padding solved as well: a program for every such number (of the 66 programs that the test
    suite's fits compiled, 15 differed in it alone). On an accelerator a chunk is `shape.B`
    jobs solved at once (`jax.vmap`)."""
    s = shape.settings
    steps = s["max_steps"]
    optimizer = optimizer or s["optimizer"]
    in_turn = _in_turn()
    size = CPU_JOBS if in_turn else shape.B
    outs = []
    for c0 in range(0, len(items), size):
        chunk = items[c0 : c0 + size]
        real = len(chunk)
        chunk = chunk + [chunk[0]] * (size - real)
        stacked = {k: np.stack([it[k] for it in chunk]) for k in chunk[0]}
        p0 = jnp.asarray(stacked.pop("p"), dtype=float)
        d = _Data(
            **{
                k: jnp.asarray(v) if k in ("k", "code") else jnp.asarray(v, dtype=float)
                for k, v in stacked.items()
            }
        )
        mask = jnp.asarray(np.arange(size) < real)
        with vmj.assume_valid():
            if optimizer == "lm":
                res = _solve_lm(space, s["forward"], shape.n_model, steps, in_turn, d, p0, mask)
            else:
                res = _solve_adam(
                    space, s["forward"], shape.n_model, s["adam_steps"], in_turn, d, p0, mask
                )
        p, theta, J, r, ok, st = (np.asarray(v) for v in res)
        for j in range(real):
            outs.append(
                {
                    "p": p[j],
                    "theta": theta[j],
                    "J": J[j],
                    "r": r[j],
                    "ok": bool(ok[j]),
                    "steps": int(st[j]),
                }
            )
    return outs


def _rss(out) -> float:
    """Residual sum of squares of a solve's output (infinite when not finite)."""
    r = out["r"]
    return float(np.sum(r * r)) if np.all(np.isfinite(r)) else math.inf


# -- profile likelihood ------------------------------------------------------------------------
def _profiles(requests, shape):
    """95 % profile-likelihood intervals of the active slots of each request `(job, problem,
    est, se, inflation, s2)` (None: none wanted): every slot and side of every request solved
    together per root-finding iteration (one batched solve per space, chunked by the call's
    batch size, so that a batch of records fills its solves instead of padding one per
    record), each warm-started (first at the optimum).

    The profile deviance `(rss(v) - rss) / s2` is scaled by the residual-autocorrelation
    `inflation` through the target, `3.84 inflation`; each end, started at the Wald end, is
    bracketed and found by regula falsi (`_profile_step`). An end whose bound lies inside the
    region is the bound. A slot that the solver held at a bound (`job.bound_hit`) gets the one
    end away from it, its 95 % one-sided limit (target `2.71 inflation`, `_CHI2_90`). Returns
    per request `{slot: {-1: lo, +1: hi}}` for the ends found (the others failed), None where
    none was wanted, and under the key `"open"` `{(slot, side): v}` for the ends the data do
    not bound (`_open_end`): `v` the farthest point found inside the region."""
    state = []  # one per interval end: its request, slot and side, and where it stands
    bases = {}  # per request: its job's solve arrays at the optimum
    for n, request in enumerate(requests):
        if request is None:
            continue
        job, prob, est, se, inflation, _ = request
        base = bases[n] = _job_arrays(job, prob, shape)
        for s in range(len(job.slots)):
            t = job.transforms[s]
            if job.code[s] != HELD:
                sides, target = (-1, 1), _CHI2_95
            elif job.bound_hit[s]:
                sides, target = (1 if job.held[s] == t.lo else -1,), _CHI2_90
            else:
                continue
            width = (
                1.96 * se[s] * math.sqrt(max(inflation, 1.0))
                if np.isfinite(se[s]) and se[s] > 0
                else 0.1 * max(abs(est[s]), job.scale[s])
            )
            for side in sides:
                bound = t.lo if side < 0 else t.hi
                start = est[s] + side * width
                state.append(_profile_end(n, s, side, est[s], start, bound, base["p"], target))
    for _ in range(_PROFILE_STEPS):
        by_space = {}
        for st in state:
            if not st["done"]:
                by_space.setdefault(requests[st["request"]][0].space, []).append(st)
        if not by_space:
            break
        for space, group in by_space.items():
            items = []
            for st in group:
                t = requests[st["request"]][0].transforms[st["slot"]]
                st["v"] = min(max(st["v"], t.lo), t.hi)
                base = bases[st["request"]]
                # (only what the end changes is copied: the data are shared, not written)
                it = {**base, "code": base["code"].copy(), "held": base["held"].copy()}
                it["code"][st["slot"]] = HELD
                it["held"][st["slot"]] = st["v"]
                it["p"] = st["p"]
                items.append(it)
            outs = _solve(space, items, shape, optimizer="lm")  # profiles need exact minima
            for st, out in zip(group, outs):
                _profile_step(st, out, requests[st["request"]])
    ends = [None if request is None else {} for request in requests]
    for st in state:
        if st["ok"]:
            ends[st["request"]].setdefault(st["slot"], {})[st["side"]] = st["v"]
        elif _open_end(st, requests[st["request"]]):
            ends[st["request"]].setdefault("open", {})[st["slot"], st["side"]] = st["inside"][0]
    return ends


def _open_end(st, request) -> bool:
    """Whether the failed interval end `st` is one the data do not bound: no point beyond the
    95 % region was found, and the farthest point inside lies beyond twice the Wald end. The
    profile is then far flatter than the curvature at the estimate says (a ridge of the
    least-squares surface: variable-mass peaks without times, fitted for FT, mu and c, put
    FT = 141 N inside the region of an estimate 4.9 +- 6.2 N; the Wald interval [0, 17] was
    reported and the fit "converged")."""
    job, _, est, se, inflation, _ = request
    wald = 1.96 * se[st["slot"]] * math.sqrt(max(inflation, 1.0))
    reach = abs(st["inside"][0] - est[st["slot"]])
    return st["outside"] is None and np.isfinite(wald) and reach > 2 * wald


def _profile_end(request: int, slot: int, side: int, est: float, start: float, bound, p, target):
    """The state of the interval end `side` (-1, +1) of `slot` of `_profiles`' request
    `request`: started at `start` (the Wald end) from the solution `p` at the estimate `est`,
    towards `bound`; the end is where the deviance reaches `target` (times the request's
    inflation)."""
    return {
        "request": request,
        "slot": slot,
        "side": side,
        "target": target,
        "v": start,
        "done": False,
        "ok": False,
        "p": p,
        "bound": bound,
        # (v, g, p) farthest inside the region (g = sqrt(deviance / target) - 1 < 0) and
        # nearest outside it (g > 0), see `_profile_step`
        "inside": (est, -1.0, p),
        "outside": None,
        "moved": None,  # the bracket's end that the last step replaced
    }


def _profile_step(st, out, request):
    """One root-finding iteration of the interval end `st` of `request` (see `_profiles`)
    from the solve `out` at its current point.

    The root of `g(v) = sqrt(deviance(v) / target) - 1` (linear in `v` for a quadratic
    profile) is bracketed between the farthest point found inside the region (the estimate,
    `g = -1`, at first) and the nearest outside it: the next point is regula falsi's between
    them (Illinois' variant: the `g` of an end kept twice in a row is halved, so that a curved
    profile cannot keep one end for good), or, while no point outside is known, the line
    through the estimate and the farthest point inside extrapolated to the target (four times
    as far when the deviance is still about 0). Each solve starts from the solution at the
    bracket's end nearest its point. An end located to 1 % of its distance from the estimate
    is taken (where the profile jumps over the target, from one local minimum to another).
    Measured on `80P.txt` (pendulum): the end `zeta +` alternated between deviance 37 and 181
    (target 82) with the extrapolation alone and failed after 8 iterations (the Wald interval
    reported instead)."""
    job, _, est, _, inflation, s2 = request
    dev = (_rss(out) - job.rss) / s2
    target = st["target"] * max(inflation, 1.0)
    if not np.isfinite(dev):
        st["done"] = True
        return
    if st["v"] == st["bound"] and dev < target:
        st["done"], st["ok"] = True, True  # the bound is inside the 95 % region
        return
    if abs(dev / target - 1) < _PROFILE_TOL:
        st["done"], st["ok"] = True, True
        return
    centre = est[st["slot"]]
    point = (st["v"], math.sqrt(max(dev, 0.0) / target) - 1.0, out["p"])
    end, other = ("inside", "outside") if dev < target else ("outside", "inside")
    known, dist = st[end], abs(st["v"] - centre)
    if known is None:
        st[end] = point
    elif (dist > abs(known[0] - centre)) if end == "inside" else (dist < abs(known[0] - centre)):
        st[end] = point  # farther inside, or nearer outside
    if st["moved"] == end and st[other] is not None:  # Illinois: the other end kept twice
        v, g, p = st[other]
        st[other] = (v, 0.5 * g, p)
    st["moved"] = end
    inside, outside = st["inside"], st["outside"]
    if outside is None:  # extrapolate from the farthest point inside
        dist, g = inside[0] - centre, inside[1]
        st["v"] = centre + (4 * dist if dev <= 1e-3 * target else dist / (1 + g))
        st["p"] = inside[2]
        return
    (a, ga, pa), (b, gb, pb) = inside, outside
    if abs(b - a) <= 0.01 * abs(b - centre):
        st["v"], st["done"], st["ok"] = 0.5 * (a + b), True, True
        return
    st["v"] = a - ga * (b - a) / (gb - ga)
    st["p"] = pa if abs(st["v"] - a) <= abs(st["v"] - b) else pb
