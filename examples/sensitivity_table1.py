"""Sensitivities of the amplitudes a_k to (F, mu, eps, delta) for the paper's table-1 case
(m0 = 5 kg, c = 4900 N/m, F_T = 14.7 N, a0 = 6 cm, delta = +3 kg/s; mu in {2, 9} kg/s,
eps in {0, 1}), from the exact solver with forward-mode derivatives, checked against central
finite differences.

Run: .venv/bin/python examples/sensitivity_table1.py [PNG]
(default out/sensitivity_table1.png; docs/figures/sensitivity_table1.png for the site)
"""

import os
import sys

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import vmj  # noqa: E402
from vmj._sweep._sensitivity import central_difference  # noqa: E402
from vmj.plot import pyplot as _pyplot, save  # noqa: E402

A0, N = 0.06, 12
WRT = ("F", "mu", "eps", "delta")
UNITS = {"F": "cm/N", "mu": "cm/(kg/s)", "eps": "cm", "delta": "cm/(kg/s)"}


def amplitudes(model, a0, n):
    return vmj.turning_points(model, a0, n).amplitudes


model = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))
columns = vmj.grid(model, mu=[2.0, 9.0], eps=[0.0, 1.0])
result = vmj.sweep(lambda m: vmj.sensitivity(amplitudes, m, WRT, a0=A0, n=N), columns)
values = vmj.sweep(vmj.turning_points, columns, a0=A0, n=N).values

# check one column against central differences (eps inside (0, 1) so both sides are valid);
# VMJ_EXAMPLES_QUICK=1 (the test suite's smoke run) skips the check: tests/test_sensitivity.py
# makes it
QUICK = os.environ.get("VMJ_EXAMPLES_QUICK") == "1"
inner = vmj.VariableMass(5.0, 4900.0, 3.0, 0.5, 2.0, vmj.Coulomb(14.7))
ad = {} if QUICK else vmj.sensitivity(amplitudes, inner, WRT, a0=A0, n=N)
steps = {"F": 1e-5, "mu": 1e-6, "eps": 1e-7, "delta": 1e-6}
for name in ad:
    fd = central_difference(amplitudes, inner, name, steps[name], a0=A0, n=N)
    rel = np.max(np.abs(np.asarray(ad[name]) - fd)) / np.max(np.abs(fd))
    print(
        f"d a_k/d {name:5s} (mu=2, eps=0.5): forward mode vs central differences, "
        f"max relative difference {rel:.1e}"
    )

plt = _pyplot()
fig, axes = plt.subplots(1, 4, figsize=(16, 3.6), constrained_layout=True)
k = np.arange(1, N + 1)
for ax, name in zip(axes, WRT):
    for i, mu in enumerate(result.coords["mu"]):
        for j, eps in enumerate(result.coords["eps"]):
            count = int(values.count[i, j])
            d = 100 * np.asarray(result.values[name][i, j])  # m -> cm
            (line,) = ax.plot(k[:count], d[:count], "o-", ms=3, label=f"mu={mu:g}, eps={eps:g}")
            ax.plot(k[count - 1 :], d[count - 1 :], ":", color=line.get_color())
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("swing k")
    ax.set_title(f"d a_k / d {name}  [{UNITS[name]}]", fontsize=10)
    ax.grid(alpha=0.3)
axes[0].legend(fontsize=8)
fig.suptitle(
    "Table 1 (delta = +3 kg/s, F_T = 14.7 N): sensitivities of the exact amplitudes "
    "(dotted: after the mass sticks)",
    fontsize=10,
)
path = sys.argv[1] if len(sys.argv) > 1 else os.path.join("out", "sensitivity_table1.png")
os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
save(fig, path)
print(f"figure written to {path}")
