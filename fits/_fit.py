"""Least-squares identification of friction and damping from turning-point sequences.

The residuals compare SIGNED turning-point positions (and times, when the record has them)
with the forward model. A model that sticks early repeats its last turning point
(`vmj.DecaySequence` padding), and a swing that does not pass the centre keeps its sign, so the
objective is continuous in the parameters.

One compiled solver serves every fit of a model family, forward method and record length:
which parameters are free, their fixed values, the data and the weights are all array data, so
the Coulomb-only / viscous-only / both comparison, robust reweighting passes and batches of
records (`jax.vmap`) reuse it.
"""

from __future__ import annotations

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
from vmj._checks import check, nonnegative, positive, unit_interval, warn_if_float32

from ._decrement import decrement, starting_guess
from ._io import Record
from ._models import FORWARDS, KIND_CODES, SPACES, Space, theta_dict

__all__ = ["FitResult", "fit", "fit_batch", "LOSSES", "OPTIMIZERS"]

LOSSES = ("l2", "huber", "cauchy")
OPTIMIZERS = ("lm", "adam")
_TUNING = {"huber": 1.345, "cauchy": 2.385}  #: 95 % efficiency constants of the robust losses
_ROBUST_PASSES = 10
_LM_RTOL, _LM_ATOL = 1e-10, 1e-12


# -- the compiled core -------------------------------------------------------------------------
class _Data(eqx.Module):
    k: jax.Array  # (N,) swing index of each point
    x: jax.Array  # (N,) measured positions
    t: jax.Array  # (N,) measured times from the release
    wx: jax.Array  # (N,) weights of the position residuals (0 = ignored / padding)
    wt: jax.Array  # (N,) weights of the time residuals
    orient: jax.Array  # () +1 if the release is below the centre
    fixed: jax.Array  # (P + 1,) parameter values (last slot: a dummy for unused free slots)
    free: jax.Array  # (q,) indices of the free parameters in `fixed`
    code: jax.Array  # (q,) transform of each free slot: KIND_CODES, or 3 = held at its bound
    scale: jax.Array  # (P + 1,) scale of each parameter's transform


_HELD = 3  #: a free slot held at its bound (an active constraint): not moved by the solver


def _theta(space, p, d: _Data):
    code, sc = d.code, d.scale[d.free]
    val = jnp.where(code == 0, sc * p, jnp.where(code == 1, sc * p * p, jnp.sin(p) ** 2))
    return d.fixed.at[d.free].set(jnp.where(code == _HELD, d.fixed[d.free], val))


def _to_p(space, theta, d_free, scale):
    """Inverse of `_theta` for the starting values (NumPy)."""
    out = []
    for i in d_free:
        if i >= len(space.kinds):
            out.append(0.0)
            continue
        kind, v, s = space.kinds[i], theta[i], scale[i]
        if kind == "real":
            out.append(v / s)
        elif kind == "positive":
            out.append(math.sqrt(max(v, 0.0) / s))
        else:
            out.append(math.asin(math.sqrt(min(max(v, 0.02), 0.98))))
    return np.asarray(out)


def _residual(space, forward, n, theta, d: _Data):
    th = theta_dict(space, theta[:-1])
    times, positions = space.predict(th, n, forward)
    px = th["offset"] + d.orient * positions[d.k]
    return jnp.concatenate([d.wx * (px - d.x), d.wt * (times[d.k] - d.t)])


def _dtheta_dp(space, p, d):
    code, sc = d.code, d.scale[d.free]
    dv = jnp.where(code == 0, sc, jnp.where(code == 1, 2 * sc * p, jnp.sin(2 * p)))
    return jnp.where(code == _HELD, 0.0, dv)


