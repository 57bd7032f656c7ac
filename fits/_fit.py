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
import numbers
import warnings
from dataclasses import dataclass

import numpy as np

import vmj
from vmj.cli import name_list

from ._decrement import decrement, starting_guess
from ._extract import extract_turning_points, local_centres, sample_window
from ._models import SPACES
from ._params import (
    HELD,
    INTERVAL,
    LOWER,
    REAL,
    Transform,
    at_bound,
    check_value,
    inverse,
    transform_for,
    warn_if_float32,
)
from ._record import EDGE_RELEASE, HELD_RELEASE, Record, in_metres
from ._result import (
    FitResult,
    _assess,
    _information,
    _result,
    _robust_scale,
    _values_of,
    shared_test,
)
from ._solve import _job_arrays, _profiles, _rss, _Shape, _solve
from ._space import FORWARDS, Space, series_space

__all__ = ["FitResult", "fit", "fit_batch", "LOSSES", "OPTIMIZERS", "RESIDUALS"]

LOSSES = ("l2", "huber", "cauchy")
RESIDUALS = ("turning-points", "series")
OPTIMIZERS = ("lm", "adam")
_ROBUST_PASSES = 10

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
    free = name_list(free)
    if not free:
        raise ValueError(
            "give at least one parameter to fit (--fit NAME[,NAME...]): with every "
            "parameter fixed there is nothing to identify"
        )
    for name in free:
        if name not in space.names:
            raise ValueError(
                f"unknown parameter {name!r} for the {space.name} model "
                f"(parameters: {', '.join(space.names)})"
            )
    for name in given:
        if name == "angle_unit" and name not in space.names:
            raise ValueError(
                f"--angle-unit applies only to models with an angle_unit parameter "
                f"(the {space.name} model has none)"
            )
        if name not in space.names:
            raise ValueError(
                f"unknown parameter {name!r} for the {space.name} model "
                f"(parameters: {', '.join(space.names)})"
            )
    if len(set(free)) != len(free):
        raise ValueError(f"a parameter is listed twice in {free}")
    for name in shared:
        if name not in free:
            raise ValueError(
                f"--shared {name}: only fitted parameters can be shared (fitted: {', '.join(free)})"
            )
    for name, (lo, hi) in bounds.items():
        if name not in space.names:
            raise ValueError(
                f"--bounds: unknown parameter {name!r} for the {space.name} model "
                f"(parameters: {', '.join(space.names)})"
            )
        if (
            not (isinstance(lo, (int, float)) and isinstance(hi, (int, float)))
            or not lo < hi
            or math.isnan(lo)
            or math.isnan(hi)
        ):
            raise ValueError(f"--bounds {name}: need LO < HI (got {lo}:{hi})")
        plo, phi = _physical_range(space, name)
        if max(lo, plo) >= min(hi, phi):
            raise ValueError(
                f"--bounds {name}={lo}:{hi} leaves nothing of its physical range "
                f"[{plo}, {phi}] [{space.unit(name)}]"
            )
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
                raise ValueError(
                    f"--set {name}={value} is outside --bounds {name}={lo}:{hi} [{unit}]"
                )
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
    ulo, uhi = bounds.get(name, (-math.inf, math.inf))
    lo, hi = max(plo, ulo), min(phi, uhi)
    return transform_for(lo, hi), name in bounds and ulo >= plo, name in bounds and uhi <= phi


class MissingParameters(ValueError):
    """A model's parameter that is neither fitted, given nor defaulted (the command line adds
    which models need fewer)."""


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
            raise MissingParameters(
                f"the {space.name} model needs {nm}: give {nm} with --set {nm}=VALUE or fit it"
            )
        raise MissingParameters(
            f"the {space.name} model needs {', '.join(missing)}: give them with "
            f"--set NAME=VALUE or fit them"
        )
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
    tw: list = None  # per record: relative precision of each time (1: the noise scale `st`)
    turning: list = None  # series fits: the turning-point records the samples belong to


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


def _make_job(index, prob, space, label, free, hold, bounds, headline, fixed=None, start=None):
    """A job of problem `index`; `fixed` and `start` (per record dicts) default to the
    parameters' given or default values and the starting guess from the decrement estimate."""
    R = len(prob.records)
    fixed = fixed or [
        _fixed_values(space, rec, free, {k: v for k, v in g.items() if k in space.names}, hold)
        for rec, g in zip(prob.records, prob.givens)
    ]
    start = start or _starts(prob, space, free, fixed)
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
    job = _Job(
        index,
        space,
        label,
        tuple(free),
        dict(hold),
        slots,
        transforms,
        ulo,
        uhi,
        fixed,
        start,
        headline,
    )
    q = len(slots)
    job.code = np.array([t.code for t in transforms])
    job.held = np.zeros(q)
    job.bound_hit = np.zeros(q, dtype=bool)
    job.scale = np.array(
        [
            _scale(slots[s][0], t, _slot_start(job, s), prob.records)
            for s, t in enumerate(transforms)
        ]
    )
    job.p = _coordinates(job, [dict(s) for s in start])
    return job


