"""The result of a fit (`FitResult`, its JSON contract and its text report) and how a solved
job becomes one: statistics (AIC, BIC), the corrected covariance (`fits._stats`), the converged
rules, the profile-likelihood intervals, the residual diagnostics and the model comparison.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vmj.cli import jsonable

from ._params import HELD
from ._record import ROWS_AS_HALF_SWINGS, Record, value_name
from ._stats import RANK_RTOL, _chi2_sf, covariance, diagnostics, f_sf

__all__ = ["FitResult"]


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
    - `residuals_of`: what the residuals compare, `"turning-points"` or `"series"` (every
      sample of the raw signal, `fits.fit(..., residuals="series")`).
    - `residuals` (per point of the first record: `k`, `position`, `time`, `standardized`,
      `outlier`, NaN (JSON null) where a point is no datum: the position and time of a release
      at the signal's edge, the time of one from a hold; for a series fit per sample: `t` [s]
      from the release instead of `k` and `time`); `outliers` (the flagged `k`, or sample
      indices); `decrement` (the decrement-method estimate);
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
    residuals_of: str = "turning-points"

    def to_json(self) -> dict:
        """The command line's JSON object: `model`, `params`, `stderr`, `stderr_gn`,
        `intervals` (`{name: [lo, hi]}`), `correlation`, `converged`, `iterations`, `rms`,
        `diagnostics`, `model_comparison`, `residuals_of`, then `records` (joint fits), `clock` (raw signals)
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
            "residuals_of": self.residuals_of,
        }
        if self.records:
            out["records"] = [
                {k: v for k, v in r.items() if k != "residuals"} for r in self.records
            ]
        if self.clock is not None:
            out["clock"] = self.clock
        out["units"] = self.units
        return jsonable(out)

    def report(self) -> str:
        """The readable summary ([`fits.text_report`][])."""
        return text_report(self)


# -- the text report ---------------------------------------------------------------------------
def _fmt(v) -> str:
    try:
        v = float(v)
    except (TypeError, ValueError):
        return "nan"
    return "nan" if not np.isfinite(v) else f"{v:.6g}"


def _interval(lo, hi) -> str:
    """`[lo, hi]` with enough digits to tell the ends apart."""
    try:
        lo, hi = float(lo), float(hi)
    except (TypeError, ValueError):
        return "[nan, nan]"
    if not (np.isfinite(lo) and np.isfinite(hi)):  # (an open end: inf)
        return f"[{lo if np.isinf(lo) else _fmt(lo)}, {hi if np.isinf(hi) else _fmt(hi)}]"
    width, size = abs(hi - lo), max(abs(lo), abs(hi))
    digits = (
        6 if width <= 0 or size <= 0 else int(min(15, max(6, np.ceil(np.log10(size / width)) + 3)))
    )
    return f"[{lo:.{digits}g}, {hi:.{digits}g}]"


def _p(p: float) -> str:
    """A p-value; one that underflows is below the smallest double."""
    return "< 1e-300" if p == 0 else f"= {p:.2g}"


def _short(v, digits: int) -> str:
    return "nan" if v is None or not np.isfinite(v) else f"{v:.{digits}g}"


def _corr(v) -> str:
    return "nan" if v is None or not np.isfinite(v) else f"{v:+.3f}"


def _field(result, name, default=None):
    """A field of the result, `default` when this result does not carry it."""
    value = getattr(result, name, None)
    return default if value is None else value


def _unit(result, name: str) -> str:
    unit = _field(result, "units", {}).get(name)
    if unit and unit.startswith("signal"):
        unit = "signal units" + unit[len("signal") :]
    return f" [{unit}]" if unit and unit != "-" else ""


def _comparison_rows(comparison: dict) -> list:
    return [(k, v) for k, v in comparison.items() if isinstance(v, dict) and "aic" in v]


def _warnings(result) -> list:
    seen = []
    for w in list(_field(result, "warnings", [])) + list(
        _field(result, "diagnostics", {}).get("warnings", [])
    ):
        if w not in seen:
            seen.append(w)
    return seen


def outliers_at(result: FitResult) -> str:
    """Where the flagged outliers are: `"at k = [...]"` (turning points) or `"at samples
    [...]"` (a fit on the whole time series)."""
    where = "samples" if _field(result, "residuals_of") == "series" else "k ="
    return f"at {where} {result.outliers}"


