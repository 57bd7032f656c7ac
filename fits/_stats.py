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
#: a lag-1 autocorrelation of `n` residuals is structure only beyond `LAG1_Z / sqrt(n)` as well:
#: white noise's is about normal with standard deviation `1 / sqrt(n)`, and this is its
#: two-sided quantile at `RUNS_P_WARN`
LAG1_Z = 3.2905


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


def _chi2_sf(x: float, k: int) -> float:
    """Survival function of the chi-square distribution with integer `k` degrees of freedom."""
    if x <= 0:
        return 1.0
    if k % 2 == 0:  # exp(-x/2) sum_{j < k/2} (x/2)^j / j!
        term = total = math.exp(-x / 2)
        for j in range(1, k // 2):
            term *= (x / 2) / j
            total += term
        return min(1.0, total)
    total = math.erfc(math.sqrt(x / 2))  # k = 1, then the odd terms
    term = math.sqrt(2 * x / math.pi) * math.exp(-x / 2)
    for j in range(1, (k + 1) // 2):
        total += term
        term *= x / (2 * j + 1)
    return min(1.0, total)


def _betacf(a: float, b: float, x: float) -> float:
    """The continued fraction of the regularised incomplete beta function (modified Lentz)."""
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 1000):
        for num in (
            m * (b - m) * x / ((a + 2 * m - 1) * (a + 2 * m)),
            -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1)),
        ):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            break
    return h


def _betainc(a: float, b: float, x: float) -> float:
    """The regularised incomplete beta function `I_x(a, b)`."""
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    log_front = (
        math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    )
    if x < (a + 1) / (a + b + 2):
        return math.exp(log_front) * _betacf(a, b, x) / a
    return 1.0 - math.exp(log_front) * _betacf(b, a, 1.0 - x) / b


def f_sf(f: float, d1: float, d2: float) -> float:
    """Survival function of the F distribution with `d1` and `d2` degrees of freedom: the
    chance of an F statistic above `f` (`I_{d2/(d2 + d1 f)}(d2/2, d1/2)`)."""
    if not f > 0:
        return 1.0
    if math.isinf(f):
        return 0.0
    return _betainc(d2 / 2, d1 / 2, d2 / (d2 + d1 * f))


def _runs(blocks) -> float:
    """Two-sided Wald-Wolfowitz runs test on the signs of the residuals: per block the runs'
    z-score given its numbers of positive and negative residuals (normal approximation), the
    blocks combined by `sum z_b^2 ~ chi^2(B)` (too many runs in one block and too few in
    another do not cancel). Zero residuals are dropped; a block of one sign tells nothing about
    the order. Every block one-signed: the chance of that under random signs."""
    zs = []
    n_total = 0
    for b in blocks:
        s = np.sign(np.asarray(b, dtype=float))
        s = s[s != 0]
        n = s.size
        n_total += n
        n1 = int(np.sum(s > 0))
        n2 = n - n1
        if n1 == 0 or n2 == 0 or n < 3:
            continue
        runs = 1 + int(np.sum(s[1:] != s[:-1]))
        mean = 1 + 2.0 * n1 * n2 / n
        var = 2.0 * n1 * n2 * (2.0 * n1 * n2 - n) / (n * n * (n - 1.0))
        if var > 0:
            zs.append((runs - mean) / math.sqrt(var))
    if zs:
        return _chi2_sf(float(np.sum(np.square(zs))), len(zs))
    if n_total >= 2:
        return min(1.0, 2.0 * 0.5**n_total)
    return float("nan")


def _structured(rho: float, n: int) -> bool:
    """Whether a lag-1 autocorrelation `rho` of `n` residuals is structure: beyond `LAG1_WARN`
    and beyond what white noise gives at `RUNS_P_WARN` (`LAG1_Z / sqrt(n)`)."""
    return abs(rho) > LAG1_WARN and abs(rho) * math.sqrt(n) > LAG1_Z


