"""The compiled entry points as JAX's persistent compilation cache sees them, and the checks that
run before them.

- For concrete inputs the compiled program holds no host callback (`equinox.error_if` is one):
  the inputs were checked on the host, `throw=True` raises on the host, and the checks that only
  the program can make are returned as values and raise on the host, so the cache can store
  every entry point. Inside the user's own `jit`/`vmap` the guards stay.
- A model is checked once, at construction; one rebuilt without its constructor
  (`eqx.tree_at`, `jax.tree.unflatten`) is checked again by the entry points.
"""

import re

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_conformance import LIMIT_CYCLE, MODELS, SIMULATE, SOLVERS, TURNING_POINTS, _a0

import vmj
import vmj._integrate as entry


def compiled_program(monkeypatch, name, call):
    """The StableHLO text of the compiled function `name` of vmj/_integrate.py as `call` runs
    it (the arguments recorded on the way in)."""
    seen = []
    compiled = getattr(entry, name)
    monkeypatch.setattr(entry, name, lambda *args: seen.append(args) or compiled(*args))
    call()
    assert seen, f"{name} was not called"
    return compiled.lower(*seen[-1]).as_text()


def has_callback(text: str) -> bool:
    return "callback" in text.lower()


@pytest.mark.parametrize("model,solver", sorted(TURNING_POINTS))
def test_turning_points_compile_without_host_callbacks(monkeypatch, model, solver):
    m, s = MODELS[model](), SOLVERS[solver]()
    text = compiled_program(
        monkeypatch, "_turning_points", lambda: vmj.turning_points(m, _a0(model), 6, s, throw=True)
    )
    assert not has_callback(text)


@pytest.mark.parametrize("model,solver", sorted(SIMULATE))
def test_simulate_compiles_without_host_callbacks(monkeypatch, model, solver):
    m, s = MODELS[model](), SOLVERS[solver]()
    x0, v0 = (-5.5, -1.0) if model == "stick-slip" else (-_a0(model), 0.0)
    text = compiled_program(
        monkeypatch, "_simulate", lambda: vmj.simulate(m, x0, v0, 0.5, s, n_save=11, throw=True)
    )
    assert not has_callback(text)


@pytest.mark.parametrize("solver", sorted(s for _, s in LIMIT_CYCLE if s != "smoothed"))
def test_limit_cycle_compiles_without_host_callbacks(monkeypatch, solver):
    m, s = MODELS["stick-slip"](), SOLVERS[solver]()
    text = compiled_program(monkeypatch, "_limit_cycle", lambda: vmj.limit_cycle(m, s, throw=True))
    assert not has_callback(text)


def test_guards_stay_inside_the_users_own_jit():
    """Traced parameters cannot be checked on the host: the guard is compiled in (and fires)."""

    def positions(mu):
        model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, mu, vmj.Coulomb(14.7))
        return vmj.turning_points(model, 0.06, 4).positions

    assert has_callback(jax.jit(positions).lower(2.0).as_text())
    with pytest.raises(Exception, match="mu must be finite and >= 0"):
        jax.jit(positions)(-1.0).block_until_ready()


