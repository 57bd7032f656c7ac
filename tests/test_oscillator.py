"""The identification oscillator: every restoring x dissipation combination by the exact solver
against an event-driven SciPy reference, the smoothed and energy-balance solutions against the
exact one, closed forms and limits, the static stick rule, gradients, batching and input checks.

Each restoring law is one model structure with every dissipation law present (coefficients zero
where a combination leaves a law out), batched with `jax.vmap`: one compilation per law and
solver.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy_oscillator import oscillator_turning_points

import vmj

OMEGA, A0, N = 6.0, 1.0, 24

#: restoring laws: (reference kind, b2, b3, the sine's share w)
RESTORING = {
    "linear": ("linear", 0.0, 0.0, 1.0),
    "polynomial": ("linear", 0.05, 0.3, 1.0),
    "sine": ("sine", 0.0, 0.0, 1.0),
    "sine+cubic": ("sine", 0.03, -0.02, 1.0),
    "sine+spring": ("sine", 0.03, 0.0, 0.5),
}
DISSIPATION = {
    "viscous": dict(zeta=0.01),
    "coulomb": dict(xF=0.01),
    "static": dict(xF=0.01, xS=0.03),
    "quadratic": dict(cq=0.05),
    "all": dict(zeta=0.005, xF=0.005, xS=0.012, cq=0.03),
}
#: the model structures: one per restoring law class
STRUCTURES = {
    "linear": ["linear"],
    "polynomial": ["polynomial"],
    "sine": ["sine", "sine+cubic", "sine+spring"],
}


def law(name):
    kind, b2, b3, w = RESTORING[name]
    if kind == "sine":
        return vmj.SineRestoring(b2, b3, w)
    return vmj.LinearRestoring() if name == "linear" else vmj.PolynomialRestoring(b2, b3)


def model(restoring, zeta=0.0, xF=0.0, xS=None, cq=0.0, omega=OMEGA):
    return vmj.Oscillator(
        omega,
        law(restoring),
        (vmj.ViscousDamping(zeta), vmj.CoulombDamping(xF, xS), vmj.QuadraticDamping(cq)),
    )


def stack(models):
    return jax.tree.map(lambda *xs: jnp.stack(xs), *models)


def cases(structure):
    return [(r, d) for r in STRUCTURES[structure] for d in DISSIPATION]


def batched(structure, solver, n=N, a0=A0):
    """Turning points of every case of a structure, as NumPy arrays `(times, positions, count)`
    (one compilation)."""
    models = stack([model(r, **DISSIPATION[d]) for r, d in cases(structure)])
    seq = jax.vmap(lambda m: vmj.turning_points(m, a0, n, solver))(models)
    assert not np.any(np.asarray(seq.failed)), np.asarray(seq.result)
    return np.asarray(seq.times), np.asarray(seq.positions), np.asarray(seq.count)


_cache = {}


def solved(structure, name):
    key = (structure, name)
    if key not in _cache:
        solver = {"exact": vmj.Exact(), "smooth": vmj.Smoothed(), "energy": vmj.EnergyBalance()}[
            name
        ]
        _cache[key] = batched(structure, solver)
    return _cache[key]


# -- the exact solver against SciPy ------------------------------------------------------------
@pytest.mark.parametrize("structure", list(STRUCTURES))
def test_exact_matches_scipy(structure):
    """Every combination: positions to 1e-9 of the amplitude, times to 1e-10 relative (measured:
    5e-12 and 6e-13)."""
    times, positions, count = solved(structure, "exact")
    for i, (r, d) in enumerate(cases(structure)):
        kind, b2, b3, w = RESTORING[r]
        rt, rx = oscillator_turning_points(OMEGA, A0, N, kind, b2=b2, b3=b3, w=w, **DISSIPATION[d])
        assert count[i] == len(rx), (r, d)
        np.testing.assert_allclose(positions[i, : len(rx)], rx, rtol=1e-9, err_msg=f"{r} {d}")
        np.testing.assert_allclose(times[i, : len(rt)], rt, rtol=1e-10, err_msg=f"{r} {d}")


# -- the smoothed and energy-balance solutions against the exact one ----------------------------
@pytest.mark.parametrize("structure", list(STRUCTURES))
def test_smoothed_matches_exact(structure):
    """At the default smoothing (1e-4 of the velocity scale): 1e-7 relative without a static
    level (measured 4e-8), 3e-6 with one (measured 1.6e-6 over 24 half-swings: the smoothed
    static level adds friction near each reversal)."""
    et, ex, ec = solved(structure, "exact")
    st_, sx, sc = solved(structure, "smooth")
    np.testing.assert_array_equal(sc, ec)
    for i, (r, d) in enumerate(cases(structure)):
        tol = 3e-6 if "xS" in DISSIPATION[d] else 1e-7
        np.testing.assert_allclose(sx[i], ex[i], rtol=tol, err_msg=f"{r} {d}")
        np.testing.assert_allclose(st_[i], et[i], rtol=tol, err_msg=f"{r} {d}")


@pytest.mark.parametrize("structure", list(STRUCTURES))
def test_energy_balance_matches_exact(structure):
    """Exact (1e-10) with dry friction alone; the averaged map with speed-dependent damping to
    its stated accuracy over 24 half-swings: amplitudes 5e-4, times 1e-3 relative (measured
    2e-4 and 5e-4 with about 5 % of the amplitude lost per half-swing)."""
    et, ex, ec = solved(structure, "exact")
    gt, gx, gc = solved(structure, "energy")
    np.testing.assert_array_equal(gc, ec)
    for i, (r, d) in enumerate(cases(structure)):
        exact = set(DISSIPATION[d]) <= {"xF", "xS"}
        tol = (1e-10, 1e-10) if exact else (5e-4, 1e-3)
        np.testing.assert_allclose(gx[i], ex[i], rtol=tol[0], err_msg=f"{r} {d}")
        np.testing.assert_allclose(gt[i], et[i], rtol=tol[1], err_msg=f"{r} {d}")


def test_averaged_energy_map_is_third_order_in_zeta():
    """The averaged map's amplitude error per half-swing is O(zeta^3): halving zeta divides the
    error after a fixed number of half-swings by about 8 (measured 7.9)."""

    def error(zeta):
        m = model("sine", zeta=zeta)
        ex = vmj.turning_points(m, A0, 8).positions
        en = vmj.turning_points(m, A0, 8, vmj.EnergyBalance()).positions
        return float(jnp.max(jnp.abs(en / ex - 1)))

    ratio = error(0.02) / error(0.01)
    assert 6 < ratio < 10, ratio


# -- closed forms and limits --------------------------------------------------------------------
@settings(max_examples=10)
@given(omega=st.floats(5.0, 40.0), zeta=st.floats(0.0, 0.2), xF=st.floats(0.0, 0.05))
def test_linear_oscillator_is_the_closed_form_map(omega, zeta, xF):
    """`Oscillator.linear`: the exact solver, the energy balance (its closed form) and the
    constant-mass variable-mass model agree with the map `x -> -s xF - rho (x + s xF)` written
    out here, `rho = exp(-zeta omega pi / omega_d)`, `pi/omega_d` per half-swing."""
    a0, n = 1.0, 12
    wd = omega * np.sqrt(1 - zeta**2)
    rho = np.exp(-zeta * omega * np.pi / wd)
    x, xs = -a0, []
    for _ in range(n):
        if abs(x) <= xF:
            break
        s = -np.sign(x)
        x = -s * xF - rho * (x + s * xF)
        xs.append(x)
    osc = vmj.Oscillator.linear(omega, zeta, xF)
    vm = vmj.VariableMass(1.0, omega**2, 0.0, 0.0, 2 * zeta * omega, vmj.Coulomb(omega**2 * xF))
    for seq in (
        vmj.turning_points(osc, a0, n, vmj.EnergyBalance()),
        vmj.turning_points(osc, a0, n),
        vmj.turning_points(vm, a0, n),
    ):
        assert int(seq.count) == len(xs)
        np.testing.assert_allclose(np.asarray(seq.positions)[: len(xs)], xs, atol=1e-10)
        np.testing.assert_allclose(
            np.asarray(seq.times)[: len(xs)], np.pi / wd * np.arange(1, len(xs) + 1), rtol=1e-10
        )


@pytest.mark.parametrize("zeta", [0.99, 0.995, 0.999])
def test_exact_solver_reaches_turning_points_near_critical_damping(zeta):
    """Near critical damping the half-swing `pi/omega_d` grows without bound; the exact
    solver's substeps span it within their default limit up to zeta = 0.999 (until
    2026-11-28 it reported a step limit from zeta = 0.985 on). Against the closed form
    (`rho = exp(-zeta omega pi/omega_d)` per half-swing): positions within 1e-12 of a0
    (measured 5e-39 to 3e-23), times within 1e-8 relative (measured 2e-10 to 8e-10)."""
    omega, n = 10.0, 3
    wd = omega * np.sqrt(1 - zeta**2)
    rho = np.exp(-zeta * omega * np.pi / wd)
    seq = vmj.turning_points(vmj.Oscillator.linear(omega, zeta), 1.0, n)
    assert int(seq.result) == vmj.RESULTS.successful, seq.message
    k = np.arange(1, n + 1)
    np.testing.assert_allclose(seq.positions, -((-rho) ** k), rtol=0, atol=1e-12)
    np.testing.assert_allclose(seq.times, np.pi / wd * k, rtol=1e-8)


def test_sine_tends_to_linear_at_small_amplitude():
    """The pendulum's turning points approach the linear oscillator's as `a0 -> 0`, the
    relative difference falling as `a0^2` (the frequency is `1 - a0^2/16 + ...`)."""

    def difference(a0):
        sine = vmj.Oscillator.pendulum(OMEGA, zeta=0.01, xF=0.01 * a0)
        lin = vmj.Oscillator.linear(OMEGA, zeta=0.01, xF=0.01 * a0)
        s, l_ = vmj.turning_points(sine, a0, 6), vmj.turning_points(lin, a0, 6)
        return float(jnp.max(jnp.abs(s.times / l_.times - 1)))

    d1, d2 = difference(0.1), difference(0.05)
    assert d1 < 1e-3
    assert 3.5 < d1 / d2 < 4.5, d1 / d2


@settings(max_examples=8)
@given(
    xF=st.floats(0.01, 0.05),
    extra=st.floats(0.0, 0.3),
    b3=st.floats(-0.05, 0.3),
    sine=st.booleans(),
)
def test_static_level_decides_where_the_mass_sticks(xF, extra, b3, sine):
    """The mass stops exactly at the first turning point where `|r(x)| <= xS`."""
    xS = xF + extra
    restoring = vmj.SineRestoring(0.0, b3) if sine else vmj.PolynomialRestoring(0.0, b3)
    osc = vmj.Oscillator(OMEGA, restoring, (vmj.CoulombDamping(xF, xS),))
    seq = vmj.turning_points(osc, 1.0, 60)
    assert bool(seq.stopped)
    x = np.concatenate([[-1.0], seq.reached()["positions"]])
    r = np.asarray(restoring.value(jnp.asarray(x)))
    assert np.all(np.abs(r[:-1]) > xS)
    assert abs(r[-1]) <= xS


def test_smoothed_model_sticks_with_the_static_level():
    """The smoothed static level stops the smoothed decay at the same turning point (with a
    large static excess, `xS - xF = 0.18 a0`, its extra friction near each reversal costs
    8e-5 relative by the stop)."""
    osc = vmj.Oscillator(OMEGA, vmj.SineRestoring(), (vmj.CoulombDamping(0.02, 0.2),))
    ex = vmj.turning_points(osc, 1.0, 30)
    sm = vmj.turning_points(osc, 1.0, 30, vmj.Smoothed())
    assert bool(ex.stopped) and bool(sm.stopped)
    assert int(ex.count) == int(sm.count) < 30
    np.testing.assert_allclose(sm.positions, ex.positions, rtol=2e-4)


@pytest.mark.parametrize("zeta", [1.0001, 1.5, 10.0])
def test_overdamped_release_has_no_turning_point_in_either_solver(zeta):
    """A mass released from rest at `-a0` with damping above critical never reverses: the
    exact solver reports no velocity zero (`step_limit`). The smoothed one reported a turning
    point where the mass slowed through its creep speed (`20 w`) on its approach to rest (zeta
    1.0001 and 1.5, at 2e-3 and 5e-3 of a0; with friction 1e-5, 'stopped' there), reversals of
    roundoff size near x = 0 after it (four, at 3e-15 of a0, over a longer horizon), and
    'stopped' where it crept into a tiny friction's band by the horizon. Now both say no
    turning point, step_limit, frictionless and with tiny dry friction (1e-9 and 1e-5 of a0),
    over the horizons of 4 and 12 turning points. A decay with real stops still ends alike."""
    for xF in (0.0, 1e-10, 1e-6):
        osc = vmj.Oscillator.linear(OMEGA, zeta, xF)
        for n in (4, 12):
            exact = vmj.turning_points(osc, 0.1, n, vmj.Exact())
            smooth = vmj.turning_points(osc, 0.1, n, vmj.Smoothed())
            assert int(exact.count) == int(smooth.count) == 0, (xF, n)
            assert int(exact.result) == int(smooth.result) == vmj.RESULTS.step_limit, (xF, n)
    osc = vmj.Oscillator.linear(OMEGA, 0.3, 0.01)  # under-damped: stops after two swings
    exact = vmj.turning_points(osc, 0.1, 12, vmj.Exact())
    smooth = vmj.turning_points(osc, 0.1, 12, vmj.Smoothed())
    assert int(exact.count) == int(smooth.count) == 2
    assert int(exact.result) == int(smooth.result) == vmj.RESULTS.stopped


# -- a pendulum released near the upright position ----------------------------------------------
UPRIGHT = dict(zeta=0.01, xF=0.001)


@pytest.mark.parametrize("a0", [2.8, 3.0, 3.1, 3.14])
def test_pendulum_near_upright_by_default(a0):
    """The documented release range `(0, pi)`: the default exact solver reaches every turning
    point near the separatrix (with 12 substeps of `0.3 K'/omega` it stopped at 2.8 rad with
    "no velocity zero within the step limit"), to SciPy's accuracy (measured: 2e-13 in
    position, 9e-13 in time)."""
    seq = vmj.turning_points(vmj.Oscillator.pendulum(1.0, **UPRIGHT), a0, 6)
    assert int(seq.result) == 0, seq.message
    rt, rx = oscillator_turning_points(1.0, a0, 6, "sine", rtol=1e-13, **UPRIGHT)
    np.testing.assert_allclose(np.asarray(seq.positions), rx, rtol=1e-11)
    np.testing.assert_allclose(np.asarray(seq.times), rt, rtol=1e-11)


def test_pendulum_near_upright_other_solvers_and_damping():
    """Up to `pi - 1e-4` without friction (the undamped pendulum returns to the hilltop every
    half-swing: exact times `2 K(k) j/omega`, to the conditioning, ~1e-16/(pi - a0)), and
    with damping or drag up to 3.14 rad; the smoothed solver reaches the same turning
    points."""
    from scipy.special import ellipkm1

    a0 = jnp.array([3.0, 3.1, 3.14, np.pi - 1e-4])
    undamped = jax.vmap(lambda a: vmj.turning_points(vmj.Oscillator.pendulum(2.0), a, 4))(a0)
    assert not np.any(np.asarray(undamped.failed))
    quarter = ellipkm1(np.cos(np.asarray(a0) / 2) ** 2)  # K(k), k = sin(a0/2)
    times = 2 * quarter[:, None] * np.arange(1, 5) / 2.0
    np.testing.assert_allclose(undamped.times, times, rtol=2e-5)
    np.testing.assert_allclose(undamped.times[:2], times[:2], rtol=1e-10)
    signs = (-1.0) ** np.arange(4)
    np.testing.assert_allclose(undamped.positions, np.asarray(a0)[:, None] * signs, rtol=1e-8)
    for kw in (dict(zeta=0.2), dict(cq=0.1), dict(zeta=0.05, xF=0.001, cq=0.05)):
        seq = vmj.turning_points(vmj.Oscillator.pendulum(1.0, **kw), 3.14, 4)
        assert int(seq.result) == 0, (kw, seq.message)
        rt, rx = oscillator_turning_points(1.0, 3.14, 4, "sine", rtol=1e-13, **kw)
        np.testing.assert_allclose(np.asarray(seq.positions), rx, rtol=1e-11, err_msg=str(kw))
        np.testing.assert_allclose(np.asarray(seq.times), rt, rtol=1e-11, err_msg=str(kw))
    osc = vmj.Oscillator.pendulum(1.0, **UPRIGHT)
    ex, sm = vmj.turning_points(osc, 3.1, 6), vmj.turning_points(osc, 3.1, 6, vmj.Smoothed())
    assert int(sm.result) == 0
    np.testing.assert_allclose(sm.positions, ex.positions, rtol=1e-8)
    np.testing.assert_allclose(sm.times, ex.times, rtol=1e-4)  # (measured 1.6e-5)


def test_pendulum_near_upright_trajectory_and_derivatives():
    """`vmj.decay_trajectory` samples the same substeps (against SciPy's dense output), and the
    derivatives run the bounded loop, nested in blocks of 8 substeps, to the same values as
    the early-exit one and central differences."""
    from scipy_oscillator import motion

    osc = vmj.Oscillator.pendulum(1.0, **UPRIGHT)
    segments = []
    rt, rx = oscillator_turning_points(
        1.0, 3.1, 4, "sine", rtol=1e-13, segments=segments, **UPRIGHT
    )
    ts = np.linspace(0.0, 0.999 * rt[-1], 1501)
    traj = vmj.decay_trajectory(osc, 3.1, ts, 4)
    assert int(traj.result) == 0
    np.testing.assert_allclose(traj.xs, motion(segments, 3.1, ts, rx[-1]), atol=1e-10)

    def f(p, derivatives):
        zeta, xF = p
        seq = vmj.turning_points(
            vmj.Oscillator.pendulum(1.0, zeta=zeta, xF=xF),
            3.1,
            4,
            vmj.Exact(derivatives=derivatives),
        )
        return jnp.concatenate([seq.positions, seq.times])

    p = jnp.array([0.01, 0.001])
    bounded = np.asarray(jax.jacfwd(lambda q: f(q, "any"))(p))
    early = np.asarray(jax.jacfwd(lambda q: f(q, "forward"))(p))
    np.testing.assert_allclose(bounded, early, rtol=1e-10)
    h = 1e-7
    for i in range(2):
        step = jnp.zeros(2).at[i].set(h)
        fd = (f(p + step, "forward") - f(p - step, "forward")) / (2 * h)
        np.testing.assert_allclose(bounded[:, i], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


# -- gradients ----------------------------------------------------------------------------------
NAMES = ("omega", "zeta", "xF", "cq", "b2", "b3", "a0")


def _sequence(p, restoring, solver=None):
    omega, zeta, xF, cq, b2, b3, a0 = p
    law = vmj.SineRestoring(b2, b3) if restoring == "sine" else vmj.PolynomialRestoring(b2, b3)
    osc = vmj.Oscillator(
        omega, law, (vmj.ViscousDamping(zeta), vmj.CoulombDamping(xF), vmj.QuadraticDamping(cq))
    )
    seq = vmj.turning_points(osc, a0, 10, solver)
    return jnp.concatenate([seq.positions, seq.times])


@pytest.mark.parametrize("restoring,derivatives", [("sine", "any"), ("polynomial", "forward")])
def test_gradients_match_finite_differences(restoring, derivatives):
    """`jax.jacfwd` of the turning points (positions and times) with respect to every law's
    parameters and `a0` against central differences (step 1e-6 relative), through the exact
    solver's bounded loops (`derivatives="any"`) and its early-exit loops (`"forward"`, whose
    reverse mode is refused)."""
    p = jnp.array([6.0, 0.01, 0.01, 0.05, 0.04, 0.2, 1.1])
    solver = vmj.Exact(derivatives=derivatives)
    f = lambda q: _sequence(q, restoring, solver)  # noqa: E731
    jac = np.asarray(jax.jacfwd(f)(p))
    h = 1e-6 * np.maximum(np.abs(np.asarray(p)), 1e-2)
    steps = np.diag(h)
    both = jax.vmap(f)(jnp.concatenate([p + steps, p - steps]))
    fd = np.asarray((both[: len(p)] - both[len(p) :]) / (2 * h[:, None])).T
    for i, name in enumerate(NAMES):
        scale = np.max(np.abs(fd[:, i]))
        np.testing.assert_allclose(jac[:, i], fd[:, i], rtol=1e-5, atol=1e-6 * scale, err_msg=name)
    if derivatives == "forward":
        with pytest.raises(ValueError, match="Reverse-mode differentiation does not work"):
            jax.grad(lambda q: f(q)[3])(p)


@pytest.mark.long
def test_reverse_mode_matches_forward_mode():
    """`jax.grad` of one turning point's position equals the forward-mode row (with the long
    runs, for CI's time: the reverse-mode compilation of the Taylor march takes about 12 s;
    both modes are checked against central differences in the default suite,
    tests/test_variable_mass.py and above)."""
    p = jnp.array([6.0, 0.01, 0.01, 0.05, 0.04, 0.2, 1.1])
    f = lambda q: _sequence(q, "sine")[7]  # noqa: E731
    np.testing.assert_allclose(
        np.asarray(jax.grad(f)(p)), np.asarray(jax.jacfwd(f)(p)), rtol=1e-8, atol=1e-12
    )


# -- batching, simulation and input checks ------------------------------------------------------
def test_vmap_over_oscillators_equals_one_by_one():
    times, positions, _ = solved("sine", "exact")
    one = vmj.turning_points(model("sine", **DISSIPATION["all"]), A0, N)
    i = cases("sine").index(("sine", "all"))
    np.testing.assert_allclose(positions[i], np.asarray(one.positions), rtol=1e-13)
    np.testing.assert_allclose(times[i], np.asarray(one.times), rtol=1e-13)


def test_simulate_passes_the_turning_points():
    osc = vmj.Oscillator.pendulum(OMEGA, zeta=0.01, xF=0.01, cq=0.05)
    seq = vmj.turning_points(osc, 1.0, 4)
    traj = vmj.simulate(osc, -1.0, 0.0, float(seq.times[3]) + 1e-9, n_save=40001)
    k = np.argmin(np.abs(np.asarray(traj.ts)[:, None] - np.asarray(seq.times)), axis=0)
    np.testing.assert_allclose(np.asarray(traj.xs)[k], np.asarray(seq.positions), atol=1e-6)


@pytest.mark.parametrize(
    "build, name",
    [
        (lambda: vmj.Oscillator(0.0), "omega"),
        (lambda: vmj.Oscillator.pendulum(6.0, zeta=-0.1), "zeta"),
        (lambda: vmj.Oscillator.pendulum(6.0, xF=-0.01), "xF"),
        (lambda: vmj.Oscillator.pendulum(6.0, xF=0.02, xS=0.01), "xS"),
        (lambda: vmj.Oscillator.pendulum(6.0, cq=-1.0), "cq"),
        (lambda: vmj.Oscillator.pendulum(6.0, b3=np.nan), "b3"),
        (lambda: vmj.PolynomialRestoring(b2=np.inf), "b2"),
        (lambda: vmj.Oscillator(6.0, "sine"), "restoring"),
        (lambda: vmj.Oscillator(6.0, dissipation=(0.1,)), "dissipation"),
        (lambda: vmj.turning_points(vmj.Oscillator.pendulum(6.0), -1.0, 5), r"a0 .*\[rad\]"),
        (lambda: vmj.turning_points(vmj.Oscillator.pendulum(6.0), 80.0, 5), r"a0 .*deg2rad"),
        (lambda: vmj.turning_points(vmj.Oscillator.linear(6.0), 0.0, 5), r"a0 .*> 0"),
    ],
)
def test_bad_input_names_the_parameter(build, name):
    with pytest.raises(ValueError, match=name):
        build()


def test_traced_bad_static_level_is_refused():
    """Inside `jit` a static level below the kinetic one raises at run time."""

    @jax.jit
    def stop(xS):
        osc = vmj.Oscillator(OMEGA, vmj.SineRestoring(), (vmj.CoulombDamping(0.02, xS),))
        return vmj.turning_points(osc, 1.0, 5).positions

    stop(0.05)
    with pytest.raises(Exception, match="xS must be >= xF"):
        jax.block_until_ready(stop(0.01))  # (a GPU raises when the result is awaited)


def test_traced_fields_of_laws_in_the_tuple_are_validated():
    """`validated` reaches the laws inside the dissipation tuple: a negative traced `zeta`
    raises inside `jit`."""
    base = vmj.Oscillator.pendulum(OMEGA, zeta=0.01)
    f = eqx.filter_jit(lambda m: vmj.turning_points(m, 1.0, 3).positions)
    f(base)
    bad = eqx.tree_at(lambda m: m.dissipation[0].zeta, base, jnp.asarray(-0.01))
    with pytest.raises(Exception, match="zeta must be finite and >= 0"):
        f(bad)


def test_sweep_reaches_the_laws_parameters():
    """`vmj.grid`/`vmj.sweep` name the laws' fields (`zeta`, or a dotted path into the tuple of
    dissipation laws) and agree with one-by-one solutions."""
    osc = vmj.Oscillator.pendulum(OMEGA, zeta=0.01, xF=0.01)
    g = vmj.grid(osc, zeta=[0.0, 0.02], **{"dissipation.1.xF": [0.0, 0.01]})
    res = vmj.sweep(vmj.turning_points, g, a0=1.0, n=4, chunk_size=4)
    assert res.dims == ("zeta", "dissipation.1.xF")
    one = vmj.turning_points(vmj.Oscillator.pendulum(OMEGA, zeta=0.02, xF=0.0), 1.0, 4)
    np.testing.assert_allclose(res.values.positions[1, 0], one.positions, rtol=1e-13)


@pytest.mark.parametrize(
    "kw,message",
    [
        (dict(derivatives="reverse"), "derivatives must be 'any' or 'forward'"),
        (dict(max_substeps=0), "max_substeps must be an integer >= 1"),
        (dict(one_lane=1), "one_lane must be True or False"),
    ],
)
def test_exact_solver_settings_are_checked(kw, message):
    with pytest.raises(ValueError, match=message):
        vmj.Exact(**kw)


def test_the_energy_map_reports_a_swing_at_the_separatrix():
    """Near the upright position the averaged map's chord-swing time diverges: a failure named
    as such (it returned infinite times as a success), where the exact solver goes on."""
    model = vmj.Oscillator.pendulum(1.0, zeta=0.01, xF=0.001)
    seq = vmj.turning_points(model, 3.14, 3, vmj.EnergyBalance())
    assert int(seq.result) == vmj.RESULTS.map_diverged and "separatrix" in seq.message
    assert np.all(np.isfinite(np.asarray(seq.times)))
    assert int(vmj.turning_points(model, 3.14, 3).count) == 3


def test_a_pendulum_stuck_near_the_top_has_finite_reverse_gradients():
    """Released at 3.14 rad with a static level 0.01 (|sin 3.14| = 0.0016 below it) the
    pendulum stays put: x_2 = -a0, d x_2 / d(a0, omega, xF) = (-1, 0, 0). The energy map's
    discarded swing from there (over the top) took the square root of a negative chord and its
    reciprocal, and jax.grad was NaN (jax.jacfwd and the exact solver gave the right value)."""

    def x2(p):
        a0, omega, xF = p
        model = vmj.Oscillator.pendulum(omega, 0.01, xF)
        return vmj.turning_points(model, a0, 4, vmj.EnergyBalance()).positions[1]

    p = jnp.array([3.14, 6.0, 0.01])
    np.testing.assert_array_equal(np.asarray(jax.grad(x2)(p)), [-1.0, 0.0, 0.0])
