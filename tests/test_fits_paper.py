"""Acceptance of the variable-mass fits (issue 5): synthetic records of the exact model with noise
0.2 % of a0, and the monograph columns of the paper's 16 table columns.

Both friction laws go through one compiled solver (vmj.AffineFriction, free parameters as data,
records of equal bucketed length and equal batch size), so the module compiles once.
"""

import warnings
from importlib.resources import files

import numpy as np
import pytest

import fits
import vmj
from vmj import PAPER

A0 = PAPER["a0"]
MU_SYNTH = 2.0  #: viscous coefficient of the synthetic records [kg/s]
DELTAS = (0.0, 3.0, -3.0)  #: constant, growing and shrinking mass [kg/s]
SEEDS = (11, 12)


def _synthetic(law: str, delta: float, seed: int):
    value = PAPER[law]
    friction = vmj.AffineFriction(value if law == "FT" else 0.0, value if law == "f" else 0.0)
    model = vmj.VariableMass(PAPER["m0"], PAPER["c"], delta, 0.0, MU_SYNTH, friction)
    seq = vmj.turning_points(model, A0, 12)
    n = int(seq.count)
    noise = np.random.default_rng(seed).normal(0.0, 0.002 * A0, n + 1)
    positions = np.concatenate([[-A0], np.asarray(seq.positions)[:n]]) + noise
    record = fits.record_from_sequence(
        positions=positions, source=f"synthetic {law} delta={delta} seed={seed}"
    )
    given = {"m0": PAPER["m0"], "c": PAPER["c"], "delta": delta, "eps": 0.0, "a0": A0}
    return {"record": record, "given": given, "truth": {law: value, "mu": MU_SYNTH}, "delta": delta}


def _batch(law: str, tables, loss: str):
    columns = fits.paper_records(tables[0]) + fits.paper_records(tables[1])
    synthetic = [_synthetic(law, d, s) for d in DELTAS for s in SEEDS]
    items = columns + synthetic
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = fits.fit_batch(
            [it["record"] for it in items],
            "variable-mass",
            (law, "mu"),
            [it["given"] for it in items],
            loss=loss,
            intervals=False,
        )
    return list(zip(items, results))


@pytest.fixture(scope="module")
def coulomb_l2():
    return _batch("FT", (1, 2), "l2")


@pytest.fixture(scope="module")
def coulomb_cauchy():
    return _batch("FT", (1, 2), "cauchy")


@pytest.fixture(scope="module")
def proportional_l2():
    return _batch("f", (3, 4), "l2")


def _columns(pairs):
    return [(it, r) for it, r in pairs if "table" in it]


def _synthetics(pairs):
    return [(it, r) for it, r in pairs if "table" not in it]


def _mu_ok(estimate, truth, rel):
    return abs(estimate - truth) <= (rel * truth if truth > 0 else 0.3)


@pytest.mark.long  # 40-60 s: with the long runs, for CI's time
@pytest.mark.parametrize("which", ["coulomb_l2", "proportional_l2"])
def test_synthetic_records_constant_growing_shrinking_mass(which, request):
    pairs = _synthetics(request.getfixturevalue(which))
    assert {it["delta"] for it, _ in pairs} == set(DELTAS)
    for it, r in pairs:
        law = next(k for k in it["truth"] if k != "mu")
        assert r.converged, it["record"].source
        assert abs(r.params[law] / it["truth"][law] - 1) < 0.03, (it["record"].source, r.params)
        assert abs(r.params["mu"] / MU_SYNTH - 1) < 0.15, (it["record"].source, r.params)
        # the standard errors describe the scatter: the truth lies within 4 of them
        for name in (law, "mu"):
            assert abs(r.params[name] - it["truth"][name]) < 4 * r.stderr[name], (name, r)


@pytest.mark.parametrize("which", ["coulomb_l2", "proportional_l2"])
def test_monograph_columns(which, request):
    pairs = _columns(request.getfixturevalue(which))
    assert len(pairs) == 8
    for it, r in pairs:
        law = it["free"][0]
        if it["mu"] == 0 and not r.converged:  # mu at its physical bound 0 is flagged (issue 12)
            assert any(w.startswith("mu ran into its bound 0") for w in r.warnings), r.warnings
        else:
            assert r.converged, it["record"].source
        if it["table"] == 1 and it["mu"] == 9:
            continue  # bad published cells: see test_bad_cells_need_the_robust_loss
        assert abs(r.params[law] / PAPER[law] - 1) < 0.02, (it["record"].source, r.params)
        assert _mu_ok(r.params["mu"], it["mu"], 0.10), (it["record"].source, r.params)


def test_bad_cells_need_the_robust_loss(coulomb_l2, coulomb_cauchy):
    robust = {it["record"].source: (it, r) for it, r in _columns(coulomb_cauchy)}
    plain = {it["record"].source: r for it, r in _columns(coulomb_l2)}
    bad = [src for src, (it, _) in robust.items() if it["table"] == 1 and it["mu"] == 9]
    assert len(bad) == 2
    for src in bad:
        it, r = robust[src]
        assert r.converged
        assert abs(r.params["FT"] / PAPER["FT"] - 1) < 0.02, (src, r.params)
        assert _mu_ok(r.params["mu"], it["mu"], 0.10), (src, r.params)
        # the erratum cell (2.212 printed for 3.212; 0.236 for about 0.024) is flagged
        assert set(it["notes"]) <= set(r.outliers), (src, r.outliers, it["notes"])
        # without the robust loss the printed 2.212 spoils the estimate
    assert abs(plain[bad[0]].params["FT"] / PAPER["FT"] - 1) > 0.05
    # the robust loss does not disturb the clean columns
    for src, (_, r) in robust.items():
        assert abs(r.params["FT"] / PAPER["FT"] - 1) < 0.02, src