def _residual_and_jacobian_impl(space, forward, n, p, d):
    """Residuals at `p` and their Jacobian with respect to the free parameters (in their
    physical units), from one forward-mode pass. Wrapping it as a `custom_jvp` whose tangent
    is that materialised Jacobian keeps the solvers from tracing (and compiling) the forward
    model again for linearisation and transposition: one compiled Jacobian serves the
    Levenberg-Marquardt steps, Adam's gradients and the standard errors."""
    theta = _theta(space, p, d)

    def r_of(values):
        r = _residual(space, forward, n, theta.at[d.free].set(values), d)
        return r, r

    # the smoothed model's diffrax solve differentiates in reverse mode only
    jacobian = jax.jacrev if forward == "smooth" else jax.jacfwd
    J, r = jacobian(r_of, has_aux=True)(theta[d.free])
    return r, J


_residual_and_jacobian = jax.custom_jvp(_residual_and_jacobian_impl, nondiff_argnums=(0, 1, 2))


@_residual_and_jacobian.defjvp
def _residual_and_jacobian_jvp(space, forward, n, primals, tangents):
    p, d = primals
    dp, _ = tangents  # never differentiated with respect to the data
    r, J = _residual_and_jacobian(space, forward, n, p, d)
    return (r, J), (J @ (_dtheta_dp(space, p, d) * dp), jnp.zeros_like(J))


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
        return sol.value, _theta(space, sol.value, d), J, r, ok, sol.stats["num_steps"]

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
        return p, _theta(space, p, d), J, r, ok, jnp.asarray(steps)

    return jax.vmap(one)(d, p0)


