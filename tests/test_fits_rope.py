"""fits: the rope friction stress T from a noisy peak sequence of a lowering rope (issue 5)."""

import json
import warnings

import numpy as np
import pytest

import fits
import vmj
from vmj.cli import main

A0, U, T_KG = 0.01, -2.0, 4.0  # 1 cm, lowering at 2 m/s, T = 4 kG/cm^2 (the paper's example)


@pytest.fixture(scope="module")
def lowering(tmp_path_factory):
    rope = vmj.Rope.paper(u=U, T=T_KG, cubic=True)
    seq = vmj.turning_points(rope, A0, 40)
    assert int(seq.count) == 40
    rng = np.random.default_rng(5)
    pos = np.concatenate([[-A0], np.asarray(seq.positions)]) + rng.normal(0, 0.002 * A0, 41)
    times = np.concatenate([[0.0], np.asarray(seq.times) + rng.normal(0, 1e-4, 40)])
    path = tmp_path_factory.mktemp("rope") / "peaks.csv"
    np.savetxt(
        path, np.column_stack([times, pos]), delimiter=",", header="time,position", comments=""
    )
    given = {
        "m": float(rope.m),
        "A": float(rope.A),
        "e": float(rope.e),
        "d": float(rope.d),
        "l0": 10.0,
        "u": U,
        "a0": A0,
    }
    return str(path), given, float(rope.T)


@pytest.mark.long  # 30 s: with the long runs, for CI's time
def test_rope_T_from_a_lowering_rope(lowering):
    path, given, T = lowering
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fits.fit(fits.read_peaks(path), "rope", ("T",), given, intervals=False)
    assert r.converged
    assert abs(r.params["T"] / T - 1) < 0.03
    assert abs(r.params["T"] - T) < 4 * r.stderr["T"]
    assert r.model_comparison == {}  # no viscous parameter in the rope model


def test_rope_cli(lowering, capsys):
    path, given, T = lowering
    settings = ",".join(f"{k}={v!r}" for k, v in given.items())
    assert main(["fit", path, "--model", "rope", "--fit", "T", "--set", settings, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert abs(out["params"]["T"] / T - 1) < 0.03 and out["converged"] is True
    assert main(["fit", path, "--model", "rope", "--fit", "T", "--set", "m=19.6"]) == 2
    assert "needs" in capsys.readouterr().err


def test_a_wrong_fixed_stiffness_is_reported_by_the_times(lowering):
    """With `e` four times too large the positions can still be fitted, but the turning-point
    times miss the record's by several half-swings: the fit warns (the right `e`: it does not)."""
    path, given, T = lowering
    record = fits.read_peaks(path)
    messages = {}
    for scale in (1.0, 4.0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = fits.fit(record, "rope", ("T",), {**given, "e": scale * given["e"]}, compare=False)
        messages[scale] = [w for w in r.warnings if "turning-point times miss" in w]
    assert messages[1.0] == [] and len(messages[4.0]) == 1
