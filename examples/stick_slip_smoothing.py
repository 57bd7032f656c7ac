"""How the smoothed (diffrax) stick-slip cycle approaches the exact one as the smoothing shrinks.

The smoothed model (`vmj.simulate` with `vmj.Smoothed`) replaces sign(u) by P(z) tanh(u/w) with a rest
memory z that raises the friction limit to the static eps while the disk (nearly) rests. It
cannot truly stick: at rest it creeps with u ~ w, and the static friction needs a memory time
w**0.25 to build up and to fade. This script measures the cycle (reversals, slip/stick times,
period) for w = 1e-2 ... 1e-6 against the exact event-driven solver and plots both
(`VMJ_EXAMPLES_QUICK=1`: one case and two smoothings, a smoke run for the test suite).

    .venv/bin/python examples/stick_slip_smoothing.py [OUTDIR]     (default out/; docs/figures for the site)
"""

import os
import sys

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import vmj  # noqa: E402
from vmj.plot import pyplot as _pyplot, save  # noqa: E402

OUT = sys.argv[1] if len(sys.argv) > 1 else "out"
os.makedirs(OUT, exist_ok=True)
QUICK = os.environ.get("VMJ_EXAMPLES_QUICK") == "1"  # a smoke run (the test suite)
CASES = [(6.3, 0.7)] if QUICK else [(2.5, 0.5), (4.0, 1.0), (6.3, 0.7)]
WS = [1e-2, 1e-3] if QUICK else [1e-2, 1e-3, 1e-4, 1e-5, 1e-6]
SHOWN = (1e-2, 1e-3) if QUICK else (1e-2, 1e-3, 1e-5)  # smoothings whose trajectories are drawn


def main():
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    rows = []
    for eps, Omega in CASES:
        model = vmj.StickSlip(eps, Omega)
        exact = vmj.limit_cycle(model)
        errs = []
        for w in WS:
            try:
                sm = vmj.limit_cycle(model, vmj.Smoothed(smoothing=w))
            except RuntimeError as e:  # no settled cycle at this smoothing
                rows.append((eps, Omega, w, None, str(e)))
                errs.append(np.nan)
                continue
            err = float(sm.period / exact.period - 1)
            errs.append(abs(err))
            rows.append(
                (
                    eps,
                    Omega,
                    w,
                    int(sm.reversals),
                    err,
                    float(sm.slip_time / exact.slip_time - 1),
                    float(sm.stick_time / exact.stick_time - 1),
                )
            )
        axes[1].loglog(
            WS, errs, "o-", label=f"eps={eps:g}, Omega={Omega:g} (k*={int(exact.reversals)})"
        )
    # trajectories of one case
    eps, Omega = CASES[-1]
    model = vmj.StickSlip(eps, Omega)
    exact = vmj.limit_cycle(model)
    T = float(exact.period)
    ex = exact.trajectory(n_save=3001, periods=1.0)
    axes[0].plot(ex.ts, ex.vs, "k", lw=2, label="exact")
    for w in SHOWN:
        tr = vmj.simulate(
            model, *model.breakaway(), 3.3 * T, vmj.Smoothed(smoothing=w), n_save=6001
        )
        # align on the last breakaway before 3.3 T (the disk accelerates from rest at xi = -eps)
        ts, u = np.asarray(tr.ts), np.asarray(tr.vs) + Omega
        moving = np.abs(u) > 20 * w
        starts = np.nonzero(~moving[:-1] & moving[1:] & (ts[:-1] > 1.2 * T))[0]
        i0 = starts[0]
        sel = (ts >= ts[i0]) & (ts <= ts[i0] + T)
        axes[0].plot(ts[sel] - ts[i0], np.asarray(tr.vs)[sel], lw=1, label=f"smoothed w={w:g}")
    axes[0].set_title(f"dxi/dtau over one cycle, eps={eps:g}, Omega={Omega:g}", fontsize=9)
    axes[0].set_xlabel("tau from breakaway")
    axes[0].legend(fontsize=7)
    axes[1].set_xlabel("smoothing w")
    axes[1].set_ylabel("|period(smoothed) / period(exact) - 1|")
    axes[1].set_title("convergence of the smoothed cycle (about w^0.28)", fontsize=9)
    axes[1].legend(fontsize=7)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    save(fig, f"{OUT}/stick_slip_smoothing.png")
    plt.close(fig)
    print("| eps | Omega | w | reversals | period err | slip err | stick err |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        if r[3] is None:
            print(f"| {r[0]:g} | {r[1]:g} | {r[2]:g} | - | {r[4]} | | |")
        else:
            print(
                f"| {r[0]:g} | {r[1]:g} | {r[2]:g} | {r[3]} | {r[4]:+.2e} | {r[5]:+.2e} | "
                f"{r[6]:+.2e} |"
            )


if __name__ == "__main__":
    main()
