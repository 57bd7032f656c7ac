"""Benchmark of the exact stick-slip cycle: a vmap'd (eps, Omega) grid against the independent
SciPy event integration (tests/scipy_stickslip.py) point by point, and the smoothed diffrax
model's cost per cycle. Prints times and ratios measured in this run.

Run: .venv/bin/python benchmarks/bench_stickslip.py [--grid 200]
"""

import argparse
import os
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import vmj  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
from scipy_stickslip import stick_slip_cycle as scipy_cycle  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--grid", type=int, default=200, help="grid size n (n x n cycles)")
    ap.add_argument("--scipy-points", type=int, default=40)
    args = ap.parse_args()
    n = args.grid
    E, O = jnp.meshgrid(jnp.linspace(1.1, 15.0, n), jnp.geomspace(0.05, 5.0, n))
    e, o = E.ravel(), O.ravel()
    solve = jax.jit(jax.vmap(lambda a, b: vmj.limit_cycle(vmj.StickSlip(a, b)).period))
    t = time.perf_counter()
    solve(e, o).block_until_ready()
    first = time.perf_counter() - t
    t = time.perf_counter()
    periods = solve(e, o).block_until_ready()
    warm = time.perf_counter() - t
    per_jax = warm / e.size

    rng = np.random.default_rng(0)
    idx = rng.choice(e.size, args.scipy_points, replace=False)
    t = time.perf_counter()
    ref = [scipy_cycle(float(e[i]), float(o[i]))[4] for i in idx]
    per_scipy = (time.perf_counter() - t) / len(idx)
    err = np.max(np.abs(np.asarray(periods)[idx] / np.array(ref) - 1))

    model = vmj.StickSlip(6.3, 0.7)
    t = time.perf_counter()
    vmj.limit_cycle(model, vmj.Smoothed(smoothing=1e-4))
    smooth_first = time.perf_counter() - t
    t = time.perf_counter()
    vmj.limit_cycle(model, vmj.Smoothed(smoothing=1e-5))
    smooth_warm = time.perf_counter() - t

    print(
        f"exact, vmap over {e.size} cycles: first call {first:.2f} s (incl. compilation), "
        f"warm {warm:.3f} s = {1e6 * per_jax:.2f} us/cycle"
    )
    print(
        f"SciPy event integration: {1e3 * per_scipy:.2f} ms/cycle "
        f"({args.scipy_points} points); max relative period difference {err:.1e}"
    )
    print(f"ratio SciPy / vmj exact (per cycle, warm): {per_scipy / per_jax:.0f}x")
    print(
        f"smoothed diffrax cycle (3.3 periods): first {smooth_first:.1f} s, warm "
        f"{smooth_warm:.2f} s; ratio smoothed / exact single cycle: "
        f"{smooth_warm / per_jax:.0f}x"
    )


if __name__ == "__main__":
    main()
