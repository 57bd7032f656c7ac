"""Every model against every solver and entry point: each combination that applies runs and
returns an okay result; each that does not gives a clear ValueError naming the solver, the model
and what to use instead (as diffrax's suite is parametrised over all its solvers)."""

import jax.numpy as jnp
import numpy as np
import pytest

import vmj

MODELS = {
    "variable-mass": lambda: vmj.VariableMass(5.0, 4900.0, 3.0, 0.5, 2.0, vmj.Coulomb(14.7)),
    "variable-mass-f": lambda: vmj.VariableMass(
        5.0, 4900.0, -0.2, 0.5, 1.0, vmj.MassProportional(0.3)
    ),
    "rope": lambda: vmj.Rope.paper(u=0.0, T=40.0),
    "rope-hoisting": lambda: vmj.Rope.paper(u=1.0, T=40.0),
    "linear": lambda: vmj.LinearOscillator(1.0, 0.2, 100.0),
    "linear-forced": lambda: vmj.LinearOscillator(1.0, 0.2, 100.0, vmj.HarmonicForce(1.0, 7.0)),
    "stick-slip": lambda: vmj.StickSlip(5.5, 1.0),
    "oscillator": lambda: vmj.Oscillator.linear(20.0, zeta=0.01, xF=1e-3),
    "pendulum": lambda: vmj.Oscillator.pendulum(6.3, zeta=0.002, xF=1e-3, xS=2e-3, cq=0.05),
}
SOLVERS = {
    "exact": vmj.Exact,
    "smoothed": vmj.Smoothed,
    "energy": vmj.EnergyBalance,
    "closed": vmj.ClosedForm,
}
#: (model, solver) pairs that apply, per task
TURNING_POINTS = {
    ("variable-mass", "exact"),
    ("variable-mass", "smoothed"),
    ("variable-mass", "energy"),
    ("variable-mass-f", "exact"),
    ("variable-mass-f", "smoothed"),
    ("variable-mass-f", "energy"),
    ("rope", "exact"),
    ("rope", "smoothed"),
    ("rope", "energy"),
    ("rope-hoisting", "exact"),
    ("rope-hoisting", "smoothed"),
} | {(m, s) for m in ("oscillator", "pendulum") for s in ("exact", "smoothed", "energy")}
SIMULATE = {(m, "smoothed") for m in MODELS} | {("linear", "closed"), ("linear-forced", "closed")}
LIMIT_CYCLE = {("stick-slip", s) for s in ("exact", "smoothed", "closed")}


def _a0(name):
    return {"rope": 0.01, "rope-hoisting": 0.01, "pendulum": 0.8}.get(name, 0.06)


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("model", MODELS)
def test_turning_points(model, solver):
    m, s = MODELS[model](), SOLVERS[solver]()
    if (model, solver) not in TURNING_POINTS:
        with pytest.raises(ValueError, match=f"{type(s).__name__} does not solve|energy map"):
            vmj.turning_points(m, _a0(model), 6, s)
        return
    seq = vmj.turning_points(m, _a0(model), 6, s)
    assert vmj.RESULTS.okay(int(seq.result)), seq.message
    assert int(seq.count) >= 2
    assert np.all(np.isfinite(np.asarray(seq.positions)))


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("model", MODELS)
def test_simulate(model, solver):
    m, s = MODELS[model](), SOLVERS[solver]()
    x0, v0 = (-5.5, -1.0) if model == "stick-slip" else (-_a0(model), 0.0)
    if (model, solver) not in SIMULATE:
        with pytest.raises(ValueError, match=f"{type(s).__name__} does not solve"):
            vmj.simulate(m, x0, v0, 0.5, s, n_save=11)
        return
    traj = vmj.simulate(m, x0, v0, 0.5, s, n_save=11)
    assert int(traj.result) == vmj.RESULTS.successful, traj.message
    assert traj.xs.shape == (11,) and np.all(np.isfinite(np.asarray(traj.xs)))
    assert float(traj.xs[0]) == pytest.approx(x0)


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("model", MODELS)
def test_limit_cycle(model, solver):
    m, s = MODELS[model](), SOLVERS[solver]()
    if (model, solver) not in LIMIT_CYCLE:
        with pytest.raises(ValueError, match=f"{type(s).__name__} does not solve"):
            vmj.limit_cycle(m, s)
        return
    cycle = vmj.limit_cycle(m, s)
    assert int(cycle.result) == vmj.RESULTS.successful, cycle.message
    assert int(cycle.reversals) == 2  # floor((5.5 - 1)/2)


