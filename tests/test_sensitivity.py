"""vmj.sensitivity: forward and reverse mode against central finite differences, under vmap and
inside vmj.sweep."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import vmj
from vmj._sweep._sensitivity import central_difference

A0 = 0.06
WRT = ("F", "mu", "eps", "delta", "a0")


def model_at(delta=3.0, eps=0.3, mu=2.0, F=14.7):
    return vmj.VariableMass(5.0, 4900.0, delta, eps, mu, vmj.Coulomb(F))


def exact_amplitudes(m, a0, n):
    return vmj.turning_points(m, a0, n).amplitudes


def energy_amplitudes(m, a0, n):
    return vmj.turning_points(m, a0, n, vmj.EnergyBalance()).amplitudes


# steps of the central differences: about 1e-6 of each parameter's scale
STEPS = {"F": 1e-5, "mu": 1e-6, "eps": 1e-7, "delta": 1e-6, "a0": 1e-8}


# with the long runs, for CI's time (31 s of compiling): the exact solver's derivatives are
# checked against central differences in tests/test_variable_mass.py and tests/test_oscillator.py,
# `vmj.sensitivity` itself by the energy-balance test below
@pytest.mark.long
@pytest.mark.parametrize("delta", [3.0, -3.0])
def test_exact_forward_mode_matches_central_differences(delta):
    m = model_at(delta=delta, eps=0.3, mu=2.0)
    got = vmj.sensitivity(exact_amplitudes, m, WRT, a0=A0, n=8)
    assert list(got) == list(WRT)
    for name in WRT:
        fd = central_difference(exact_amplitudes, m, name, STEPS[name], a0=A0, n=8)
        assert got[name].shape == (8,)
        scale = np.max(np.abs(fd))
        assert scale > 0
        np.testing.assert_allclose(got[name], fd, rtol=0, atol=1e-5 * scale, err_msg=name)


def test_reverse_mode_equals_forward_mode_and_central_differences():
    m = model_at(delta=-3.0, eps=0.7, mu=5.0)
    fwd = vmj.sensitivity(energy_amplitudes, m, WRT, a0=A0, n=12)
    rev = vmj.sensitivity(energy_amplitudes, m, WRT, a0=A0, n=12, mode="reverse")
    for name in WRT:
        np.testing.assert_allclose(rev[name], fwd[name], rtol=1e-12, atol=1e-15)
        fd = central_difference(energy_amplitudes, m, name, STEPS[name], a0=A0, n=12)
        np.testing.assert_allclose(fwd[name], fd, rtol=0, atol=1e-6 * np.max(np.abs(fd)))


def test_stop_time_sensitivity():
    # the exact stop time moves smoothly with the friction force while the count is unchanged
    def stop_time(m, a0, n):
        return vmj.turning_points(m, a0, n, vmj.EnergyBalance()).stop_time

    m = model_at(delta=3.0, eps=0.0, mu=9.0)
    assert np.isfinite(stop_time(m, A0, 20))
    got = vmj.sensitivity(stop_time, m, ("delta", "mu"), a0=A0, n=20)
    for name in ("delta", "mu"):
        fd = central_difference(stop_time, m, name, STEPS[name], a0=A0, n=20)
        np.testing.assert_allclose(got[name], fd, rtol=1e-6)


def test_vmappable_and_sweepable():
    eps = jnp.array([0.1, 0.5, 0.9])

    def at(e):
        return vmj.sensitivity(energy_amplitudes, model_at(eps=e), ("mu", "F"), a0=A0, n=6)

    batched = jax.vmap(at)(eps)
    swept = vmj.sweep(
        lambda m: vmj.sensitivity(energy_amplitudes, m, ("mu", "F"), a0=A0, n=6),
        vmj.grid(model_at(), eps=eps),
    )
    for i, e in enumerate(eps):
        one = at(e)
        for name in ("mu", "F"):
            np.testing.assert_allclose(batched[name][i], one[name], rtol=1e-12)
            np.testing.assert_allclose(swept.values[name][i], one[name], rtol=1e-12)
    assert "mu_1" in swept.columns()


def test_bad_input():
    m = model_at()
    with pytest.raises(ValueError, match="'nu' is not a parameter"):
        vmj.sensitivity(energy_amplitudes, m, ("nu",), a0=A0, n=3)
    with pytest.raises(ValueError, match="mode must be"):
        vmj.sensitivity(energy_amplitudes, m, ("mu",), a0=A0, n=3, mode="central")
    with pytest.raises(ValueError, match="float arrays only"):
        vmj.sensitivity(
            lambda m, a0, n: vmj.turning_points(m, a0, n, vmj.EnergyBalance()).count,
            m,
            ("mu",),
            a0=A0,
            n=3,
        )
    with pytest.raises(ValueError, match="at least one"):
        vmj.sensitivity(energy_amplitudes, m, (), a0=A0, n=3)


def test_other_models_stick_slip_period_and_stick_time():
    # nothing in sweep/sensitivity is specific to VariableMass: the stick-slip model works as is
    def period_and_stick(m):
        cycle = vmj.limit_cycle(m)
        return {"period": cycle.period, "stick_time": cycle.stick_time}

    m = vmj.StickSlip(eps=3.0, Omega=0.5)
    got = vmj.sensitivity(period_and_stick, m, ("eps", "Omega"))
    for name in ("eps", "Omega"):
        fd = central_difference(period_and_stick, m, name, 1e-6)
        for out in ("period", "stick_time"):
            np.testing.assert_allclose(got[name][out], fd[out], rtol=1e-6, err_msg=name + out)
    swept = vmj.sweep(period_and_stick, vmj.grid(m, eps=[2.0, 3.0], Omega=[0.5, 1.0]))
    one = period_and_stick(vmj.StickSlip(eps=3.0, Omega=1.0))
    np.testing.assert_allclose(swept.values["period"][1, 1], one["period"], rtol=1e-12)


def test_forward_mode_through_a_reverse_only_solve_says_which_mode():
    """The smoothed solve differentiates through diffrax's adjoint (reverse mode only): forward
    mode is refused with the mode to use, not JAX's traceback about custom_vjp."""
    model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))

    def fn(m, a0, n):
        return vmj.turning_points(m, a0, n, vmj.Smoothed()).amplitudes

    with pytest.raises(ValueError, match=r"use mode='reverse', or .*derivatives='forward'"):
        vmj.sensitivity(fn, model, ["mu"], a0=0.06, n=2)


