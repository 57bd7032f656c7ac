"""Rope of varying length (SYSTEMS.md section 2): exact solver against SciPy and the u = 0
energy map, the corrected first-order averaging, the action-averaged law, bad input, CLI."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cli_args import ROPE_MODEL
from hypothesis import given, settings, strategies as st
from scipy_rope import rope_turning_points

import vmj
from vmj._closed_forms._osinski import _kbm_printed
from vmj.cli import main

KG_CM2 = vmj.KGF * 1e4
E, D = 0.8e6 * KG_CM2, 0.8e11 * KG_CM2
M, AREA, L0 = 2 * vmj.KGF, 1.74e-4, 10.0
N = 210  # half-swings: covers 2 s for |u| <= 3 m/s (about 206 for u = 3)

# one batch, one compilation: (b, d, T [kG/cm^2], u [m/s], a0 [m])
CASES = {
    **{("kbm", u, T): (0.0, 0.0, T, u, 0.01) for u in (-3.0, 0.0, 3.0) for T in (0.0, 4.0)},
    ("map", "linear"): (0.0, 0.0, 4.0, 0.0, 0.04),
    ("map", "cubic"): (0.0, D, 4.0, 0.0, 0.04),
    ("map", "quadratic"): (2e8 * KG_CM2, D, 2.0, 0.0, 0.04),
    ("scale", 3.0): (0.0, 0.0, 0.0, 3.0, 0.04),
    ("scale", -3.0): (0.0, 0.0, 0.0, -3.0, 0.04),
    ("small", 3.0): (0.0, 0.0, 0.0, 3.0, 0.04 / 7),
    ("small", -3.0): (0.0, 0.0, 0.0, -3.0, 0.04 / 7),
    **{("action", u, T): (0.0, D, T, u, 0.04) for u in (-3.0, 0.0, 3.0) for T in (0.0, 4.0)},
}
KEYS = list(CASES)


def padded(t):
    """Times padded to the fixed length N (one compilation for every case)."""
    return jnp.asarray(np.concatenate([t, np.zeros(N - len(t))]))


def rope(b, d, T, u, l0=L0):
    return vmj.Rope(M, AREA, E, b, d, T * KG_CM2, vmj.ConstantSpeed(l0, u))


@pytest.fixture(scope="module")
def exact():
    cols = [jnp.array([CASES[k][i] for k in KEYS]) for i in range(5)]

    @jax.jit
    def run(b, d, T, u, a0):
        def one(b, d, T, u, a0):
            return vmj.turning_points(rope(b, d, T, u), a0, N, vmj.Exact(max_substeps=10))

        return jax.vmap(one)(b, d, T, u, a0)

    seq = run(*cols)
    out = {}
    for i, k in enumerate(KEYS):
        s = jax.tree.map(lambda x: x[i], seq)
        assert int(s.result) in (vmj.RESULTS.successful, vmj.RESULTS.stopped), s.message
        got = s.reached()
        out[k] = (got["times"], got["positions"], bool(s.stopped))
    return out


@pytest.mark.parametrize("u", [-3.0, 0.0, 3.0])
@pytest.mark.parametrize("T", [0.0, 4.0])
def test_kbm_matches_exact_for_linear_rope(exact, u, T):
    """Corrected first-order amplitude vs exact turning points, b = d = 0, a0 = 1 cm, 2 s:
    within 1e-3 of the exact amplitude while it is above 10 % of a0."""
    t, x, _ = exact[("kbm", u, T)]
    keep = (t <= 2.0) & (np.abs(x) > 0.1 * 0.01)
    assert keep.sum() > 50
    a = np.asarray(vmj.kbm_amplitude(rope(0.0, 0.0, T, u), 0.01, padded(t)))[: len(t)][keep]
    err = np.max(np.abs(a - np.abs(x[keep])) / np.abs(x[keep]))
    assert err < 1e-3, err


def test_printed_kbm_violates_its_ode_and_corrected_satisfies_it():
    """Residual of (2.6), da/dt + a u/(4 l) + D sqrt(l), with da/dt from jax.grad."""
    r = vmj.Rope.paper(u=3.0, T=4.0)
    D_ = 2 * r.T / (jnp.pi * jnp.sqrt(r.e * r.m / r.A))
    a0 = 0.01

    def residual(f, t):
        a = f(t)
        l = r.length.length(t)
        return (jax.grad(f)(t) + a * 3.0 / (4 * l) + D_ * jnp.sqrt(l)) / (D_ * jnp.sqrt(l))

    corrected = lambda t: vmj.kbm_amplitude(r, a0, t)  # noqa: E731
    printed = lambda t: _kbm_printed(r, a0, t)  # noqa: E731
    ts = jnp.array([0.05, 0.2, 0.5])
    assert np.max(np.abs(jax.vmap(lambda t: residual(corrected, t))(ts))) < 1e-9
    assert np.min(np.abs(jax.vmap(lambda t: residual(printed, t))(ts))) > 0.5
    assert float(printed(jnp.asarray(1.0))) < 0  # the printed form goes negative within a second


@pytest.mark.parametrize("which", ["linear", "cubic", "quadratic"])
def test_energy_map_matches_exact(exact, which):
    """u = 0: exact energy map per swing vs the exact solver, 1e-8 relative (times too)."""
    b, d, T, u, a0 = CASES[("map", which)]
    t, x, stopped = exact[("map", which)]
    seq = vmj.turning_points(rope(b, d, T, u), jnp.asarray(a0), N, vmj.EnergyBalance())
    got = seq.reached()
    assert len(got["positions"]) == len(x) and bool(seq.stopped) == stopped
    assert np.max(np.abs(got["positions"] - x) / np.abs(x)) < 1e-8
    assert np.max(np.abs(got["times"] - t) / t) < 1e-8
    # the balance itself: V(x_k) - V(x_{k+1}) = A T |x_k - x_{k+1}|
    r = rope(b, d, T, u)
    xs = np.concatenate([[-a0], x])
    V = np.asarray(r.potential(jnp.asarray(xs), L0))
    lhs, rhs = V[:-1] - V[1:], float(r.A * r.T) * np.abs(np.diff(xs))
    assert np.max(np.abs(lhs - rhs)) < 1e-9 * np.max(V)


@settings(max_examples=10)
@given(T=st.floats(0.1, 10.0), d=st.floats(0.0, 1.0), a0=st.floats(0.002, 0.06))
def test_energy_map_invariants(T, d, a0):
    """Fixed length, b = 0: amplitudes fall by less than the linear decrement 2 T l/e per swing
    (the cubic spring only shortens it), alternate sides until they stick, and time moves on."""
    seq = vmj.turning_points(
        rope(0.0, d * D, T, 0.0), jnp.asarray(a0), N, vmj.EnergyBalance()
    ).reached()
    a = np.concatenate([[a0], seq["amplitudes"]])
    step = 2 * T * KG_CM2 * L0 / E
    assert np.all(np.diff(a) < 0) and np.all(-np.diff(a) <= step * (1 + 1e-9))
    assert np.all(np.diff(np.concatenate([[0.0], seq["times"]])) > 0)
    assert np.all(seq["crossed"][:-1])


def test_linear_frictionless_ratio_independent_of_a0(exact):
    """T = 0, b = d = 0: a/a0 does not depend on a0 (the paper's claim), to 1e-9."""
    for u in (3.0, -3.0):
        t, x, _ = exact[("scale", u)]
        ts, xs, _ = exact[("small", u)]
        assert len(x) == len(xs) == N
        np.testing.assert_allclose(xs * 7, x, rtol=1e-9)
        np.testing.assert_allclose(ts, t, rtol=1e-9)


@pytest.mark.parametrize("key", [("action", 3.0, 4.0), ("map", "quadratic"), ("action", -3.0, 0.0)])
def test_exact_matches_scipy(exact, key):
    """Exact solver vs an event-driven SciPy DOP853 integration: 1e-7 on the first 40 peaks."""
    b, d, T, u, a0 = CASES[key]
    r = rope(b, d, T, u)
    tr, xr = rope_turning_points(
        float(r.m), float(r.A), float(r.e), float(r.b), float(r.d), float(r.T), L0, u, a0, 40
    )
    t, x, _ = exact[key]
    assert len(tr) == 40
    np.testing.assert_allclose(x[:40], xr, rtol=1e-7)
    np.testing.assert_allclose(t[:40], tr, rtol=1e-7)


def test_action_law_beats_first_order_when_cubic_is_large(exact):
    """Paper's a0 = 4 cm: the action-averaged law stays within 1e-3 of the exact amplitudes over
    2 s (above 10 % a0) where first order is off by several per cent."""
    worst_action, worst_kbm = 0.0, 0.0
    for u in (-3.0, 0.0, 3.0):
        for T in (0.0, 4.0):
            t, x, _ = exact[("action", u, T)]
            keep = (t <= 2.0) & (np.abs(x) > 0.004)
            r = rope(0.0, D, T, u)
            a = np.abs(x[keep])
            act = np.asarray(vmj.action_amplitude(r, 0.04, padded(t)))[: len(t)][keep]
            kbm = np.asarray(vmj.kbm_amplitude(r, 0.04, padded(t)))[: len(t)][keep]
            worst_action = max(worst_action, np.max(np.abs(act - a) / a))
            worst_kbm = max(worst_kbm, np.max(np.abs(kbm - a) / a))
    assert worst_action < 1e-3
    assert worst_kbm > 0.05


def test_gradient_matches_finite_differences():
    """d x_k / d(T, e, d) through the exact solver vs central differences."""
    n = 12

    def peak(theta):
        T, e, d = theta
        r = vmj.Rope(M, AREA, e, 0.0, d, T, vmj.ConstantSpeed(L0, 2.0))
        return vmj.turning_points(r, jnp.asarray(0.02), n).positions[-1]

    theta = jnp.array([2 * KG_CM2, E, D])
    # forward mode compiles faster than reverse mode; both use the same differentiation rules
    value_and_grad = jax.jit(lambda th: (peak(th), jax.jacfwd(peak)(th)))
    g = np.asarray(value_and_grad(theta)[1])
    f = lambda th: float(value_and_grad(th)[0])  # noqa: E731
    for i in range(3):
        h = 1e-5 * float(theta[i])
        fd = (f(theta.at[i].add(h)) - f(theta.at[i].add(-h))) / (2 * h)
        assert abs(g[i] - fd) <= 1e-5 * abs(fd) + 1e-12, (i, g[i], fd)


def test_technical_units_constructor_is_differentiable():
    """`Rope.paper`/`Rope.from_technical` under `jax.grad` (it converted with NumPy: a
    TracerArrayConversionError): d x_4 / d T [m per kG/cm^2] vs central differences."""

    def peak(T):
        return vmj.turning_points(vmj.Rope.paper(u=3.0, T=T), 0.04, 4).positions[-1]

    g = float(jax.grad(peak)(4.0))
    h = 1e-4
    fd = (float(peak(4.0 + h)) - float(peak(4.0 - h))) / (2 * h)
    assert abs(g - fd) <= 1e-6 * abs(fd), (g, fd)


def test_smooth_matches_exact():
    r = vmj.Rope.paper(u=3.0, T=4.0)
    ex = vmj.turning_points(r, jnp.asarray(0.04), 12, vmj.Exact(max_substeps=10))
    sm = vmj.turning_points(r, jnp.asarray(0.04), 12, vmj.Smoothed())
    np.testing.assert_allclose(np.asarray(sm.positions), np.asarray(ex.positions), rtol=1e-8)
    np.testing.assert_allclose(np.asarray(sm.times), np.asarray(ex.times), rtol=1e-8)


def test_braking_drum_dynamic_force():
    """Problem book 4.1.3, problem 11: load lowered at u, the drum brakes in a short time
    tau; from rest relative to the rope, the load overshoots by u/omega (rectangular pulse:
    (2 u/(omega tau)) sin(omega tau/2)), so the dynamic rope stress is e x_max / l."""
    u, tau, l0 = -0.2094, 2e-3, 1.0
    A, e, m = np.pi * 0.01**2, 2e11, 1000.0
    r = vmj.Rope(m, A, e, 0.0, 0.0, 0.0, vmj.Braking(l0, u, 0.01, 0.01 + tau))
    traj = vmj.simulate(r, 1e-8, 0.0, 0.1, vmj.Smoothed(smoothing=1e-6), n_save=4001)
    assert traj.message == "reached every requested turning point"
    l_end = float(r.length.length(1.0))  # length after the stop
    omega = np.sqrt(A * e / (m * l_end))
    expected = 2 * abs(u) / (omega**2 * tau) * np.sin(omega * tau / 2)
    assert abs(float(jnp.max(jnp.abs(traj.xs))) / expected - 1) < 2e-3
    # exact solver: with friction the load sticks until the drum starts braking, is pushed off
    # by the inertial force m l'' at t_brake, and then decays by 2 A T / k per half-swing
    T = 2e6
    static = A * T
    k = A * e / l_end
    r = vmj.Rope(m, A, e, 0.0, 0.0, T, vmj.Braking(l0, u, 0.01, 0.01 + tau))
    seq = vmj.turning_points(
        r, jnp.asarray(0.5 * static / (A * e / l0)), 6, vmj.Exact(max_substeps=10)
    )
    x = np.asarray(seq.positions)
    assert seq.message == "reached every requested turning point"
    assert float(seq.times[0]) > 0.01 + tau
    # rectangular pulse -m|l''| for tau on a spring k, friction +A T against the motion from
    # rest at -start: equilibria (static - pulse)/k during the pulse and static/k after it
    pulse, start = m * abs(u) / tau, 0.5 * static / (A * e / l0)
    e1, e2 = (static - pulse) / k, static / k
    d = e1 - e2 + (-start - e1) * np.cos(omega * tau)
    v = -(-start - e1) * omega * np.sin(omega * tau)
    expected = e2 - np.hypot(d, v / omega)
    assert abs(x[0] / expected - 1) < 5e-3, (x[0], expected)
    np.testing.assert_allclose(-np.diff(np.abs(x)), 2 * static / k, rtol=1e-6)


@pytest.mark.parametrize(
    "bad, name",
    [
        (dict(A=0.0), "A"),
        (dict(e=-1.0), "e"),
        (dict(m=0.0), "m"),
        (dict(l0=0.0), "l0"),
        (dict(T=-1.0), "T"),
        (dict(e=float("nan")), "e"),
        (dict(d=-1.0), "d"),
    ],
)
def test_bad_parameters_raise(bad, name):
    p = dict(m=M, A=AREA, e=E, b=0.0, d=D, T=1e5, l0=L0)
    p.update(bad)
    with pytest.raises(ValueError, match=rf"^{name} must be"):
        vmj.Rope(p["m"], p["A"], p["e"], p["b"], p["d"], p["T"], vmj.ConstantSpeed(p["l0"], 1.0))


def test_horizon_beyond_zero_length_raises():
    r = vmj.Rope.paper(u=3.0)  # l = 0 at t = 10/3 s
    with pytest.raises(ValueError, match="rope length reaches zero"):
        vmj.kbm_amplitude(r, 0.01, jnp.array([1.0, 3.4]))
    with pytest.raises(ValueError, match="l\\(t\\) reaches 0"):
        vmj.simulate(r, -0.01, 0.0, 3.5)
    with pytest.raises(ValueError, match="u must be 0"):
        vmj.turning_points(r, 0.01, 5, vmj.EnergyBalance())
    with pytest.raises(ValueError, match="a0 must be"):
        vmj.kbm_amplitude(r, float("nan"), 1.0)


CLI = ["decay", "rope", *ROPE_MODEL, "--units", "technical"]


def test_cli_json_shape(capsys):
    assert main(CLI + ["--u", "3", "--a0", "1", "--t1", "0.05", "--method", "kbm", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == {"model", "method", "times", "amplitudes", "stopped"}
    assert out["model"] == "rope" and out["method"] == "kbm" and out["stopped"] is False
    assert len(out["times"]) == len(out["amplitudes"]) and out["times"][-1] == 0.05
    assert np.max(np.diff(out["times"])) < np.pi / 264  # at least every half period
    assert out["amplitudes"][0] == pytest.approx(0.01)
    assert main(CLI + ["--u", "-3", "--a0", "1", "--t1", "0.06", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "exact" and max(out["times"]) <= 0.06 and len(out["times"]) == 5


def test_cli_status_is_of_the_time_shown(capsys):
    """Turning points after --t1 are not shown, and the solve's status (of a time after it) is
    not either: a --t1 before the first turning point printed 'reached every requested
    turning point' over an empty table."""
    for t1, shown in (("0.005", 0), ("0.03", 2)):
        assert main(CLI + ["--u", "-3", "--a0", "1", "--t1", t1]) == 0
        out = capsys.readouterr().out
        assert f"status: reached --t1 {t1} s ({shown} turning points before it)" in out
        assert len(out.strip().splitlines()) == 2 + shown


def test_cli_kbm_of_a_mass_friction_holds_from_the_start(capsys):
    """With A T above the spring force at the release the mass never moves (the exact solver
    has no turning point); the averaged envelope decayed it to 0 in 5 ms all the same."""
    i = CLI.index("--T")
    argv = CLI[: i + 1] + ["1e6"] + CLI[i + 2 :]
    argv += ["--u", "0", "--a0", "1", "--t1", "0.05", "--method", "kbm"]
    assert main(argv + ["--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["times"] == [0.0] and out["amplitudes"] == [pytest.approx(0.01)] and out["stopped"]
    assert main(argv) == 0
    assert "the mass does not move" in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra",
    [
        ["--u", "3", "--a0", "1", "--t1", "4"],
        ["--u", "3", "--a0", "-1", "--t1", "1"],
        ["--u", "3", "--a0", "1", "--t1", "1", "--T", "-2"],
    ],
)
def test_cli_bad_input_exit_2(capsys, extra):
    base = list(CLI)
    if "--T" in extra:  # (an option may be given once)
        i = base.index("--T")
        del base[i : i + 2]
    assert main(base + extra + ["--method", "kbm"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vmj: error:") and err.count("\n") == 1


def test_a_swing_over_the_potential_barrier_is_refused():
    """b < 0: a swing from -a0 with more energy than the barrier has no turning point; the
    averaged laws refuse it and the u = 0 energy map reports it as a value."""
    moving = vmj.Rope(1000.0, 1e-4, 1e11, -1e13, 0.0, 1e6, vmj.ConstantSpeed(100.0, 2.0))
    for law in (vmj.kbm_amplitude, vmj.action_amplitude):
        with pytest.raises(Exception, match="above the potential barrier"):
            law(moving, 0.6, jnp.linspace(0.0, 1.0, 3))
    fixed = vmj.Rope(1000.0, 1e-4, 1e11, -1e13, 0.0, 1e6, vmj.ConstantSpeed(100.0, 0.0))
    seq = vmj.turning_points(fixed, 0.6, 5, vmj.EnergyBalance())
    assert int(seq.result) == vmj.RESULTS.unbounded and int(seq.count) == 0
    # below the barrier the same rope has turning points
    assert int(vmj.turning_points(fixed, 0.05, 5, vmj.EnergyBalance()).count) > 0


def test_a_rope_run_out_says_so():
    """Hoisted at 3 m/s the 10 m rope's length reaches zero at t = 10/3 s: the swings there
    shrink with the length, and the solve ends with `length_exhausted` (it said "no velocity
    zero within the step limit")."""
    seq = vmj.turning_points(vmj.Rope.paper(u=3.0, T=4.0), 0.04, 6000)
    assert int(seq.result) == vmj.RESULTS.length_exhausted
    assert 3.3333 < float(np.asarray(seq.times)[int(seq.count) - 1]) < 10 / 3


def test_a_lowered_rope_that_runs_out_of_steps_is_not_run_out():
    """Lowered, the rope only grows: a swing too slow for the substeps (a cross-section of
    1e-24 m^2: a half-period of about 1e8 s) ends at the step limit. It said "the rope length
    l(t) reaches zero" (the substeps are bounded by l/|l'| either way)."""
    r = vmj.Rope.paper(u=-3.0, T=0.0)
    slow = vmj.Rope(r.m, 1e-24, r.e, r.b, r.d, r.T, r.length)
    seq = vmj.turning_points(slow, 0.04, 6000)
    assert int(seq.result) == vmj.RESULTS.step_limit and int(seq.count) == 0
