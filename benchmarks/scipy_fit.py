"""The SciPy peer of

    vmj fit fits/data/table1_mu9_eps0.csv --model variable-mass --fit FT,mu \
        --set m0=5,c=4900,delta=3,eps=0 --loss cauchy

as a whole process: the same record, the same model (the exact variable-mass decay, here an
event-driven `solve_ivp` per half-swing: tests/scipy_reference.py), the same estimator (signed
turning points, Cauchy loss with tuning constant 2.385 on residuals scaled by their robust
spread 1.4826 MAD over every turning point of the record, the release included), fitted by
`scipy.optimize.least_squares` with the robust weights re-estimated after each fit (iteratively
reweighted least squares, ten passes after a plain least-squares start, as fits does). Prints
the parameters as JSON.

Run: python benchmarks/scipy_fit.py [record.csv]
"""

import json
import os
import sys

import numpy as np
from scipy.optimize import least_squares

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from scipy_reference import variable_mass_turning_points  # noqa: E402

M0, C, DELTA, EPS = 5.0, 4900.0, 3.0, 0.0
CAUCHY = 2.385  #: tuning constant of the Cauchy loss (95 % efficiency), as in fits


def read(path):
    """Signed turning points from a `k,amplitude,crossed` record released from `-a0`."""
    k, amplitude, crossed = np.loadtxt(path, delimiter=",", skiprows=1, unpack=True)
    side = -1.0
    signed = [-amplitude[0]]
    for a, c in zip(amplitude[1:], crossed[1:]):
        side = -side if c else side
        signed.append(side * a)
    return amplitude[0], np.array(signed[1:])


def main():
    path = (
        sys.argv[1]
        if len(sys.argv) > 1
        else os.path.join(HERE, "..", "fits", "data", "table1_mu9_eps0.csv")
    )
    a0, data = read(path)
    n = len(data)

    def residual(p):
        _, x, _ = variable_mass_turning_points(M0, C, DELTA, EPS, p[1], a0, n, F=p[0], rtol=1e-10)
        x = np.concatenate([x, np.repeat(x[-1] if x.size else -a0, n - x.size)])
        return x - data

    # start: the classical decrement (constant 2 F / c per swing), a small viscous term
    steps = -np.diff(np.concatenate([[a0], np.abs(data)]))
    p = np.array([C * np.median(steps) / 2, 1.0])
    weights = np.ones(n)
    for _ in range(11):  # a plain fit, then ten with the Cauchy weights of its residuals
        fit = least_squares(
            lambda q: np.sqrt(weights) * residual(q),
            p,
            bounds=([0, 0], [np.inf, np.inf]),
            x_scale="jac",
            xtol=1e-10,
            ftol=1e-10,
            gtol=1e-10,
        )
        p = fit.x
        r = np.concatenate([[0.0], residual(p)])  # (the release: no residual)
        scale = max(1.4826 * np.median(np.abs(r - np.median(r))), 1e-6 * a0)
        weights = 1.0 / (1.0 + (r[1:] / (CAUCHY * scale)) ** 2)
    print(json.dumps({"params": {"FT": p[0], "mu": p[1]}, "converged": bool(fit.success)}))


if __name__ == "__main__":
    main()