def test_smoothed_forward_mode():
    """`vmj.Smoothed(derivatives="forward")` differentiates in forward mode (diffrax's forward
    adjoint): the derivatives of the smoothed amplitudes equal the exact solver's to the smoothed model's
    accuracy (1e-5 of the largest derivative; measured 3e-7; forward and reverse mode of the
    smoothed solve agreed to 8e-16 in amplitudes and 6e-11 in times when measured, and reverse
    mode is checked against central differences in tests/test_variable_mass.py). Forward mode
    through the default is refused with the spelling to use (above); any other mode is refused
    by name."""
    model = vmj.VariableMass(5.0, 4900.0, -1.0, 0.5, 2.0, vmj.Coulomb(14.7))

    def amplitudes(solver):
        return lambda m, a0, n: vmj.turning_points(m, a0, n, solver).amplitudes

    forward = vmj.Smoothed(derivatives="forward")
    got = vmj.sensitivity(amplitudes(forward), model, ["mu", "F"], a0=0.06, n=4)
    exact = vmj.sensitivity(amplitudes(vmj.Exact()), model, ["mu", "F"], a0=0.06, n=4)
    for w in ("mu", "F"):
        scale = np.max(np.abs(exact[w]))
        np.testing.assert_allclose(got[w], exact[w], rtol=0, atol=1e-5 * scale)
    with pytest.raises(ValueError, match="derivatives must be 'reverse' or 'forward'"):
        vmj.Smoothed(derivatives="any")
