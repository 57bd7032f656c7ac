"""fits._stats: residual diagnostics and autocorrelation-corrected covariances (pure NumPy)."""

import math

import numpy as np
import pytest

from fits._stats import covariance, diagnostics


def _ar1(rng, n, rho):
    e = rng.normal(size=n)
    x = np.empty(n)
    x[0] = e[0] / np.sqrt(1 - rho**2)
    for i in range(1, n):
        x[i] = rho * x[i - 1] + e[i]
    return x


def test_white_noise_diagnostics():
    ps, lags, neff = [], [], []
    for seed in range(300):
        rng = np.random.default_rng(seed)
        blocks = [rng.normal(size=300), rng.normal(size=200)]
        d = diagnostics(blocks, 3)
        ps.append(d["runs_p"])
        lags.append(d["lag1"])
        assert 0.7 * 500 < d["n_eff"] <= 500
        neff.append(d["n_eff"])
        if d["runs_p"] > 1e-3 and abs(d["lag1"]) < 0.5:
            assert d["warnings"] == []
    ps = np.asarray(ps)
    # |rho| of white noise is ~ 0.8 / sqrt(n_b), so n_eff averages ~ 0.9 n (measured 0.89)
    assert 0.85 * 500 < np.mean(neff) <= 500, np.mean(neff)
    assert abs(np.mean(lags)) < 0.01 and np.std(lags) < 1.5 / np.sqrt(500)
    # runs-test p-values roughly uniform: deciles each hold 10 % +- 6 %
    counts = np.histogram(ps, bins=10, range=(0, 1))[0] / ps.size
    assert np.all(np.abs(counts - 0.1) < 0.06), counts
    assert 0.01 < np.mean(ps < 0.05) < 0.1


def test_white_noise_of_a_short_record_is_not_called_structure():
    """Two blocks of 12 white residuals (the positions and times of 13 turning points): a
    lag-1 autocorrelation beyond 0.5 is common there (its standard deviation is 0.29), and
    with 0.5 alone 175 of 2000 such records were flagged "the model does not explain the
    data" (4 of 10 fits of the exact oscillator to 13 extracted turning points); flagged where
    it is also beyond white noise's 3.29 standard deviations, 1 of 2000."""
    rng = np.random.default_rng(11)
    flagged = sum(
        bool(diagnostics([rng.normal(size=12), rng.normal(size=12)], 5)["warnings"])
        for _ in range(2000)
    )
    assert flagged <= 10, flagged
    # structure in a short block is still structure
    alt = np.array([1.0, -1.0] * 10) + 0.1 * rng.normal(size=20)
    (w,) = diagnostics([alt, rng.normal(size=20)], 5, ["the positions of a", "the times of a"])[
        "warnings"
    ]
    assert "(the positions of a; pooled" in w, w


def test_ar1_effective_sample_size_and_warning():
    rng = np.random.default_rng(7)
    blocks = [_ar1(rng, 5000, 0.8) for _ in range(4)]
    d = diagnostics(blocks, 2)
    theory = 20000 * (1 - 0.8) / (1 + 0.8)
    assert abs(d["n_eff"] / theory - 1) < 0.15, d["n_eff"]
    assert 0.75 < d["lag1"] < 0.85
    assert d["runs_p"] < 1e-12
    (w,) = d["warnings"]
    assert w.startswith("the model does not explain the data: residual lag-1 autocorrelation 0.8")
    assert "model_comparison" in w
    # a block worse than the pooled figure is named in the warning, with the pooled figure
    white = rng.standard_normal(400)
    d = diagnostics([white, _ar1(rng, 60, 0.95)], 2, ["the positions of a", "the times of a"])
    (w,) = d["warnings"]
    assert f"(the times of a; pooled {d['lag1']:.2f})" in w, w
    # alternating structure (signed turning points of a smooth model error) is structure too
    alt = [b * (-1.0) ** np.arange(b.size) for b in blocks]
    d = diagnostics(alt, 2)
    assert d["lag1"] < -0.75 and abs(d["n_eff"] / theory - 1) < 0.15 and d["warnings"]


def test_runs_and_edge_cases():
    d = diagnostics([np.ones(30)], 2)  # all one sign: structured
    assert d["runs_p"] < 1e-8 and d["warnings"]
    d = diagnostics([np.array([0.5])], 1)
    assert np.isnan(d["runs_p"]) and d["n_eff"] == 2.0
    d = diagnostics([np.array([1.0, -1.0] * 20)], 1)  # perfectly alternating: too many runs
    assert d["runs_p"] < 1e-6 and d["lag1"] < -0.9