def text_report(result: FitResult) -> str:
    """A readable summary of a [`fits.FitResult`][]: each fitted parameter with its unit, its
    standard error corrected for residual autocorrelation (`+-`), the Gauss-Newton standard
    error (`gn`) and the 95 % interval; correlations; convergence; residual RMS and
    diagnostics (lag-1 autocorrelation, runs test, effective sample size); the decrement
    method; the model comparison by AIC/BIC; per-record values of a joint fit; the sample
    clock of a raw signal; every warning."""
    label = _field(result, "label", "")
    records = _field(result, "records", [])
    what = f"{len(records)} records" if len(records) > 1 else f"{len(result.record)} turning points"
    lines = [
        f"model {result.model}"
        + (f" ({label})" if label else "")
        + f", forward {result.forward}, loss {result.loss}, optimizer {result.optimizer}, "
        + what
    ]
    intervals = _field(result, "intervals", {})
    stderr_gn = _field(result, "stderr_gn", {})
    for name, value in result.params.items():
        stderr = _fmt(result.stderr.get(name))
        # no standard error: on a bound or not identified (the warnings say which)
        spread = "(no standard error)" if stderr == "nan" else f"+- {stderr:<10}"
        line = f"  {name:>7} = {_fmt(value):>12} {spread}{_unit(result, name)}"
        gn = _fmt(stderr_gn.get(name))
        if gn != "nan":
            line += f"  (gn +- {gn})"
        if name in intervals and intervals[name] is not None:
            line += "  95 % " + _interval(*intervals[name])
        lines.append(line)
    names = list(result.params)
    pairs = [  # (a parameter without a standard error has no correlations)
        f"{a}/{b} {c}"
        for i, a in enumerate(names)
        for j, b in enumerate(names)
        if j > i and (c := _corr(result.correlation[i][j])) != "nan"
    ]
    if pairs:
        lines.append("  correlation: " + "; ".join(pairs))
    lines.append(
        f"  converged: {result.converged} after {result.iterations} iterations; "
        f"rms {_fmt(result.rms)}"
        + ("" if result.rms_time is None else f", time rms {_fmt(result.rms_time)} s")
    )
    diag = _field(result, "diagnostics", {})
    if diag:
        n_res = _field(result, "n_residuals")
        lines.append(
            f"  residuals: lag-1 autocorrelation {_short(diag.get('lag1'), 3)}, runs test "
            f"p = {_short(diag.get('runs_p'), 3)}, effective sample size "
            f"{_short(diag.get('n_eff'), 4)}" + ("" if not n_res else f" of {n_res}")
        )
    dec = result.decrement
    if dec:
        lines.append(
            f"  decrement method: r = {_fmt(dec.get('r'))} per half-swing, zeta = "
            f"{_fmt(dec.get('zeta'))}, xF = {_fmt(dec.get('xF'))} +- "
            f"{_fmt(dec.get('stderr_xF'))} (signal units)"
        )
    rows = _comparison_rows(result.model_comparison or {})
    aic, bic = _field(result, "aic"), _field(result, "bic")
    if not rows and aic is not None and np.isfinite(aic):
        lines.append(f"  AIC {aic:.2f}, BIC {bic:.2f}")
    if rows:
        lines.append("  model comparison (lower is better):")
        for k, c in rows:
            lines.append(
                f"    {k:>10}: AIC {c['aic']:10.2f}  BIC {c['bic']:10.2f}  "
                + ", ".join(f"{n}={_fmt(v)}" for n, v in c.get("params", {}).items())
            )
        best = [
            f"by {k[5:].upper()}: {v}"
            for k, v in result.model_comparison.items()
            if k.startswith("best_")
        ]
        if best:
            lines.append("    best " + ", ".join(best))
    if len(records) > 1:
        lines.append("  per record:")
        for i, item in enumerate(records):
            item = item if isinstance(item, dict) else {}
            src = item.get("source") or f"record {i}"
            values = item.get("params", {})
            err = item.get("stderr", {})
            ivs = item.get("intervals", {})
            lines.append(
                f"    {src}: "
                + ", ".join(
                    f"{n}={_fmt(v)} +- {_fmt(err.get(n))}"
                    + (" " + _interval(*ivs[n]) if ivs.get(n) is not None else "")
                    for n, v in values.items()
                )
            )
    test = diag.get("shared") if diag else None
    if test and not test.get("tested", True):
        lines.append(
            f"  shared ({', '.join(test['parameters'])}) not tested against each record alone: "
            f"{test['reason']}"
        )
    elif test:
        lines.append(
            f"  shared ({', '.join(test['parameters'])}) against each record alone: F = "
            f"{test['F']:.3g} on ({test['df'][0]}, {test['df'][1]}), p {_p(test['p'])}"
            + (" -- rejected by the data" if test["rejected"] else "")
        )
    clock = _field(result, "clock", None) or result.record.clock
    if clock:
        lines.append(
            "  clock: "
            + str(
                clock.get("message")
                or ", ".join(
                    f"{k} {v}" for k, v in clock.items() if not isinstance(v, (list, dict))
                )
            )
        )
    if result.outliers:
        lines.append(f"  outliers (|residual| > 5 robust sd) {outliers_at(result)}")
    lines += [f"  warning: {w}" for w in _warnings(result)]
    return "\n".join(lines)


#: a fit whose turning-point times miss the record's by more than this fraction of a
#: half-swing (rms) gets a warning: its period is wrong, whatever its positions say
TIME_OFF = 0.1
#: kept irregular stamps that scatter about a uniform clock by more than this fraction of a
#: half-swing (rms) get a warning naming the clock (`fits._clock._near_uniform`)
STAMPS_OFF = 0.02


# -- views of a solved job ---------------------------------------------------------------------
def _slot_names(job) -> list:
    return [nm if r is None else f"{nm}[{r}]" for nm, r in job.slots]


def _values_of(job) -> list:
    """Per record {name: value} at the job's last solution."""
    th = job.out["theta"]
    return [dict(zip(job.space.names, th[r].tolist())) for r in range(th.shape[0])]


def _robust_scale(r, floor):
    r = r[np.isfinite(r)]
    if r.size == 0:
        return floor
    return max(1.4826 * float(np.median(np.abs(r - np.median(r)))), floor)


# -- per-job statistics ------------------------------------------------------------------------
def _used(job, prob, N):
    """Indices of the residuals that count, the blocks (slices of them) in record order, and
    what each block holds ("the times of 80P.txt")."""
    idx, blocks, names, at = [], [], [], 0
    what = ("samples", "times") if prob.turning is not None else ("positions", "times")
    for r in range(len(prob.records)):
        for kind, w in ((0, prob.wx[r]), (1, prob.wt[r])):
            sel = np.nonzero(w > 0)[0] + r * 2 * N + kind * N
            if sel.size:
                idx.append(sel)
                blocks.append(slice(at, at + sel.size))
                names.append(f"the {what[kind]} of {record_name(prob.records[r], r)}")
                at += sel.size
    return np.concatenate(idx), blocks, names


def _clock_shifts(prob) -> int:
    """Nuisance parameters profiled out of the residuals: one clock shift per record with timed
    residuals (`fits._solve._align_clocks`)."""
    return sum(bool(np.any(w > 0)) for w in prob.wt)


