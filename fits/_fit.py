"""Least-squares identification of friction and damping from turning-point sequences.

The residuals compare the model's readings of the turning points with the record: SIGNED
positions when the record knows the sides (signed positions, or amplitudes with a `crossed`
column), the distances `|reading - offset|` when it gives amplitudes only (the model decides
whether a swing passes the centre), and times when the record has them. A model that sticks
early repeats its last turning point (`vmj.DecaySequence` padding) and a swing that does not
pass the centre keeps its sign, so the objective is continuous in the parameters.

**Parameters.** Each free parameter is a *slot*: one value for every record (a single record,
or a parameter shared by a joint fit) or one per record. A slot's value is its unconstrained
coordinate through a bijection of `fits._params` (`Real`, `LowerBound`, `UpperBound`,
`Interval`), the physical range of the parameter intersected with the user's bounds; a slot
that runs into a bound is held there (an active constraint) and the fit repeated.

**One compiled solve** serves every fit of a model family, forward method, record shape and
batch size: which parameters are free, their bounds and fixed values, the data and the weights
are array data. Jobs (sub-models, records of a batch, profile-likelihood points) are solved
`jax.vmap`-batched in chunks of one batch size per call.

**Sub-models** (`Space.variants`, e.g. Coulomb-only and viscous-only) are fitted in rounds by
their number of free parameters; a fit starts from the best (lowest residual sum of squares)
sub-model nested in it that is already fitted, and is never reported worse than it.

**Uncertainty.** `stderr_gn`: Gauss-Newton standard errors; `stderr`: corrected for serially
correlated residuals (`fits._stats.covariance`); `intervals`: 95 % profile-likelihood
intervals, the deviance scaled by the same inflation (the Wald interval, flagged, where a
profile fails).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings
from dataclasses import dataclass, field

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import optimistix as optx

import vmj

from ._decrement import decrement, starting_guess
from ._io import Record
from ._models import FORWARDS, KIND_RANGES, SPACES, Space, theta_dict
from ._params import HELD, check_value, warn_if_float32, INTERVAL, LOWER, REAL, Transform, apply, at_bound, derivative, \
    inverse, transform_for
from ._stats import RANK_RTOL, covariance, diagnostics

__all__ = ["FitResult", "fit", "fit_batch", "LOSSES", "OPTIMIZERS"]

LOSSES = ("l2", "huber", "cauchy")
OPTIMIZERS = ("lm", "adam")
_TUNING = {"huber": 1.345, "cauchy": 2.385}  #: 95 % efficiency constants of the robust losses
_ROBUST_PASSES = 10
_LM_RTOL, _LM_ATOL = 1e-10, 1e-12
_CHI2_95 = 3.841458820694124  #: 95 % quantile of chi-square with 1 degree of freedom
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


def _residual(space, forward, n, theta, d: _Data):
    def one(th_row, k, x, t, wx, wt, orient, absval):
        th = theta_dict(space, th_row)
        times, y = space.predict(th, n, forward)
        oy = orient * y[k]
        dev = oy * (1 + th["asym"] * jnp.sign(oy)) if "asym" in th else oy
        offset = th["offset"] if "offset" in th else 0.0
        px = jnp.where(absval > 0, jnp.abs(dev), offset + dev)
        return jnp.concatenate([wx * (px - x), wt * (times[k] - t)])

    r = jax.vmap(one)(theta, d.k, d.x, d.t, d.wx, d.wt, d.orient, d.absval)
    return r.reshape(-1)


def _residual_and_jacobian_impl(space, forward, n, p, d):
    """Residuals at `p` and their Jacobian with respect to the slot values (in the parameters'
    units), from one forward-mode pass. Wrapping it as a `custom_jvp` whose tangent is that
    materialised Jacobian keeps the solvers from tracing (and compiling) the forward model
    again for linearisation and transposition: one compiled Jacobian serves the
    Levenberg-Marquardt steps, Adam's gradients and the standard errors."""
    val = _values(d, p)

    def r_of(v):
        r = _residual(space, forward, n, _place(d, v), d)
        return r, r

    # the smoothed model's diffrax solve differentiates in reverse mode only
    jacobian = jax.jacrev if forward == "smooth" else jax.jacfwd
    J, r = jacobian(r_of, has_aux=True)(val)
    return r, J


_residual_and_jacobian = jax.custom_jvp(_residual_and_jacobian_impl, nondiff_argnums=(0, 1, 2))


@_residual_and_jacobian.defjvp
def _residual_and_jacobian_jvp(space, forward, n, primals, tangents):
    p, d = primals
    dp, _ = tangents  # never differentiated with respect to the data
    r, J = _residual_and_jacobian(space, forward, n, p, d)
    dv = derivative(d.code, d.lo, d.hi, d.scale, p)
    return (r, J), (J @ (dv * dp), jnp.zeros_like(J))


@eqx.filter_jit
def _solve_lm(space, forward, n, max_steps, d, p0):
    def one(d, p0):
        def fn(p, d):
            r, J = _residual_and_jacobian(space, forward, n, p, d)
            return r, (r, J)

        sol = optx.least_squares(fn, optx.LevenbergMarquardt(_LM_RTOL, _LM_ATOL), p0, d,
                                 has_aux=True, max_steps=max_steps, throw=False)
        r, J = sol.aux  # at the returned point: no second compiled copy of the Jacobian
        ok = sol.result == optx.RESULTS.successful
        return sol.value, _place(d, _values(d, sol.value)), J, r, ok, sol.stats["num_steps"]

    return jax.vmap(one)(d, p0)


def _rho(loss, u):
    if loss == "l2":
        return 0.5 * u * u
    c = _TUNING[loss]
    if loss == "huber":
        return optax.losses.huber_loss(u, jnp.zeros_like(u), delta=c)
    return 0.5 * c * c * jnp.log1p((u / c) ** 2)


@eqx.filter_jit
def _solve_adam(space, forward, n, steps, loss, d, p0):
    def one(d, p0):
        def objective(p):
            r, _ = _residual_and_jacobian(space, forward, n, p, d)
            return jnp.sum(_rho(loss, r))

        opt = optax.adam(optax.cosine_decay_schedule(0.02, steps, alpha=1e-3))
        grad = jax.value_and_grad(objective)

        def body(carry, _):
            p, state = carry
            _, g = grad(p)
            updates, state = opt.update(g, state, p)
            return (optax.apply_updates(p, updates), state), None

        (p, _), _ = jax.lax.scan(body, (p0, opt.init(p0)), None, length=steps)
        value, g = grad(p)
        ok = jnp.max(jnp.abs(g)) <= 1e-4 * jnp.maximum(1.0, value)
        r, J = _residual_and_jacobian(space, forward, n, p, d)
        return p, _place(d, _values(d, p)), J, r, ok, jnp.asarray(steps)

    return jax.vmap(one)(d, p0)