def test_sensitivity_and_the_averaged_laws_compile_without_host_callbacks(monkeypatch):
    """The `filter_jit` entry points return the checks of their own trace as values and raise
    on the host (`vmj._checks.collecting`): `vmj.sensitivity` (its function's checks, traced in
    the derivative's trace, `a0` among the parameters), the rope's averaged laws (the swing
    above the potential barrier, the action law's ODE solve, diffrax's dense output instead of
    its checked `SaveAt(ts=...)`). Bad values still raise at the call with their message, and
    inside the user's own `jit` the guards stay."""
    import vmj._models._rope as rope_module
    import vmj._sweep._sensitivity as sensitivity_module

    def program(module, name, call):
        seen = []
        compiled = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a: seen.append(a) or compiled(*a))
        call()
        monkeypatch.setattr(module, name, compiled)
        return compiled.lower(*seen[-1]).as_text()

    model = MODELS["variable-mass"]()
    amplitudes = lambda m, a0, n: vmj.turning_points(m, a0, n).amplitudes  # noqa: E731
    wrt = ("mu", "a0")
    text = program(
        sensitivity_module,
        "_sensitivity",
        lambda: vmj.sensitivity(amplitudes, model, wrt=wrt, a0=0.06, n=6),
    )
    assert not has_callback(text)
    with pytest.raises(ValueError, match="^a0 must be finite and > 0"):
        vmj.sensitivity(amplitudes, model, wrt=wrt, a0=-0.06, n=6)
    inside = jax.jit(lambda a0: vmj.sensitivity(amplitudes, model, wrt=wrt, a0=a0, n=6)["a0"])
    assert has_callback(inside.lower(0.06).as_text())

    rope = vmj.Rope(1000.0, 1e-4, 1e11, -1e13, 0.0, 1e6, vmj.ConstantSpeed(100.0, 2.0))
    ts = jnp.linspace(0.0, 1.0, 3)
    for law, name in ((vmj.kbm_amplitude, "_kbm"), (vmj.action_amplitude, "_action")):
        assert not has_callback(program(rope_module, name, lambda: law(rope, 0.05, ts)))
        with pytest.raises(ValueError, match="above the potential barrier"):
            law(rope, 0.6, ts)
        assert has_callback(jax.jit(lambda a0, law=law: law(rope, a0, ts)).lower(0.05).as_text())


def test_sweep_chunks_return_their_functions_checks_as_values(monkeypatch):
    """A sweep's chunk collects the checks of what its function computes (the derivative's
    inputs of `vmj.sensitivity` over a grid, `throw=True`) as values: no host callback in the
    chunk's program, and a failing point raises on the host with its plain message."""
    import vmj._sweep._sweep as sweep_module

    seen = []
    call = sweep_module._ChunkFunction.__call__
    monkeypatch.setattr(
        sweep_module._ChunkFunction, "__call__", lambda f, *a: seen.append((f, a)) or call(f, *a)
    )
    model = MODELS["variable-mass"]()
    g = vmj.grid(model, mu=[1.0, 2.0])
    amplitudes = lambda m, a0, n: vmj.turning_points(m, a0, n).amplitudes  # noqa: E731
    got = vmj.sensitivity(amplitudes, g, ("mu", "a0"), a0=0.06, n=6)
    function, args = seen[-1]
    assert not has_callback(function.lower(*args).as_text())
    at = vmj.sensitivity(amplitudes, eqx.tree_at(lambda m: m.mu, model, 2.0), ("mu",), a0=0.06, n=6)
    np.testing.assert_allclose(got.values["d_mu"][1], at["mu"], rtol=1e-12)
    shifted = lambda m, a0, n: vmj.turning_points(m, a0 - 1.0, n).amplitudes  # noqa: E731
    with pytest.raises(ValueError, match=r"^a0 must be finite and > 0 \[m\]$"):
        vmj.sensitivity(shifted, g, ("mu", "a0"), a0=0.06, n=6)
    stuck = vmj.grid(vmj.VariableMass(5.0, 4900.0, -3.0, 0.0, 0.0, vmj.Coulomb(14.7)), F=[0.01])
    with pytest.raises(vmj.SolverError, match=re.escape(vmj.RESULTS.mass_exhausted.message)):
        vmj.sweep(vmj.turning_points, stuck, a0=0.06, n=40, throw=True)
    function, args = seen[-1]
    assert not has_callback(function.lower(*args).as_text())


@pytest.mark.production_compile
def test_assume_valid_compiles_no_guards():
    """Code that keeps its values in range itself traces its solves inside
    `vmj.assume_valid()`: no host callback, the same answer; concrete values are still checked
    there."""

    def positions(mu, a0):
        model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, mu, vmj.Coulomb(14.7))
        return vmj.turning_points(model, a0, 4).positions

    with vmj.assume_valid():
        text = jax.jit(positions).lower(2.0, 0.06).as_text()
        vouched = jax.jit(positions)(2.0, 0.06)
        with pytest.raises(ValueError, match="^a0 must be finite and > 0"):
            positions(2.0, -0.06)
    assert not has_callback(text)
    # (a new function: JAX would reuse the trace of `positions` made in the block)
    assert has_callback(jax.jit(lambda mu, a0: positions(mu, a0)).lower(2.0, 0.06).as_text())
    np.testing.assert_array_equal(vouched, positions(2.0, 0.06))


