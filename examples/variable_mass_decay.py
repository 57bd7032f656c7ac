"""Variable-mass oscillator: exact, smoothed and energy-balance decay, and a sensitivity.

Run: .venv/bin/python examples/variable_mass_decay.py  (writes out/variable_mass_decay.png)
"""

import os

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402

import vmj  # noqa: E402
from vmj.plot import pyplot, save  # noqa: E402

# Table 4 of the paper: shrinking mass, friction proportional to the weight
model = vmj.VariableMass(
    m0=5.0, c=4900.0, delta=-3.0, eps=1.0, mu=5.0, friction=vmj.MassProportional(f=0.3)
)
a0, n = 0.06, 12
exact = vmj.turning_points(model, a0, n)
energy = vmj.turning_points(model, a0, n, vmj.EnergyBalance())
traj = vmj.simulate(model, -a0, 0.0, float(exact.times[-1]) + 0.05)
print("exact amplitudes [cm]:", jnp.round(exact.amplitudes * 100, 4))
print("energy balance   [cm]:", jnp.round(energy.amplitudes * 100, 4))
print("status:", exact.message)


# derivative of the 12th amplitude with respect to the friction coefficient f
def last_amplitude(f):
    m = vmj.VariableMass(5.0, 4900.0, -3.0, 1.0, 5.0, vmj.MassProportional(f))
    return vmj.turning_points(m, a0, n).amplitudes[-1]


print("d a_12 / d f =", float(jax.grad(last_amplitude)(0.3)), "m")

plt = pyplot()
fig, ax = plt.subplots(figsize=(8, 3.5))
ax.plot(traj.ts, traj.xs * 100, lw=0.8, label="smoothed ODE (diffrax)")
ax.plot(exact.times, exact.positions * 100, "o", label="exact turning points")
ax.plot(energy.times, energy.positions * 100, "x", label="energy balance")
ax.set_xlabel("t [s]")
ax.set_ylabel("x [cm]")
ax.legend()
os.makedirs("out", exist_ok=True)
save(fig, "out/variable_mass_decay.png")
print("figure: out/variable_mass_decay.png")