def diagnostics(blocks: list[np.ndarray], n_params: int, names: list | None = None) -> dict:
    """Serial-structure diagnostics of standardised residuals.

    **Arguments:**

    - `blocks`: residual blocks in record order (e.g. one record's position residuals, then its
      time residuals), each standardised (divided by its noise scale), so dimensionless.
      Padding and ignored points must be left out.
    - `n_params`: number of fitted parameters.
    - `names`: what each block holds ("the times of 80P.txt"), for the warning.

    **Returns:** a dict with

    - `lag1` [-]: pooled lag-1 autocorrelation, `sum_b |sum_t r_t r_{t+1}| / sum_b sum_t r_t^2`
      over the blocks (not demeaned) with the sign of `sum_b sum_t r_t r_{t+1}`: blocks of
      opposite sign (alternating position residuals, drifting time residuals) do not cancel.
      For one block, its lag-1 autocorrelation.
    - `runs_p` [-]: two-sided p-value of the Wald-Wolfowitz runs test on the residuals' signs,
      the blocks' z-scores combined as `sum z_b^2 ~ chi^2(B)` (NaN with fewer than two
      non-zero residuals).
    - `n_eff` [-]: effective sample size, `n_b (1 - |rho_b|) / (1 + |rho_b|)` per block with
      `rho_b` its lag-1 autocorrelation (debiased as in `covariance`, clipped to `RHO_MAX`),
      summed and clipped to `[n_params + 1, n]`. `|rho|`, because signed turning-point
      residuals alternate with the swing, so a smooth model error shows as a *negative* lag-1
      correlation. (On white noise `|rho_b| ~ 0.8 / sqrt(n_b)`: `n_eff` averages ~0.9 `n`.)
    - `warnings`: a sentence when `|lag1|` or the lag-1 autocorrelation of a block of at
      least 10 residuals exceeds `LAG1_WARN` (0.5) in size and `LAG1_Z / sqrt(n)` (3.29
      standard deviations of white noise's, `n` the residuals it is taken over), or `runs_p <
      RUNS_P_WARN` (1e-3): structured residuals, the model does not explain the data. (With
      0.5 alone, 4 of 10 fits of the exact oscillator to 13 extracted turning points were
      flagged, and 175 of 2000 pairs of blocks of 12 white residuals; now 0 and 1.)
    """
    blocks = [np.asarray(b, dtype=float).ravel() for b in blocks]
    blocks = [b[np.isfinite(b)] for b in blocks]
    n = sum(b.size for b in blocks)
    num = mag = den = 0.0
    n_eff = 0.0
    worst, worst_name = 0.0, None  # the largest structured lag-1 of a block of >= 10 residuals
    names = list(names) if names is not None else [None] * len(blocks)
    for b, name in zip(blocks, names):
        if b.size == 0:
            continue
        bn, bd = _lag1(b)
        num += bn
        mag += abs(bn)
        den += bd
        r = abs(_rho(b, debias=True))
        n_eff += b.size * (1 - r) / (1 + r)
        if b.size >= 10 and bd > 0 and _structured(bn / bd, b.size) and abs(bn / bd) > abs(worst):
            worst, worst_name = bn / bd, name
    lag1 = math.copysign(mag / den, num) if den > 0 else float("nan")
    runs_p = _runs(blocks)
    n_eff = float(min(max(n_eff, n_params + 1), max(n, n_params + 1)))
    warnings = []
    structured = []
    pooled = bool(np.isfinite(lag1) and _structured(lag1, n))
    if worst or pooled:
        if abs(worst) > abs(lag1) or not pooled:
            of = f" ({worst_name}; pooled {lag1:.2f})" if worst_name else f" (pooled {lag1:.2f})"
            structured.append(f"residual lag-1 autocorrelation {worst:.2f}{of}")
        else:
            structured.append(f"residual lag-1 autocorrelation {lag1:.2f}")
    if np.isfinite(runs_p) and runs_p < RUNS_P_WARN:
        structured.append(f"runs test p = {runs_p:.2g}")
    if structured:
        warnings.append(
            "the model does not explain the data: "
            + ", ".join(structured)
            + f" (effective sample size {n_eff:.0f} of {n}); the standard errors and intervals "
            "are widened for it, but a richer model (see model_comparison) may fit better"
        )
    return {"lag1": float(lag1), "runs_p": float(runs_p), "n_eff": n_eff, "warnings": warnings}


