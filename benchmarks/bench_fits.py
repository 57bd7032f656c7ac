"""Benchmark of fits: fit latency (first call including compilation, and warm) against SciPy
least_squares over an event-driven solve_ivp model on the same data, and a batched fit of 1000
records. Prints ratios measured in this run.

Run: .venv/bin/python benchmarks/bench_fits.py [--records 1000]
"""

import argparse
import os
import sys
import time
import warnings

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

import fits  # noqa: E402
import vmj  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
from scipy_reference import variable_mass_turning_points  # noqa: E402

M0, C, DELTA, EPS, MU, FT, A0, N = 5.0, 4900.0, 3.0, 0.0, 2.0, 14.7, 0.06, 10
GIVEN = {"m0": M0, "c": C, "delta": DELTA, "eps": EPS, "a0": A0}


def record(seed):
    model = vmj.VariableMass(M0, C, DELTA, EPS, MU, vmj.Coulomb(FT))
    seq = vmj.turning_points(model, A0, N)
    n = int(seq.count)
    pos = np.concatenate([[-A0], np.asarray(seq.positions)[:n]])
    pos = pos + np.random.default_rng(seed).normal(0, 0.002 * A0, n + 1)
    return fits.record_from_sequence(positions=pos)


def scipy_fit(rec, start):
    data = rec.positions[1:]

    def residual(p):
        _, x, _ = variable_mass_turning_points(
            M0, C, DELTA, EPS, p[1], A0, len(data), F=p[0], rtol=1e-10
        )
        x = np.concatenate([x, np.repeat(x[-1] if x.size else -A0, len(data) - x.size)])
        return x - data

    return least_squares(residual, start, bounds=([0, 0], [np.inf, np.inf]), x_scale=start)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--records", type=int, default=1000)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    rec = record(0)
    t = time.perf_counter()
    first = fits.fit(rec, "variable-mass", ("FT", "mu"), GIVEN, compare=False)
    t_first = time.perf_counter() - t
    warm = []
    for seed in range(1, 6):
        r = record(seed)
        t = time.perf_counter()
        fits.fit(r, "variable-mass", ("FT", "mu"), GIVEN, compare=False)
        warm.append(time.perf_counter() - t)
    t_warm = float(np.median(warm))
    dec = first.decrement
    start = np.array([C * max(dec["xF"], 1e-4), 2.0 * 1.05])
    t = time.perf_counter()
    sp = scipy_fit(rec, start)
    t_scipy = time.perf_counter() - t
    print(f"single fit (FT, mu; {len(rec)} turning points, exact model):")
    print(
        f"  vmj/fits first call (with compilation): {t_first:8.3f} s  "
        f"FT={first.params['FT']:.4f} mu={first.params['mu']:.4f}"
    )
    print(f"  vmj/fits warm (median of 5):            {t_warm:8.3f} s")
    print(
        f"  SciPy least_squares + solve_ivp events: {t_scipy:8.3f} s  "
        f"FT={sp.x[0]:.4f} mu={sp.x[1]:.4f} ({sp.nfev} model evaluations)"
    )
    print(f"  ratio SciPy / vmj warm:  {t_scipy / t_warm:8.2f}")
    print(f"  ratio SciPy / vmj first: {t_scipy / t_first:8.2f}")
    recs = [record(100 + i) for i in range(args.records)]
    t = time.perf_counter()
    out = fits.fit_batch(recs, "variable-mass", ("FT", "mu"), GIVEN, compare=False)
    t_batch = time.perf_counter() - t
    t = time.perf_counter()
    fits.fit_batch(recs, "variable-mass", ("FT", "mu"), GIVEN, compare=False)
    t_batch_warm = time.perf_counter() - t
    ft = np.array([r.params["FT"] for r in out])
    print(
        f"batched fit of {args.records} records (jax.vmap): first {t_batch:.2f} s, "
        f"warm {t_batch_warm:.2f} s = {1e3 * t_batch_warm / args.records:.2f} ms/record; "
        f"FT mean {ft.mean():.4f} sd {ft.std():.4f}; converged "
        f"{sum(r.converged for r in out)}/{len(out)}"
    )
    print(
        f"  ratio SciPy single / vmj batched per record: "
        f"{t_scipy / (t_batch_warm / args.records):.1f}"
    )


if __name__ == "__main__":
    main()