# -- results -----------------------------------------------------------------------------------
@dataclass
class FitResult:
    """The outcome of a fit.

    **Fields:**

    - `model` (the model family of the headline fit), `label` (its label in the model
      comparison, e.g. `"both"`), `forward`, `loss`, `optimizer`.
    - `params` (the free parameters, in the order fitted; for a joint fit the shared ones) and
      `fixed` (the others), in SI units or the signal's units (`units`: `{name: unit}`).
    - `stderr`: standard errors corrected for serially correlated residuals (the Gauss-Newton
      ones times the square root of an inflation >= 1); `stderr_gn`: the Gauss-Newton ones;
      `None` (JSON null) for a parameter the data do not identify, never 0.
    - `intervals`: `{name: (lo, hi)}` 95 % profile-likelihood intervals (Wald where a profile
      failed, said in the warnings).
    - `correlation`: correlation matrix of `params`; `converged`: the optimiser converged AND
      the Jacobian has full rank AND no parameter sits at a bound the user did not set;
      `iterations` (solver steps over all passes).
    - `rms` (RMS position residual, data units), `rms_time` [s]; `rss` (weighted residual sum of
      squares), `n_residuals`, `aic`, `bic`.
    - `diagnostics`: `{"lag1", "runs_p", "n_eff", "warnings"}` (see `fits._stats`); `warnings`
      (the same list).
    - `model_comparison`: `{label: {"aic", "bic", "rss", "params", "converged"}, "best_aic",
      "best_bic"}` over the sub-models fitted beside the headline (empty when none).
    - `residuals` (per point of the first record: `k`, `position`, `time`, `standardized`,
      `outlier`); `outliers` (the flagged `k`); `decrement` (the decrement-method estimate);
      `record`; `records` (joint fits: per record `source`, `params`, `stderr`, `stderr_gn`,
      `intervals`, `rms`, `outliers`); `clock` (the sample-clock report of a raw signal).
    """

    model: str
    forward: str
    loss: str
    optimizer: str
    params: dict
    fixed: dict
    stderr: dict
    correlation: list
    converged: bool
    iterations: int
    rms: float
    rms_time: float | None
    model_comparison: dict
    residuals: dict
    outliers: list
    warnings: list
    decrement: dict
    record: Record = field(repr=False)
    prediction: dict = field(default_factory=dict, repr=False)
    stderr_gn: dict = field(default_factory=dict)
    intervals: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    aic: float = math.nan
    bic: float = math.nan
    rss: float = math.nan
    n_residuals: int = 0
    records: list = field(default_factory=list)
    clock: dict | None = None
    units: dict = field(default_factory=dict)
    label: str = ""

    def to_json(self) -> dict:
        """The command line's JSON object: `model`, `params`, `stderr`, `stderr_gn`,
        `intervals` (`{name: [lo, hi]}`), `correlation`, `converged`, `iterations`, `rms`,
        `diagnostics`, `model_comparison`, then `records` (joint fits), `clock` (raw signals)
        and `units`; NaN becomes `null`."""
        out = {
            "model": self.model,
            "params": self.params,
            "stderr": self.stderr,
            "stderr_gn": self.stderr_gn,
            "intervals": {k: list(v) for k, v in self.intervals.items()},
            "correlation": self.correlation,
            "converged": self.converged,
            "iterations": self.iterations,
            "rms": self.rms,
            "diagnostics": self.diagnostics,
            "model_comparison": self.model_comparison,
        }
        if self.records:
            out["records"] = [{k: v for k, v in r.items() if k != "residuals"}
                              for r in self.records]
        if self.clock is not None:
            out["clock"] = self.clock
        out["units"] = self.units
        return _jsonable(out)

    def report(self) -> str:
        from ._report import text_report

        return text_report(self)


def _jsonable(obj):
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    return obj


# -- input checks ------------------------------------------------------------------------------
_RANGES = {
    "real": (lambda x: True, "a real number"),
    "positive": (lambda x: x >= 0, ">= 0"),
    "unit": (lambda x: 0 <= x <= 1, "in [0, 1]"),
    "damping": (lambda x: 0 <= x < 1, "in [0, 1) (an underdamped oscillator)"),
}
_STRICTLY_POSITIVE = ("m0", "c", "g", "omega", "m", "A", "l0")


def _check_inputs(space, free, shared, given, bounds, forward, loss, optimizer):
    if forward not in FORWARDS:
        raise ValueError(f"forward must be one of {list(FORWARDS)} (got {forward!r})")
    if loss not in LOSSES:
        raise ValueError(f"loss must be one of {list(LOSSES)} (got {loss!r})")
    if optimizer not in OPTIMIZERS:
        raise ValueError(f"optimizer must be one of {list(OPTIMIZERS)} (got {optimizer!r})")
    free = tuple(free)
    if not free:
        raise ValueError("give at least one parameter to fit (--fit NAME[,NAME...]): with every "
                         "parameter fixed there is nothing to identify")
    for name in free:
        if name not in space.names:
            raise ValueError(f"unknown parameter {name!r} for the {space.name} model "
                             f"(parameters: {', '.join(space.names)})")
    for name in given:
        if name == "angle_unit" and name not in space.names:
            raise ValueError(f"--angle-unit applies only to models with an angle_unit parameter "
                             f"(the {space.name} model has none)")
        if name not in space.names:
            raise ValueError(f"unknown parameter {name!r} for the {space.name} model "
                             f"(parameters: {', '.join(space.names)})")
    if len(set(free)) != len(free):
        raise ValueError(f"a parameter is listed twice in {free}")
    for name in shared:
        if name not in free:
            raise ValueError(f"--shared {name}: only fitted parameters can be shared "
                             f"(fitted: {', '.join(free)})")
    for name, (lo, hi) in bounds.items():
        if name not in space.names:
            raise ValueError(f"--bounds: unknown parameter {name!r} for the {space.name} model "
                             f"(parameters: {', '.join(space.names)})")
        if not (isinstance(lo, (int, float)) and isinstance(hi, (int, float))) or not lo < hi \
                or math.isnan(lo) or math.isnan(hi):
            raise ValueError(f"--bounds {name}: need LO < HI (got {lo}:{hi})")
        plo, phi = _physical_range(space, name)
        if max(lo, plo) >= min(hi, phi):
            raise ValueError(f"--bounds {name}={lo}:{hi} leaves nothing of its physical range "
                             f"[{plo}, {phi}] [{space.unit(name)}]")
    for name, value in given.items():
        kind = space.kinds[space.index(name)]
        unit = space.unit(name)
        ok, allowed = _RANGES[kind]
        if name in _STRICTLY_POSITIVE or (name == "a0" and name not in free):
            ok, allowed = (lambda x: x > 0), "> 0"
        value = check_value(name, value, ok, f"{allowed} [{unit}]")
        if name in bounds and name not in free:
            lo, hi = bounds[name]
            if not lo <= value <= hi:
                raise ValueError(f"--set {name}={value} is outside --bounds {name}={lo}:{hi} "
                                 f"[{unit}]")
    return free