def _regression_coverage(alternating: bool, seeds=200, n=200, rho=0.8):
    t = np.linspace(0.0, 1.0, n)
    sign = (-1.0) ** np.arange(n) if alternating else np.ones(n)
    J = np.stack([sign, sign * t], axis=1)
    hits_c = hits_gn = 0
    inflations = []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        y = J @ np.array([1.0, 2.0]) + 0.1 * sign * _ar1(rng, n, rho)
        beta, *_ = np.linalg.lstsq(J, y, rcond=None)
        r = J @ beta - y
        cov_c, cov_gn, inflation = covariance(J, r, [slice(0, n)])
        assert np.allclose(cov_c, inflation * cov_gn) and inflation >= 1
        inflations.append(inflation)
        hits_c += abs(beta[1] - 2.0) < 1.96 * np.sqrt(cov_c[1, 1])
        hits_gn += abs(beta[1] - 2.0) < 1.96 * np.sqrt(cov_gn[1, 1])
    return hits_c, hits_gn, float(np.mean(inflations))


@pytest.mark.parametrize("alternating", [False, True])
def test_ar1_regression_coverage(alternating):
    """Slope of a linear regression with AR(1) errors (rho = 0.8, n = 200) over 200 seeds:
    measured 187/200 corrected vs 98/200 Gauss-Newton (smooth regressors; alternating ones the
    same, by symmetry); the mean inflation 9.36 against the theoretical (1 + rho)/(1 - rho) = 9."""
    hits_c, hits_gn, mean_inflation = _regression_coverage(alternating)
    assert hits_c >= 180, hits_c
    assert hits_gn <= 120, hits_gn
    assert abs(mean_inflation / 9.0 - 1) < 0.1, mean_inflation


def test_white_noise_regression_not_inflated_much():
    n = 200
    t = np.linspace(0.0, 1.0, n)
    J = np.stack([np.ones(n), t], axis=1)
    infl = []
    for seed in range(50):
        rng = np.random.default_rng(seed)
        y = rng.normal(size=n)
        r = J @ np.linalg.lstsq(J, y, rcond=None)[0] - y
        c, g, f = covariance(J, r, [slice(0, n)])
        assert np.allclose(g, (r @ r / (n - 2)) * np.linalg.inv(J.T @ J))
        infl.append(f)
    assert 1.0 <= np.median(infl) < 1.3


def test_a_profiled_nuisance_parameter_gives_the_same_covariance():
    """A weighted time shift profiled out of the residuals (`fits._solve._align_clocks`: the
    residuals and the Jacobian projected off the weights' direction), with `nuisance=1`, gives
    the Gauss-Newton covariance of the other parameters that fitting the shift as a
    parameter gives, to rounding."""
    rng = np.random.default_rng(3)
    n = 40
    w = rng.uniform(0.5, 2.0, n)  # the weights of the times
    J = rng.normal(size=(n, 3))
    r = rng.normal(size=n)
    full = np.column_stack([J, w])  # the shift's column: d(w (dt - s))/ds = -w, sign immaterial
    w_hat = w / np.linalg.norm(w)
    project = np.eye(n) - np.outer(w_hat, w_hat)
    r_full = r - full @ np.linalg.lstsq(full, r, rcond=None)[0]  # residuals at the optimum
    _, g_full, _ = covariance(full, r_full, [slice(0, n)])
    _, g_prof, _ = covariance(project @ J, project @ r_full, [slice(0, n)], nuisance=1)
    np.testing.assert_allclose(g_prof, g_full[:3, :3], rtol=1e-10)
    _, g_naive, _ = covariance(project @ J, project @ r_full, [slice(0, n)])
    assert not np.allclose(g_naive, g_full[:3, :3], rtol=1e-3)  # the degree of freedom counts