# -- results -----------------------------------------------------------------------------------
@dataclass
class FitResult:
    """The outcome of a fit.

    **Fields:** `model`, `forward`, `loss`, `optimizer`; `params` (free parameters, in the
    order fitted) and `fixed` (the others) in SI units or the signal's units; `stderr`
    (Gauss-Newton standard errors of the free parameters); `correlation` (their correlation
    matrix); `converged`; `iterations` (solver steps over all passes); `rms` (RMS position
    residual) and `rms_time` [s]; `model_comparison` (Coulomb-only / viscous-only / both by
    AIC and BIC, when both kinds of friction are free); `residuals` (per point: `k`,
    `position`, `time`, `standardized`, `outlier`); `outliers` (the flagged `k`); `warnings`
    (identifiability); `decrement` (the decrement-method estimate); `record`.
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

    def to_json(self) -> dict:
        """The command line's JSON object (`params`, `stderr`, `correlation`, `converged`,
        `iterations`, `rms`, `model_comparison`); NaN becomes `null`."""
        return _jsonable({
            "params": self.params,
            "stderr": self.stderr,
            "correlation": self.correlation,
            "converged": self.converged,
            "iterations": self.iterations,
            "rms": self.rms,
            "model_comparison": self.model_comparison,
        })

    def report(self) -> str:
        from ._report import text_report

        return text_report(self)


def _jsonable(obj):
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    return obj


# -- input checks ------------------------------------------------------------------------------
_RANGES = {
    "real": (lambda x: x == x, "a real number"),
    "positive": (nonnegative, ">= 0"),
    "unit": (unit_interval, "in [0, 1]"),
    "damping": (lambda x: (x >= 0) & (x < 1), "in [0, 1) (an underdamped oscillator)"),
}


def _check_inputs(space, free, given, forward, loss, optimizer):
    if forward not in FORWARDS:
        raise ValueError(f"forward must be one of {list(FORWARDS)} (got {forward!r})")
    if loss not in LOSSES:
        raise ValueError(f"loss must be one of {list(LOSSES)} (got {loss!r})")
    if optimizer not in OPTIMIZERS:
        raise ValueError(f"optimizer must be one of {list(OPTIMIZERS)} (got {optimizer!r})")
    free = tuple(free)
    if not free:
        raise ValueError("give at least one parameter to fit")
    for name in list(free) + list(given):
        if name not in space.names:
            raise ValueError(f"unknown parameter {name!r} for the {space.name} model "
                             f"(parameters: {', '.join(space.names)})")
    if len(set(free)) != len(free):
        raise ValueError(f"a parameter is listed twice in {free}")
    for name, value in given.items():
        kind = space.kinds[space.index(name)]
        unit = space.units[space.index(name)]
        ok, allowed = _RANGES[kind]
        if name in ("m0", "c", "g", "omega") or (name == "a0" and name not in free):
            ok, allowed = positive, "> 0"
        check(name, value, ok, f"{allowed} [{unit}]")
    missing = [n for n in space.required if n not in given and n not in free]
    if missing:
        raise ValueError(f"the {space.name} model needs {', '.join(missing)} "
                         f"(give them with --set / given=)")
    return free


def _defaults(space: Space, record: Record, free, given) -> dict:
    """Fixed values of the parameters neither fitted nor given."""
    out = {}
    for name in space.names:
        if name in free or name in given:
            continue
        if name == "offset":
            out[name] = 0.0 if space.name != "oscillator" else record.centre
        elif name == "g":
            out[name] = 9.81
        elif name == "a0":
            if record.k[0] != 0:
                raise ValueError("the record has no k = 0 row: give a0 or fit it")
            out[name] = abs(float(record.positions[0]) - 0.0)
        elif name == "omega":
            out[name] = 1.0
        else:
            out[name] = 0.0
    return out


# -- the driver --------------------------------------------------------------------------------
@dataclass
class _Job:
    record: Record
    free: tuple
    start: dict
    fixed_values: dict
    leader: int  # index of the job whose weights this one shares
    variant: str  # "fit", "coulomb", "viscous"


def _robust_scale(r, floor):
    r = r[np.isfinite(r)]
    if r.size == 0:
        return floor
    return max(1.4826 * float(np.median(np.abs(r - np.median(r)))), floor)


def _prepare(space, records, free, givens, compare):
    jobs = []
    decs = []
    for rec, given in zip(records, givens):
        if not isinstance(rec, Record):
            raise ValueError("records must be fits.Record objects (see fits.read_record)")
        if len(rec) <= len(free):
            raise ValueError(f"{rec.source or 'record'}: {len(rec)} turning points are too few for "
                             f"{len(free)} free parameters (need at least {len(free) + 1})")
        if "omega" in free and rec.times is None:
            raise ValueError("omega can only be fitted from a record with times")
        centre = rec.centre if space.name == "oscillator" else 0.0
        dec = decrement(rec, centre)
        decs.append(dec)
        start = starting_guess(space.name, rec, given, dec)
        fixed = {**_defaults(space, rec, free, given), **{k: float(v) for k, v in given.items()}}
        leader = len(jobs)
        jobs.append(_Job(rec, free, start, fixed, leader, "fit"))
        dry = [n for n in free if n in space.dry]
        visc = [n for n in free if n in space.viscous]
        if compare and dry and visc:
            for variant, zero in (("coulomb", visc), ("viscous", dry)):
                jobs.append(_Job(rec, tuple(n for n in free if n not in zero), start,
                                 {**fixed, **{n: 0.0 for n in zero}}, leader, variant))
    return jobs, decs


def _bucket(n: int) -> int:
    """Round a length up to a multiple of 8, so records of similar length share a compilation."""
    return max(8, -(-n // 8) * 8)


def _arrays(space, jobs, q, sigma_x, sigma_t):
    P = len(space.names)
    N = _bucket(max(len(j.record) for j in jobs))
    cols = {k: [] for k in ("k", "x", "t", "wx", "wt", "orient", "fixed", "free", "code", "scale",
                            "p0")}
    for j, (job, sx, st) in enumerate(zip(jobs, sigma_x, sigma_t)):
        rec = job.record
        m = len(rec)
        pad = N - m
        theta = np.zeros(P + 1)
        scale = np.ones(P + 1)
        for i, name in enumerate(space.names):
            theta[i] = job.fixed_values.get(name, job.start.get(name, 0.0))
            s0 = abs(job.start.get(name, 0.0))
            scale[i] = s0 if s0 > 0 else 1.0
            if space.kinds[i] == "real" and name == "offset":
                scale[i] = max(float(np.max(rec.amplitudes)), 1e-300)
            elif space.kinds[i] == "real":
                scale[i] = max(s0, 1.0)
        for name in job.free:
            theta[space.index(name)] = job.start[name]
        free_idx = [space.index(nm) for nm in job.free] + [P] * (q - len(job.free))
        cols["k"].append(np.pad(rec.k, (0, pad)))
        cols["x"].append(np.pad(rec.positions, (0, pad)))
        times = rec.times if rec.times is not None else np.zeros(m)
        cols["t"].append(np.pad(times, (0, pad)))
        cols["wx"].append(np.pad(np.broadcast_to(1.0 / sx, (m,)), (0, pad)))
        wt = np.zeros(m) if rec.times is None else np.broadcast_to(1.0 / st, (m,)).copy()
        if rec.times is not None and rec.k[0] == 0:
            wt[0] = 0.0  # the release time is zero by definition
        cols["wt"].append(np.pad(wt, (0, pad)))
        cols["orient"].append(rec.orientation)
        cols["fixed"].append(theta)
        cols["free"].append(np.asarray(free_idx))
        cols["code"].append(np.asarray([KIND_CODES[space.kinds[i]] if i < P else 0
                                        for i in free_idx]))
        cols["scale"].append(scale)
        cols["p0"].append(_to_p(space, theta, free_idx, scale))
    arr = {k: np.stack(v) for k, v in cols.items()}
    n_model = _bucket(int(max(int(j.record.k[-1]) for j in jobs)))
    d = _Data(k=jnp.asarray(arr["k"]), x=jnp.asarray(arr["x"], dtype=float),
              t=jnp.asarray(arr["t"], dtype=float), wx=jnp.asarray(arr["wx"], dtype=float),
              wt=jnp.asarray(arr["wt"], dtype=float), orient=jnp.asarray(arr["orient"], dtype=float),
              fixed=jnp.asarray(arr["fixed"], dtype=float), free=jnp.asarray(arr["free"]),
              code=jnp.asarray(arr["code"]), scale=jnp.asarray(arr["scale"], dtype=float))
    return d, jnp.asarray(arr["p0"], dtype=float), max(n_model, 1), N


def _psi_weight(loss, u):
    """IRLS weight `psi(u)/u` of a robust loss."""
    if loss == "l2":
        return np.ones_like(u)
    c = _TUNING[loss]
    if loss == "huber":
        return np.minimum(1.0, c / np.maximum(np.abs(u), 1e-300))
    return 1.0 / (1.0 + (u / c) ** 2)


def fit_batch(records, model: str = "variable-mass", free=("FT", "mu"), given=None, *,
              forward: str = "exact", loss: str = "l2", optimizer: str = "lm",
              compare: bool = True, max_steps: int = 200, adam_steps: int = 3000,
              outlier_sigma: float = 5.0, chunk_size: int | None = None, client=None,
              store=None, resume: bool = False, progress=None) -> list:
    """Fit the same model to many records at once (`jax.vmap` over records; one compilation).

    Arguments as in [`fit`][]; `given` is one dict for every record or a list of one dict per
    record (the free parameters are the same for all). Returns a list of
    [`FitResult`][], one per record.

    With `chunk_size`, `client` or `store` the records are fitted in chunks of at most
    `chunk_size` records through [`vmj.map_chunks`][]: in threads of this process, or as tasks
    of a Dask cluster (`client`: a `dask.distributed.Client`, `"tcp://host:8786"` or
    `"local"`), each finished chunk written to a Zarr store (`store`) and a rerun with
    `resume=True` fitting only the chunks not yet in it; `progress` as in [`vmj.sweep`][]. The
    same chunks give the same results, to the last bit, in-process and on a cluster.
    """
    warn_if_float32()
    if model not in SPACES:
        raise ValueError(f"model must be one of {sorted(SPACES)} (got {model!r})")
    space = SPACES[model]
    records = list(records)
    if not records:
        raise ValueError("no records to fit")
    if given is None or isinstance(given, dict):
        givens = [dict(given or {})] * len(records)
    else:
        givens = [dict(g) for g in given]
        if len(givens) != len(records):
            raise ValueError(f"given: {len(givens)} dicts for {len(records)} records")
    for g in givens:
        free = _check_inputs(space, free, g, forward, loss, optimizer)
    if chunk_size is not None or client is not None or store is not None:
        chunk = functools.partial(_fit_chunk, model=model, free=free, forward=forward,
                                  loss=loss, optimizer=optimizer, compare=compare,
                                  max_steps=max_steps, adam_steps=adam_steps,
                                  outlier_sigma=outlier_sigma)
        return vmj.map_chunks(chunk, list(zip(records, givens)), chunk_size=chunk_size,
                              client=client, store=store, resume=resume, progress=progress)
    jobs, decs = _prepare(space, records, free, givens, compare)
    q = len(free)
    has_times = [j.record.times is not None for j in jobs]
    sx = [max(j.record.noise or 0.0, 1e-3 * float(np.max(j.record.amplitudes))) for j in jobs]
    st = [1e-3 * float(np.median(np.diff(j.record.times))) if t else 1.0
          for j, t in zip(jobs, has_times)]
    d, p, n_model, N = _arrays(space, jobs, q, sx, st)
    wx0 = np.asarray(d.wx) * np.asarray(sx)[:, None]  # 1 on data, 0 on padding
    wt0 = np.asarray(d.wt) * np.asarray(st)[:, None]
    passes = 1 + any(has_times) + (_ROBUST_PASSES if loss != "l2" else 0)
    iterations = np.zeros(len(jobs), dtype=int)
    weights_x = np.ones((len(jobs), N))
    weights_t = np.ones((len(jobs), N))
    it = 0
    while True:
        if optimizer == "lm":
            out = _solve_lm(space, forward, n_model, max_steps, d, p)
        else:
            out = _solve_adam(space, forward, n_model, adam_steps, loss, d, p)
        p, theta, J, r, ok, steps = (np.asarray(v) for v in out)
        iterations += steps.astype(int)
        it += 1
        # a positive (or [0, 1]) parameter that ran into its bound is held there (an active
        # constraint) and the pass repeated: the solver cannot converge onto p = 0 of sqrt(theta)
        code = np.asarray(d.code)
        sin2 = np.sin(p) ** 2
        near = np.where(ok[:, None], 1e-8, 1e-4)
        at_bound = (((code == 1) & (p * p < near))
                    | ((code == 2) & ((sin2 < near) | (sin2 > 1 - near))))
        if at_bound.any() and it < passes + 2 * np.asarray(d.free).shape[1]:
            fixed = np.asarray(d.fixed).copy()
            rows, cols_ = np.nonzero(at_bound)
            fixed[rows, np.asarray(d.free)[rows, cols_]] = np.where(
                code[rows, cols_] == 1, 0.0, np.round(sin2[rows, cols_]))
            code = np.where(at_bound, _HELD, code)
            d = eqx.tree_at(lambda z: (z.fixed, z.code), d, (jnp.asarray(fixed), jnp.asarray(code)))
            p = jnp.asarray(p)
            passes += 1
            continue
        if it >= passes:
            break
        # re-estimate the noise of each block and the robust weights from the leader's residuals
        wx_now, wt_now = np.asarray(d.wx), np.asarray(d.wt)
        rx = np.where(wx_now > 0, r[:, :N] / np.where(wx_now > 0, wx_now, 1), np.nan)
        rt = np.where(wt_now > 0, r[:, N:] / np.where(wt_now > 0, wt_now, 1), np.nan)
        new_wx, new_wt = wx_now.copy(), wt_now.copy()
        for j, job in enumerate(jobs):
            L = job.leader
            if j == L:
                amp = float(np.max(job.record.amplitudes))
                sx[j] = _robust_scale(rx[j][wx0[j] > 0], 1e-6 * amp)
                if has_times[j]:
                    st[j] = _robust_scale(rt[j][wt0[j] > 0], 1e-9)
                if loss != "l2":
                    weights_x[j] = np.nan_to_num(_psi_weight(loss, rx[j] / sx[j]), nan=0.0)
                    weights_t[j] = np.nan_to_num(_psi_weight(loss, rt[j] / st[j]), nan=0.0)
            new_wx[j] = wx0[j] * np.sqrt(weights_x[L]) / sx[L]
            new_wt[j] = wt0[j] * np.sqrt(weights_t[L]) / st[L]
        d = eqx.tree_at(lambda z: (z.wx, z.wt), d, (jnp.asarray(new_wx), jnp.asarray(new_wt)))
        p = jnp.asarray(p)
    return _results(space, forward, loss, optimizer, jobs, decs, d, theta, J, r, ok, iterations,
                    N, n_model, outlier_sigma)


def _fit_chunk(items, **settings) -> list:
    """`fit_batch` of one chunk of `(record, given)` pairs (a picklable function of the chunk,
    for `vmj.map_chunks`)."""
    return fit_batch([r for r, _ in items], given=[g for _, g in items], **settings)


def _results(space, forward, loss, optimizer, jobs, decs, d, theta, J, r, ok, iterations, N,
             n_model, outlier_sigma):
    wx, wt = np.asarray(d.wx), np.asarray(d.wt)
    stats = []
    for j, job in enumerate(jobs):
        rw = r[j]
        used = np.concatenate([wx[j] > 0, wt[j] > 0])
        n_res = int(np.sum(used))
        rss = float(np.sum(rw[used] ** 2))
        q = len(job.free)
        ll = n_res * math.log(max(rss, 1e-300) / n_res)
        stats.append({"aic": ll + 2 * q, "bic": ll + q * math.log(n_res), "rss": rss,
                      "n": n_res, "q": q})
    results = []
    leaders = [j for j, job in enumerate(jobs) if job.variant == "fit"]
    for dec, L in zip(decs, leaders):
        job = jobs[L]
        rec = job.record
        q = len(job.free)
        m = len(rec)
        th = dict(zip(space.names, theta[L][:-1].tolist()))
        params = {nm: th[nm] for nm in job.free}
        fixed = {nm: v for nm, v in th.items() if nm not in job.free}
        Jf = J[L][:, :q]
        used = np.concatenate([wx[L] > 0, wt[L] > 0])
        dof = max(stats[L]["n"] - q, 1)
        s2 = stats[L]["rss"] / dof
        cov = s2 * np.linalg.pinv(Jf[used].T @ Jf[used])
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = cov / np.outer(se, se)
        stderr = dict(zip(job.free, se.tolist()))
        warn = []
        for i, nm in enumerate(job.free):
            if not se[i] < abs(params[nm]):
                warn.append(f"{nm} is not identifiable from these data: its standard error "
                            f"{se[i]:.3g} is not below its value {params[nm]:.3g}")
        for a in range(q):
            for b in range(a + 1, q):
                if abs(corr[a, b]) > 0.99:
                    warn.append(f"{job.free[a]} and {job.free[b]} are not separately identifiable:"
                                f" correlation {corr[a, b]:.4f}")
        # per-point residuals in the data's units
        res_x = r[L][:m] / np.where(wx[L][:m] > 0, wx[L][:m], 1.0)
        floor = 1e-4 * float(np.max(rec.amplitudes))
        sig = _robust_scale(res_x, floor)
        z = res_x / sig
        flagged = np.abs(z) > outlier_sigma
        res_t = None
        z_t = None
        if rec.times is not None:
            res_t = r[L][N:N + m] / np.where(wt[L][:m] > 0, wt[L][:m], 1.0)
            res_t[wt[L][:m] == 0] = 0.0
            z_t = res_t / _robust_scale(res_t[wt[L][:m] > 0], 1e-12)
            flagged |= np.abs(z_t) > outlier_sigma
        comparison = {}
        variants = [j for j, jb in enumerate(jobs) if jb.leader == L]
        if len(variants) > 1:
            names = {"fit": "both"}
            for j in variants:
                comparison[names.get(jobs[j].variant, jobs[j].variant)] = {
                    "aic": stats[j]["aic"], "bic": stats[j]["bic"],
                    "params": dict(zip(jobs[j].free,
                                       [float(theta[j][space.index(nm)]) for nm in jobs[j].free])),
                    "converged": bool(ok[j]),
                }
            comparison["best_aic"] = min((k for k in comparison), key=lambda k: comparison[k]["aic"])
            comparison["best_bic"] = min((k for k in comparison if k != "best_aic"),
                                         key=lambda k: comparison[k]["bic"])
        results.append(FitResult(
            model=space.name, forward=forward, loss=loss, optimizer=optimizer,
            params=params, fixed=fixed, stderr=stderr,
            correlation=np.where(np.isfinite(corr), corr, np.nan).tolist(),
            converged=bool(ok[L]), iterations=int(iterations[L]),
            rms=float(np.sqrt(np.mean(res_x**2))),
            rms_time=None if res_t is None else float(np.sqrt(np.mean(res_t[1:] ** 2))),
            model_comparison=comparison,
            residuals={"k": rec.k.tolist(), "position": res_x.tolist(),
                       "time": None if res_t is None else res_t.tolist(),
                       "standardized": z.tolist(), "outlier": flagged.tolist()},
            outliers=[int(k) for k in rec.k[flagged]],
            warnings=warn, decrement={k: v for k, v in dec.items() if k != "pairs"},
            record=rec,
        ))
        results[-1].decrement["pairs"] = dec["pairs"]
        for w in warn:
            warnings.warn(w, stacklevel=3)
    return results


def fit(record: Record, model: str = "variable-mass", free=("FT", "mu"), given=None, *,
        forward: str = "exact", loss: str = "l2", optimizer: str = "lm", compare: bool = True,
        max_steps: int = 200, adam_steps: int = 3000, outlier_sigma: float = 5.0) -> FitResult:
    """Identify friction and damping from one measured decay.

    **Arguments:**

    - `record`: a [`Record`][] (see [`read_record`][], [`record_from_sequence`][]).
    - `model`: `"variable-mass"` (parameters `FT` [N], `f` [-], `mu` [kg/s], `eps` [-],
      `delta` [kg/s], `a0` [m], `offset` [m], `m0` [kg], `c` [N/m], `g` [m/s^2]; `m0` and `c`
      must be given), `"oscillator"` (`omega` [rad/s], `zeta` [-], `xF`, `a0`, `offset` in the
      signal's units) or `"rope"` (when available).
    - `free`: names of the parameters to fit.
    - `given`: values of fixed parameters (and starting values of free ones, overriding the
      decrement-method start). Unlisted parameters default to 0 (`g` 9.81, `a0` the first
      amplitude, the oscillator's `offset` the record's centre).
    - `forward`: `"exact"` (default; exact turning points), `"smooth"` (smoothed ODE) or
      `"energy"` (the closed-form energy-balance recurrence).
    - `loss`: `"l2"`, or a robust `"huber"`/`"cauchy"` (iteratively reweighted, with the scale
      re-estimated from the residuals' MAD each pass).
    - `optimizer`: `"lm"` (Levenberg-Marquardt, optimistix) or `"adam"` (optax; minimises the
      loss directly for `adam_steps` steps).
    - `compare`: when both dry and viscous parameters are free, also fit Coulomb-only and
      viscous-only and compare by AIC/BIC.
    - `max_steps`: Levenberg-Marquardt step limit per pass.
    - `outlier_sigma`: residuals beyond this many robust standard deviations are flagged.

    **Returns:** a [`FitResult`][].

    Raises `ValueError` for unknown parameters, values out of range, too few points for the
    free parameters, or a record that does not decay.
    """
    return fit_batch([record], model, free, given, forward=forward, loss=loss,
                     optimizer=optimizer, compare=compare, max_steps=max_steps,
                     adam_steps=adam_steps, outlier_sigma=outlier_sigma)[0]