def _physical_range(space, name):
    t = space.transform(name)
    lo, hi = t.lo, t.hi
    if name in _STRICTLY_POSITIVE:
        lo = max(lo, 0.0)
    return lo, hi


def _slot_transform(space, name, bounds) -> tuple[Transform, bool, bool]:
    """The transform of a free parameter: its physical range intersected with the user's
    bounds; and whether its lower / upper end was set by the user."""
    plo, phi = _physical_range(space, name)
    if name == "zeta" and KIND_RANGES.get(space.kinds[space.index(name)]) == (0.0, 1.0):
        phi = min(phi, 1.0 - 1e-9)  # underdamped
    ulo, uhi = bounds.get(name, (-math.inf, math.inf))
    lo, hi = max(plo, ulo), min(phi, uhi)
    return transform_for(lo, hi), name in bounds and ulo >= plo, name in bounds and uhi <= phi


def _fixed_values(space, record, free, given, hold=None) -> dict:
    """Values of every parameter not fitted: held (sub-model), given, or the physical default;
    a parameter with none of these is an error naming it."""
    hold = hold or {}
    out, missing = {}, []
    for name in space.names:
        if name in hold:
            out[name] = float(hold[name])
        elif name in given:
            out[name] = float(given[name])
        elif name in free:
            continue
        else:
            value = space.default(name, record)
            if value is None:
                missing.append(name)
            else:
                out[name] = float(value)
    if missing:
        if len(missing) == 1:
            nm = missing[0]
            raise ValueError(f"the {space.name} model needs {nm}: give {nm} with --set {nm}=VALUE "
                             f"or fit it")
        raise ValueError(f"the {space.name} model needs {', '.join(missing)}: give them with "
                         f"--set NAME=VALUE or fit them")
    return out


# -- jobs --------------------------------------------------------------------------------------
@dataclass
class _Problem:
    """One fit asked for: a record, or several records fitted jointly."""

    records: list
    givens: list
    free: tuple
    shared: tuple
    decs: list
    wx: list = None  # per record: position weights (N,)
    wt: list = None
    robust_x: list = None  # per record: robust (IRLS) weights
    robust_t: list = None
    sx: list = None  # per record: noise scale of positions [data units]
    st: list = None  # per record: noise scale of times [s]


@dataclass
class _Job:
    """One least-squares problem: a problem's model or one of its sub-models."""

    problem: int
    space: Space
    label: str
    free: tuple
    hold: dict
    slots: list  # (name, record index or None for every record)
    transforms: list
    user_lo: list
    user_hi: list
    fixed: list  # per record {name: value} of the non-free parameters
    start: list  # per record {name: value} of every parameter
    headline: bool
    code: np.ndarray = None
    held: np.ndarray = None
    scale: np.ndarray = None
    p: np.ndarray = None
    out: dict = None  # theta, J, r, ok, steps of the last solve
    iterations: int = 0
    rss: float = math.inf
    bound_hit: np.ndarray = None  # slots held at a bound by the solver
    signs: list = None  # per record: sides assumed for amplitude-only data (a start hypothesis)


def _slot_names(job) -> list:
    return [nm if r is None else f"{nm}[{r}]" for nm, r in job.slots]


def _make_job(index, prob, space, label, free, hold, bounds, headline):
    R = len(prob.records)
    fixed = [_fixed_values(space, rec, free, {k: v for k, v in g.items() if k in space.names},
                           hold) for rec, g in zip(prob.records, prob.givens)]
    start = []
    for rec, g, dec, fx in zip(prob.records, prob.givens, prob.decs, fixed):
        guess = starting_guess(space, rec, {**fx, **{k: v for k, v in g.items()
                                                     if k in space.names}}, dec)
        st = {**guess, **fx}
        for name in free:
            if name not in st:
                raise ValueError(f"no starting value for {name}: give one with --set "
                                 f"{name}=VALUE")
        start.append(st)
    slots = []
    for name in free:
        if R == 1 or name in prob.shared:
            slots.append((name, None))
        else:
            slots.extend((name, r) for r in range(R))
    transforms, ulo, uhi = [], [], []
    for name, _ in slots:
        t, lo_user, hi_user = _slot_transform(space, name, bounds)
        transforms.append(t)
        ulo.append(lo_user)
        uhi.append(hi_user)
    job = _Job(index, space, label, tuple(free), dict(hold), slots, transforms, ulo, uhi, fixed,
               start, headline)
    q = len(slots)
    job.code = np.array([t.code for t in transforms])
    job.held = np.zeros(q)
    job.bound_hit = np.zeros(q, dtype=bool)
    job.scale = np.array([_scale(slots[s][0], t, _slot_start(job, s), prob.records)
                          for s, t in enumerate(transforms)])
    job.p = _coordinates(job, [dict(s) for s in start])
    return job


def _slot_start(job, s):
    name, r = job.slots[s]
    if r is not None:
        return float(job.start[r][name])
    return float(np.mean([st[name] for st in job.start]))


def _scale(name, t: Transform, start: float, records) -> float:
    """The scale of a slot's transform: its starting distance from its bound (1 for an interval;
    the records' largest amplitude for `offset`, at least 1 for other real parameters)."""
    if t.code == INTERVAL:
        return 1.0
    if t.code == REAL:
        if name == "offset":
            return max(float(np.max(np.concatenate([rec.amplitudes for rec in records]))), 1e-300)
        return max(abs(start), 1.0)
    ref = t.lo if t.code == LOWER else t.hi
    s = abs(start - ref)
    return s if s > 0 else (abs(start) if start != 0 else 1.0)


def _coordinates(job, values: list) -> np.ndarray:
    """The slots' coordinates for parameter values `values` (per record dicts)."""
    p = np.zeros(len(job.slots))
    for s, ((name, r), t) in enumerate(zip(job.slots, job.transforms)):
        v = values[r][name] if r is not None else float(np.mean([val[name] for val in values]))
        v = min(max(v, t.lo), t.hi)
        p[s] = 0.0 if job.code[s] == HELD else inverse(t.code, t.lo, t.hi, job.scale[s], v)
    return p


def _jobs_for(index, prob, space, bounds, compare) -> list:
    jobs = [_make_job(index, prob, space, space.label, prob.free, {}, bounds, True)]
    if not compare:
        return jobs
    for v in space.variants:
        vs = v.space or space
        hold = dict(v.hold)
        free_v = tuple(n for n in prob.free if n in vs.names and n not in hold)
        if not free_v:
            continue
        if v.space is None and not set(hold) & set(prob.free):
            continue
        b = {k: val for k, val in bounds.items() if k in vs.names}
        jobs.append(_make_job(index, prob, vs, v.label, free_v, hold, b, False))
    return jobs