def test_model_comparison_finds_the_friction_present(proportional_l2, coulomb_l2):
    for it, r in _columns(proportional_l2) + _columns(coulomb_l2):
        comp = r.model_comparison
        assert set(comp) == {"coulomb", "viscous", "both", "best_aic", "best_bic"}
        assert comp["viscous"]["bic"] > comp["both"]["bic"]  # dry friction is always there
        if it["mu"] > 0 and not (it["table"] == 1 and it["mu"] == 9):
            assert comp["best_bic"] == "both", it["record"].source
        # (for mu = 0 a tiny mu absorbs part of the monograph method's own approximation
        # error, so "both" may win by a few BIC units: no assertion there)


def test_shrinking_mass_starts_in_the_basin_of_the_right_stick_count():
    """A shrinking mass with mass-proportional friction (f = 0.3, mu = 5 kg/s, delta = -3 kg/s):
    the constant-ratio decrement starts mu at 8.2 kg/s, from where the fit of (f, mu) ended in 4
    of 12 noisy records (noise 2e-4 a0) at f = 0.323-0.327, mu = 3.8-4.0 kg/s, where the model
    sticks one swing early (weighted RSS 470-630 against 22-80). The start from the
    energy-balance recurrences (masses known from m0, c, delta) puts mu near 5 kg/s; the two
    records here, which ended there with `a0` fitted too, now reach the truth. The records
    have no release row, so `a0` is started from the decrement line, not from a k = 0 row."""
    truth = vmj.VariableMass(PAPER["m0"], PAPER["c"], -3.0, 0.0, 5.0, vmj.MassProportional(0.3))
    seq = vmj.turning_points(truth, A0, 12)
    n = int(seq.count)
    records = [
        fits.record_from_sequence(
            positions=np.asarray(seq.positions)[:n]
            + np.random.default_rng(seed).normal(0.0, 1.2e-4, n),
            k=np.arange(1, n + 1),
            source=f"shrinking mass seed {seed}",
        )
        for seed in (4, 10)
    ]
    given = {"m0": PAPER["m0"], "c": PAPER["c"], "delta": -3.0, "eps": 0.0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = fits.fit_batch(
            records, "variable-mass", ("f", "mu", "a0"), given, compare=False, intervals=False
        )
    for r in results:
        assert abs(r.params["f"] - 0.3) < 0.01, (r.record.source, r.params)
        assert abs(r.params["mu"] - 5.0) < 0.5, (r.record.source, r.params)
        assert abs(r.params["a0"] / A0 - 1) < 0.01, (r.record.source, r.params)


def test_both_friction_terms_free_with_a_constant_mass():
    """With a constant mass `FT` and `f g m` are the same term: the energy-balance start's
    least squares is singular there (it raised numpy's LinAlgError); the fit says that the
    Jacobian is rank-deficient and finds their sum."""
    item = _synthetic("FT", 0.0, SEEDS[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fits.fit(item["record"], "variable-mass", ("FT", "f", "mu"), item["given"])
    assert any("rank-deficient" in w for w in r.warnings), r.warnings
    friction = r.params["FT"] + r.params["f"] * PAPER["g"] * PAPER["m0"]
    assert abs(friction / PAPER["FT"] - 1) < 0.03, r.params


def test_a_column_in_millimetres_is_read_in_metres(tmp_path):
    """The shipped table-1 column written in mm (`amplitude [mm]`, `position_mm`): the
    variable-mass model's lengths are SI, so the positions are converted to metres (said in the
    warnings) and the fit is the one of the column in metres. Read as metres, the same numbers
    gave F_T 1000 times too large. A column naming no unit is read in metres, as before; the
    oscillator's positions stay in the signal's units."""
    shipped = fits.read_peaks(files("fits") / "data" / "table1_mu9_eps0.csv")
    rows = np.loadtxt(files("fits") / "data" / "table1_mu9_eps0.csv", delimiter=",", skiprows=1)
    mm = tmp_path / "mm.csv"
    mm.write_text(
        "k,amplitude [mm],crossed\n"
        + "".join(f"{int(k)},{1000 * a:.2f},{int(c)}\n" for k, a, c in rows)
    )
    signed = tmp_path / "signed.csv"
    signed.write_text(
        "k,position_mm\n"
        + "".join(f"{k},{1000 * x:.2f}\n" for k, x in zip(shipped.k, shipped.positions))
    )
    given = {"m0": 5.0, "c": 4900.0, "delta": 3.0, "eps": 0.0}
    kwargs = dict(forward="energy", loss="cauchy", compare=False, intervals=False)
    ref = fits.fit(shipped, "variable-mass", ("FT", "mu"), given, **kwargs)
    assert not any("converted to m" in w for w in ref.warnings)
    for path in (mm, signed):
        rec = fits.read_peaks(path)
        got = fits.fit(rec, "variable-mass", ("FT", "mu"), given, **kwargs)
        for name in ("FT", "mu"):
            assert got.params[name] == pytest.approx(ref.params[name], rel=1e-6), name
        assert any("its positions are in mm" in w and "converted to m" in w for w in got.warnings)
        osc = fits.fit(rec, "oscillator", ("zeta", "xF", "a0"), compare=False, intervals=False)
        assert osc.params["a0"] > 10  # signal units: mm
