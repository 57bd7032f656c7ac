"""Fits in Python (`fits.fit`, `fits.fit_batch`) against SciPy `least_squares` over an
event-driven `solve_ivp` model of the same record (no intervals: SciPy's fit has none).

- one fit of (FT, mu) on an 11-point record, the first call (compilation) and warm;
- a batch of records (`fits.fit_batch`, one compiled solve), without intervals and with the
  95 % profile-likelihood intervals (the default), per record.

Medians with min/max of 5 repetitions on each side, in one run.

Run: .venv/bin/python benchmarks/bench_fits.py [--records 200]
"""

import argparse
import os
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _timing import REPEAT, machine, ratio, repeat, set_up_jax  # noqa: E402

set_up_jax()

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
    ap.add_argument("--records", type=int, default=200)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    print(machine())
    rec = record(0)

    def fit(intervals=True):
        return fits.fit(
            rec, "variable-mass", ("FT", "mu"), GIVEN, compare=False, intervals=intervals
        )

    t = time.perf_counter()
    first = fit()
    t_first = time.perf_counter() - t
    dec = first.decrement
    start = np.array([C * max(dec["xF"], 1e-4), 2.0 * 1.05])
    sp = scipy_fit(rec, start)
    t_warm = repeat(lambda: fit(intervals=False), times=REPEAT)
    t_warm_intervals = repeat(fit, times=REPEAT)
    t_scipy = repeat(lambda: scipy_fit(rec, start), times=REPEAT)
    print(f"one fit of (FT, mu) on {len(rec)} turning points, exact model")
    print(f"  first call (compilation, intervals):  {t_first:.2f} s")
    print(f"  warm, no intervals:                   {t_warm}")
    print(f"  warm, profile-likelihood intervals:   {t_warm_intervals}")
    print(f"  SciPy least_squares + solve_ivp:      {t_scipy}  ({sp.nfev} model evaluations)")
    print(
        f"  answers: vmj FT = {first.params['FT']:.4f} N, mu = {first.params['mu']:.4f} kg/s; "
        f"SciPy FT = {sp.x[0]:.4f} N, mu = {sp.x[1]:.4f} kg/s"
    )
    ratio("SciPy / vmj warm (no intervals)", t_scipy, t_warm)

    recs = [record(100 + i) for i in range(args.records)]

    def batch(intervals):
        return fits.fit_batch(
            recs, "variable-mass", ("FT", "mu"), GIVEN, compare=False, intervals=intervals
        )

    print(f"a batch of {args.records} records (fits.fit_batch), per record")
    for intervals in (False, True):
        t = time.perf_counter()
        out = batch(intervals)
        t_compile = time.perf_counter() - t
        t_batch = repeat(lambda i=intervals: batch(i), times=REPEAT).per(args.records)
        ft = np.array([r.params["FT"] for r in out])
        what = "with intervals" if intervals else "no intervals"
        print(
            f"  {what + ':':16s}{t_batch}  (first call {t_compile:.1f} s; FT mean {ft.mean():.4f} "
            f"sd {ft.std():.4f}; converged {sum(r.converged for r in out)}/{len(out)})"
        )
        ratio(f"SciPy one fit / vmj per record, {what}", t_scipy, t_batch)


if __name__ == "__main__":
    main()