def _information(job, prob, N):
    """AIC and BIC of a solved job: `-2 log L` of Gaussian residuals with one unknown variance
    per block (each record's positions, its times), each at its maximum-likelihood value
    `rss_b / n_b`, plus the penalty.

    One variance per block, not one for all: the weights that put positions and times on one
    scale are estimated from one fit's residuals (`_reweight`), and a model that explains the
    data worse than that fit (or better) sees blocks of unequal scale. With a pooled variance
    the larger block dominates the likelihood while `n` counts both: on a linear record
    weighted from a misfitting sine law, the times' scale was set by the misfit, the
    positions carried the whole RSS, and a law that moved the positions' RSS by what noise
    moves it by was chosen over the true law set (2 of 10 seeds)."""
    idx, blocks, _ = _used(job, prob, N)
    n = idx.size
    shifts = _clock_shifts(prob)
    # moved by the solver, and each timed record's clock shift: the residuals' degrees of freedom
    q = int(np.sum(job.code != HELD)) + shifts
    # the criteria count every free parameter of the model, also one that ended on a bound (a
    # law whose level went to 0 is still a law of the model: counting only the moved ones
    # would tie a model whose extra law vanished with its sub-model, and a tie or a 1e-9 lower
    # rss would then report the larger law set). The blocks' variances are parameters of every
    # model alike and left out; the clock shifts are counted (the same for every model).
    k = len(job.slots) + shifts
    rss = job.rss
    if math.isfinite(rss):
        r = np.asarray(job.out["r"])[idx]
        ll = sum(
            (b.stop - b.start) * math.log(max(float(r[b] @ r[b]), 1e-300) / (b.stop - b.start))
            for b in blocks
        )
    else:
        ll = math.inf
    return {
        "aic": ll + 2 * k,
        "bic": ll + k * math.log(n),
        "rss": rss,
        "n": n,
        "q": q,
        "nuisance": shifts,
    }


# -- results -----------------------------------------------------------------------------------
def _at_user_bound(job, s) -> bool:
    """Whether slot `s` is held at a bound the user set (`bounds=`, `--bounds`)."""
    t = job.transforms[s]
    return bool(
        (job.user_lo[s] and job.held[s] == t.lo) or (job.user_hi[s] and job.held[s] == t.hi)
    )


def _pooled_rms(per_record, kind: str) -> float | None:
    """RMS of the `kind` residuals ("position" or "time", in data units) of every record in
    `per_record`, leaving out those that are no datum (NaN: a release located from one side);
    None where no record has any. (A joint fit's figure is over all its records: it was NaN
    where a record's release was no datum, and its time RMS the first record's alone.)"""
    r = [p["residuals"][kind] for p in per_record if p["residuals"][kind] is not None]
    return float(np.sqrt(np.nanmean(np.concatenate(r) ** 2))) if r else None


@dataclass
class _Assessed:
    """A solved job's covariance and estimates, before its intervals (`_assess`)."""

    job: object
    prob: object
    names: list
    blocks: list  # slices of the used residuals `r`, one per block
    block_names: list
    r: np.ndarray  # the residuals that count
    J: np.ndarray  # their Jacobian, every slot's column (a held slot's too)
    info: dict  # `_information`
    active: np.ndarray  # the slots the solver moved
    inflation: float  # of the covariance, for correlated residuals (`fits._stats.covariance`)
    full_rank: bool
    vals: list  # `_values_of`
    est: np.ndarray
    se_c: np.ndarray
    se_gn: np.ndarray
    corr: np.ndarray

    @property
    def n_dof(self) -> int:
        return self.info["n"] - self.info["q"]

    def profile(self, settings):
        """The request of its profile-likelihood intervals (`fits._solve._profiles`), or None
        where they are not computed."""
        job = self.job
        # (a slot held at a bound gets its one-sided limit also where it is the only one: a
        # fit whose every slot ended held at the user's bounds had "no interval" until
        # 2026-11-28, where beside a moved slot it had its limit)
        wanted = self.active.any() or job.bound_hit.any()
        if not (wanted and job.out["ok"] and self.full_rank and settings["intervals"]):
            return None
        s2 = job.rss / max(self.n_dof, 1)
        return (job, self.prob, self.est, self._held_se(s2), self.inflation, s2)

    def _held_se(self, s2) -> np.ndarray:
        """The Gauss-Newton standard errors, and for a slot held at a bound the one it would
        have if freed alone (its Jacobian column's part orthogonal to the moved slots'): the
        scale of its profile's one-sided limit. (Without it the profile started a tenth of
        the slot's transform scale away, 1 for an interval: `xF` of a clean viscous decay
        bounded to 0:0.5 by the user got no limit, where bounded by its physical range, 0 and
        up, it got 4.4e-08.)"""
        se = self.se_gn.copy()
        J = self.J
        Ja = J[:, self.active]
        for s in np.flatnonzero(self.job.bound_hit & ~self.active):
            j = J[:, s]
            if Ja.shape[1]:
                j = j - Ja @ np.linalg.lstsq(Ja, j, rcond=None)[0]
            norm2 = float(j @ j)
            if norm2 > 0 and np.isfinite(norm2):
                se[s] = math.sqrt(s2 / norm2)
        return se


def _assess(job, prob, shape) -> _Assessed:
    """The covariance (corrected and Gauss-Newton) of a solved job over the slots it moved,
    its rank and its estimates."""
    N = shape.N
    q = len(job.slots)
    idx, blocks, block_names = _used(job, prob, N)
    J = job.out["J"][:, :q][idx]
    r = job.out["r"][idx]
    active = job.code != HELD
    info = _information(job, prob, N)
    # covariance over the slots the solver moved; held slots have none
    cov_c = np.full((q, q), np.nan)
    cov_gn = np.full((q, q), np.nan)
    inflation = 1.0
    full_rank = True
    if active.any():
        Ja = J[:, active]
        c_c, c_gn, inflation = covariance(Ja, r, blocks, info["nuisance"])
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
    return _Assessed(
        job=job,
        prob=prob,
        names=_slot_names(job),
        blocks=blocks,
        block_names=block_names,
        r=r,
        J=J,
        info=info,
        active=active,
        inflation=inflation,
        full_rank=full_rank,
        vals=vals,
        est=est,
        se_c=se_c,
        se_gn=se_gn,
        corr=corr,
    )