def test_rank_deficient_gives_nan_never_zero():
    rng = np.random.default_rng(1)
    n = 50
    a = rng.normal(size=n)
    b = rng.normal(size=n)
    r = rng.normal(size=n)
    # a duplicated direction: the two parameters along it are NaN, the third is finite
    J = np.stack([a, 2 * a, b], axis=1)
    cov_c, cov_gn, inflation = covariance(J, r, [slice(0, n)])
    for cov in (cov_c, cov_gn):
        assert np.all(np.isnan(cov[:2, :])) and np.all(np.isnan(cov[:, :2]))
        assert np.isfinite(cov[2, 2]) and cov[2, 2] > 0
    # a parameter the residuals do not depend on at all
    J = np.stack([a, np.zeros(n)], axis=1)
    cov_c, cov_gn, _ = covariance(J, r, [slice(0, n)])
    assert np.isfinite(cov_gn[0, 0]) and np.all(np.isnan(cov_gn[1]))
    assert np.all(np.isnan(cov_c[:, 1]))
    # nearly collinear beyond the rank tolerance (1e-8 relative) is rank deficient too
    J = np.stack([a, a + 1e-12 * b], axis=1)
    assert np.all(np.isnan(covariance(J, r, [slice(0, n)])[1]))
    # too few residuals
    assert np.all(np.isnan(covariance(J[:2], r[:2], [slice(0, 2)])[0]))


def test_blocks_and_padding():
    """Padding rows (zero residual, zero Jacobian) are not counted; blocks are separate series."""
    rng = np.random.default_rng(3)
    n = 120
    J1 = np.stack([np.ones(n), np.linspace(0, 1, n)], axis=1)
    r1 = rng.normal(size=n)
    pad = np.zeros((8, 2))
    J = np.concatenate([J1, pad, J1, pad])
    r = np.concatenate([r1, np.zeros(8), r1, np.zeros(8)])
    blocks = [slice(0, n + 8), slice(n + 8, 2 * n + 16)]
    _, g, _ = covariance(J, r, blocks)
    JJ = np.concatenate([J1, J1])
    rr = np.concatenate([r1, r1])
    assert np.allclose(g, rr @ rr / (2 * n - 2) * np.linalg.inv(JJ.T @ JJ))
    with pytest.raises(ValueError, match="J must be"):
        covariance(J[:, 0], r, blocks)


# -- the report and figure of a joint, amplitude-only result (no fit needed to draw one) -------
def _result(records, residuals, params, stderr):
    import fits

    rec = records[0]
    warn = ["xF is not identified by these data: no standard error"]
    per = (
        [
            {
                "source": r.source,
                "params": {"offset": 0.0},
                "stderr": {"offset": None},
                "intervals": {"offset": (math.nan, math.nan)},
                "residuals": res,
                "rms": 0.1,
            }
            for r, res in zip(records, residuals)
        ]
        if len(records) > 1
        else []
    )
    return fits.FitResult(
        model="oscillator",
        forward="exact",
        loss="l2",
        optimizer="lm",
        params=params,
        fixed={"offset": 0.0, "asym": 0.0},
        stderr=stderr,
        correlation=[[1.0, float("nan")], [float("nan"), 1.0]],
        converged=False,
        iterations=7,
        rms=0.1,
        rms_time=None,
        model_comparison={},
        residuals=residuals[0],
        outliers=[],
        warnings=warn,
        decrement=fits.decrement(rec),
        record=rec,
        stderr_gn={"zeta": 0.001, "xF": None},
        intervals={"zeta": (0.009, 0.011), "xF": (math.nan, math.nan)},
        diagnostics={"lag1": 0.7, "runs_p": 1e-5, "n_eff": 3.2, "warnings": list(warn)},
        n_residuals=12,
        records=per,
        units={"zeta": "-", "xF": "signal", "offset": "signal"},
        label="both",
    )


def test_report_and_figure_of_a_joint_amplitude_only_result(tmp_path):
    import fits

    amps = 10 * 0.9 ** np.arange(12)
    records = [
        fits.record_from_sequence(amplitudes=amps * s, source=f"r{i}")
        for i, s in enumerate((1.0, 1.1))
    ]
    assert not records[0].sides_known
    residuals = [
        {
            "k": list(range(12)),
            "position": list(0.01 * np.sin(np.arange(12))),
            "time": None,
            "outlier": [False] * 11 + [True],
        }
        for _ in records
    ]
    result = _result(records, residuals, {"zeta": 0.01, "xF": 0.02}, {"zeta": 0.002, "xF": None})
    text = result.report()
    assert "2 records" in text and "per record:" in text and "r1: offset=0" in text
    assert (
        "xF =         0.02 (no standard error)" in text
        and "gn +- nan" not in text
        and "95 % [0.009, 0.011]" in text
    )
    assert "  correlation:" not in text and "lag-1 autocorrelation 0.7" in text
    assert text.count("not identified") == 1  # in warnings and diagnostics: listed once
    path = tmp_path / "joint.svg"
    fits.plot_fit(result, path)
    assert path.read_text().startswith("<?xml")