def _starts(prob, space, free, fixed) -> list:
    """Per record the starting value of every parameter: fixed, given, else the decrement
    estimate's guess, else the physical default."""
    out = []
    for rec, g, dec, fx in zip(prob.records, prob.givens, prob.decs, fixed):
        given = {**fx, **{k: v for k, v in g.items() if k in space.names}}
        guess = starting_guess(space, rec, given, dec)
        defaults = {
            n: space.default(n, rec) for n in free if n in space.defaults and n not in guess
        }
        st = {**{n: v for n, v in defaults.items() if v is not None}, **guess, **fx}
        for name in free:
            if name not in st:
                raise ValueError(f"no starting value for {name}: give one with --set {name}=VALUE")
        out.append(st)
    return out


def _slot_start(job, s):
    name, r = job.slots[s]
    if r is not None:
        return float(job.start[r][name])
    return float(np.mean([st[name] for st in job.start]))


def _scale(name, t: Transform, start: float, records) -> float:
    """The scale of a slot's transform: its starting distance from its bound (1 for an interval;
    the records' largest amplitude for `offset`, that over their longest duration for `drift`,
    at least 1 for other real parameters)."""
    if t.code == INTERVAL:
        return 1.0
    if t.code == REAL:
        if name not in ("offset", "drift"):
            return max(abs(start), 1.0)
        amplitude = max(float(np.max(np.concatenate([rec.amplitudes for rec in records]))), 1e-300)
        if name == "offset":
            return amplitude
        durations = [float(np.ptp(rec.times)) for rec in records if rec.times is not None]
        return amplitude / max(max(durations, default=1.0), 1e-300)
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