def _ar1_sums(X: np.ndarray, rho: float) -> np.ndarray:
    """Forward sums `S_i = rho S_{i-1} + X_i` along the rows (a doubling scan: log2(n)
    vectorised steps)."""
    S = np.array(X, dtype=float, copy=True)
    a, d = rho, 1
    while d < S.shape[0] and a != 0.0:
        S[d:] = S[d:] + a * S[:-d]
        a, d = a * a, 2 * d
    return S


def _ar1_cross(X: np.ndarray, Y: np.ndarray, rho: float) -> np.ndarray:
    """`X^T R Y` with `R_ij = rho^|i-j|` (AR(1) correlation), in O(n q^2 log n):
    `R Y = S + B - Y` with `S`, `B` the forward and backward sums of `Y`."""
    RY = _ar1_sums(Y, rho) + _ar1_sums(Y[::-1], rho)[::-1] - Y
    return X.T @ RY


def _up(X: np.ndarray) -> np.ndarray:
    """`A X` for the lag-1 operator `A` (`r^T A r = sum_t r_t r_{t+1}`): row t is `X_{t+1}`."""
    return np.concatenate([X[1:], np.zeros_like(X[:1])])


def _down(X: np.ndarray) -> np.ndarray:
    """`A^T X`: row t is `X_{t-1}`."""
    return np.concatenate([np.zeros_like(X[:1]), X[:-1]])


def _root(f, lo: float, hi: float, fallback: float, tol: float = 1e-6) -> float:
    """The root of an increasing `f` in `[lo, hi]` by the Illinois method (regula falsi);
    an end when `f` keeps one sign there; `fallback` when `f` is not finite at the ends."""
    f_lo, f_hi = f(lo), f(hi)
    if not (np.isfinite(f_lo) and np.isfinite(f_hi)):
        return fallback
    if f_lo >= 0:
        return lo
    if f_hi <= 0:
        return hi
    side = 0
    for _ in range(60):
        x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        fx = f(x)
        if not np.isfinite(fx):
            return fallback
        if fx > 0:
            hi, f_hi = x, fx
            if side == 1:
                f_lo /= 2
            side = 1
        else:
            lo, f_lo = x, fx
            if side == -1:
                f_hi /= 2
            side = -1
        if hi - lo < tol or fx == 0:
            break
    return x


def _block_rhos(blocks_J, blocks_r, pinv, iterations=2):
    """AR(1) coefficient of each block by the method of moments on the fitted residuals.

    Residuals `r = (I - H) e` of a fit are less correlated than the errors `e`: the fit absorbs
    their slow part (with a smooth error and parameters that shape the amplitudes, the raw
    lag-1 correlation of `r` is far below that of `e`). `rho_b` solves
    `E[r_b^T A r_b] / E[r_b^T r_b] = observed`, both expectations under AR(1) errors with the
    fit's hat matrix `H = J (J^T J)^+ J^T`:
    `E[r_b^T A r_b] ~ tr(A R_b) - tr(A H_bb R_b) - tr(A R_b H_bb) + tr(A J_b P M P J_b^T)`,
    `E[r_b^T r_b] ~ n_b - 2 tr(P J_b^T R_b J_b) + tr(P M P J_b^T J_b)` with `P = (J^T J)^+`,
    `M = sum_c J_c^T R_c J_c`; Illinois root finding per block, Gauss-Seidel over the
    blocks (two sweeps)."""
    nb = len(blocks_J)
    observed = []
    for r in blocks_r:
        num, den = _lag1(r)
        observed.append(num / den if den > 0 and r.size >= 3 else 0.0)
    rho = [float(np.clip(o, -RHO_MAX, RHO_MAX)) for o in observed]
    grams = [_ar1_cross(Jb, Jb, rh) for Jb, rh in zip(blocks_J, rho)]
    G0 = [Jb.T @ Jb for Jb in blocks_J]
    G1 = [Jb.T @ _up(Jb) for Jb in blocks_J]
    for _ in range(iterations if nb > 1 else 1):
        for b, (Jb, rb) in enumerate(zip(blocks_J, blocks_r)):
            n = rb.size
            if n < 3:
                continue
            others = sum((g for c, g in enumerate(grams) if c != b), np.zeros_like(pinv))

            def excess(rh, b=b, Jb=Jb, n=n, others=others):
                RJ = _ar1_sums(Jb, rh) + _ar1_sums(Jb[::-1], rh)[::-1] - Jb  # R_b J_b
                g = Jb.T @ RJ
                PMP = pinv @ (others + g) @ pinv
                num = (
                    (n - 1) * rh
                    - np.trace(pinv @ (RJ.T @ _up(Jb)))
                    - np.trace(pinv @ (_down(Jb).T @ RJ))
                    + np.trace(PMP @ G1[b])
                )
                den = n - 2 * np.trace(pinv @ g) + np.trace(PMP @ G0[b])
                return num / den - observed[b] if den > 0 else float("nan")

            rho[b] = _root(excess, -RHO_MAX, RHO_MAX, rho[b])
            grams[b] = _ar1_cross(Jb, Jb, rho[b])
    return rho, grams


