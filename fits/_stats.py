"""Residual diagnostics and standard errors that account for correlated residuals.

Pure NumPy. A least-squares fit's Gauss-Newton covariance `s^2 (J^T J)^-1` assumes independent
residuals; residuals of a decay fit are rarely independent (a model that misses an amplitude-
dependent loss leaves a smooth trend, which in signed turning-point positions shows as an
alternating sequence). [`diagnostics`][fits._stats.diagnostics] measures that structure and says
so; [`covariance`][fits._stats.covariance] widens the covariance by the factor the structure
implies.

Both work on residual *blocks* (positions, times, one record after another) in record order:
serial correlation is estimated within a block, never across blocks.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["diagnostics", "covariance", "RANK_RTOL", "RHO_MAX", "LAG1_WARN", "RUNS_P_WARN"]

RANK_RTOL = 1e-8  #: singular values below this fraction of the largest are rank deficiency
RHO_MAX = 0.95  #: lag-1 autocorrelations are clipped to [-RHO_MAX, RHO_MAX]
LAG1_WARN = 0.5  #: |pooled lag-1 autocorrelation| above this is structure
RUNS_P_WARN = 1e-3  #: a runs-test p-value below this is structure


def _lag1(x: np.ndarray) -> tuple[float, float]:
    """Sum of lag-1 products and sum of squares of one block (residuals are deviations from the
    model, zero-mean under it, so they are not demeaned: a constant bias counts as correlation)."""
    x = np.asarray(x, dtype=float)
    return float(np.dot(x[:-1], x[1:])), float(np.dot(x, x))


def _rho(x: np.ndarray, debias: bool = False) -> float:
    """Lag-1 autocorrelation of one block, clipped to `[-RHO_MAX, RHO_MAX]`; with `debias`,
    moved away from 0 by `(1 + 3 |rho|) / n` (the first-order bias of the estimator on
    residuals with a fitted mean, Marriott and Pope 1954)."""
    num, den = _lag1(x)
    if x.size < 3 or not den > 0:
        return 0.0
    rho = num / den
    if debias:
        rho += math.copysign((1 + 3 * abs(rho)) / x.size, rho)
    return float(np.clip(rho, -RHO_MAX, RHO_MAX))


def _runs(blocks) -> tuple[float, int]:
    """Two-sided Wald-Wolfowitz runs test on the signs of the residuals, pooled over blocks
    (runs, their expectation and variance given each block's numbers of positive and negative
    residuals, summed; normal approximation). Zero residuals are dropped. Returns `(p, n)`."""
    runs = mean = var = 0.0
    n_total = 0
    for b in blocks:
        s = np.sign(np.asarray(b, dtype=float))
        s = s[s != 0]
        n = s.size
        n_total += n
        n1 = int(np.sum(s > 0))
        n2 = n - n1
        if n1 == 0 or n2 == 0:
            continue  # no information about the order given the counts
        runs += 1 + int(np.sum(s[1:] != s[:-1]))
        mean += 1 + 2.0 * n1 * n2 / n
        var += 2.0 * n1 * n2 * (2.0 * n1 * n2 - n) / (n * n * (n - 1.0))
    if var > 0:
        z = (runs - mean) / math.sqrt(var)
        return math.erfc(abs(z) / math.sqrt(2.0)), n_total
    if n_total >= 2:  # every block one-signed: the chance of that under random signs
        return min(1.0, 2.0 * 0.5**n_total), n_total
    return float("nan"), n_total


def diagnostics(blocks: list[np.ndarray], n_params: int) -> dict:
    """Serial-structure diagnostics of standardised residuals.

    **Arguments:**

    - `blocks`: residual blocks in record order (e.g. one record's position residuals, then its
      time residuals), each standardised (divided by its noise scale), so dimensionless.
      Padding and ignored points must be left out.
    - `n_params`: number of fitted parameters.

    **Returns:** a dict with

    - `lag1` [-]: pooled lag-1 autocorrelation, `sum_b sum_t r_t r_{t+1} / sum_b sum_t r_t^2`
      over the blocks (not demeaned).
    - `runs_p` [-]: two-sided p-value of the Wald-Wolfowitz runs test on the residuals' signs,
      pooled over the blocks (NaN with fewer than two non-zero residuals).
    - `n_eff` [-]: effective sample size, `n_b (1 - |rho_b|) / (1 + |rho_b|)` per block with
      `rho_b` its lag-1 autocorrelation (debiased as in `covariance`, clipped to `RHO_MAX`),
      summed and clipped to `[n_params + 1, n]`. `|rho|`, because signed turning-point
      residuals alternate with the swing, so a smooth model error shows as a *negative* lag-1
      correlation. (On white noise `|rho_b| ~ 0.8 / sqrt(n_b)`: `n_eff` averages ~0.9 `n`.)
    - `warnings`: a sentence when `|lag1| > LAG1_WARN` or `runs_p < RUNS_P_WARN` (structured
      residuals: the model does not explain the data).
    """
    blocks = [np.asarray(b, dtype=float).ravel() for b in blocks]
    blocks = [b[np.isfinite(b)] for b in blocks]
    n = sum(b.size for b in blocks)
    num = den = 0.0
    n_eff = 0.0
    for b in blocks:
        if b.size == 0:
            continue
        bn, bd = _lag1(b)
        num += bn
        den += bd
        r = abs(_rho(b, debias=True))
        n_eff += b.size * (1 - r) / (1 + r)
    lag1 = num / den if den > 0 else float("nan")
    runs_p, _ = _runs(blocks)
    n_eff = float(min(max(n_eff, n_params + 1), max(n, n_params + 1)))
    warnings = []
    structured = []
    if np.isfinite(lag1) and abs(lag1) > LAG1_WARN:
        structured.append(f"residual lag-1 autocorrelation {lag1:.2f}")
    if np.isfinite(runs_p) and runs_p < RUNS_P_WARN:
        structured.append(f"runs test p = {runs_p:.2g}")
    if structured:
        warnings.append(
            "the model does not explain the data: " + ", ".join(structured)
            + f" (effective sample size {n_eff:.0f} of {n}); the standard errors and intervals "
            "are widened for it, but a richer model (see model_comparison) may fit better")
    return {"lag1": float(lag1), "runs_p": float(runs_p), "n_eff": n_eff, "warnings": warnings}


def _ar1_gram(J: np.ndarray, rho: float) -> np.ndarray:
    """`J^T R J` with `R_ij = rho^|i-j|` (AR(1) correlation), in O(n q^2): with the forward
    sums `S_i = rho S_{i-1} + J_i`, `J^T R J = sum_i J_i^T (S_i + B_i - J_i)`, `B` the
    backward sums."""
    S = np.empty_like(J)
    B = np.empty_like(J)
    acc = np.zeros(J.shape[1])
    for i in range(J.shape[0]):
        acc = rho * acc + J[i]
        S[i] = acc
    acc = np.zeros(J.shape[1])
    for i in range(J.shape[0] - 1, -1, -1):
        acc = rho * acc + J[i]
        B[i] = acc
    return J.T @ (S + B - J)


def covariance(J: np.ndarray, r: np.ndarray,
               blocks: list[slice]) -> tuple[np.ndarray, np.ndarray, float]:
    """Gauss-Newton covariance and its correction for serially correlated residuals.

    **Arguments:**

    - `J`: `(n, q)` Jacobian of the weighted residuals with respect to the parameters (in the
      parameters' units).
    - `r`: `(n,)` weighted residuals at the optimum (dimensionless when weighted by the noise).
    - `blocks`: slices of `r` in record order (positions, times, one record after another);
      rows outside every block are ignored. Rows with `r = 0` and a zero Jacobian row (padding,
      zero weight) are not counted.

    **Returns:** `(cov_corrected, cov_gn, inflation)`, covariances in the parameters' units
    squared:

    - `cov_gn = s^2 (J^T J)^-1` with `s^2 = rss / (n - q)`;
    - `inflation >= 1` [-]: the largest ratio, over the identified parameters, of the variance
      under AR(1) residuals to the Gauss-Newton variance: the sandwich
      `(J^T J)^-1 (sum_b J_b^T R_b J_b) (J^T J)^-1` with `R_b` the AR(1) correlation matrix
      `rho_b^|i-j|` of block `b`, `rho_b` its residuals' lag-1 autocorrelation debiased by
      `(1 + 3 |rho|)/n_b` away from 0 and clipped to `[-RHO_MAX, RHO_MAX]`, and the noise
      variance `rss / (n - tr((J^T J)^-1 sum_b J_b^T R_b J_b))` (the expected residual sum of
      squares under those correlations). For smooth regressors this is the familiar
      `(1 + rho)/(1 - rho)`; unlike that factor it is right for alternating regressors too
      (signed turning points), and for any mix of blocks (positions, times, records);
    - `cov_corrected = inflation * cov_gn` (one factor for every parameter, so that profile
      likelihood intervals can scale their deviance by it).

    Rank: the columns of `J` are scaled to unit norm and `J` decomposed by SVD; singular values
    below `RANK_RTOL` (1e-8) times the largest are zero. A parameter with a component along such
    a null direction (squared projection above 1e-6) is unidentified: its rows and columns are
    NaN (never 0); the others come from the pseudo-inverse.
    """
    J = np.asarray(J, dtype=float)
    r = np.asarray(r, dtype=float).ravel()
    if J.ndim != 2 or J.shape[0] != r.size:
        raise ValueError(f"J must be (n, q) with n = len(r) = {r.size} (got {J.shape})")
    q = J.shape[1]
    rows = []
    for sl in blocks:
        idx = np.arange(r.size)[sl]
        keep = (r[idx] != 0) | np.any(J[idx] != 0, axis=1)
        rows.append(idx[keep])
    used = np.concatenate(rows) if rows else np.zeros(0, dtype=int)
    nan = np.full((q, q), np.nan)
    n = used.size
    if q == 0:
        return np.zeros((0, 0)), np.zeros((0, 0)), 1.0
    if n <= q or not np.all(np.isfinite(J[used])) or not np.all(np.isfinite(r[used])):
        return nan, nan.copy(), float("nan")
    Ju = J[used]
    norms = np.linalg.norm(Ju, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    _, s, Vt = np.linalg.svd(Ju / safe, full_matrices=False)
    ok = s > RANK_RTOL * s[0] if s[0] > 0 else np.zeros_like(s, dtype=bool)
    null = Vt[~ok]
    identified = (norms > 0) & (np.sum(null**2, axis=0) < 1e-6)
    # (J^T J)^+ in the parameters' units, from the scaled decomposition
    inv_s2 = np.where(ok, 1.0 / np.where(ok, s, 1.0) ** 2, 0.0)
    pinv = (Vt.T * inv_s2) @ Vt / np.outer(safe, safe)
    rss = float(np.dot(r[used], r[used]))
    s2 = rss / (n - q)
    cov_gn = s2 * pinv
    meat = np.zeros((q, q))
    for idx in rows:
        if idx.size:
            meat += _ar1_gram(J[idx], _rho(r[idx], debias=True))
    # E[rss] = sigma^2 (n - tr(H R)) under correlated residuals, tr(H R) = tr((J^T J)^+ meat)
    s2_ar = rss / max(n - float(np.trace(pinv @ meat)), 1.0)
    sandwich = s2_ar * pinv @ meat @ pinv
    d_gn = np.diag(cov_gn)[identified]
    d_sw = np.diag(sandwich)[identified]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratios = d_sw / d_gn
    ratios = ratios[np.isfinite(ratios)]
    inflation = float(max(1.0, ratios.max())) if ratios.size else 1.0
    mask = np.outer(identified, identified)
    cov_gn = np.where(mask, cov_gn, np.nan)
    return inflation * cov_gn, cov_gn, inflation