#: a joint fit whose shared parameters raise the residual sum of squares beyond what noise does
#: at this chance (`shared_test`) is rejected by the data (not converged)
SHARED_P = 1e-3


def shared_test(joint: _Assessed, alone: list, N: int) -> dict:
    """Whether the records of a joint fit (`joint`) share its shared parameters: the fit
    against each record fitted alone (`alone`, one `_Assessed` per record, in order: a problem
    of that record, its parameters its own; `fits._fit._alone`), the nested models compared
    by the extra sum of squares,

        F = ((RSS_joint - RSS_alone) / (q_alone - q_joint)) / (RSS_alone / (n - q_alone)),

    both sums in units of each record's own noise scales (those of its fit alone, so that a
    misfit does not widen its own yardstick: the joint fit's scales are estimated from its
    residuals), `q` the parameters moved and the clock shifts, divided by the largest
    inflation of the records' covariances for correlated residuals (as the profiles' deviance
    is) and referred to the F distribution. `p` below `SHARED_P` (1e-3): the joint model is
    rejected by the data. Returns the evidence (`diagnostics["shared"]` of the result): `F`,
    `df`, `inflation`, `p`, `rejected`, per record its values and standard errors alone and
    its joint residuals' RMS in units of its own noise scales (`scale`: about 1 where it
    shares the parameters), and per shared parameter the spread of the values alone (`spread`:
    `sum (v_i - mean)^2 / se_i^2` about their weighted mean, chi-square on the records less
    one); `message` where rejected.

    Where the test cannot be done, `tested` is False (True otherwise), `F`, `df`, `p` and
    `rejected` are absent and `reason` says why: a record's fit alone that did not converge
    (its solver's step limit, values that are not finite, or a Jacobian without full rank: its
    residual sum of squares is then no minimum, and F would measure the failure), or records
    whose fits alone leave no degree of freedom to test with (`q_alone - q_joint < 1`: sharing
    takes no parameter; `n - q_alone < 1`: each record's own parameters fit its data
    exactly)."""
    prob, job = joint.prob, joint.job
    R = len(prob.records)
    failed = [
        f"{record_name(prob.records[i], i)}: "
        + (
            "its solver did not converge (step limit or no progress)"
            if not a.job.out["ok"]
            else "its residuals are not finite"
            if not math.isfinite(a.job.rss)
            else "its Jacobian is rank-deficient (its parameters are not all determined by "
            "its data alone)"
        )
        for i, a in enumerate(alone)
        if not (a.job.out["ok"] and math.isfinite(a.job.rss) and a.full_rank)
    ]
    if failed:
        return _untested(
            prob,
            "a record fitted alone failed (" + "; ".join(failed) + "): the extra sum of "
            "squares would measure that failure, not whether the records share them",
        )
    r = np.asarray(job.out["r"], dtype=float).reshape(R, 2, N)
    rss_joint, rss_alone, q_alone, records = 0.0, 0.0, 0, []
    for i, a in enumerate(alone):
        own = a.prob
        # the joint residuals in units of the record's own noise scales (the weights differ
        # from the joint fit's by these factors alone: the robust weights are the same)
        rx = r[i, 0] * prob.sx[i] / own.sx[0]
        rt = r[i, 1] * prob.st[i] / own.st[0]
        rss_joint += float(rx @ rx + rt @ rt)
        rss_alone += a.job.rss
        q_alone += a.info["q"]
        used_x, used_t = own.wx[0] > 0, own.wt[0] > 0
        shared_slots = [s for s, (name, _) in enumerate(a.job.slots) if name in prob.shared]
        records.append(
            {
                "source": prob.records[i].source,
                "params": {a.job.slots[s][0]: float(a.est[s]) for s in shared_slots},
                "stderr": {
                    a.job.slots[s][0]: float(a.se_c[s]) if np.isfinite(a.se_c[s]) else None
                    for s in shared_slots
                },
                "scale": {
                    "position": float(np.sqrt(np.mean(rx[used_x] ** 2))) if used_x.any() else None,
                    "time": float(np.sqrt(np.mean(rt[used_t] ** 2))) if used_t.any() else None,
                },
            }
        )
    n, q_joint = joint.info["n"], joint.info["q"]
    df1, df2 = q_alone - q_joint, n - q_alone
    if df1 < 1:
        return _untested(
            prob,
            f"the records fitted alone move {q_alone} parameters and clock shifts, the joint "
            f"fit {q_joint}: sharing takes no degree of freedom to test",
        )
    if df2 < 1 or not rss_alone > 0:
        return _untested(
            prob,
            f"the records fitted alone leave no residual degree of freedom ({n} residuals, "
            f"{q_alone} parameters and clock shifts): each fits its own data exactly, and "
            "nothing measures the noise against which sharing would be judged",
        )
    inflation = max(max(a.inflation for a in alone), 1.0)
    F = max((rss_joint - rss_alone) / df1, 0.0) / (rss_alone / df2)
    p = f_sf(F / inflation, df1, df2)
    spread = {}
    for name in prob.shared:
        v = np.array([rec["params"].get(name, np.nan) for rec in records], dtype=float)
        se = np.array([np.nan if (e := rec["stderr"].get(name)) is None else e for rec in records])
        ok = np.isfinite(v) & np.isfinite(se) & (se > 0)
        if ok.sum() < 2:
            continue
        w = 1 / se[ok] ** 2
        mean = float(w @ v[ok] / w.sum())
        chi2 = float(w @ (v[ok] - mean) ** 2)  # (`se`: corrected for correlated residuals)
        spread[name] = {
            "chi2": chi2,
            "df": int(ok.sum() - 1),
            "p": _chi2_sf(chi2, int(ok.sum() - 1)),
        }
    out = {
        "parameters": list(prob.shared),
        "tested": True,
        "F": F,
        "df": [int(df1), int(df2)],
        "inflation": inflation,
        "p": p,
        "rejected": bool(p < SHARED_P),
        "records": records,
        "spread": spread,
    }
    if out["rejected"]:
        out["message"] = _disagreement(joint, out)
    return out