def _bucket(n: int) -> int:
    """Round a length up to a multiple of 8, so records of similar length share a compilation."""
    return max(8, -(-n // 8) * 8)


# -- weights -----------------------------------------------------------------------------------
def _robust_scale(r, floor):
    r = r[np.isfinite(r)]
    if r.size == 0:
        return floor
    return max(1.4826 * float(np.median(np.abs(r - np.median(r)))), floor)


def _psi_weight(loss, u):
    """IRLS weight `psi(u)/u` of a robust loss."""
    if loss == "l2":
        return np.ones_like(u)
    c = _TUNING[loss]
    if loss == "huber":
        return np.minimum(1.0, c / np.maximum(np.abs(u), 1e-300))
    return 1.0 / (1.0 + (u / c) ** 2)


def _init_weights(prob, N):
    prob.sx = [max(rec.noise or 0.0, 1e-3 * float(np.max(rec.amplitudes))) for rec in prob.records]
    prob.st = [1e-3 * float(np.median(np.diff(rec.times))) if rec.times is not None else 1.0
               for rec in prob.records]
    prob.robust_x = [np.ones(N) for _ in prob.records]
    prob.robust_t = [np.ones(N) for _ in prob.records]
    _set_weights(prob, N)


def _set_weights(prob, N):
    prob.wx, prob.wt = [], []
    for r, rec in enumerate(prob.records):
        m = len(rec)
        on = np.zeros(N)
        on[:m] = 1.0
        prob.wx.append(on * np.sqrt(prob.robust_x[r]) / prob.sx[r])
        if rec.times is None:
            prob.wt.append(np.zeros(N))
        else:
            ont = on.copy()
            if rec.k[0] == 0:
                ont[0] = 0.0  # the release time is zero by definition
            prob.wt.append(ont * np.sqrt(prob.robust_t[r]) / prob.st[r])


def _reweight(prob, job, loss, N):
    """Re-estimate each record's noise scales (and the robust weights) from `job`'s residuals."""
    r_all = job.out["r"].reshape(len(prob.records), 2, N)
    for i, rec in enumerate(prob.records):
        m = len(rec)
        wx, wt = prob.wx[i][:m], prob.wt[i][:m]
        rx = r_all[i, 0, :m] / np.where(wx > 0, wx, 1.0)
        amp = float(np.max(rec.amplitudes))
        prob.sx[i] = _robust_scale(rx[wx > 0], 1e-6 * amp)
        if rec.times is not None:
            rt = r_all[i, 1, :m] / np.where(wt > 0, wt, 1.0)
            prob.st[i] = _robust_scale(rt[wt > 0], 1e-9)
        if loss != "l2":
            prob.robust_x[i][:m] = np.nan_to_num(_psi_weight(loss, rx / prob.sx[i]), nan=0.0)
            if rec.times is not None:
                prob.robust_t[i][:m] = np.nan_to_num(_psi_weight(loss, rt / prob.st[i]), nan=0.0)
    _set_weights(prob, N)


# -- batched solves ----------------------------------------------------------------------------
@dataclass
class _Shape:
    N: int  # points per record (bucketed)
    q: int  # slots
    n_model: int  # turning points predicted
    B: int  # jobs per compiled solve
    settings: dict


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
        x[r, :m] = rec.positions if rec.sides_known else \
            rec.amplitudes if signs is None else signs * rec.amplitudes
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
    return dict(k=k, x=x, t=t, wx=np.stack(prob.wx), wt=np.stack(prob.wt),
                orient=np.array([rec.orientation for rec in prob.records]),
                absval=np.array([0.0 if rec.sides_known or job.signs is not None else 1.0
                                 for rec in prob.records]),
                fixed=fixed, M=M, code=np.concatenate([job.code, np.full(pad, HELD)]),
                lo=lo, hi=hi, scale=np.concatenate([job.scale, np.ones(pad)]),
                held=np.concatenate([job.held, np.zeros(pad)]),
                p=np.concatenate([job.p, np.zeros(pad)]))


def _solve(space, items, shape, optimizer=None):
    """Solve the jobs `items` (dicts of `_job_arrays`) of one space in chunks of `shape.B`
    (the last one padded with copies); returns per item a dict of numpy outputs."""
    s = shape.settings
    steps = s["max_steps"]
    optimizer = optimizer or s["optimizer"]
    outs = []
    for c0 in range(0, len(items), shape.B):
        chunk = items[c0:c0 + shape.B]
        chunk = chunk + [chunk[0]] * (shape.B - len(chunk))
        stacked = {k: np.stack([it[k] for it in chunk]) for k in chunk[0]}
        p0 = jnp.asarray(stacked.pop("p"), dtype=float)
        d = _Data(**{k: jnp.asarray(v) if k in ("k", "code") else jnp.asarray(v, dtype=float)
                     for k, v in stacked.items()})
        with vmj.assume_valid():
            if optimizer == "lm":
                res = _solve_lm(space, s["forward"], shape.n_model, steps, d, p0)
            else:
                res = _solve_adam(space, s["forward"], shape.n_model, s["adam_steps"], s["loss"],
                                  d, p0)
        p, theta, J, r, ok, st = (np.asarray(v) for v in res)
        for j in range(min(shape.B, len(items) - c0)):
            outs.append({"p": p[j], "theta": theta[j], "J": J[j], "r": r[j], "ok": bool(ok[j]),
                         "steps": int(st[j])})
    return outs


def _rss(out, q_used=None):
    r = out["r"]
    return float(np.sum(r * r)) if np.all(np.isfinite(r)) else math.inf


def _fit_jobs(jobs, problems, shape):
    """Solve `jobs` (one round) grouped by space; a slot that runs into a bound is held there
    and the job solved again."""
    pending = list(jobs)
    for _ in range(2 * shape.q + 2):
        if not pending:
            break
        by_space = {}
        for job in pending:
            by_space.setdefault(job.space, []).append(job)
        again = []
        for space, group in by_space.items():
            items = [_job_arrays(job, problems[job.problem], shape) for job in group]
            for job, out in zip(group, _solve(space, items, shape)):
                q = len(job.slots)
                job.out = out
                job.p = out["p"][:q]
                job.iterations += out["steps"]
                job.rss = _rss(out)
                near = 1e-5 if out["ok"] else 1e-4  # (value - bound) / scale
                hit, value = at_bound(job.code, [t.lo for t in job.transforms],
                                      [t.hi for t in job.transforms], job.scale, job.p, near)
                hit &= job.code != HELD
                if hit.any():
                    job.code = np.where(hit, HELD, job.code)
                    job.held = np.where(hit, value, job.held)
                    job.bound_hit |= hit
                    again.append(job)
        pending = again


def _nested_in(a: _Job, b: _Job) -> bool:
    """Whether sub-model `a` is nested in `b` (same problem and space, fewer free parameters,
    the same values of the parameters fixed in both, and a's held values inside b's range)."""
    if a is b or a.problem != b.problem or a.space != b.space or len(a.slots) >= len(b.slots):
        return False
    if not set(a.free) < set(b.free):
        return False
    for r, fb in enumerate(b.fixed):
        for name, v in fb.items():
            if a.fixed[r].get(name) != v:
                return False
    for s, (name, r) in enumerate(b.slots):
        if name in a.free:
            continue
        rr = 0 if r is None else r
        if not b.transforms[s].contains(a.fixed[rr][name]):
            return False
    return True


def _values_of(job) -> list:
    """Per record {name: value} at the job's last solution."""
    th = job.out["theta"]
    return [dict(zip(job.space.names, th[r].tolist())) for r in range(th.shape[0])]


def _start_from(job, sub):
    """Start `job` from the solution of its nested sub-model `sub`."""
    job.p = _coordinates(job, _values_of(sub))


def _adopt(job, sub, problems, shape):
    """`job` ended worse than its nested sub-model: take the sub-model's solution (the slots it
    holds held at its values) and evaluate it."""
    vals = _values_of(sub)
    for s, (name, r) in enumerate(job.slots):
        if name not in sub.free:
            rr = 0 if r is None else r
            job.code[s] = HELD
            job.held[s] = vals[rr][name]
            t = job.transforms[s]
            job.bound_hit[s] = job.held[s] in (t.lo, t.hi)
    job.p = _coordinates(job, vals)
    out = _solve(job.space, [_job_arrays(job, problems[job.problem], shape)], shape)[0]
    job.out, job.p, job.rss = out, out["p"][:len(job.slots)], _rss(out)
    job.iterations += out["steps"]


_HYPOTHESES = (0, 1, 2, 3)  #: amplitude-only records: fits assuming the last j swings did not cross


def _twin(job, signs=None, records=None) -> _Job:
    """A copy of `job` (its own starting point) to solve beside it; with `signs` (per record),
    the copy fits signed positions `signs * amplitudes` (a hypothesis on the sides)."""
    twin = dataclasses.replace(job, signs=signs)
    for name in ("code", "held", "scale", "p", "bound_hit"):
        setattr(twin, name, np.copy(getattr(job, name)))
    if signs is not None:  # started from the decrement method on the hypothesised sides
        start = []
        for r, (rec, sg) in enumerate(zip(records, signs)):
            if sg is not None:
                rec = dataclasses.replace(rec, positions=rec.centre + sg * rec.amplitudes,
                                          sides_known=True)
            guess = starting_guess(job.space, rec, job.fixed[r], decrement(rec, rec.centre))
            start.append({**job.start[r], **guess, **job.fixed[r]})
        twin.p = _coordinates(twin, start)
    return twin


def _hypothesis_signs(records, j) -> list | None:
    """Sides of each record's points if every swing crossed the centre except the last `j`
    swings (of the amplitude-only records) (`None` when no record is amplitude-only)."""
    if all(rec.sides_known for rec in records):
        return None
    out = []
    for rec in records:
        if rec.sides_known:
            out.append(None)
            continue
        flips = np.ones(int(rec.k[-1]) + 1, dtype=bool)
        if j:
            flips[rec.k[-j:]] = False
        flips[0] = False
        out.append(-np.cumprod(np.where(flips, -1.0, 1.0))[rec.k])
    return out


def _fit_all(jobs, problems, shape, first_pass):
    """Every job in rounds by number of slots. On the first pass a job with a fitted nested
    sub-model is solved twice, from its own start and from the best such sub-model, and keeps
    the better (it is never reported worse than that sub-model); a job with amplitude-only
    records is also solved on signed positions under the hypotheses that the last 0, 1, 2, 3
    swings did not cross, and the best of these starts it again."""
    for q in sorted({len(j.slots) for j in jobs}):
        round_jobs = [j for j in jobs if len(j.slots) == q]
        subs, twins = {}, {}
        for job in round_jobs:
            nested = [a for a in jobs if len(a.slots) < q and a.out is not None
                      and _nested_in(a, job)]
            mine = []
            if nested:
                best = min(nested, key=lambda a: a.rss)
                subs[id(job)] = best
                if first_pass:
                    mine.append(_twin(job))
                    _start_from(job, best)
            if first_pass:
                for j in _HYPOTHESES:
                    signs = _hypothesis_signs(problems[job.problem].records, j)
                    if signs is not None:
                        mine.append(_twin(job, signs, problems[job.problem].records))
            twins[id(job)] = mine
        _fit_jobs(round_jobs + [t for ts in twins.values() for t in ts], problems, shape)
        again = []
        for job in round_jobs:
            mine = twins[id(job)]
            best = min([job] + mine, key=lambda a: a.rss)
            if best is not job:
                for name in ("code", "held", "p", "bound_hit", "out", "rss"):
                    setattr(job, name, getattr(best, name))
                if best.signs is not None:
                    again.append(job)  # a signed-hypothesis optimum: refit the amplitudes
            job.iterations += sum(t.iterations for t in mine)
        _fit_jobs(again, problems, shape)
        for job in round_jobs:
            best = subs.get(id(job))
            if best is not None and not job.rss <= best.rss * (1 + 1e-9):
                _adopt(job, best, problems, shape)


# -- per-job statistics ------------------------------------------------------------------------
def _used(job, prob, N):
    """Indices of the residuals that count, and the blocks (slices of them) in record order."""
    idx, blocks, at = [], [], 0
    for r in range(len(prob.records)):
        for kind, w in ((0, prob.wx[r]), (1, prob.wt[r])):
            sel = np.nonzero(w > 0)[0] + r * 2 * N + kind * N
            if sel.size:
                idx.append(sel)
                blocks.append(slice(at, at + sel.size))
                at += sel.size
    return np.concatenate(idx), blocks


def _information(job, prob, N):
    idx, _ = _used(job, prob, N)
    n = idx.size
    q = int(np.sum(job.code != HELD))
    rss = job.rss
    ll = n * math.log(max(rss, 1e-300) / n)
    return {"aic": ll + 2 * q, "bic": ll + q * math.log(n), "rss": rss, "n": n, "q": q}


# -- profile likelihood ------------------------------------------------------------------------
def _profiles(job, prob, shape, est, se, inflation, s2):
    """95 % profile-likelihood intervals of the job's active slots: all slots and both sides
    solved together per root-finding iteration, warm-started at the optimum."""
    active = [s for s in range(len(job.slots)) if job.code[s] != HELD]
    target = _CHI2_95 * max(inflation, 1.0)
    ends = {}
    state = []
    for s in active:
        t = job.transforms[s]
        width = 1.96 * se[s] * math.sqrt(max(inflation, 1.0)) if np.isfinite(se[s]) and se[s] > 0 \
            else 0.1 * max(abs(est[s]), job.scale[s])
        for side in (-1, 1):
            v = est[s] + side * width
            state.append({"slot": s, "side": side, "v": v, "done": False, "ok": False,
                          "step": width, "bound": t.lo if side < 0 else t.hi})
    base = _job_arrays(job, prob, shape)
    for _ in range(_PROFILE_STEPS):
        live = [st for st in state if not st["done"]]
        if not live:
            break
        items = []
        for st in live:
            lo_b, hi_b = job.transforms[st["slot"]].lo, job.transforms[st["slot"]].hi
            st["v"] = min(max(st["v"], lo_b), hi_b)
            it = {k: np.copy(v) for k, v in base.items()}
            it["code"][st["slot"]] = HELD
            it["held"][st["slot"]] = st["v"]
            items.append(it)
        outs = _solve(job.space, items, shape, optimizer="lm")  # profiles need exact minima
        for st, out in zip(live, outs):
            dev = (_rss(out) - job.rss) / s2
            st["dev"] = dev
            if not np.isfinite(dev):
                st["done"] = True
                continue
            at_edge = st["v"] == st["bound"]
            if at_edge and dev < target:
                st["done"], st["ok"] = True, True  # the bound is inside the 95 % region
                continue
            if abs(dev / target - 1) < _PROFILE_TOL:
                st["done"], st["ok"] = True, True
                continue
            s = st["slot"]
            dist = st["v"] - est[s]
            if dev <= 1e-3 * target:
                st["v"] = est[s] + 4 * dist
            else:
                st["v"] = est[s] + dist * math.sqrt(target / dev)
    for st in state:
        if st["ok"]:
            ends.setdefault(st["slot"], {})[st["side"]] = st["v"]
    return ends


# -- results -----------------------------------------------------------------------------------
def _result(job, prob, jobs, shape, outlier_sigma):
    space, settings = job.space, shape.settings
    N = shape.N
    names = _slot_names(job)
    q = len(job.slots)
    idx, blocks = _used(job, prob, N)
    J = job.out["J"][:, :q][idx]
    r = job.out["r"][idx]
    info = _information(job, prob, N)
    active = job.code != HELD
    warn = []
    # covariance over the slots the solver moved; held slots have none
    cov_c = np.full((q, q), np.nan)
    cov_gn = np.full((q, q), np.nan)
    inflation = 1.0
    full_rank = True
    if active.any():
        Ja = J[:, active]
        c_c, c_gn, inflation = covariance(Ja, r, blocks)
        sel = np.ix_(active, active)
        cov_c[sel], cov_gn[sel] = c_c, c_gn
        norms = np.linalg.norm(Ja, axis=0)
        if np.any(norms == 0) or not np.all(np.isfinite(Ja)):
            full_rank = False
        else:
            sv = np.linalg.svd(Ja / norms, compute_uv=False)
            full_rank = bool(sv[-1] > RANK_RTOL * sv[0])
    if not np.isfinite(inflation):
        inflation = 1.0
    vals = _values_of(job)
    est = np.array([vals[0 if rr is None else rr][name] for name, rr in job.slots])
    se_c = np.sqrt(np.where(np.diag(cov_c) > 0, np.diag(cov_c), np.nan))
    se_gn = np.sqrt(np.where(np.diag(cov_gn) > 0, np.diag(cov_gn), np.nan))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov_c / np.outer(se_c, se_c)
    for s, nm in enumerate(names):
        if job.bound_hit[s]:
            t = job.transforms[s]
            user = (job.user_lo[s] and job.held[s] == t.lo) or (job.user_hi[s]
                                                                 and job.held[s] == t.hi)
            if not user:
                warn.append(f"{nm} ran into its bound {job.held[s]:.6g} "
                            f"[{space.unit(job.slots[s][0])}]: held there (a sub-model fits "
                            f"as well; see model_comparison)")
        elif not np.isfinite(se_c[s]):
            warn.append(f"{nm} is not identified by these data: no standard error")
        elif not se_c[s] < abs(est[s]):
            warn.append(f"{nm} is not identifiable from these data: its standard error "
                        f"{se_c[s]:.3g} is not below its value {est[s]:.3g}")
    for a in range(q):
        for b in range(a + 1, q):
            if np.isfinite(corr[a, b]) and abs(corr[a, b]) > 0.99:
                warn.append(f"{names[a]} and {names[b]} are not separately identifiable: "
                            f"correlation {corr[a, b]:.4f}")
    if not full_rank:
        warn.append("the Jacobian is rank-deficient (relative singular-value tolerance "
                    f"{RANK_RTOL:g}): some parameters are not determined by the data")
    at_unset_bound = any(job.bound_hit[s] and not (
        (job.user_lo[s] and job.held[s] == job.transforms[s].lo)
        or (job.user_hi[s] and job.held[s] == job.transforms[s].hi)) for s in range(q))
    if not job.out["ok"]:
        warn.append("the optimiser did not converge (step limit or no progress)")
    converged = bool(job.out["ok"] and full_rank and not at_unset_bound)
    # residual diagnostics
    std_blocks = [r[b] for b in blocks]
    diag = diagnostics(std_blocks, int(np.sum(active)))
    n_dof = info["n"] - info["q"]
    if n_dof < 3:
        warn.append(f"only {n_dof} residual degrees of freedom: the uncertainties are not "
                    f"reliable")
        converged = False if n_dof < 1 else converged
    # intervals
    intervals = {}
    s2 = job.rss / max(n_dof, 1)
    ends = _profiles(job, prob, shape, est, se_gn, inflation, s2) if active.any() and \
        converged and settings["intervals"] else {}
    for s, nm in enumerate(names):
        if not active[s]:
            intervals[nm] = (math.nan, math.nan)
            continue
        got = ends.get(s, {})
        wald = 1.96 * se_c[s]
        lo = got.get(-1, est[s] - wald)
        hi = got.get(1, est[s] + wald)
        t = job.transforms[s]
        lo, hi = max(lo, t.lo), min(hi, t.hi)
        if len(got) < 2 and np.isfinite(wald) and settings["intervals"]:
            warn.append(f"{nm}: the profile likelihood failed; the interval is the Wald "
                        f"interval +- 1.96 stderr")
        intervals[nm] = (float(lo), float(hi))
    warn += diag["warnings"]
    diag = {**diag, "warnings": warn}
    # per-record residuals in data units
    per_record = []
    R = len(prob.records)
    r_all = job.out["r"].reshape(R, 2, N)
    for i, rec in enumerate(prob.records):
        m = len(rec)
        wx, wt = prob.wx[i][:m], prob.wt[i][:m]
        res_x = r_all[i, 0, :m] / np.where(wx > 0, wx, 1.0)
        floor = 1e-4 * float(np.max(rec.amplitudes))
        z = res_x / _robust_scale(res_x, floor)
        flagged = np.abs(z) > outlier_sigma
        res_t = None
        if rec.times is not None:
            res_t = r_all[i, 1, :m] / np.where(wt > 0, wt, 1.0)
            res_t[wt == 0] = 0.0
            z_t = res_t / _robust_scale(res_t[wt > 0], 1e-12)
            flagged |= np.abs(z_t) > outlier_sigma
        per_record.append({
            "residuals": {"k": rec.k.tolist(), "position": res_x.tolist(),
                          "time": None if res_t is None else res_t.tolist(),
                          "standardized": z.tolist(), "outlier": flagged.tolist()},
            "rms": float(np.sqrt(np.mean(res_x ** 2))),
            "rms_time": None if res_t is None else float(np.sqrt(np.mean(res_t[1:] ** 2))),
            "outliers": [int(kk) for kk in rec.k[flagged]],
        })
    top = [s for s, (nm, rr) in enumerate(job.slots) if rr is None]

    def pick(arr, sel):
        return {names[s]: (float(arr[s]) if np.isfinite(arr[s]) else None) for s in sel}

    params = {names[s]: float(est[s]) for s in top}
    records = []
    if R > 1:
        for i, rec in enumerate(prob.records):
            sel = [s for s, (nm, rr) in enumerate(job.slots) if rr == i]
            records.append({
                "source": rec.source,
                "params": {job.slots[s][0]: float(est[s]) for s in sel},
                "stderr": {job.slots[s][0]: pick(se_c, [s])[names[s]] for s in sel},
                "stderr_gn": {job.slots[s][0]: pick(se_gn, [s])[names[s]] for s in sel},
                "intervals": {job.slots[s][0]: intervals[names[s]] for s in sel},
                "fixed": {k: v for k, v in vals[i].items() if k not in job.free},
                **{k: per_record[i][k] for k in ("rms", "rms_time", "outliers", "residuals")},
            })
    comparison = {}
    mine = [j for j in jobs if j.problem == job.problem]
    if len(mine) > 1:
        for j in mine:
            inf_j = _information(j, prob, N)
            vj = _values_of(j)
            comparison[j.label] = {
                "aic": inf_j["aic"], "bic": inf_j["bic"], "rss": inf_j["rss"],
                "params": {nm: vj[0 if rr is None else rr][nm] for nm, rr in j.slots},
                "converged": bool(j.out["ok"]),
            }
        labels = [j.label for j in mine]
        comparison["best_aic"] = min(labels, key=lambda k: comparison[k]["aic"])
        comparison["best_bic"] = min(labels, key=lambda k: comparison[k]["bic"])
    rec0 = prob.records[0]
    dec = prob.decs[0]
    corr_top = corr[np.ix_(top, top)] if top else np.zeros((0, 0))
    result = FitResult(
        model=space.name, forward=settings["forward"], loss=settings["loss"],
        optimizer=settings["optimizer"], params=params,
        fixed={k: v for k, v in vals[0].items() if k not in job.free},
        stderr=pick(se_c, top), correlation=np.where(np.isfinite(corr_top), corr_top,
                                                     np.nan).tolist(),
        converged=converged, iterations=int(sum(j.iterations for j in mine)),
        rms=per_record[0]["rms"] if R == 1 else float(np.sqrt(np.mean(np.concatenate(
            [np.asarray(p["residuals"]["position"]) ** 2 for p in per_record])))),
        rms_time=per_record[0]["rms_time"], model_comparison=comparison,
        residuals=per_record[0]["residuals"], outliers=per_record[0]["outliers"],
        warnings=warn, decrement={k: v for k, v in dec.items() if k != "pairs"}, record=rec0,
        stderr_gn=pick(se_gn, top), intervals={names[s]: intervals[names[s]] for s in top},
        diagnostics=diag, aic=info["aic"], bic=info["bic"], rss=info["rss"],
        n_residuals=info["n"], records=records, clock=rec0.clock,
        units={nm: space.unit(nm) for nm in space.names}, label=job.label,
    )
    result.decrement["pairs"] = dec["pairs"]
    return result


# -- the driver --------------------------------------------------------------------------------
def _problem(space, records, givens, free, shared):
    recs = []
    for rec in records:
        if not isinstance(rec, Record):
            raise ValueError("records must be fits.Record objects (see fits.read_record)")
        recs.append(rec)
    for rec, given in zip(recs, givens):
        _fixed_values(space, rec, free, given)  # a parameter without a value: its name first
    decs = []
    for rec in recs:
        per_record = len(free) if len(recs) == 1 else len(free) - len(shared)
        if len(rec) <= per_record:
            raise ValueError(f"{rec.source or 'record'}: {len(rec)} turning points are too few "
                             f"for {per_record} free parameters (need at least "
                             f"{per_record + 1})")
        if "omega" in free and rec.times is None:
            raise ValueError("omega can only be fitted from a record with times")
        centre = rec.centre if "offset" in space.names else 0.0
        decs.append(decrement(rec, centre))
    return _Problem(recs, [dict(g) for g in givens], tuple(free), tuple(shared), decs)


def _run(space, problems, free, bounds, settings, compare, outlier_sigma):
    jobs = []
    for i, prob in enumerate(problems):
        jobs.extend(_jobs_for(i, prob, space, bounds, compare))
    N = _bucket(max(len(rec) for prob in problems for rec in prob.records))
    n_model = _bucket(max(int(rec.k[-1]) for prob in problems for rec in prob.records))
    q = max(len(j.slots) for j in jobs)
    per_round = {}
    for j in jobs:  # extra starts on the first pass (see _fit_all)
        amp_only = not all(rec.sides_known for rec in problems[j.problem].records)
        starts = 1 + any(_nested_in(a, j) for a in jobs) + amp_only * len(_HYPOTHESES)
        per_round[(len(j.slots), j.space)] = per_round.get((len(j.slots), j.space), 0) + starts
    shape = _Shape(N, q, max(n_model, 1), max(per_round.values()), settings)
    for prob in problems:
        _init_weights(prob, N)
    has_times = any(rec.times is not None for prob in problems for rec in prob.records)
    passes = 1 + has_times + (_ROBUST_PASSES if settings["loss"] != "l2" else 0)
    for it in range(passes):
        _fit_all(jobs, problems, shape, first_pass=it == 0)
        if it + 1 < passes:
            for i, prob in enumerate(problems):
                lead = next(j for j in jobs if j.problem == i and j.headline)
                _reweight(prob, lead, settings["loss"], N)
    results = []
    for i, prob in enumerate(problems):
        mine = [j for j in jobs if j.problem == i]
        head = next(j for j in mine if j.headline)
        if space.select and len(mine) > 1:
            head = min(mine, key=lambda j: _information(j, prob, N)["bic"])
        results.append(_result(head, prob, jobs, shape, outlier_sigma))
    for res in results:
        for w in res.warnings:
            warnings.warn(w, stacklevel=4)
    return results


def _parse_given(given, n):
    if given is None or isinstance(given, dict):
        return [dict(given or {})] * n
    givens = [dict(g) for g in given]
    if len(givens) != n:
        raise ValueError(f"given: {len(givens)} dicts for {n} records")
    return givens


def _settings(space, free, shared, givens, bounds, forward, loss, optimizer, max_steps,
              adam_steps, intervals):
    bounds = {k: (float(v[0]), float(v[1])) for k, v in (bounds or {}).items()}
    for g in givens:
        free = _check_inputs(space, free, shared, g, bounds, forward, loss, optimizer)
    return free, bounds, {"forward": forward, "loss": loss, "optimizer": optimizer,
                          "max_steps": max_steps, "adam_steps": adam_steps,
                          "intervals": intervals}


def fit_batch(records, model: str = "variable-mass", free=("FT", "mu"), given=None, *,
              bounds=None, forward: str = "exact", loss: str = "l2", optimizer: str = "lm",
              compare: bool = True, max_steps: int = 200, adam_steps: int = 3000,
              outlier_sigma: float = 5.0, intervals: bool = True,
              chunk_size: int | None = None, client=None, store=None, resume: bool = False,
              progress=None) -> list:
    """Fit the same model to many records independently, at once (`jax.vmap` over records and
    sub-models; one compilation).

    Arguments as in [`fits.fit`][]; `given` is one dict for every record or a list of one dict per
    record (the free parameters are the same for all). Returns a list of
    [`fits.FitResult`][], one per record.

    With `chunk_size`, `client` or `store` the records are fitted in chunks of at most
    `chunk_size` records through [`vmj.map_chunks`][]: in threads of this process, or as tasks
    of a Dask cluster (`client`: a `dask.distributed.Client`, `"tcp://host:8786"` or
    `"local"`), each finished chunk written to a Zarr store (`store`) and a rerun with
    `resume=True` fitting only the chunks not yet in it; `progress` as in [`vmj.sweep`][]. The
    same chunks give the same results, to the last bit, in-process and on a cluster.
    """
    warn_if_float32()
    space = _space(model)
    records = list(records)
    if not records:
        raise ValueError("no records to fit")
    givens = _parse_given(given, len(records))
    free, bounds, settings = _settings(space, free, (), givens, bounds, forward, loss, optimizer,
                                       max_steps, adam_steps, intervals)
    if chunk_size is not None or client is not None or store is not None:
        chunk = functools.partial(_fit_chunk, model=model, free=free, bounds=bounds,
                                  forward=forward, loss=loss, optimizer=optimizer,
                                  compare=compare, max_steps=max_steps, adam_steps=adam_steps,
                                  outlier_sigma=outlier_sigma, intervals=intervals)
        return vmj.map_chunks(chunk, list(zip(records, givens)), chunk_size=chunk_size,
                              client=client, store=store, resume=resume, progress=progress)
    problems = [_problem(space, [rec], [g], free, ()) for rec, g in zip(records, givens)]
    return _run(space, problems, free, bounds, settings, compare, outlier_sigma)


def _space(model) -> Space:
    if model not in SPACES:
        raise ValueError(f"model must be one of {sorted(SPACES)} (got {model!r})")
    return SPACES[model]


def _fit_chunk(items, **settings) -> list:
    """`fit_batch` of one chunk of `(record, given)` pairs (a picklable function of the chunk,
    for `vmj.map_chunks`)."""
    return fit_batch([r for r, _ in items], given=[g for _, g in items], **settings)


def fit(record, model: str = "variable-mass", free=("FT", "mu"), given=None, *,
        shared=(), bounds=None, forward: str = "exact", loss: str = "l2",
        optimizer: str = "lm", compare: bool = True, max_steps: int = 200,
        adam_steps: int = 3000, outlier_sigma: float = 5.0,
        intervals: bool = True) -> FitResult:
    """Identify friction and damping from one measured decay, or from several jointly.

    **Arguments:**

    - `record`: a [`fits.Record`][] (see [`fits.read_record`][],
      [`fits.record_from_sequence`][]), or a list of records fitted jointly (one
      least-squares solve over all their residuals).
    - `model`: `"variable-mass"` (parameters `FT` [N], `f` [-], `mu` [kg/s], `eps` [-],
      `delta` [kg/s], `a0` [m], `offset` [m], `m0` [kg], `c` [N/m], `g` [m/s^2]; `m0` and `c`
      must be given), `"oscillator"` (`omega` [rad/s], `zeta` [-], `xF`, `a0`, `offset` in the
      signal's units, `asym` [-] the sensor's side-dependent gain; `omega` must be given or
      fitted) or `"rope"`.
    - `free`: names of the parameters to fit.
    - `given`: values of fixed parameters (and starting values of free ones, overriding the
      decrement-method start), a dict or one per record. A parameter neither fitted nor given
      takes its physical default (friction and damping terms 0, `g` 9.81 m/s^2, `asym` 0,
      `a0` the release point's distance from the record's centre, `offset` the record's
      centre); one without a default (`m0`, `c`, the oscillator's `omega`, ...) is an error.
    - `shared`: with several records, the free parameters that take one value for all of them
      (the others, e.g. `offset`, `a0`, one value per record).
    - `bounds`: `{name: (lo, hi)}` in the parameter's units, narrowing its physical range; a
      parameter ending at a bound set here is not flagged (one at a physical bound is).
    - `forward`: `"exact"` (default; exact turning points), `"smooth"` (smoothed ODE) or
      `"energy"` (the closed-form energy-balance recurrence).
    - `loss`: `"l2"`, or a robust `"huber"`/`"cauchy"` (iteratively reweighted, with the scale
      re-estimated from the residuals' MAD each pass).
    - `optimizer`: `"lm"` (Levenberg-Marquardt, optimistix) or `"adam"` (optax; minimises the
      loss directly for `adam_steps` steps).
    - `compare`: also fit the model's sub-models (`Space.variants`: Coulomb-only and
      viscous-only) and compare them by AIC/BIC.
    - `max_steps`: Levenberg-Marquardt step limit per pass.
    - `outlier_sigma`: residuals beyond this many robust standard deviations are flagged.
    - `intervals`: compute 95 % profile-likelihood intervals (else Wald intervals).

    **Returns:** a [`fits.FitResult`][].

    Raises `ValueError` for unknown parameters, values out of range or outside `bounds`, a
    parameter neither fitted, given nor defaulted, too few points for the free parameters, or a
    record that does not decay.
    """
    warn_if_float32()
    space = _space(model)
    records = list(record) if isinstance(record, (list, tuple)) else [record]
    if not records:
        raise ValueError("no records to fit")
    givens = _parse_given(given, len(records))
    shared = tuple(shared)
    if shared and len(records) < 2:
        raise ValueError("--shared needs several records")
    free, bounds, settings = _settings(space, free, shared, givens, bounds, forward, loss,
                                       optimizer, max_steps, adam_steps, intervals)
    prob = _problem(space, records, givens, free, shared)
    return _run(space, [prob], free, bounds, settings, compare, outlier_sigma)[0]
