"""Redraw figures 3-7 of Osinski's rope paper with the exact solver and the averaged laws.

Paper's data (technical units as printed, converted by `vmj.Rope.paper`): rope 6x37, 22 mm,
A = 1.74 cm^2, l0 = 10 m, m = 2 kG s^2/m, e = 0.8e6 kG/cm^2, d = 0.8e11 kG/cm^2, b = 0.
Each figure shows the exact turning-point amplitudes (dots), the paper's first-order law
(corrected, dashed) and the action-averaged law (solid).

- fig. 3: T = 0, amplitude ratio a/a0 against time for several hoisting speeds (a0 = 1 cm and
  4 cm: with the cubic term the ratio does depend on a0 a little);
- fig. 4: friction T = 0, 2, 4, 10 kG/cm^2 when hoisting and lowering at 3 m/s (a0 = 1 cm);
- fig. 5: the balance of lowering and friction (constant amplitude): the T at which the exact
  amplitude is back at a0 after 2 s, for u = -3 m/s and a0 = 1 cm and 4 cm;
- figs. 6, 7: frequency against time for a0 = 1 cm and 4 cm.

It also prints the errors of the first-order and action-averaged amplitude laws against the
exact solver (docs/rope.md quotes them). `VMJ_EXAMPLES_QUICK=1` makes a smoke run over 0.5 s
instead of 2 s (the test suite runs it so).

    .venv/bin/python examples/rope_paper_figures.py [OUTDIR]     (default out/; docs/figures for the site)
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
QUICK = os.environ.get("VMJ_EXAMPLES_QUICK") == "1"  # a smoke run (the test suite): 0.5 s
T_END = 0.5 if QUICK else 2.0
N = 150 if QUICK else 460  # half-swings: covers T_END in every case below
PAD = 460  # the averaged laws are evaluated on this many times (one compilation)
KG_CM2 = vmj.KGF * 1e4


@jax.jit
def _exact(u, T, a0):
    def one(u, T, a0):
        rope = vmj.Rope.paper(l0=10.0)
        rope = vmj.Rope(
            rope.m, rope.A, rope.e, rope.b, rope.d, T * KG_CM2, vmj.ConstantSpeed(10.0, u)
        )
        seq = vmj.turning_points(rope, a0, N, vmj.Exact(max_substeps=10))
        return seq.times, seq.positions, seq.count, seq.result

    return jax.vmap(one)(u, T, a0)


def exact(cases):
    """Exact turning points (t, |x|) within T_END for each (u, T [kG/cm^2], a0 [m])."""
    padded = list(cases) + [cases[-1]] * (-len(cases) % 8)  # batches of 8: few compilations
    u, T, a0 = (jnp.array([c[i] for c in padded], dtype=float) for i in range(3))
    ts, xs, counts, results = _exact(u, T, a0)
    out = []
    for t, x, n, r in list(zip(ts, xs, counts, results))[: len(cases)]:
        assert int(r) in (vmj.RESULTS.successful, vmj.RESULTS.stopped), vmj.RESULTS.messages[int(r)]
        t, a = np.asarray(t)[: int(n)], np.abs(np.asarray(x))[: int(n)]
        assert int(r) == vmj.RESULTS.stopped or t[-1] > T_END, "raise N"
        keep = t <= T_END
        out.append((t[keep], a[keep]))
    return out


def laws(u, T, a0, ts):
    """First-order and action-law amplitude [m] and frequency [rad/s] at `ts` (padded to a fixed
    length so that every call shares one compilation)."""
    rope = vmj.Rope.paper(u=u, T=T)
    n = len(ts)
    padded = jnp.asarray(np.concatenate([ts, np.zeros(PAD - n)]))
    a0 = jnp.asarray(a0)
    out = (
        vmj.kbm_amplitude(rope, a0, padded),
        vmj.action_amplitude(rope, a0, padded),
        vmj.kbm_frequency(rope, a0, padded),
        vmj.action_frequency(rope, a0, padded),
    )
    return tuple(np.asarray(o)[:n] for o in out)


GRID = np.linspace(0.0, T_END, 201)


def amplitude_panel(ax, cases, results, scale_by_a0):
    for (u, T, a0), (t, a), color in zip(cases, results, _colors(len(cases))):
        k, act, _, _ = laws(u, T, a0, GRID)
        s = a0 if scale_by_a0 else 0.01
        label = f"u={u:g} m/s, T={T:.4g}" + (f", a0={100 * a0:g} cm" if scale_by_a0 else "")
        ax.plot(t[::3], a[::3] / s, ".", ms=2.5, color=color)
        ax.plot(GRID, act / s, "-", lw=1.2, color=color, label=label)
        ax.plot(GRID, k / s, "--", lw=0.9, color=color)
    ax.set_xlabel("t [s]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def _colors(n):
    plt = _pyplot()
    return plt.cm.viridis(np.linspace(0, 0.9, n))


def fig3(plt):
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, a0 in zip(axes, (0.01, 0.04)):
        cases = [(u, 0.0, a0) for u in (3.0, 1.5, 0.0, -1.5, -3.0)]
        amplitude_panel(ax, cases, exact(cases), True)
        ax.set_title(f"fig. 3: T = 0, a0 = {100 * a0:g} cm", fontsize=9)
    axes[0].set_ylabel("a / a0   (dots exact, solid action law, dashed first order)")
    save(fig, f"{OUT}/rope_fig3.png")
    plt.close(fig)


def fig4(plt):
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, u in zip(axes, (3.0, -3.0)):
        cases = [(u, T, 0.01) for T in (0.0, 2.0, 4.0, 10.0)]
        amplitude_panel(ax, cases, exact(cases), False)
        ax.set_title(f"fig. 4: friction T [kG/cm^2], u = {u:g} m/s, a0 = 1 cm", fontsize=9)
    axes[0].set_ylabel("amplitude [cm]")
    save(fig, f"{OUT}/rope_fig4.png")
    plt.close(fig)


def balance_T(u, a0):
    """T [kG/cm^2] at which the exact amplitude after T_END is back at a0 (bracket + secant)."""
    grid = np.linspace(0.0, 4.0, 5 if QUICK else 17)

    def final(Ts):
        res = exact([(u, T, a0) for T in Ts])
        return np.array([a[-1] if t[-1] > T_END - 0.05 else 0.0 for t, a in res]) - a0

    f = final(grid)
    i = int(np.nonzero((f[:-1] > 0) & (f[1:] <= 0))[0][0])
    lo, hi, flo, fhi = grid[i], grid[i + 1], f[i], f[i + 1]
    for _ in range(1 if QUICK else 3):
        mids = lo + (hi - lo) * np.array([flo / (flo - fhi), 0.25, 0.5, 0.75])
        mids = np.clip(mids, lo, hi)
        fm = final(mids)
        Ts = np.concatenate([[lo], mids, [hi]])
        Fs = np.concatenate([[flo], fm, [fhi]])
        order = np.argsort(Ts)
        Ts, Fs = Ts[order], Fs[order]
        j = int(np.nonzero((Fs[:-1] > 0) & (Fs[1:] <= 0))[0][0])
        lo, hi, flo, fhi = Ts[j], Ts[j + 1], Fs[j], Fs[j + 1]
    return lo + (hi - lo) * flo / (flo - fhi)


def first_order_balance_T(u, a0):
    """First order: da/dt = 0 at t = 0 when D sqrt(l0) = -a0 u/(4 l0)."""
    r = vmj.Rope.paper()
    D = -a0 * u / (4 * 10.0**1.5)
    return float(np.pi * np.sqrt(r.e * r.m / r.A) * D / 2 / KG_CM2)


def fig5(plt):
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    found = {}
    for ax, a0 in zip(axes, (0.01, 0.04)):
        Tb = balance_T(-3.0, a0)
        found[a0] = Tb
        cases = [(-3.0, Tb, a0), (-3.0, 4.0, a0)]
        amplitude_panel(ax, cases, exact(cases), False)
        ax.axhline(100 * a0, color="k", lw=0.6, ls=":")
        ax.set_title(
            f"fig. 5: u = -3 m/s, a0 = {100 * a0:g} cm: exact balance at T = {Tb:.3f} "
            f"kG/cm^2\n(first order, da/dt = 0 at t = 0: "
            f"{first_order_balance_T(-3.0, a0):.3f})",
            fontsize=8,
        )
        ax.set_ylabel("amplitude [cm]")
    save(fig, f"{OUT}/rope_fig5.png")
    plt.close(fig)
    return found


def fig67(plt):
    for number, a0 in ((6, 0.01), (7, 0.04)):
        cases = [(u, T, a0) for u in (3.0, 0.0, -3.0) for T in (0.0, 4.0)]
        results = exact(cases)
        fig, ax = plt.subplots(figsize=(7.5, 4.5))
        for (u, T, _), (t, _), color in zip(cases, results, _colors(len(cases))):
            # exact: 2 pi / (time between peaks on the same side), at the middle turning point
            om = 2 * np.pi / (t[2:] - t[:-2])
            _, _, kf, af = laws(u, T, a0, GRID)
            ax.plot(t[1:-1][::3], om[::3], ".", ms=2.5, color=color)
            ax.plot(GRID, af, "-", lw=1.2, color=color, label=f"u={u:g} m/s, T={T:g} kG/cm^2")
            ax.plot(GRID, kf, "--", lw=0.9, color=color)
        ax.set_title(
            f"fig. {number}: frequency, a0 = {100 * a0:g} cm (dots exact, solid action "
            "law, dashed first order)",
            fontsize=9,
        )
        ax.set_xlabel("t [s]")
        ax.set_ylabel("angular frequency [rad/s]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        save(fig, f"{OUT}/rope_fig{number}.png")
        plt.close(fig)


def error_table():
    """Largest relative amplitude error over 2 s (amplitude > 10 % a0), a0 = 4 cm."""
    cases = [(u, T, 0.04) for u in (3.0, 0.0, -3.0) for T in (0.0, 4.0)]
    rows = []
    for (u, T, a0), (t, a) in zip(cases, exact(cases)):
        keep = a > 0.1 * a0
        k, act, _, _ = laws(u, T, a0, t[keep])
        rows.append(
            (u, T, np.max(np.abs(k - a[keep]) / a[keep]), np.max(np.abs(act - a[keep]) / a[keep]))
        )
    return rows


if __name__ == "__main__":
    plt = _pyplot()
    fig3(plt)
    fig4(plt)
    found = fig5(plt)
    fig67(plt)
    print("balance (constant amplitude over 2 s), u = -3 m/s:")
    for a0, Tb in found.items():
        print(
            f"  a0 = {100 * a0:g} cm: exact T = {Tb:.4f} kG/cm^2; first order (da/dt = 0 at "
            f"t = 0): {first_order_balance_T(-3.0, a0):.4f} kG/cm^2"
        )
    print("a0 = 4 cm, largest relative amplitude error over 2 s (amplitude > 10 % a0):")
    print("  u [m/s]  T [kG/cm^2]  first order  action law")
    for u, T, ek, ea in error_table():
        print(f"  {u:7g}  {T:11g}  {ek:11.2e}  {ea:10.2e}")