def _untested(prob, reason: str) -> dict:
    """`shared_test`'s evidence where the test cannot be done: why, and the warning saying so
    (`message`)."""
    return {
        "parameters": list(prob.shared),
        "tested": False,
        "reason": reason,
        "message": f"the shared parameters ({', '.join(prob.shared)}) are not tested against "
        f"each record fitted alone: {reason}",
    }


def record_name(rec: Record, i: int) -> str:
    """How messages name record `i` of a fit: its source (the file), else `record i`."""
    return rec.source or f"record {i}"


def _about(rec: Record, i: int, count: int) -> str:
    """The `name: ` in front of a warning about record `i` of a fit of `count` records; none
    for the one record of a fit without a source (there is no other to tell it from)."""
    return f"{record_name(rec, i)}: " if rec.source or count > 1 else ""


def _disagreement(joint: _Assessed, test: dict) -> str:
    """The warning of a joint fit that `shared_test` rejects: the values of the records fitted
    alone, their residuals in the joint fit against their own noise, and the test."""
    space, records, prob = joint.job.space, test["records"], joint.prob
    shared_est = dict(zip(joint.names, joint.est))
    spread = test["spread"]
    names = [nm for nm, sp in spread.items() if sp["p"] < SHARED_P] or list(test["parameters"])
    parts = []
    for name in names:
        unit = space.unit(name)
        values = ", ".join(
            f"{rec['params'][name]:.6g}"
            + ("" if rec["stderr"].get(name) is None else f" +- {rec['stderr'][name]:.2g}")
            + f" ({record_name(prob.records[i], i)})"
            for i, rec in enumerate(records)
            if name in rec["params"]
        )
        sp = spread.get(name)
        chi = "" if sp is None else f"; spread chi2 {sp['chi2']:.3g} on {sp['df']}, p {_p(sp['p'])}"
        shared = shared_est.get(name)
        joint_value = "" if shared is None else f", shared {shared:.6g}"
        parts.append(f"{name} [{unit}] {values}{joint_value}{chi}")
    scales = []
    # (a fit on the whole time series: its position residuals are the samples')
    labels = ("samples", "times") if joint.prob.turning is not None else ("positions", "times")
    for kind, label in zip(("position", "time"), labels):
        got = [rec["scale"][kind] for rec in records]
        if any(g is not None for g in got):
            scales.append(f"{label} " + ", ".join("-" if g is None else f"{g:.3g}" for g in got))
    df1, df2 = test["df"]
    return (
        f"the records disagree about the shared parameters ({', '.join(test['parameters'])}): "
        f"the joint model is rejected by the data. Fitted alone: {'; '.join(parts)}. The "
        f"joint fit's residuals, in each record's own noise scale (about 1 where it fits): "
        f"{'; '.join(scales)}. Sharing raises the residual sum of squares by F = "
        f"{test['F']:.3g} on ({df1}, {df2}) degrees of freedom"
        + (
            ""
            if test["inflation"] <= 1
            else f" (scaled by 1/{test['inflation']:.3g} for correlated residuals)"
        )
        + f", p {_p(test['p'])} (below {SHARED_P:g}): fit the records separately or share "
        "fewer parameters (--shared); where they cover different amplitudes, the model may "
        "lack a law that depends on the amplitude"
    )