# -- the profile-likelihood root finding (fits._solve._profile_step), on given profiles --------
def _drive_profile_end(deviance, est=0.0, wald=1.0, steps=8):
    """Drive one interval end (side +1) of `fits._solve._profiles`' iteration on a profile
    deviance given as a function: returns (v, ok, the deviances visited)."""
    from types import SimpleNamespace

    from fits._solve import _CHI2_95, _PROFILE_STEPS, _profile_end, _profile_step

    assert steps == _PROFILE_STEPS
    job = SimpleNamespace(rss=10.0)
    request = (job, None, [est], None, 1.0, 1.0)  # (job, problem, est, se, inflation, s2)
    st = _profile_end(0, 0, 1, est, est + wald, math.inf, "optimum", _CHI2_95)
    seen = []
    for _ in range(steps):
        dev = deviance(st["v"])
        seen.append(dev)
        out = {"r": np.array([math.sqrt(job.rss + dev)]), "p": st["v"]}  # rss = job.rss + dev
        _profile_step(st, out, request)
        if st["done"]:
            break
    return st["v"], st["ok"], seen


def test_profile_ends_quadratic_curved_and_jumping():
    """The end of a quadratic profile is found in one step from the Wald end (the regula falsi
    through the estimate is exact there); a profile that steepens beyond the estimate's
    neighbourhood (where extrapolating from the last point alone alternates between two points
    on either side and fails, as the end `zeta +` of the pendulum fit of 80P.txt did) is
    bracketed and found within the tolerance (2 % of the deviance); where the profile jumps over
    the target (another local minimum), an end is either the jump's place to 1 % of its
    distance or reported as not found (the Wald interval is used then), never elsewhere."""
    from fits._solve import _CHI2_95 as target  # (inflation 1)

    v, ok, seen = _drive_profile_end(lambda v: (v / 0.8) ** 2)
    assert ok and len(seen) == 2 and v == pytest.approx(0.8 * math.sqrt(target), rel=1e-12)

    steep = lambda v: (v / 0.8) ** 2 * math.exp(6 * max(v - 1.2, 0))  # noqa: E731
    v, ok, seen = _drive_profile_end(steep)
    assert ok and abs(steep(v) / target - 1) < 0.02
    naive = [1.0]  # the extrapolation alone: v <- v sqrt(target / deviance(v))
    for _ in range(8):
        naive.append(naive[-1] * math.sqrt(target / steep(naive[-1])))
    assert abs(steep(naive[-1]) / target - 1) > 0.02  # (why the bracket is needed)

    for at in (1.05, 1.2, 1.3, 1.45, 1.55):
        jump = lambda v: (v / 0.8) ** 2 + (50.0 if v > at else 0.0)  # noqa: E731,B023
        v, ok, _ = _drive_profile_end(jump)
        assert not ok or abs(v - at) <= 0.01 * at + 1e-12, (at, v)


# -- the Levenberg-Marquardt solve's ends (fits._solve._LevenbergMarquardt) -------------------
def _least_squares(residuals, y0, strict=False, max_steps=200):
    """Solve with the fits' Levenberg-Marquardt (or optimistix's own, `strict`): (y, rss,
    steps, converged)."""
    import jax
    import jax.numpy as jnp
    import optimistix as optx

    from fits._solve import _LM_ATOL, _LM_RTOL, _LevenbergMarquardt

    def fn(y, _):
        r = residuals(y)
        return r, (r, jax.jacfwd(residuals)(y), jnp.ones_like(y))

    solver = (optx.LevenbergMarquardt if strict else _LevenbergMarquardt)(_LM_RTOL, _LM_ATOL)
    sol = optx.least_squares(
        fn, solver, jnp.asarray(y0), has_aux=True, max_steps=max_steps, throw=False
    )
    r = np.asarray(sol.aux[0])
    ok = bool(sol.result == optx.RESULTS.successful)
    return np.asarray(sol.value), float(r @ r), int(sol.stats["num_steps"]), ok