def test_models_rebuilt_without_their_constructor_are_checked_again():
    model = MODELS["variable-mass"]()
    vmj.turning_points(model, 0.06, 6)
    bad = eqx.tree_at(lambda m: m.mu, model, jnp.asarray(-1.0))
    with pytest.raises(ValueError, match="^mu must be finite and >= 0"):
        vmj.turning_points(bad, 0.06, 6)
    leaves, treedef = jax.tree.flatten(model)
    leaves = [jnp.asarray(np.nan) if i == 1 else x for i, x in enumerate(leaves)]  # c
    with pytest.raises(ValueError, match="^c must be finite and > 0"):
        vmj.turning_points(jax.tree.unflatten(treedef, leaves), 0.06, 6)
    friction = eqx.tree_at(lambda m: m.friction.F, model, jnp.asarray(-2.0))
    with pytest.raises(ValueError, match="^F must be finite and >= 0"):
        vmj.simulate(friction, -0.06, 0.0, 0.5)
    # a good value put in the same way passes, and gives the constructor's answer
    good = eqx.tree_at(lambda m: m.mu, model, jnp.asarray(2.5))
    direct = vmj.VariableMass(5.0, 4900.0, 3.0, 0.5, 2.5, vmj.Coulomb(14.7))
    np.testing.assert_array_equal(
        vmj.turning_points(good, 0.06, 6).positions, vmj.turning_points(direct, 0.06, 6).positions
    )


def test_scalar_arguments_are_checked_on_the_host():
    model = MODELS["variable-mass"]()
    for a0 in (0.0, -1.0, float("nan"), np.float64(-1.0), jnp.asarray(float("inf"))):
        with pytest.raises(ValueError, match="^a0 must be finite and > 0"):
            vmj.turning_points(model, a0, 6)
    # Python, NumPy and JAX scalars give one compiled program and the same answer
    seqs = [vmj.turning_points(model, 0.06, 6)]
    compiled = entry._turning_points._cache_size()
    seqs += [vmj.turning_points(model, a0, 6) for a0 in (np.float64(0.06), jnp.asarray(0.06), 6e-2)]
    assert entry._turning_points._cache_size() == compiled
    for seq in seqs[1:]:
        np.testing.assert_array_equal(seq.positions, seqs[0].positions)


@pytest.mark.production_compile
def test_one_calls_compile_with_the_older_kernel_emitters_to_the_same_numbers():
    """A concrete call's program is compiled with `ONE_CALL` (XLA's older kernel emitters:
    less compile time; vmj/_exported.py), which this XLA takes on a CPU (a GPU's compiler
    refuses it: no options there). The exact and energy-balance
    turning points equal those of XLA's default emitters (as a sweep or the user's own `jit`
    compiles them) to the last bit; the smoothed ones agree to the ODE's tolerance (measured
    2.6e-10 of a0; the two programs differed by 2.9e-10 with the default emitters in both)."""
    from vmj._exported import ONE_CALL, _one_call_options

    assert dict(_one_call_options()) == (ONE_CALL if jax.default_backend() == "cpu" else {})
    model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
    for solver, tol in ((vmj.Exact(), 0.0), (vmj.EnergyBalance(), 0.0), (vmj.Smoothed(), 1e-8)):
        one = vmj.turning_points(model, 0.06, 12, solver)  # the options' program
        default = jax.jit(lambda m, s=solver: vmj.turning_points(m, 0.06, 12, s))(model)
        np.testing.assert_allclose(one.positions, default.positions, rtol=0, atol=tol * 0.06)
        np.testing.assert_allclose(one.times, default.times, rtol=0, atol=tol)