def _steepening(rec: Record, of: str | None = None) -> str | None:
    """A warning where `rec`'s amplitudes fall faster later than earlier (the mean decrement
    over windows of an even number of half-swings, so that the sides' asymmetry cancels, rises
    by more than 5 of its standard errors from one window to the next), which no free decay of
    a space with `constant_laws` does: an oscillation held steady (forced) before the release,
    say. `of`: the record's name in front of the message (`_about`; default: as the one record
    of a fit)."""
    of = _about(rec, 0, 1) if of is None else of
    skip = 1 if rec.meta.get("release") else 0  # a release located from one side: no datum
    a = rec.amplitudes[skip:]
    width = max(4, 2 * (a.size // 16))
    windows = a.size // width
    if windows < 3:
        return None
    ends = a[: windows * width + 1 : width]  # (the last window's end where the record has it)
    drops = -np.diff(ends) / width  # mean decrement of each window [signal units]
    # the amplitudes' own scatter (a turning point is located less sharply than a sample)
    noise = max(rec.noise or 0.0, _robust_scale(np.diff(a, 2), 0.0) / math.sqrt(6))
    rises = np.nonzero(np.diff(drops) > 5 * math.sqrt(6) * noise / width)[0]
    if rises.size == 0:
        return None
    k = int(rec.k[skip + (rises[0] + 1) * width])
    return (
        f"{of}its amplitudes fall faster after turning point k = {k} than before it "
        f"({drops[rises[0] + 1]:.3g} against {drops[rises[0]]:.3g} per half-swing), which no "
        f"free decay of this model does: an oscillation held or forced before the release? "
        f"Fit the free decay alone (--window START:, read_record(window=...))"
    )


def _decays_left_out(records) -> list:
    """A warning per signal of several free decays of which the fit leaves some out."""
    taken, starts = {}, {}
    for i, rec in enumerate(records):
        decays = rec.meta.get("decays")
        if decays:  # (records of one signal have its source; without one, each is its own)
            name = record_name(rec, i)
            taken.setdefault(name, set()).add(decays["index"])
            starts[name] = decays["starts"]
    out = []
    for source, indices in taken.items():
        if len(indices) < len(starts[source]):
            at = ", ".join(f"{v:.6g}" for v in starts[source])
            which = ", ".join(str(i) for i in sorted(indices))
            out.append(
                f"{source}: the signal holds {len(starts[source])} free decays (starting at {at} "
                f"s of its clock, numbered from 0): decay {which} fitted; another with --decay "
                f"N (decay=N), all of them jointly with --decay all (fits.read_decays)"
            )
    return out


def _line(x, y) -> tuple:
    """(the fraction of `y`'s variance that a straight line in `x` explains, its slope)."""
    design = np.column_stack([np.ones(x.size), x])
    beta = np.linalg.lstsq(design, y, rcond=None)[0]
    return 1 - np.var(y - design @ beta) / np.var(y), beta[1]


def _sensor_hints(records, per_record, space, free) -> list:
    """Where a fit's residuals are structured: what their mean over each pair of successive
    turning points (the part that both sides share) follows. A linear trend in time is a
    sensor zero that drifts (`drift`); a trend with the amplitude, sides that differ (the
    sensor's gain, `asym`; an uneven restoring force, the pendulum's `b2`). Said only where
    that shared part is at least half of the residuals and a straight line in time or in the
    amplitude explains at least half of its variance, and only for a parameter the model has
    and the fit left out."""
    out = []
    for i, (rec, one) in enumerate(zip(records, per_record)):
        x = np.asarray(one["residuals"]["position"], dtype=float)
        if rec.times is None or x.size < 8:
            continue
        shared = (x[:-1] + x[1:]) / 2
        t = (rec.times[:-1] + rec.times[1:]) / 2
        a = (rec.amplitudes[:-1] + rec.amplitudes[1:]) / 2
        ok = np.isfinite(shared)
        if ok.sum() < 6 or np.mean(shared[ok] ** 2) < 0.25 * np.nanmean(x**2):
            continue
        shared, t, a = shared[ok], t[ok], a[ok]
        (in_time, slope), (in_amplitude, _) = _line(t, shared), _line(a, shared)
        if max(in_time, in_amplitude) < 0.5:
            continue
        of = _about(rec, i, len(records))
        if in_time > in_amplitude and "drift" in space.names and "drift" not in free:
            out.append(
                f"{of}the residuals' mean over successive turning points drifts with "
                f"time (a line of {-slope:.3g} [{space.unit('drift')}] explains "
                f"{in_time:.0%} of it): the sensor's zero may drift; fit drift (--fit "
                f"...,drift)"
            )
        elif in_amplitude >= in_time and "asym" in space.names and "asym" not in free:
            out.append(
                f"{of}the residuals' mean over successive turning points follows the "
                f"amplitude (a line explains {in_amplitude:.0%} of it): the two sides differ "
                f"(the sensor's gain: fit asym, --fit ...,asym; or an uneven restoring force: "
                f"the pendulum model's b2)"
            )
    return out


def _holds_laws_of(a, b) -> bool:
    """Whether law set `a` is `b` with some of its laws held: `a`'s free parameters among
    `b`'s, the parameters fixed in both at the same values (a held value on `b`'s bound, such
    as a drag held at 0, included)."""
    return set(a.free) <= set(b.free) and all(
        a.fixed[r].get(name) == v for r, fb in enumerate(b.fixed) for name, v in fb.items()
    )


#: the BIC weight of the chosen law set below which it is not decided by the data
DECIDED = 0.95


def _undecided(job, mine, bic: dict) -> list:
    """A warning where the data do not decide between the chosen law set (`job`, of a space
    that selects among its variants) and law sets that are neither nested in it nor contain
    it (another mechanism: Coulomb instead of viscous damping, a linear restoring law instead
    of the sine): the chosen one's BIC weight `exp(-BIC/2)` among them (`bic`: each law set's,
    by label) below `DECIDED` (95 %), where its 95 % intervals, which hold for it alone, say
    more than the data do."""
    own = bic[job.label]
    rivals = {
        j.label: bic[j.label]
        for j in mine
        if j is not job and not _holds_laws_of(j, job) and not _holds_laws_of(job, j)
    }
    rivals = {k: v for k, v in rivals.items() if math.isfinite(v)}
    if not rivals or not math.isfinite(own):
        return []
    weight = 1.0 / (1.0 + sum(math.exp(-(v - own) / 2) for v in rivals.values()))
    if weight >= DECIDED:
        return []
    label = min(rivals, key=rivals.get)
    return [
        f"the law set is not decided by the data: {label} is {rivals[label] - own:.1f} above "
        f"{job.label} in BIC (the chosen set's BIC weight {weight:.0%} against the law sets "
        f"of another mechanism, below {DECIDED:.0%}); the values and intervals hold for "
        f"{job.label} alone (see model_comparison)"
    ]


def _result(assessed: _Assessed, jobs, shape, outlier_sigma, ends, shared=None):
    """The [`fits.FitResult`][] of an assessed job; `ends`: its profile-likelihood interval
    ends (`fits._solve._profiles`; None where they were not computed); `shared`: the test of a
    joint fit's shared parameters (`shared_test`), None for none."""
    job, prob = assessed.job, assessed.prob
    space, settings = job.space, shape.settings
    N = shape.N
    names, q = assessed.names, len(job.slots)
    info, active, full_rank = assessed.info, assessed.active, assessed.full_rank
    est, se_c, se_gn, corr = assessed.est, assessed.se_c, assessed.se_gn, assessed.corr
    vals = assessed.vals
    warn = []
    # a slot held at a bound: its 95 % one-sided limit away from it, where it was profiled
    limits = {s: v for s in range(q) if job.bound_hit[s] for v in (ends or {}).get(s, {}).values()}
    # ends of the 95 % region that the data do not bound (`fits._solve._open_end`)
    unbounded = {} if ends is None else ends.get("open", {})
    for s, nm in enumerate(names):
        if job.bound_hit[s]:
            unit = space.unit(job.slots[s][0])
            limit = (
                f"; its 95 % one-sided limit {nm} {'<=' if limits[s] > job.held[s] else '>='}"
                f" {limits[s]:.3g} [{unit}]"
                if s in limits
                else ""
            )
            if not _at_user_bound(job, s):
                warn.append(
                    f"{nm} ran into its bound {job.held[s]:.6g} [{unit}]: held there (a sub-model "
                    f"fits as well; see model_comparison){limit}"
                )
            else:  # the user's bound: not flagged (`converged`), but said
                what = (
                    f"its interval [{min(job.held[s], limits[s]):.6g}, "
                    f"{max(job.held[s], limits[s]):.6g}] is the bound and {nm}'s 95 % one-sided "
                    "limit"
                    if s in limits
                    else "no interval"
                    + ("" if ends is None else " (its one-sided limit was not found)")
                )
                warn.append(
                    f"{nm} is held at {job.held[s]:.6g} [{unit}], the bound set for it (--bounds, "
                    f"bounds=): the data put it there or beyond, so it has no standard error, and "
                    f"{what}"
                )
        elif not np.isfinite(se_c[s]):
            warn.append(f"{nm} is not identified by these data: no standard error")
        elif not se_c[s] < abs(est[s]):
            warn.append(
                f"{nm} is not identifiable from these data: its standard error "
                f"{se_c[s]:.3g} is not below its value {est[s]:.3g}"
            )
    for a in range(q):
        for b in range(a + 1, q):
            if np.isfinite(corr[a, b]) and abs(corr[a, b]) > 0.99:
                warn.append(
                    f"{names[a]} and {names[b]} are not separately identifiable: "
                    f"correlation {corr[a, b]:.4f}"
                )
    if not full_rank:
        warn.append(
            "the Jacobian is rank-deficient (relative singular-value tolerance "
            f"{RANK_RTOL:g}): some parameters are not determined by the data"
        )
    at_unset_bound = any(job.bound_hit[s] and not _at_user_bound(job, s) for s in range(q))
    if not job.out["ok"]:
        warn.append("the optimiser did not converge (step limit or no progress)")
    converged = bool(job.out["ok"] and full_rank and not at_unset_bound)
    # residual diagnostics
    diag = diagnostics(
        [assessed.r[b] for b in assessed.blocks], assessed.info["q"], assessed.block_names
    )
    n_dof = assessed.n_dof
    if n_dof < 3:
        warn.append(f"only {n_dof} residual degrees of freedom: the uncertainties are not reliable")
        converged = False if n_dof < 2 else converged
    if any(active[s] and not np.isfinite(se_c[s]) for s in range(q)):
        converged = False  # a parameter without a standard error is not determined
    if any(active[s] for s, _ in unbounded):
        converged = False  # nor one whose 95 % region the data leave open
    # intervals
    intervals = {}
    for s, nm in enumerate(names):
        if not active[s]:
            ends_s = (job.held[s], limits[s]) if s in limits else (math.nan, math.nan)
            intervals[nm] = (float(min(ends_s)), float(max(ends_s)))
            continue
        got = {} if ends is None else ends.get(s, {})
        t = job.transforms[s]
        for side, bound in ((-1, t.lo), (1, t.hi)):
            if (s, side) in unbounded:  # the end is the parameter's range's (None in JSON)
                got = {**got, side: bound}
                reach = unbounded[s, side]
                warn.append(
                    f"{nm} is not determined by these data: its 95 % profile-likelihood region "
                    f"reaches {reach:.3g} [{space.unit(job.slots[s][0])}] and goes on "
                    f"{'above' if side > 0 else 'below'} it (the estimate {est[s]:.3g}): the "
                    f"interval is open there"
                )
        wald = 1.96 * se_c[s]
        lo = got.get(-1, est[s] - wald)
        hi = got.get(1, est[s] + wald)
        lo, hi = max(lo, t.lo), min(hi, t.hi)
        if len(got) < 2 and np.isfinite(wald) and ends is not None:
            warn.append(
                f"{nm}: the profile likelihood failed; the interval is the Wald "
                f"interval +- 1.96 stderr"
            )
        intervals[nm] = (float(lo), float(hi))
    warn += _decays_left_out(prob.records)
    for i, (rec, peaks) in enumerate(zip(prob.records, prob.turning or prob.records)):
        of = _about(rec, i, len(prob.records))
        # (a series fit's: of its turning points; its samples' "amplitudes" rise and fall
        # within every swing, and a clean free decay was told it was forced)
        steeper = _steepening(peaks, of) if space.constant_laws else None
        if steeper:
            warn.append(steeper)
        if rec.meta.get("rows") == ROWS_AS_HALF_SWINGS:
            warn.append(
                f"{of}its rows are read as successive half-swings (both sides' peaks "
                f"in turn); a table of one side's peaks (one per period) needs a 'cycle' "
                f"column: read as half-swings, it gives half the frequency and twice the "
                f"damping"
            )
        if "length_unit" in rec.meta:
            warn.append(
                f"{of}its positions are in {rec.meta['length_unit']} (the column "
                f"{value_name(rec)!r}): converted to m, the model's unit (a0, offset and the "
                f"friction are in SI units)"
            )
        faster = rec.meta.get("faster")
        if faster:
            warn.append(
                f"{of}a faster oscillation rides on the signal ({1 / faster['period']:.4g}"
                f" Hz, amplitude about {faster['amplitude']:.3g}: mains hum? a higher mode?): "
                f"the turning points were found without it and located with it fitted beside them"
            )
        levels = [f"{v:.6g}" for v in rec.meta.get("clipped", {}).values() if v is not None]
        if levels:
            warn.append(
                f"{of}the signal is clipped at {' and '.join(levels)} (a saturated "
                f"sensor): the extrema cut off there are left out of the fit"
            )
    structured = bool(diag["warnings"])
    warn += diag["warnings"]
    diag = {**diag, "warnings": warn}
    if shared is not None:  # a joint fit's shared parameters tested against each record alone
        diag["shared"] = {k: v for k, v in shared.items() if k != "message"}
        if not shared["tested"]:
            warn.append(shared["message"])
        elif shared["rejected"]:
            warn.insert(0, shared["message"])
            converged = False
    # per-record residuals in data units
    per_record = []
    R = len(prob.records)
    r_all = job.out["r"].reshape(R, 2, N)
    series = prob.turning is not None
    for i, rec in enumerate(prob.records):
        m = len(rec)
        wx, wt = prob.wx[i][:m], prob.wt[i][:m]
        res_x = r_all[i, 0, :m] / np.where(wx > 0, wx, 1.0)
        res_x[wx == 0] = np.nan  # not a datum (a release located from one side)
        floor = 1e-4 * float(np.max(rec.amplitudes))
        z = res_x / _robust_scale(res_x, floor)
        flagged = np.abs(z) > outlier_sigma
        res_t = None
        if rec.times is not None and not series:
            res_t = r_all[i, 1, :m] / np.where(wt > 0, wt, 1.0)
            res_t[wt == 0] = np.nan  # not a datum (a release's time from a hold or one side)
            # in units of the record's time noise (`tw`: an extremum of a small swing is timed
            # worse), so that a small swing's time is not taken for an outlier
            rt = res_t * prob.tw[i][:m]
            z_t = rt / _robust_scale(rt[wt > 0], 1e-12)
            flagged |= np.abs(z_t) > outlier_sigma
        one = {
            "residuals": {
                **({"t": rec.times.tolist()} if series else {"k": rec.k.tolist()}),
                "position": res_x.tolist(),
                "time": None if res_t is None else res_t.tolist(),
                "standardized": z.tolist(),
                "outlier": flagged.tolist(),
            },
            "outliers": [int(kk) for kk in rec.k[flagged]],
        }
        one["rms"], one["rms_time"] = (_pooled_rms([one], kind) for kind in ("position", "time"))
        per_record.append(one)
        if one["rms_time"] is not None and len(rec.k) > 2:
            half = float(np.median(np.diff(rec.times) / np.diff(rec.k)))  # a half-swing [s]
            if half > 0 and one["rms_time"] > TIME_OFF * half:
                warn.append(
                    f"the model's turning-point times miss the record's by {one['rms_time']:.3g}"
                    f" s rms, {one['rms_time'] / half:.0%} of a half-swing ({half:.3g} s): the "
                    "model's period is not the record's (check the fixed parameters, --set)"
                )
            clock = rec.clock or {}
            if half > 0 and clock.get("uniform_rms_s", 0.0) > STAMPS_OFF * half:
                warn.append(
                    f"the record's time stamps are irregular and scatter by "
                    f"{clock['uniform_rms_s'] * 1e3:.3g} ms rms "
                    f"({clock['uniform_rms_s'] / half:.0%} of a half-swing) about a uniform "
                    f"clock at {clock['uniform_rate_hz']:.6g} Hz: if the device samples "
                    "uniformly they are not the sample times (arrival times of thinned rows?) "
                    "and the turning points' times scatter as much; give the rate (--rate HZ)"
                )
    if structured and not series:
        warn += _sensor_hints(prob.records, per_record, space, job.free)
    top = [s for s, (nm, rr) in enumerate(job.slots) if rr is None]

    def pick(arr, sel):
        return {names[s]: (float(arr[s]) if np.isfinite(arr[s]) else None) for s in sel}

    params = {names[s]: float(est[s]) for s in top}
    records = []
    if R > 1:
        for i, rec in enumerate(prob.records):
            sel = [s for s, (nm, rr) in enumerate(job.slots) if rr == i]
            records.append(
                {
                    "source": rec.source,
                    "params": {job.slots[s][0]: float(est[s]) for s in sel},
                    "stderr": {job.slots[s][0]: pick(se_c, [s])[names[s]] for s in sel},
                    "stderr_gn": {job.slots[s][0]: pick(se_gn, [s])[names[s]] for s in sel},
                    "intervals": {job.slots[s][0]: intervals[names[s]] for s in sel},
                    "fixed": {k: v for k, v in vals[i].items() if k not in job.free},
                    **{k: per_record[i][k] for k in ("rms", "rms_time", "outliers", "residuals")},
                }
            )
    comparison = {}
    mine = [j for j in jobs if j.problem == job.problem]
    if len(mine) > 1:
        for j in mine:
            inf_j = _information(j, prob, N)
            vj = _values_of(j)
            comparison[j.label] = {
                "aic": inf_j["aic"],
                "bic": inf_j["bic"],
                "rss": inf_j["rss"],
                "params": {
                    sn: vj[0 if rr is None else rr][nm]
                    for sn, (nm, rr) in zip(_slot_names(j), j.slots)
                },
                "converged": bool(j.out["ok"]),
            }
        labels = [j.label for j in mine]
        comparison["best_aic"] = min(labels, key=lambda k: comparison[k]["aic"])
        comparison["best_bic"] = min(labels, key=lambda k: comparison[k]["bic"])
        if any(j.headline and j.space.select for j in mine):  # the chosen law set reported
            warn += _undecided(job, mine, {k: comparison[k]["bic"] for k in labels})
    rec0 = (prob.turning or prob.records)[0]
    dec = prob.decs[0]
    corr_top = corr[np.ix_(top, top)] if top else np.zeros((0, 0))
    result = FitResult(
        model=space.name.removesuffix(":series"),
        forward=settings["forward"],
        loss=settings["loss"],
        optimizer=settings["optimizer"],
        params=params,
        fixed={k: v for k, v in vals[0].items() if k not in job.free},
        stderr=pick(se_c, top),
        correlation=np.where(np.isfinite(corr_top), corr_top, np.nan).tolist(),
        converged=converged,
        iterations=int(sum(j.iterations for j in mine)),
        rms=_pooled_rms(per_record, "position"),
        rms_time=_pooled_rms(per_record, "time"),
        model_comparison=comparison,
        residuals=per_record[0]["residuals"],
        outliers=per_record[0]["outliers"],
        warnings=warn,
        decrement={k: v for k, v in dec.items() if k != "pairs"},
        record=rec0,
        stderr_gn=pick(se_gn, top),
        intervals={names[s]: intervals[names[s]] for s in top},
        diagnostics=diag,
        aic=info["aic"],
        bic=info["bic"],
        rss=info["rss"],
        n_residuals=info["n"],
        records=records,
        clock=rec0.clock,
        units={nm: space.unit(nm) for nm in space.names},
        label=job.label,
        residuals_of=settings["residuals"],
    )
    result.decrement["pairs"] = dec["pairs"]
    return result
