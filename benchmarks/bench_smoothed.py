"""The smoothed solver over the sweep grid of the command line's example: eps 0:1:11, mu
0:10:21 kg/s, delta -3:3:7 kg/s (1617 points), 12 turning points from a0 = 6 cm, every setting
at its default (`vmj.Smoothed()`: w = 1e-4 of the velocity scale, Dopri8, rtol 1e-10), against
the exact solver over the same grid (goal: completes, within 20 x of the exact sweep), the two
measured in turns (`interleaved`); the turning points of the two compared.

Run: .venv/bin/python benchmarks/bench_smoothed.py [--quick]
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _timing import REPEAT, interleaved, machine, ratio, repeat, set_up_jax  # noqa: E402

set_up_jax()  # as the vmj command runs

import numpy as np  # noqa: E402

import vmj  # noqa: E402

A0, N = 0.06, 12


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="a 3 x 3 x 3 grid (a smoke run)")
    args = ap.parse_args()
    vmj.retain_host_memory()  # as the vmj command does
    print(machine())
    sizes = (3, 3, 3) if args.quick else (11, 21, 7)
    grid = vmj.grid(
        vmj.VariableMass(5.0, 4900.0, 0.0, 0.0, 0.0, vmj.Coulomb(14.7)),
        eps=np.linspace(0, 1, sizes[0]),
        mu=np.linspace(0, 10, sizes[1]),
        delta=np.linspace(-3, 3, sizes[2]),
    )
    P = int(np.prod(sizes))

    def run(solver):
        return vmj.sweep(vmj.turning_points, grid, a0=A0, n=N, solver=solver, progress=False).values

    first = {}
    for name, solver in (("exact", vmj.Exact()), ("smoothed", vmj.Smoothed())):
        first[name] = repeat(lambda s=solver: run(s), times=1)
    exact, smooth = run(vmj.Exact()), run(vmj.Smoothed())
    # in turns, three exact sweeps (milliseconds: more runs steady their median) to one smoothed
    t_exact, t_smooth = interleaved(
        (lambda: run(vmj.Exact()), 3),
        (lambda: run(vmj.Smoothed()), 1),
        rounds=max(REPEAT, 7),
        warm_up=True,
    )
    same = np.asarray(exact.count) == np.asarray(smooth.count)
    k = np.arange(N) < np.asarray(exact.count)[..., None]
    rel = np.abs(np.asarray(smooth.amplitudes) / np.asarray(exact.amplitudes) - 1)
    rel = rel[k & same[..., None] & (np.asarray(exact.amplitudes) > 0.01 * A0)]
    print(
        f"smoothed turning points over the {' x '.join(map(str, sizes))} grid ({P} points, "
        f"{N} turning points, defaults)"
    )
    print(f"  exact sweep:     {t_exact}  (compile + first call {first['exact'].median:.1f} s)")
    print(
        f"  smoothed sweep:  {t_smooth}  (compile + first call "
        f"{first['smoothed'].median:.1f} s; results okay: "
        f"{int(np.sum(vmj.RESULTS.okay(np.asarray(smooth.result))))}/{P})"
    )
    print(
        f"  same number of turning points: {int(same.sum())}/{P}; amplitudes above 1 % of a0 "
        f"agree to {np.median(rel):.1e} (median), {np.max(rel):.1e} (max) relative"
    )
    ratio("smoothed / exact", t_smooth, t_exact, "<= 20")


if __name__ == "__main__":
    main()