def test_filter_jit_gives_one_calls_program_the_options_and_keeps_its_static_arguments(
    monkeypatch,
):
    """`vmj._exported.filter_jit` (the entry points with callables or dictionaries among their
    arguments): arrays traced, every other argument static (a new value traces anew, a new
    array does not); at top level its program is compiled with `ONE_CALL` (an option XLA does
    not know is refused there), inside the user's `jit` without it."""
    import vmj._exported as exported

    traces = []

    def scaled(x, scale, names, settings):
        traces.append(names)
        return {n: x * scale * settings["k"] for n in names}

    f = exported.filter_jit(scaled)
    x = jnp.arange(3.0)
    got = f(x, 2.0, ("a", "b"), {"k": 3})
    np.testing.assert_array_equal(got["b"], 6.0 * x)
    f(x + 1.0, 2.0, ("a", "b"), {"k": 3})
    assert len(traces) == 1
    np.testing.assert_array_equal(f(x, 2.0, ("a",), {"k": 4})["a"], 8.0 * x)
    assert len(traces) == 2
    inside = jax.jit(lambda x: f(x, 2.0, ("a",), {"k": 4})["a"])(x)
    np.testing.assert_array_equal(inside, 8.0 * x)

    monkeypatch.setattr(exported, "_one_call_options", lambda: (("xla_no_such_option", 1),))
    refused = exported.filter_jit(scaled)
    with pytest.raises(Exception, match="xla_no_such_option"):
        refused(x, 2.0, ("a",), {"k": 3})
    traced = jax.jit(lambda x: refused(x, 2.0, ("a",), {"k": 3})["a"])(x)
    np.testing.assert_array_equal(traced, 6.0 * x)


def test_a_top_level_call_waits_for_its_program_off_a_cpu(monkeypatch):
    """Where JAX's default backend is no CPU, a top-level call of either kind of entry point
    (`filter_jit`: the rope's averaged laws; `exported_jit`'s plain path: `vmj.turning_points`
    with the cache off) returns its result finished, so that a check inside the program
    raises at the call (on an H200 `vmj.kbm_amplitude` over the potential barrier returned,
    its error logged); inside the user's `jit` nothing waits, and on a CPU nothing needs to."""
    import vmj._exported as exported

    waited = []
    monkeypatch.setattr(jax, "block_until_ready", lambda out: waited.append(out) or out)
    rope = vmj.Rope(1000.0, 1e-4, 1e11, 0.0, 0.0, 1e6, vmj.ConstantSpeed(100.0, 2.0))
    model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
    for off_cpu in (False, True):
        monkeypatch.setattr(exported, "_default_backend_is_cpu", lambda on=not off_cpu: on)
        amp = vmj.kbm_amplitude(rope, 0.6, jnp.linspace(0.0, 1.0, 3))
        seq = vmj.turning_points(model, 0.06, 6)
        assert len(waited) == (2 if off_cpu else 0)
    assert jax.tree.leaves(waited[0])[0] is amp  # (the law's (amplitude, frequency))
    assert jax.tree.leaves(waited[1])[0] is jax.tree.leaves(seq)[0]
    jax.jit(lambda m: vmj.turning_points(m, 0.06, 4).positions)(model)
    assert len(waited) == 2


def test_sensitivity_and_linear_response_as_one_call_equal_the_users_jit():
    """`vmj.sensitivity` and `LinearOscillator.response` compiled on their own (`ONE_CALL`)
    give the numbers of the same code inside the user's `jit` (XLA's default emitters)."""
    model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))

    def amplitudes(m, a0, n):
        return vmj.turning_points(m, a0, n).amplitudes

    one = vmj.sensitivity(amplitudes, model, wrt=("F", "mu"), a0=0.06, n=8)
    users = jax.jit(lambda m: vmj.sensitivity(amplitudes, m, wrt=("F", "mu"), a0=0.06, n=8))(model)
    for w in ("F", "mu"):
        np.testing.assert_allclose(one[w], users[w], rtol=1e-13, atol=0)
    f = vmj.LinearOscillator(1.0, 1.0, 14.5, vmj.HarmonicForce(F0=4.0, p=15.0))
    ts = jnp.linspace(0.0, 2.0, 51)
    x, v = f.response(ts, 0.0, 0.1)
    xj, vj = jax.jit(lambda f: f.response(ts, 0.0, 0.1))(f)
    np.testing.assert_allclose(x, xj, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(v, vj, rtol=1e-13, atol=1e-15)