def test_relative_offset_against_a_direct_projection():
    """`_offset_and_scale` (Bates and Watts' relative offset, squared, and the residual
    variance) against the projection by NumPy's least squares, with a held slot (a zero column)
    and padding rows (zero), which count neither as parameters nor as data."""
    from fits._solve import _offset_and_scale

    rng = np.random.default_rng(3)
    n, p = 40, 3
    J = rng.normal(size=(n, p))
    r = rng.normal(size=n) + J @ np.array([0.3, -0.2, 0.1])
    coef = np.linalg.lstsq(J, r, rcond=None)[0]
    along, across = np.sum((J @ coef) ** 2), np.sum((r - J @ coef) ** 2)
    want = (along / p) / (across / (n - p))
    padded_J = np.zeros((n + 8, p + 1))
    padded_J[:n, [0, 1, 3]] = J  # slot 2 held
    padded_r = np.concatenate([r, np.zeros(8)])
    offset2, s2 = _offset_and_scale(padded_r, padded_J)
    assert float(offset2) == pytest.approx(want, rel=1e-10)
    assert float(s2) == pytest.approx(across / (n - p), rel=1e-10)


def test_levenberg_marquardt_ends_at_a_fraction_of_the_standard_errors():
    """Converged by the relative offset: a noisy exponential decay (60 points, noise 0.01)
    ends in fewer steps than optimistix's own test needs, at the same parameters to 1e-3 of
    their standard errors. No progress: in Rosenbrock's curved valley with noise rows
    (`10 (y1 - y0^2)`, `0.01 (1 - y0)`, 30 constant residuals of variance 1) optimistix's
    solver takes 392 steps to the minimum (1, 1); the fits' solver ends in fewer than 200,
    its residual sum of squares within 1e-3 residual variances of the minimum's, on the
    valley's floor within 1 % of y0's 95 % profile interval (y0 is barely determined: the
    interval is 1 +- 196)."""
    import jax.numpy as jnp

    rng = np.random.default_rng(5)
    t = np.linspace(0, 3, 60)
    data = 2.0 * np.exp(-1.3 * t) + 0.01 * rng.normal(size=t.size)

    def decay(y):
        return y[0] * jnp.exp(-y[1] * t) - data

    y, rss, steps, ok = _least_squares(decay, [1.0, 0.5])
    y_strict, rss_strict, steps_strict, ok_strict = _least_squares(decay, [1.0, 0.5], strict=True)
    assert ok and ok_strict and steps < steps_strict
    J = np.stack([np.exp(-y_strict[1] * t), -y_strict[0] * t * np.exp(-y_strict[1] * t)], 1)
    se = np.sqrt(np.diag(np.linalg.inv(J.T @ J)) * rss_strict / (t.size - 2))
    assert np.all(np.abs(y - y_strict) < 1e-3 * se)

    noise = rng.normal(size=30)
    noise *= math.sqrt(30 / (noise @ noise))  # residual variance about 1

    def valley(y):
        return jnp.concatenate([jnp.stack([10 * (y[1] - y[0] ** 2), 1e-2 * (1 - y[0])]), noise])

    y, rss, steps, ok = _least_squares(valley, [-1.2, 1.0], max_steps=2000)
    assert ok and steps < 200
    s2 = (noise @ noise) / (32 - 2)
    assert rss - noise @ noise < 1e-3 * s2
    # on the valley's floor, within 1 % of y0's 95 % profile interval (|1 - y0| <= 196)
    assert abs(y[1] - y[0] ** 2) < 1e-3 and abs(y[0] - 1) < 0.01 * 1.96 / 1e-2


def test_f_survival_function_against_scipy():
    """`fits._stats.f_sf` (the regularised incomplete beta function by its continued
    fraction; no SciPy at run time) against SciPy's F distribution, to 1e-10 relative (measured
    4e-12 at worst), into the far tail where the shared-parameter test of a joint fit lives."""
    from scipy.stats import f as scipy_f

    from fits._stats import f_sf

    for d1 in (1, 2, 3, 6, 12):
        for d2 in (1, 3, 10, 50, 150, 2000):
            for x in (1e-3, 0.1, 0.5, 1.0, 2.0, 3.7, 10.0, 100.0, 1e4):
                want = scipy_f.sf(x, d1, d2)
                assert f_sf(x, d1, d2) == pytest.approx(want, rel=1e-10, abs=1e-300), (x, d1, d2)
    assert f_sf(0.0, 2, 10) == 1.0 and f_sf(math.inf, 2, 10) == 0.0
