"""vmj's default ODE solver: diffrax's Tsit5 with its stages written out."""

import diffrax as dfx
import jax.numpy as jnp
import numpy as np

import vmj
from vmj._numerics._ode import ode_solve, tsit5


def _solve(solver):
    model = vmj.VariableMass(5.0, 4900.0, 1.0, 0.5, 2.0, vmj.Coulomb(14.7))
    w = 1e-3 * float(model.velocity_scale(0.06))
    return ode_solve(
        lambda t, y, args: model.vector_field(t, y, w),
        jnp.array([-0.06, 0.0]),
        0.5,
        dfx.SaveAt(ts=jnp.linspace(0.0, 0.5, 41)),  # dense output between the steps
        rtol=1e-10,
        atol=1e-12,
        max_steps=100_000,
        solver=solver,
    )


def test_tsit5_takes_the_steps_of_diffrax_tsit5():
    ours, theirs = _solve(tsit5()), _solve(dfx.Tsit5())
    assert ours.result == dfx.RESULTS.successful
    # the same tableau, error estimate and step-size control: the same steps, and the same
    # solution up to the order of the additions (measured: 4e-14 of each component's scale;
    # the solve's own tolerance is 1e-10)
    assert int(ours.stats["num_steps"]) == int(theirs.stats["num_steps"]) > 100
    assert int(ours.stats["num_rejected_steps"]) == int(theirs.stats["num_rejected_steps"])
    scale = np.abs(np.asarray(theirs.ys)).max(axis=0)
    assert np.all(np.abs(np.asarray(ours.ys - theirs.ys)) < 1e-12 * scale)
