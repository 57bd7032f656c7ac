"""The linear oscillator's worked examples.

1. Problem book (Tsuprov), 4.1.2 example 2: a 100 kg load dropped on a hinged platform;
   reduced model m3 = 100 kg, k3 = 4.7e5 N/m, c3 = 5.49e3 N s/m, X0 = -2e-3 m, V0 = 0.7 m/s:
   eta = 0.4, omega_c = 68.6 1/s, omega_3 = 62.8 1/s, A = 10.5e-3 m; with a quarter of the
   platform's 50 kg (m3 = 112.5 kg): A = 11e-3 m.
2. Lagrange-equation paper (Gorokhova): phi'' + phi' + 14.5 phi = 4 sin 15t, phi(0) = 0,
   phi'(0) = 0.1: D = 0.019 rad, tan(beta) = -0.071, settling time 11.1 s -- and the erratum in
   its final law (23), with the corrected law.

    .venv/bin/python examples/linear_examples.py [OUTDIR]     (default out/; docs/figures for the site)
"""

import math
import os
import sys

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import vmj  # noqa: E402
from vmj.plot import pyplot as _pyplot, save  # noqa: E402

OUT = sys.argv[1] if len(sys.argv) > 1 else "out"
os.makedirs(OUT, exist_ok=True)


def book_example(plt):
    print("Problem book 4.1.2, example 2")
    print(f"{'':24}{'omega_c':>9}{'eta':>7}{'omega_3':>9}{'delta':>8}{'A [mm]':>9}  printed")
    fig, ax = plt.subplots(figsize=(7, 3.4))
    for m3, printed in (
        (100.0, "68.6, 0.4, 62.8, A = 10.5 mm"),
        (112.5, "64.6, 0.38, 59.8, A = 11 mm"),
    ):
        osc = vmj.LinearOscillator(m3, 5.49e3, 4.7e5)
        A, alpha = osc.free_amplitude(-2e-3, 0.7)
        print(
            f"m3 = {m3:6.1f} kg         {float(osc.natural_frequency):9.2f}"
            f"{float(osc.damping_ratio):7.3f}{float(osc.damped_frequency):9.2f}"
            f"{float(osc.log_decrement):8.3f}{1e3 * float(A):9.2f}  {printed}"
        )
        tr = vmj.simulate(osc, -2e-3, 0.7, 0.3, vmj.Smoothed(rtol=1e-12), n_save=1201)
        ax.plot(tr.ts, 1e3 * np.asarray(tr.xs), label=f"m3 = {m3:g} kg (diffrax)")
        env = 1e3 * float(A) * np.exp(-float(osc.decay_rate) * np.asarray(tr.ts))
        ax.plot(
            tr.ts,
            env,
            ":",
            color=ax.lines[-1].get_color(),
            lw=1,
            label=f"envelope A e^(-eta omega_c t), A = {1e3 * float(A):.2f} mm",
        )
    ax.set_xlabel("t [s]")
    ax.set_ylabel("X [mm]")
    ax.set_title("problem book 4.1.2, example 2: free vibration of the platform", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    save(fig, f"{OUT}/linear_book_example.png")
    plt.close(fig)


def lagrange_example(plt):
    print("\nLagrange-equation paper: phi'' + phi' + 14.5 phi = 4 sin 15t, phi(0)=0, phi'(0)=0.1")
    osc = vmj.LinearOscillator(1.0, 1.0, 14.5, vmj.HarmonicForce(4.0, 15.0))
    D, beta = (float(v) for v in osc.forced_response())
    print(
        f"b = {float(osc.decay_rate):.3f} 1/s, k = {float(osc.natural_frequency):.3f} 1/s, "
        f"k* = sqrt(14.25) = {float(osc.damped_frequency):.4f} 1/s (printed 3.78)"
    )
    print(f"D = {D:.5f} rad (printed 0.019), tan(beta) = {math.tan(beta):.4f} (printed -0.071)")
    # the paper's branch: beta = arctan(-0.071) = -0.071 instead of pi - 0.071
    beta_p = math.atan(math.tan(beta))
    A_p, alpha_p = (
        float(v)
        for v in osc.free_amplitude(-D * math.sin(-beta_p), 0.1 - D * 15 * math.cos(-beta_p))
    )
    alpha_p = alpha_p % (2 * math.pi)
    t_p = math.log(100 * A_p / D) / float(osc.decay_rate)
    print(
        f"paper's pipeline (beta = arctan(-0.071)): A = {A_p:.4f} (printed 0.049), alpha = "
        f"{alpha_p:.4f} = pi + {alpha_p - math.pi:+.4f} (printed 0.028), settling time "
        f"ln(100 A/D)/b = {t_p:.2f} s (printed 11.1)"
    )
    A, alpha = (float(v) for v in osc.transient(0.0, 0.1))
    print(
        f"true lag beta = {beta:.4f} = pi - {math.pi - beta:.4f} (p > k: the response is nearly "
        "in antiphase with the moment)"
    )
    print(
        f"corrected law: phi = {A:.4f} e^(-0.5t) sin({float(osc.damped_frequency):.4f} t + "
        f"{alpha:.4f}) - {D:.4f} sin(15t + {math.pi - beta:.4f}) rad; "
        f"settling time {float(osc.settling_time(0.0, 0.1)):.2f} s"
    )
    tr = vmj.simulate(osc, 0.0, 0.1, 14.0, vmj.Smoothed(rtol=1e-12), n_save=4001)
    ts = np.asarray(tr.ts)
    transient23 = 0.049 * np.exp(-0.5 * ts) * np.sin(3.78 * ts + 0.028)
    forced23 = 0.019 * np.sin(15 * ts + 0.071)
    law23 = transient23 + forced23
    sysmd = -transient23 + forced23
    x, _ = osc.response(ts, 0.0, 0.1)
    sim = np.asarray(tr.xs)
    print(
        f"max |simulation - analytic| = {np.max(np.abs(sim - np.asarray(x))):.2e} rad; "
        f"max |simulation - law (23)| = {np.max(np.abs(sim - law23)):.3f} rad"
    )
    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.plot(ts, tr.xs, "k", lw=2, label="diffrax simulation = corrected analytic law")
    ax.plot(ts, law23, "r--", lw=1, label="paper's law (23)")
    ax.plot(ts, sysmd, "b:", lw=1, label="(23) with transient sign flipped only")
    ax.set_xlim(0, 6)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("phi [rad]")
    ax.set_title("phi'' + phi' + 14.5 phi = 4 sin 15t, phi(0) = 0, phi'(0) = 0.1", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    save(fig, f"{OUT}/linear_lagrange.png")
    plt.close(fig)


if __name__ == "__main__":
    plt = _pyplot()
    book_example(plt)
    lagrange_example(plt)
