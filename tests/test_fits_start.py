"""The variable-mass fits' start (`fits._decrement`): the energy-balance recurrences fitted to
the decrement pairs, the masses known from `m0`, `c` and `delta`. On a record that those
recurrences produced (noise-free) the start is the truth, up to its grid of damping exponents
(steps of 0.016 kg/s in `lam` near the optimum, 0.008 kg/s in `mu`); the constant-ratio
decrement it replaced is not (mu 8.2 for 5 kg/s on the shrinking mass of
`test_fits_paper.py`)."""

import numpy as np
from hypothesis import given, settings, strategies as st

import fits
import vmj
from fits._decrement import decrement, starting_guess
from fits._models import SPACES

M0, C, A0, G = 5.0, 4900.0, 0.06, 9.81


def _start(delta, mu, law, value):
    friction = vmj.Coulomb(value) if law == "FT" else vmj.MassProportional(value)
    model = vmj.VariableMass(M0, C, delta, 0.0, mu, friction)
    seq = vmj.turning_points(model, A0, 12, vmj.EnergyBalance())
    n = int(seq.count)
    record = fits.record_from_sequence(
        positions=np.concatenate([[-A0], np.asarray(seq.positions)[:n]])
    )
    given = {"m0": M0, "c": C, "delta": delta, "eps": 0.0, "g": G}
    given["f" if law == "FT" else "FT"] = 0.0  # the other law held at 0, as a fit holds it
    return starting_guess(SPACES["variable-mass"], record, given, decrement(record))


@settings(max_examples=25, deadline=None)
@given(
    delta=st.floats(-3.0, 3.0),
    mu=st.floats(0.5, 9.0),
    law=st.sampled_from(["FT", "f"]),
    share=st.floats(0.5, 1.5),
)
def test_the_start_inverts_the_energy_balance_recurrences(delta, mu, law, share):
    value = share * vmj.PAPER[law]
    start = _start(delta, mu, law, value)
    assert abs(start["mu"] - mu) < 0.02, start
    assert abs(start[law] / value - 1) < 0.01, start


def test_the_shrinking_mass_start_is_near_the_truth():
    start = _start(-3.0, 5.0, "f", 0.3)
    assert abs(start["mu"] - 5.0) < 0.02 and abs(start["f"] - 0.3) < 0.003, start
