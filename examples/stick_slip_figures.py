"""Redraw the stick-slip paper's figures 6-15 and map k* and the period over (eps, Omega).

Belokobylsky & Koronatov plot, for one to four instantaneous reversals per period, the disk's
velocity against dimensionless time (figures 6, 8, 10, 12, 14) and the phase plane (7, 9, 11,
13, 15). The parameter values of the figures are not legible in the source text, so each pair
uses a representative (eps, Omega) with the figure's number of reversals (k* = floor((eps-1)/2)).

    .venv/bin/python examples/stick_slip_figures.py [OUTDIR]     (default out/; docs/figures for the site)
"""

import os
import sys

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import vmj  # noqa: E402
from vmj.plot import pyplot as _pyplot, save  # noqa: E402

OUT = sys.argv[1] if len(sys.argv) > 1 else "out"
os.makedirs(OUT, exist_ok=True)

# (figure pair, reversals, eps, Omega)
CASES = [
    ((6, 7), 1, 4.0, 1.0),
    ((8, 9), 2, 6.0, 1.0),
    ((10, 11), 3, 8.0, 1.0),
    ((12, 13), 4, 10.0, 1.0),
    ((14, 15), 4, 10.5, 0.3),
]


def figures():
    plt = _pyplot()
    fig, axes = plt.subplots(len(CASES), 2, figsize=(11, 3.0 * len(CASES)))
    for (pair, k, eps, Omega), (ax_v, ax_p) in zip(CASES, axes):
        model = vmj.StickSlip(eps, Omega)
        cyc = vmj.limit_cycle(model)
        assert int(cyc.reversals) == k
        tr = cyc.trajectory(n_save=4001, periods=2.0)
        ts, xi, dxi = (np.asarray(a) for a in (tr.ts, tr.xs, tr.vs))
        ax_v.plot(ts, dxi, lw=1.2)
        ax_v.axhline(-Omega, color="k", lw=0.6, ls=":")
        ax_v.set_title(
            f"fig. {pair[0]}: {k} reversal{'s' if k > 1 else ''} (eps={eps:g}, Omega={Omega:g})",
            fontsize=9,
        )
        ax_v.set_xlabel("tau")
        ax_v.set_ylabel("dxi/dtau (rest at -Omega)")
        ax_p.plot(xi, dxi, lw=1.2)
        ax_p.plot(
            np.asarray(cyc.positions[: int(cyc.count)]),
            np.full(int(cyc.count), -Omega),
            "o",
            ms=4,
            mfc="none",
            label="velocity zeros xi_k",
        )
        ax_p.set_title(f"fig. {pair[1]}: phase plane", fontsize=9)
        ax_p.set_xlabel("xi")
        ax_p.set_ylabel("dxi/dtau")
        ax_p.legend(fontsize=7, loc="upper left")
        for ax in (ax_v, ax_p):
            ax.grid(alpha=0.3)
    fig.tight_layout()
    save(fig, f"{OUT}/stick_slip_figures_6_15.png")
    plt.close(fig)


def cycle_map(n=241):
    """k* and the period over an (eps, Omega) grid, one `jax.vmap` call."""
    eps = jnp.linspace(1.1, 15.0, n)
    Omega = jnp.geomspace(0.05, 5.0, n)
    E, O = jnp.meshgrid(eps, Omega)
    solve = jax.jit(jax.vmap(lambda e, o: vmj.limit_cycle(vmj.StickSlip(e, o))))
    cyc = solve(E.ravel(), O.ravel())
    kstar = np.asarray(cyc.reversals).reshape(E.shape)
    period = np.asarray(cyc.period).reshape(E.shape)
    assert np.all(np.asarray(cyc.result) == 0)
    plt = _pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.2))
    m = a.pcolormesh(eps, Omega, kstar, shading="auto", cmap="viridis")
    fig.colorbar(m, ax=a, label="reversals k* per period")
    a.set_title("k* = floor((eps - 1)/2): boundaries at eps = 3, 5, 7, ...", fontsize=9)
    m = b.pcolormesh(eps, Omega, period, shading="auto", cmap="magma", norm="log")
    fig.colorbar(m, ax=b, label="period Lambda (dimensionless)")
    b.set_title("period Lambda = slip time + stick time", fontsize=9)
    for ax in (a, b):
        ax.set_yscale("log")
        ax.set_xlabel("eps = M1/M0")
        ax.set_ylabel("Omega")
    fig.tight_layout()
    save(fig, f"{OUT}/stick_slip_map.png")
    plt.close(fig)
    return kstar, period


if __name__ == "__main__":
    figures()
    kstar, period = cycle_map()
    print(
        f"figures written to {OUT}/stick_slip_figures_6_15.png and {OUT}/stick_slip_map.png; "
        f"k* ranges {kstar.min()}..{kstar.max()}, period {period.min():.3f}..{period.max():.1f}"
    )