def _bucket(n: int, step: int = 8) -> int:
    """Round a length up to a multiple of `step`, so records of similar length share a
    compilation."""
    return max(step, -(-n // step) * step)


# -- weights -----------------------------------------------------------------------------------
_TUNING = {"huber": 1.345, "cauchy": 2.385}  #: 95 % efficiency constants of the robust losses


def _psi_weight(loss, u):
    """IRLS weight `psi(u)/u` of a robust loss."""
    if loss == "l2":
        return np.ones_like(u)
    c = _TUNING[loss]
    if loss == "huber":
        return np.minimum(1.0, c / np.maximum(np.abs(u), 1e-300))
    return 1.0 / (1.0 + (u / c) ** 2)


def _time_precision(space, rec, N) -> np.ndarray:
    """Relative precision of each turning point's time (padded to `N`): 1, or the point's
    amplitude over the record's largest, at least 0.02, for a record extracted from a raw
    signal or with `space.time_noise == "amplitude"` (the vertex of an extremum of amplitude
    `a` located in noisy samples is timed to about `noise / (a omega^2)`). Measured on 50
    synthetic signals of the linear oscillator (`test_fits_coverage`): with equal weights the
    times of the small swings dominated, omega's 95 % interval held the truth in 45 of 50
    fits (standardised errors' sd 1.25); weighted by amplitude, 48 (sd 0.82)."""
    out = np.ones(N)
    if space.time_noise == "amplitude" or rec.signal is not None:
        a = np.asarray(rec.amplitudes, dtype=float)
        out[: a.size] = np.maximum(a / max(float(np.max(a)), 1e-300), 0.02)
    return out


def _init_weights(prob, N, space):
    prob.tw = [_time_precision(space, rec, N) for rec in prob.records]
    prob.sx = [max(rec.noise or 0.0, 1e-3 * float(np.max(rec.amplitudes))) for rec in prob.records]
    prob.st = [
        1e-3 * float(np.median(np.diff(rec.times))) if rec.times is not None else 1.0
        for rec in prob.records
    ]
    prob.robust_x = [np.ones(N) for _ in prob.records]
    prob.robust_t = [np.ones(N) for _ in prob.records]
    _set_weights(prob, N)


def _timed(prob, rec) -> bool:
    """Whether the record's times are data (turning-point records with times; the sample times
    of a series fit are not)."""
    return rec.times is not None and prob.turning is None


def _set_weights(prob, N):
    prob.wx, prob.wt = [], []
    for r, rec in enumerate(prob.records):
        m = len(rec)
        on = np.zeros(N)
        on[:m] = 1.0
        onx, ont = on.copy(), on.copy()
        release = rec.meta.get("release") if rec.k[0] == 0 else None
        if release == EDGE_RELEASE:
            onx[0] = 0.0  # a release at the signal's edge: its position and time are no
            ont[0] = 0.0  # measurements (located from one side)
        elif release == HELD_RELEASE:
            ont[0] = 0.0  # its time is extrapolated (its position is the hold's level)
        prob.wx.append(onx * np.sqrt(prob.robust_x[r]) / prob.sx[r])
        if not _timed(prob, rec):
            prob.wt.append(np.zeros(N))
        else:
            prob.wt.append(ont * np.sqrt(prob.robust_t[r]) * prob.tw[r] / prob.st[r])


def _leverages(job, prob, N) -> np.ndarray:
    """The diagonal of the hat matrix of `job`'s weighted residuals, `(R, 2, N)`: the share of
    each residual that the fit absorbed, over the slots the solver moved and each timed
    record's clock shift (`fits._solve._align_clocks`, already projected off `J`)."""
    R = len(prob.records)
    J = np.asarray(job.out["J"])[:, : len(job.slots)][:, job.code != HELD]
    h = np.zeros(R * 2 * N)
    if J.shape[1] and np.all(np.isfinite(J)):
        u, sv, _ = np.linalg.svd(J, full_matrices=False)
        h = np.sum(u[:, sv > 1e-8 * sv[0]] ** 2, axis=1) if sv[0] > 0 else h
    h = h.reshape(R, 2, N)
    for r, w in enumerate(prob.wt):
        if np.any(w > 0):
            h[r, 1] += w**2 / np.sum(w**2)
    return h


def _block_scale(res, lev, floor, previous):
    """A block's noise scale from its residuals `res` and their leverages `lev`: the robust
    scale (`_robust_scale`) times `sqrt(n / (n - sum(lev)))`, the residuals' share of the noise
    that the fit did not absorb; `previous` where less than one residual degree of freedom
    remains (the residuals then say nothing about the noise)."""
    dof = res.size - float(np.sum(lev))
    if dof < 1.0:
        return previous
    return max(_robust_scale(res, 0.0) * math.sqrt(res.size / dof), floor)


def _reweight(prob, job, loss, N):
    """Re-estimate each record's noise scales (and the robust weights) from `job`'s residuals.

    A block's residuals are smaller than its noise by the degrees of freedom the fit took from
    it (`_block_scale`): a record of 6 turning points fits its 5 positions with 4 parameters,
    and their scale taken as the noise's weighted them 40-400 times too heavily against the
    times, the intervals of `zeta` and `xF` then 10-20 times too narrow."""
    r_all = job.out["r"].reshape(len(prob.records), 2, N)
    lev = _leverages(job, prob, N)
    for i, rec in enumerate(prob.records):
        m = len(rec)
        wx, wt = prob.wx[i][:m], prob.wt[i][:m]
        rx = r_all[i, 0, :m] / np.where(wx > 0, wx, 1.0)
        amp = float(np.max(rec.amplitudes))
        prob.sx[i] = _block_scale(rx[wx > 0], lev[i, 0, :m][wx > 0], 1e-6 * amp, prob.sx[i])
        if _timed(prob, rec):
            rt = r_all[i, 1, :m] / np.where(wt > 0, wt, 1.0) * prob.tw[i][:m]  # in units of st
            prob.st[i] = _block_scale(rt[wt > 0], lev[i, 1, :m][wt > 0], 1e-9, prob.st[i])
        if loss != "l2":  # (the loss's scale is the residuals' own, as its tuning assumes)
            sx = _robust_scale(rx[wx > 0], 1e-6 * amp)
            prob.robust_x[i][:m] = np.nan_to_num(_psi_weight(loss, rx / sx), nan=0.0)
            if _timed(prob, rec):
                st = _robust_scale(rt[wt > 0], 1e-9)
                prob.robust_t[i][:m] = np.nan_to_num(_psi_weight(loss, rt / st), nan=0.0)
    _set_weights(prob, N)


def _fit_jobs(jobs, problems, shape, optimizer=None):
    """Solve `jobs` (one round) grouped by space (with the fit's optimizer, or `optimizer`);
    a slot that runs into a bound is held there and the job solved again."""
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
            for job, out in zip(group, _solve(space, items, shape, optimizer)):
                q = len(job.slots)
                job.out = out
                job.p = out["p"][:q]
                job.iterations += out["steps"]
                job.rss = _rss(out)
                near = 1e-5 if out["ok"] else 1e-4  # (value - bound) / scale
                hit, value = at_bound(
                    job.code,
                    [t.lo for t in job.transforms],
                    [t.hi for t in job.transforms],
                    job.scale,
                    job.p,
                    near,
                )
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


def _start_from(job, sub):
    """Start `job` from the solution of its nested sub-model `sub`."""
    job.p = _coordinates(job, _values_of(sub))


def _free_where_moved(job, other) -> set:
    """Free again the slots of `job` held at a bound that `other` (started from, or taken)
    moved; returns the slots `other` moved."""
    moved = {slot for i, slot in enumerate(other.slots) if other.code[i] != HELD}
    for s, slot in enumerate(job.slots):
        if slot in moved and job.bound_hit[s]:
            job.code[s], job.bound_hit[s] = job.transforms[s].code, False
    return moved


def _adopt(job, sub, problems, shape):
    """`job` ended worse than its nested sub-model: take the sub-model's solution (the slots it
    holds held at its values, the slots it moved free again at theirs) and evaluate it. (Until
    2026-11-28 a slot `job` had held at a bound stayed held there: a joint oscillator fit
    whose zeta and xF had run into 0 took the viscous fit's values but kept zeta at 0, and
    was reported with 3 times the viscous fit's residual sum of squares.)"""
    vals = _values_of(sub)
    moved = _free_where_moved(job, sub)
    for s, (name, r) in enumerate(job.slots):
        t = job.transforms[s]
        if (name, r) not in moved:
            rr = 0 if r is None else r
            job.code[s] = HELD
            job.held[s] = vals[rr][name]
            job.bound_hit[s] = job.held[s] in (t.lo, t.hi)
    job.p = _coordinates(job, vals)
    out = _solve(job.space, [_job_arrays(job, problems[job.problem], shape)], shape)[0]
    job.out, job.p, job.rss = out, out["p"][: len(job.slots)], _rss(out)
    job.iterations += out["steps"]


_HYPOTHESES = (0, 1, 2, 3)  #: amplitude-only records: fits assuming the last j swings did not cross


def _best_nested(job, jobs):
    """The solved sub-model of `job` among `jobs` with the least RSS, or `None`."""
    nested = [a for a in jobs if a.out is not None and _nested_in(a, job)]
    return min(nested, key=lambda a: a.rss) if nested else None


def _never_worse(job, sub, problems, shape):
    """`job` takes the solution of its nested sub-model `sub` where it ended worse."""
    if sub is not None and not job.rss <= sub.rss * (1 + 1e-9):
        _adopt(job, sub, problems, shape)


def _take(job, other):
    """`job` takes the solution of `other` (a twin solved beside it)."""
    for name in ("code", "held", "p", "bound_hit", "out", "rss"):
        setattr(job, name, getattr(other, name))


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
                rec = dataclasses.replace(
                    rec, positions=rec.centre + sg * rec.amplitudes, sides_known=True
                )
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
            best = subs[id(job)] = _best_nested(job, jobs)
            mine = []
            if first_pass and best is not None:
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
                _take(job, best)
                if best.signs is not None:
                    again.append(job)  # a signed-hypothesis optimum: refit the amplitudes
            job.iterations += sum(t.iterations for t in mine)
        _fit_jobs(again, problems, shape)
        for job in round_jobs:
            _never_worse(job, subs[id(job)], problems, shape)
    if first_pass:
        _restart_from_larger(jobs, problems, shape)


def _restart_from_larger(jobs, problems, shape):
    """A sub-model that ended worse than a larger model it is nested in (stuck in another
    basin) is solved again from that model's optimum, its own held parameters at their values
    (the larger model's extra laws removed), and keeps the better; the larger models are then
    checked again against their sub-models (never reported worse)."""
    twins = {}
    for job in jobs:
        larger = [b for b in jobs if b.out is not None and _nested_in(job, b) and b.rss < job.rss]
        if larger:
            twin = _twin(job)
            best = min(larger, key=lambda b: b.rss)
            _free_where_moved(twin, best)  # (a slot held at a bound in the other basin)
            twin.p = _coordinates(twin, _values_of(best))
            twins[id(job)] = twin
    if not twins:
        return
    _fit_jobs(list(twins.values()), problems, shape)
    for job in jobs:
        twin = twins.get(id(job))
        if twin is not None:
            job.iterations += twin.iterations
            if twin.rss < job.rss:
                _take(job, twin)
    for job in sorted(jobs, key=lambda j: len(j.slots)):
        _never_worse(job, _best_nested(job, jobs), problems, shape)


# -- the driver --------------------------------------------------------------------------------
def _extracted_for(space, rec: Record, given: dict) -> Record:
    """`rec`, or where it was extracted from a raw signal and `space` reads the signal as an
    angle (its `angle_unit`) but the extraction did not, the same signal extracted again with
    that unit (the dry-friction level from a pendulum's decrements, `fits._extract._dry_level`)."""
    if "angle_unit" not in space.names or rec.signal is None or "min_amplitude" not in rec.meta:
        return rec
    unit = float(given.get("angle_unit", space.default("angle_unit", rec)))
    if rec.meta["angle_unit"] == unit:
        return rec
    return extract_turning_points(
        rec.signal,
        hysteresis=rec.meta["hysteresis"],
        min_amplitude=rec.meta["min_amplitude"],
        angle_unit=unit,
        decay=rec.meta.get("decays", {}).get("index"),
    )


def _decrement_centre(space, rec: Record, free, given: dict) -> float:
    """The zero that the decrement method (the quick look and the fit's start) measures the
    amplitudes from: none for a model without an offset; the offset given; for a table of
    turning points whose offset is fitted, the median of the local centres of its successive
    turning points (a table's centre is 0: a table of a sensor's readings about 2, amplitude
    10, read r = 0.60 per half-swing and zeta = 0.16 beside the fit's 0.0099, until
    2026-11-28); else the record's centre (the offset's default: a raw signal's estimate)."""
    if "offset" not in space.names:
        return 0.0
    if "offset" in given:
        return float(given["offset"])
    if "offset" in free and rec.signal is None and rec.sides_known:
        k = np.asarray(rec.k)
        successive = (np.diff(k)[:-1] == 1) & (np.diff(k)[1:] == 1)
        if np.count_nonzero(successive) >= 3:
            centres = local_centres(np.asarray(rec.positions, dtype=float))
            return float(np.median(centres[successive]))
    return rec.centre


def _problem(space, records, givens, free, shared):
    recs = []
    for rec, given in zip(records, givens):
        if not isinstance(rec, Record):
            raise ValueError("records must be fits.Record objects (see fits.read_record)")
        rec = _extracted_for(space, rec, given)
        # (the SI models' friction from positions in mm would be 1000 times too large)
        recs.append(in_metres(rec, space.name) if space.unit("a0") == "m" else rec)
    for rec, given in zip(recs, givens):
        _fixed_values(space, rec, free, given)  # a parameter without a value: its name first
    decs = []
    for rec, given in zip(recs, givens):
        per_record = len(free) if len(recs) == 1 else len(free) - len(shared)
        if len(rec) <= per_record:
            raise ValueError(
                f"{rec.source or 'record'}: {len(rec)} turning points are too few "
                f"for {per_record} free parameters (need at least "
                f"{per_record + 1}): fit fewer (free in Python, --fit on the command line)"
            )
        for name in ("omega", "drift"):
            if name in free and rec.times is None:
                raise ValueError(
                    f"{name} can only be fitted from a record with times: leave it out of the "
                    f"fitted parameters (free in Python, --fit on the command line)"
                )
        decs.append(decrement(rec, _decrement_centre(space, rec, free, given)))
    return _Problem(recs, [dict(g) for g in givens], tuple(free), tuple(shared), decs)


def _shape(jobs, problems, settings, n_model) -> _Shape:
    """The compiled shape of a set of jobs: points per record, slots, turning points
    predicted, and jobs per solve (the most that one round solves for one space, counting the
    extra starts of the first pass, see `_fit_all`)."""
    step = 8 if problems[0].turning is None else 512  # series: thousands of samples
    N = _bucket(max(len(rec) for prob in problems for rec in prob.records), step)
    q = max(len(j.slots) for j in jobs)
    per_round = {}
    for j in jobs:
        amp_only = not all(rec.sides_known for rec in problems[j.problem].records)
        starts = 1 + any(_nested_in(a, j) for a in jobs) + amp_only * len(_HYPOTHESES)
        per_round[(len(j.slots), j.space)] = per_round.get((len(j.slots), j.space), 0) + starts
    # a record's slots: the shared ones and its own (`fits._solve._record_slots`)
    qr = max(
        sum(1 for _, r in j.slots if r is None or r == i)
        for j in jobs
        for i in range(len(problems[j.problem].records))
    )
    return _Shape(N, q, max(_bucket(n_model), 1), max(per_round.values()), settings, qr)


def _pass_count(problems, settings) -> int:
    """Passes of `_passes`: one, once more with times, `_ROBUST_PASSES` more for a robust loss."""
    has_times = any(_timed(prob, rec) for prob in problems for rec in prob.records)
    return 1 + has_times + (_ROBUST_PASSES if settings["loss"] != "l2" else 0)


def _passes(jobs, problems, shape, settings):
    """Every job solved in rounds (`_fit_all`), the noise scales (and robust weights) of each
    problem re-estimated from its headline fit between passes: once more with times (the
    scales of positions and times set their relative weights), ten times for a robust loss."""
    for i, prob in enumerate(problems):
        head = next(j for j in jobs if j.problem == i and j.headline)
        _init_weights(prob, shape.N, head.space)
    passes = _pass_count(problems, settings)
    for it in range(passes):
        _fit_all(jobs, problems, shape, first_pass=it == 0)
        if it + 1 < passes:
            for i, prob in enumerate(problems):
                _reweight(prob, _lead(jobs, i, prob, shape.N), settings["loss"], shape.N)


def _lead(jobs, i, prob, N):
    """The job of problem `i` whose residuals estimate its noise scales: the headline, or
    where the space selects among law sets that are not nested in it (the pendulum's sine and
    linear laws), the variant preferred by BIC (a misfitting law's residuals would weigh the
    positions against the times by its misfit)."""
    mine = [j for j in jobs if j.problem == i]
    head = next(j for j in mine if j.headline)
    if head.space.select and len(mine) > 1:
        return min(mine, key=lambda j: _information(j, prob, N)["bic"])
    return head


_SERIES_MARGIN = 8  #: turning points the series model computes past the record's last one


def _samples(rec: Record) -> Record:
    """The raw samples of an extracted record from its release to its last turning point: the
    data of a fit on the whole time series (`k` numbers the samples)."""
    t, y = sample_window(rec)  # (a record without a signal is refused by `_settings`)
    meta = {k: v for k, v in rec.meta.items() if k != "release"}  # its first row is a sample
    return dataclasses.replace(rec, k=np.arange(t.size), positions=y, times=t, meta=meta)


def _series_stage(problems, jobs, bounds, settings):
    """The fits on the whole time series: each turning-point job refitted on its records'
    samples (its space's `series_space`, with the release's time shift `t0` free per record),
    started from the turning-point solution; the same rounds, nested starts and passes."""
    sprobs = [
        _Problem(
            [_samples(rec) for rec in prob.records],
            prob.givens,
            prob.free + ("t0",),
            prob.shared,
            prob.decs,
            turning=prob.records,
        )
        for prob in problems
    ]
    sjobs = []
    for job in jobs:
        space = series_space(job.space)
        start = [dict(v, t0=0.0) for v in _values_of(job)]
        b = {k: v for k, v in bounds.items() if k in space.names}
        sjobs.append(
            _make_job(
                job.problem,
                sprobs[job.problem],
                space,
                job.label,
                job.free + ("t0",),
                job.hold,
                b,
                job.headline,
                fixed=job.fixed,
                start=start,
            )
        )
    n_model = max(int(rec.k[-1]) for prob in problems for rec in prob.records) + _SERIES_MARGIN
    shape = _shape(sjobs, sprobs, settings, n_model)
    _passes(sjobs, sprobs, shape, settings)
    return sprobs, sjobs, shape


def _alone(prob, lead, bounds, shape):
    """Each record of a joint problem fitted alone: `lead`'s model (its law set, fixed and
    held values) with every parameter free for that record, started from the joint solution
    and solved by Levenberg-Marquardt (exact minima, as the profiles). Each is a problem of
    one record (its forward model alone in each solve), all of them one compiled solve of the
    joint records' length. (Until 2026-11-29 each kept the joint problem's records, the
    others' weights 0, in the joint fit's compiled solve: every solve of a record alone ran
    every record's forward model.) The records keep the joint fit's robust weights and times'
    precisions; their positions' and times' noise scales are re-estimated from their own fits
    (between two solves): the scales against which `fits._result.shared_test` measures both
    fits. Returns per record its problem and job, and their shape."""
    probs, jobs = [], []
    start = _values_of(lead)
    bounds = {k: v for k, v in bounds.items() if k in lead.space.names}
    for i, rec in enumerate(prob.records):
        one = _Problem(
            [rec],
            [prob.givens[i]],
            prob.free,
            (),
            [prob.decs[i]],
            turning=None if prob.turning is None else [prob.turning[i]],
        )
        one.robust_x, one.robust_t = [np.copy(prob.robust_x[i])], [np.copy(prob.robust_t[i])]
        one.sx, one.st, one.tw = [prob.sx[i]], [prob.st[i]], [prob.tw[i]]
        _set_weights(one, shape.N)
        probs.append(one)
        jobs.append(
            _make_job(
                i,
                one,
                lead.space,
                lead.label,
                lead.free,
                lead.hold,
                bounds,
                True,
                fixed=[dict(lead.fixed[i])],
                start=[dict(start[i])],
            )
        )
    q = len(jobs[0].slots)
    shape = dataclasses.replace(shape, q=q, qr=q, B=min(len(jobs), shape.B))
    _fit_jobs(jobs, probs, shape, optimizer="lm")
    for one, job in zip(probs, jobs):
        _reweight(one, job, "l2", shape.N)  # (the scales alone: the robust weights kept)
    _fit_jobs(jobs, probs, shape, optimizer="lm")
    return probs, jobs, shape


def _check_shared(assessed, bounds, shape) -> list:
    """Per problem (its lead job `assessed`), the test of its shared parameters against each
    record fitted alone (`fits._result.shared_test`), or None (a single record, nothing
    shared)."""
    out = []
    for a in assessed:
        if len(a.prob.records) < 2 or not a.prob.shared:
            out.append(None)
            continue
        probs, alone, one = _alone(a.prob, a.job, bounds, shape)
        out.append(shared_test(a, [_assess(j, p, one) for j, p in zip(alone, probs)], shape.N))
    return out


#: seconds per Adam step of the smoothed forward model, per record of a job and turning point
#: predicted (measured on 2 shared cores, 2026-11-28, with a reverse pass for the gradient:
#: 2 jobs of 2 records of 24 turning points, 0.47-0.50 s for 20 steps, warm; the forward-mode
#: Jacobian that replaced it took as long a step within the loaded machine's noise)
_SMOOTH_ADAM_STEP_S = 2.5e-4
#: a fit whose estimated solving time exceeds this [s] is refused before it starts
MAX_ESTIMATED_S = 600.0


def _refuse_slow_adam(jobs, problems, shape, settings) -> None:
    """Refuse `forward="smooth"` with `optimizer="adam"` where its estimated time exceeds
    `MAX_ESTIMATED_S`: every Adam step solves the smoothed ODE and its Jacobian for every job
    and record of a solve, and a solve takes `adam_steps` (3000) of them, in every round of
    sub-models and every pass (the times' weights, the robust loss's ten reweightings).
    Measured before this check (2026-11-28): two records of 25 turning points, `--forward
    smooth --optimizer adam --loss huber`, past 1800 s of its first solve of 24."""
    if settings["forward"] != "smooth" or settings["optimizer"] != "adam":
        return
    passes = _pass_count(problems, settings)
    solves = 0
    for sp in {j.space for j in jobs}:
        for q in {len(j.slots) for j in jobs if j.space == sp}:
            n = sum(1 for j in jobs if j.space == sp and len(j.slots) == q)
            solves += -(-n // shape.B)
    records = max(len(prob.records) for prob in problems)
    step = _SMOOTH_ADAM_STEP_S * shape.B * records * shape.n_model
    total = settings["adam_steps"] * solves * passes * step
    if total <= MAX_ESTIMATED_S:
        return
    raise ValueError(
        f"forward 'smooth' with optimizer 'adam' would take about {total / 60:.0f} minutes "
        f"(more than {MAX_ESTIMATED_S / 60:.0f}): {settings['adam_steps']} Adam steps "
        f"(--adam-steps) in each of {solves * passes} solves ({solves} per pass of sub-models, "
        f"{passes} passes{' for the robust loss' if passes > 2 else ''}), each step a "
        f"smoothed ODE solve and its Jacobian, about {step:.2g} s for {shape.B} jobs of {records} "
        f"record(s) of {shape.n_model} turning points. Use --optimizer lm (tens of steps), "
        "--forward exact (Adam's steps in about a millisecond), or fewer --adam-steps"
    )


def _run(space, problems, free, bounds, settings, compare, outlier_sigma):
    jobs = []
    for i, prob in enumerate(problems):
        jobs.extend(_jobs_for(i, prob, space, bounds, compare))
    n_model = max(int(rec.k[-1]) for prob in problems for rec in prob.records)
    shape = _shape(jobs, problems, settings, n_model)
    _refuse_slow_adam(jobs, problems, shape, settings)
    _passes(jobs, problems, shape, settings)
    if settings["residuals"] == "series":
        problems, jobs, shape = _series_stage(problems, jobs, bounds, settings)
    assessed = [
        _assess(_lead(jobs, i, prob, shape.N), prob, shape) for i, prob in enumerate(problems)
    ]
    tests = _check_shared(assessed, bounds, shape)
    ends = _profiles([a.profile(settings) for a in assessed], shape)
    results = [
        _result(a, jobs, shape, outlier_sigma, e, t) for a, e, t in zip(assessed, ends, tests)
    ]
    for res in results:
        for w in res.warnings:
            warnings.warn(w, stacklevel=4)
    return results


def _distinct(records) -> None:
    """Refuse a record given twice to a joint fit (it would count its evidence twice and
    shrink the shared parameters' uncertainties by about sqrt(2))."""
    for j, b in enumerate(records):
        for i, a in enumerate(records[:j]):
            same = a is b or (
                isinstance(a, Record)
                and isinstance(b, Record)
                and np.array_equal(a.k, b.k)
                and np.array_equal(a.positions, b.positions)
                and (a.times is None) == (b.times is None)
                and (a.times is None or np.array_equal(a.times, b.times))
            )
            if same:
                name = getattr(b, "source", "") or f"record {j}"
                raise ValueError(
                    f"{name} is given twice (records {i} and {j}): a joint fit would count "
                    "its evidence twice"
                )


def _parse_given(given, n):
    if given is None or isinstance(given, dict):
        return [dict(given or {})] * n
    if isinstance(given, str) or not all(isinstance(g, dict) for g in given):
        raise ValueError(
            "given: a dict of parameter values, or a list of such dicts, one per record "
            f"(got {given!r})"
        )
    givens = [dict(g) for g in given]
    if len(givens) != n:
        raise ValueError(f"given: {len(givens)} dicts for {n} records")
    return givens


def _settings(
    space,
    free,
    shared,
    givens,
    bounds,
    forward,
    loss,
    optimizer,
    max_steps,
    adam_steps,
    intervals,
    residuals,
    records,
    outlier_sigma,
):
    for name, value in (("max_steps", max_steps), ("adam_steps", adam_steps)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
            raise ValueError(f"{name} must be an integer >= 1 (got {value!r})")
    if not (isinstance(outlier_sigma, numbers.Real) and math.isfinite(outlier_sigma)) or not (
        outlier_sigma > 0
    ):
        raise ValueError(f"outlier_sigma must be a finite number > 0 (got {outlier_sigma!r})")
    for name, pair in (bounds or {}).items():
        if not (isinstance(pair, (tuple, list)) and len(pair) == 2):
            raise ValueError(f"bounds[{name!r}] must be a pair (lo, hi) (got {pair!r})")
    bounds = {k: (float(v[0]), float(v[1])) for k, v in (bounds or {}).items()}
    for g in givens:
        free = _check_inputs(space, free, shared, g, bounds, forward, loss, optimizer)
    if residuals not in RESIDUALS:
        raise ValueError(f"residuals must be one of {list(RESIDUALS)} (got {residuals!r})")
    if residuals == "series":
        if forward == "smooth":
            raise ValueError(
                "residuals 'series' needs the exact motion between turning points: "
                "forward 'exact' or 'energy' (got 'smooth')"
            )
        for rec in records:
            if isinstance(rec, Record) and rec.signal is None:
                raise ValueError(
                    f"{rec.source or 'record'}: residuals 'series' needs a raw signal "
                    "(vmj fit --series FILE; fits.read_record(path, series=True))"
                )
    return (
        free,
        bounds,
        {
            "forward": forward,
            "loss": loss,
            "optimizer": optimizer,
            "max_steps": max_steps,
            "adam_steps": adam_steps,
            "intervals": intervals,
            "residuals": residuals,
        },
    )


def fit_batch(
    records,
    model: str = "variable-mass",
    free=("FT", "mu"),
    given=None,
    *,
    bounds=None,
    forward: str = "exact",
    loss: str = "l2",
    optimizer: str = "lm",
    compare: bool = True,
    max_steps: int = 200,
    adam_steps: int = 3000,
    outlier_sigma: float = 5.0,
    intervals: bool = True,
    residuals: str = "turning-points",
    chunk_size: int | None = None,
    client=None,
    store=None,
    resume: bool = False,
    progress=None,
) -> list:
    """Fit the same model to many records independently, at once (one compiled solve for all:
    the records and sub-models one after another on a CPU, `jax.vmap`ped on an accelerator).

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
    free, bounds, settings = _settings(
        space,
        free,
        (),
        givens,
        bounds,
        forward,
        loss,
        optimizer,
        max_steps,
        adam_steps,
        intervals,
        residuals,
        records,
        outlier_sigma,
    )
    if chunk_size is not None or client is not None or store is not None:
        chunk = functools.partial(
            _fit_chunk,
            model=model,
            free=free,
            bounds=bounds,
            forward=forward,
            loss=loss,
            optimizer=optimizer,
            compare=compare,
            max_steps=max_steps,
            adam_steps=adam_steps,
            outlier_sigma=outlier_sigma,
            intervals=intervals,
            residuals=residuals,
        )
        return vmj.map_chunks(
            chunk,
            list(zip(records, givens)),
            chunk_size=chunk_size,
            client=client,
            store=store,
            resume=resume,
            progress=progress,
        )
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


def fit(
    record,
    model: str = "variable-mass",
    free=("FT", "mu"),
    given=None,
    *,
    shared=(),
    bounds=None,
    forward: str = "exact",
    loss: str = "l2",
    optimizer: str = "lm",
    compare: bool = True,
    max_steps: int = 200,
    adam_steps: int = 3000,
    outlier_sigma: float = 5.0,
    intervals: bool = True,
    residuals: str = "turning-points",
) -> FitResult:
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
    - `optimizer`: `"lm"` (Levenberg-Marquardt, optimistix) or `"adam"` (optax; `adam_steps`
      steps on the same weighted sum of squares in each pass, so a robust loss's
      reweighting reaches the same estimate).
    - `compare`: also fit the model's sub-models (`Space.variants`: Coulomb-only and
      viscous-only) and compare them by AIC/BIC.
    - `max_steps`: Levenberg-Marquardt step limit per pass.
    - `outlier_sigma`: residuals beyond this many robust standard deviations are flagged.
    - `intervals`: compute 95 % profile-likelihood intervals (else Wald intervals).
    - `residuals`: `"turning-points"` (default: the turning points' positions and times) or
      `"series"`: every sample of the raw signal between the release and the last turning
      point (records read with `series=True`), compared with the exact motion of the model
      between its turning points (`vmj.decay_trajectory`), with the release's time shift
      `t0` [s] fitted per record. The turning-point fit (every variant) runs first and starts
      the series fit; the comparison, diagnostics and intervals are those of the series fit.
      Use it where the turning points lose information (few swings, a noisy signal, a
      restoring law shaping the swings between them).

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
    _distinct(records)
    givens = _parse_given(given, len(records))
    shared = name_list(shared)
    if shared and len(records) < 2:
        raise ValueError("--shared needs several records")
    free, bounds, settings = _settings(
        space,
        free,
        shared,
        givens,
        bounds,
        forward,
        loss,
        optimizer,
        max_steps,
        adam_steps,
        intervals,
        residuals,
        records,
        outlier_sigma,
    )
    prob = _problem(space, records, givens, free, shared)
    return _run(space, [prob], free, bounds, settings, compare, outlier_sigma)[0]