def covariance(
    J: np.ndarray, r: np.ndarray, blocks: list[slice], nuisance: int = 0
) -> tuple[np.ndarray, np.ndarray, float]:
    """Gauss-Newton covariance and its correction for serially correlated residuals.

    **Arguments:**

    - `J`: `(n, q)` Jacobian of the weighted residuals with respect to the parameters (in the
      parameters' units).
    - `r`: `(n,)` weighted residuals at the optimum (dimensionless when weighted by the noise).
    - `blocks`: slices of `r` in record order (positions, times, one record after another);
      rows outside every block are ignored. Rows with `r = 0` and a zero Jacobian row (padding,
      zero weight) are not counted.
    - `nuisance`: parameters already profiled out of `r` and `J` (the fits' clock shifts of
      timed records): not in `J`, but counted in the degrees of freedom.

    **Returns:** `(cov_corrected, cov_gn, inflation)`, covariances in the parameters' units
    squared:

    - `cov_gn = s^2 (J^T J)^-1` with `s^2 = rss / (n - q - nuisance)`;
    - `inflation >= 1` [-]: the largest ratio, over the identified parameters, of the variance
      under AR(1) residuals to the Gauss-Newton variance: the sandwich
      `(J^T J)^-1 (sum_b J_b^T R_b J_b) (J^T J)^-1` with `R_b` the AR(1) correlation matrix
      `rho_b^|i-j|` of block `b`; `rho_b` in `[-RHO_MAX, RHO_MAX]` is the AR(1) coefficient
      whose expected residual lag-1 autocorrelation, after the fit (hat matrix of `J`) has
      absorbed what it can, equals the observed one (method of moments; the raw residual
      correlation would understate it badly when the parameters shape the error); the noise
      variance `rss / (n - tr((J^T J)^-1 sum_b J_b^T R_b J_b) - nuisance)` (the expected
      residual sum of squares under those correlations). For smooth regressors this is the familiar
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
    if n <= q + nuisance or not np.all(np.isfinite(J[used])) or not np.all(np.isfinite(r[used])):
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
    s2 = rss / (n - q - nuisance)
    cov_gn = s2 * pinv
    nonempty = [idx for idx in rows if idx.size]
    _, grams = _block_rhos([J[idx] for idx in nonempty], [r[idx] for idx in nonempty], pinv)
    meat = sum(grams, np.zeros((q, q)))
    # E[rss] = sigma^2 (n - tr(H R)) under correlated residuals, tr(H R) = tr((J^T J)^+ meat)
    s2_ar = rss / max(n - float(np.trace(pinv @ meat)) - nuisance, 1.0)
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