def test_linear_closed_form_equals_ode():
    m = MODELS["linear-forced"]()
    ode = vmj.simulate(m, 0.01, 0.0, 2.0, vmj.Smoothed(), n_save=21)
    exact = vmj.simulate(m, 0.01, 0.0, 2.0, vmj.ClosedForm(), n_save=21)
    np.testing.assert_allclose(ode.xs, exact.xs, rtol=0, atol=1e-9)


_ANY = r"vmj\.Exact\(\), vmj\.Smoothed\(\), vmj\.EnergyBalance\(\), vmj\.ClosedForm\(\)$"


@pytest.mark.parametrize(
    "call,says",
    [
        (
            lambda vm, ss: vmj.turning_points(vm, 0.06, 4, "smooth"),
            r"^solver must be a solver object \(got the string 'smooth'\): "
            r"pass solver=vmj\.Smoothed\(\)$",
        ),
        (
            lambda vm, ss: vmj.turning_points(vm, 0.06, 4, method="smooth"),
            r"^turning_points takes no method=: pass solver=vmj\.Smoothed\(\)$",
        ),
        (
            lambda vm, ss: vmj.turning_points(vm, 0.06, 4, method="rk4"),
            r"^turning_points takes no method=: pass a solver object: " + _ANY,
        ),
        (
            lambda vm, ss: vmj.turning_points(vm, 0.06, 4, vmj.Exact(), smoothing=1e-3),
            r"^turning_points takes no smoothing=: .* pass solver=vmj\.Smoothed\(smoothing=\.\.\.\)$",
        ),
        (
            lambda vm, ss: vmj.turning_points(vm, 0.06, 4, max_substeps=10),
            r"^turning_points takes no max_substeps=: .* solver=vmj\.Exact\(max_substeps=\.\.\.\)$",
        ),
        (
            lambda vm, ss: vmj.turning_points(vm, 0.06, 4, 3),
            r"^solver must be a solver object \(got int\): pass a solver object: " + _ANY,
        ),
        (
            lambda vm, ss: vmj.decay_trajectory(vm, 0.06, [0.1], 4, "energy"),
            r"^solver must be .* pass solver=vmj\.EnergyBalance\(\)$",
        ),
        (
            lambda vm, ss: vmj.simulate(vm, -0.06, 0.0, 1.0, smoothing=1e-4),
            r"^simulate takes no smoothing=: .* pass solver=vmj\.Smoothed\(smoothing=\.\.\.\)$",
        ),
        (
            lambda vm, ss: vmj.limit_cycle(ss, "closed"),
            r"^solver must be .* pass solver=vmj\.ClosedForm\(\)$",
        ),
        (
            lambda vm, ss: vmj.limit_cycle(ss, method="smooth"),
            r"^limit_cycle takes no method=: pass solver=vmj\.Smoothed\(\)$",
        ),
    ],
    ids=[
        "name",
        "method=",
        "method=unknown",
        "smoothing=",
        "max_substeps=",
        "not-a-solver",
        "decay_trajectory-name",
        "simulate-smoothing=",
        "limit_cycle-name",
        "limit_cycle-method=",
    ],
)
def test_a_solver_by_name_or_by_keyword_is_refused_naming_the_object(call, says):
    # the older spellings (a solver's name, `method=`, the solver's settings as keywords of the
    # entry point) once worked beside the solver objects; one way remains, and the error says it
    with pytest.raises(TypeError, match=says):
        call(MODELS["variable-mass"](), MODELS["stick-slip"]())


def test_results_enumeration():
    assert vmj.RESULTS.okay(vmj.RESULTS.stopped) and not vmj.RESULTS.failed(vmj.RESULTS.stopped)
    assert all(vmj.RESULTS.failed(r) for r in vmj.RESULTS if r > vmj.RESULTS.stopped)
    assert all(r.message for r in vmj.RESULTS)
    np.testing.assert_array_equal(
        vmj.RESULTS.failed(jnp.array([0, 1, 2, 5])), [False, False, True, True]
    )


def test_throw_raises_solver_error_with_the_message():
    m = vmj.VariableMass(5.0, 4900.0, -3.0, 0.0, 0.0, vmj.Coulomb(0.1))  # mass runs out
    with pytest.raises(vmj.SolverError, match="reaches zero"):
        vmj.turning_points(m, 0.06, 40, throw=True)


def test_applicability_that_depends_on_traced_values_is_guarded():
    import jax

    def amplitudes(u):
        rope = vmj.Rope.paper(u=u, T=40.0)
        return vmj.turning_points(rope, 0.01, 4, vmj.EnergyBalance()).amplitudes

    assert np.all(np.isfinite(np.asarray(jax.jit(amplitudes)(0.0))))
    with pytest.raises(Exception, match="u must be 0 for the energy map"):
        jax.jit(amplitudes)(1.0).block_until_ready()
