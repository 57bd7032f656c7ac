"""`vmj sensitivity`, `vmj sweep rope|stick-slip|linear`, `--force`, and the atomic writes behind
every output file."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest
from cli_args import ROPE, VARIABLE_MASS

import vmj
from vmj._files import check_writable, replacing
from vmj.cli import main

MODEL = vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(14.7))


def run_json(capsys, argv):
    assert main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


def central(f, x, h):
    return (np.asarray(f(x + h)) - np.asarray(f(x - h))) / (2 * h)


# -- vmj sensitivity ------------------------------------------------------------------------------
def test_sensitivity_variable_mass_against_finite_differences(capsys, tmp_path):
    # the energy balance compiles fastest; differentiation through the exact solver is tested in
    # test_sensitivity.py
    out = run_json(
        capsys,
        [
            "sensitivity",
            "variable-mass",
            *VARIABLE_MASS,
            "--n",
            "4",
            "--wrt",
            "FT,mu,a0",
            "--method",
            "energy",
        ],
    )
    assert out["wrt"] == ["FT", "mu", "a0"] and out["units"] == {"FT": "N", "mu": "kg/s", "a0": "m"}
    seq = vmj.turning_points(MODEL, 0.06, 4, vmj.EnergyBalance())
    np.testing.assert_allclose(out["amplitudes"], np.asarray(seq.amplitudes), rtol=1e-14)
    energy = vmj.EnergyBalance()
    amp = lambda m, a0=0.06: vmj.turning_points(m, a0, 4, energy).amplitudes  # noqa: E731
    times = lambda m, a0=0.06: vmj.turning_points(m, a0, 4, energy).times  # noqa: E731
    fd = {
        "FT": lambda g: central(
            lambda F: g(vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(F))), 14.7, 1e-4
        ),
        "mu": lambda g: central(
            lambda mu: g(vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, mu, vmj.Coulomb(14.7))), 2.0, 1e-5
        ),
        "a0": lambda g: central(lambda a0: g(MODEL, a0), 0.06, 1e-7),
    }
    for name, diff in fd.items():
        np.testing.assert_allclose(out["d_amplitudes"][name], diff(amp), rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(out["d_times"][name], diff(times), rtol=1e-5, atol=1e-9)
    assert all(d < 0 for d in out["d_amplitudes"]["FT"])  # more friction, smaller swings
    # text and figure from the same computation
    fig = tmp_path / "s.png"
    assert (
        main(
            [
                "sensitivity",
                "variable-mass",
                *VARIABLE_MASS,
                "--n",
                "4",
                "--wrt",
                "FT,mu,a0",
                "--method",
                "energy",
                "--plot",
                str(fig),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out.splitlines()
    assert "d|x|/dFT [m/N]" in text[0] and "d|x|/dmu [m/(kg/s)]" in text[0]
    assert len(text) == 1 + 4 + 1
    assert fig.stat().st_size > 10_000


def test_sensitivity_stick_slip_against_finite_differences(capsys):
    out = run_json(
        capsys,
        [
            "sensitivity",
            "stick-slip",
            "--eps",
            "6.3",
            "--Omega",
            "0.7",
            "--wrt",
            "eps,Omega",
            "--method",
            "closed",
        ],
    )
    assert set(out) >= {
        "period",
        "slip_time",
        "stick_time",
        "d_period",
        "d_slip_time",
        "d_stick_time",
        "wrt",
        "units",
    }

    def cycle(eps, Omega):
        c = vmj.limit_cycle(vmj.StickSlip(eps, Omega), vmj.ClosedForm())
        return np.array([float(c.period), float(c.slip_time), float(c.stick_time)])

    for name, diff in {
        "eps": central(lambda e: cycle(e, 0.7), 6.3, 1e-6),
        "Omega": central(lambda w: cycle(6.3, w), 0.7, 1e-7),
    }.items():
        got = [out["d_period"][name], out["d_slip_time"][name], out["d_stick_time"][name]]
        np.testing.assert_allclose(got, diff, rtol=1e-6)


def test_the_smoothed_solver_is_differentiated_in_forward_mode(capsys, monkeypatch):
    """`--method smooth` asks for the derivatives in forward mode (a few parameters, many
    outputs: `vmj.Smoothed(derivatives="forward")`, diffrax's forward adjoint) and reports
    them by name; the numbers themselves are checked against the exact solver's in
    tests/test_sensitivity.py, end to end through the command in the long run below (11 s of
    compiling). (The command's compiled function is replaced, not `vmj.sensitivity` inside
    it: a trace of a stand-in would be kept, in memory and in the exported-program cache, for
    the real command.)"""
    from vmj.cli import _sensitivity

    asked = {}

    def derivatives(model, a0, n, solver, keys, mode):
        asked.update(mode=mode, n=n, solver=type(solver), derivatives=solver.derivatives)
        return {w: {"times": np.full(n, 1.0), "amplitudes": np.full(n, -2.0)} for w in keys}

    monkeypatch.setattr(_sensitivity, "_decay_derivatives", derivatives)
    argv = ["sensitivity", "variable-mass", *VARIABLE_MASS, "--n", "4", "--wrt", "FT"]
    out = run_json(capsys, [*argv, "--method", "smooth"])
    assert asked == {
        "mode": "forward",
        "n": 4,
        "solver": vmj.Smoothed,
        "derivatives": "forward",
    }
    assert out["method"] == "smooth" and out["d_amplitudes"]["FT"] == [-2.0] * len(out["times"])
    seq = vmj.turning_points(MODEL, 0.06, 4, vmj.Smoothed())
    np.testing.assert_allclose(out["amplitudes"], seq.reached()["amplitudes"], rtol=1e-12)


@pytest.mark.long  # 11 s of compiling, with the long runs for CI's time
def test_sensitivity_of_the_smoothed_solver_in_forward_mode(capsys):
    """The smoothed solve is differentiated by diffrax's forward adjoint: against central
    differences of the exact solver's amplitudes (the two solvers agree to ~1e-8)."""
    argv = ["sensitivity", "variable-mass", *VARIABLE_MASS, "--n", "4", "--wrt", "FT"]
    out = run_json(capsys, [*argv, "--method", "smooth"])
    model = lambda F: vmj.VariableMass(5.0, 4900.0, 3.0, 0.0, 2.0, vmj.Coulomb(F))  # noqa: E731
    amp = lambda F: vmj.turning_points(model(F), 0.06, 4).amplitudes  # noqa: E731
    np.testing.assert_allclose(out["d_amplitudes"]["FT"], central(amp, 14.7, 1e-4), rtol=1e-5)


# with the long runs, for CI's time (17 s of compiling): the rope's derivatives are checked in
# tests/test_rope.py, the command's plumbing by the variable-mass sensitivity commands
@pytest.mark.long
def test_sensitivity_rope(capsys):
    argv = ["sensitivity", "rope", *ROPE, "--wrt", "T"]
    out = run_json(capsys, argv)
    assert out["units"] == {"T": "Pa"} and max(out["times"]) <= 0.05
    assert all(d < 0 for d in out["d_amplitudes"]["T"])  # more friction, smaller swings


# -- vmj sweep rope | stick-slip | linear ---------------------------------------------------------
def test_sweep_stick_slip_matches_single_cycles(tmp_path, capsys):
    path = tmp_path / "c.csv"
    assert (
        main(
            [
                "sweep",
                "stick-slip",
                "--Omega",
                "0.5,1.5",
                "--eps",
                "3.5:8.5:3",
                "--method",
                "closed",
                "--out",
                str(path),
            ]
        )
        == 0
    )
    assert "6 points (eps 3 x Omega 2), method closed" in capsys.readouterr().out
    back = vmj.SweepResult.read_csv(str(path))
    assert back.dims == ("eps", "Omega")  # the order of the model's parameters
    for i, eps in enumerate([3.5, 6.0, 8.5]):
        for j, Omega in enumerate([0.5, 1.5]):
            one = vmj.limit_cycle(vmj.StickSlip(eps, Omega), vmj.ClosedForm())
            assert back.values["period"][i, j] == pytest.approx(float(one.period), rel=1e-14)
            assert back.values["reversals"][i, j] == int(one.reversals)


def test_sweep_linear_matches_vmj_linear(tmp_path, capsys):
    path = tmp_path / "l.csv"
    assert (
        main(
            [
                "sweep",
                "linear",
                "--c",
                "1,20",
                "--set",
                "m=1,k=14.5,v0=0.1,F0=4,p=15",
                "--out",
                str(path),
            ]
        )
        == 0
    )
    capsys.readouterr()
    back = vmj.SweepResult.read_csv(str(path))
    for i, c in enumerate(["1", "20"]):  # under-damped, then over-damped (no free amplitude)
        one = run_json(
            capsys,
            [
                "linear",
                "--m",
                "1",
                "--c",
                c,
                "--k",
                "14.5",
                "--v0",
                "0.1",
                "--F0",
                "4",
                "--p",
                "15",
            ],
        )
        for key, value in one.items():
            got = back.values[key][i]
            if value is None:
                assert np.isnan(got) or np.isinf(got), key
            else:
                assert got == pytest.approx(value, rel=1e-13), key


def test_sweep_rope_in_technical_units(tmp_path, capsys):
    path = tmp_path / "r.csv"
    argv = [
        "sweep",
        "rope",
        "--T",
        "0,4",
        "--l0",
        "8,10",
        "--set",
        "m=2,A=1.74,e=0.8e6,d=0.8e11,u=0,a0=1",
        "--units",
        "technical",
        "--n",
        "3",
        "--method",
        "energy",
        "--out",
        str(path),
    ]
    assert main(argv) == 0
    assert "4 points (T 2 x l0 2)" in capsys.readouterr().out
    back = vmj.SweepResult.read_csv(str(path))
    np.testing.assert_allclose(back.coords["T"], [0.0, 4 * vmj.KGF * 1e4])  # SI coordinates
    one = vmj.turning_points(vmj.Rope.paper(T=4.0, l0=8.0), 0.01, 3, vmj.EnergyBalance())
    np.testing.assert_allclose(
        back.values["positions"][1, 0], np.asarray(one.positions), rtol=1e-12
    )


def test_sweep_takes_max_substeps_for_a_fast_growing_mass(capsys):
    """Masses growing by 200-300 kg/s from 5 kg need more than the default 8 substeps in their
    first swing: the summary names the option, and with it no point fails."""
    argv = ["sweep", "variable-mass", "--delta", "200,300", "--set"]
    argv += ["m0=5,c=4900,eps=0,mu=2,FT=14.7,a0=0.06", "--n", "12"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "failed: 2" in out and "raise --max-substeps" in out
    assert main(argv + ["--max-substeps", "24"]) == 0
    assert "failed: 0" in capsys.readouterr().out


def test_technical_units_convert_as_the_library_does():
    from vmj.cli._params import MODELS

    spec = MODELS["rope"]
    given = {
        "m": 2.0,
        "A": 1.74,
        "e": 0.8e6,
        "b": 0.5,
        "d": 0.8e11,
        "T": 4.0,
        "l0": 10.0,
        "u": -3.0,
        "a0": 1.0,
    }
    values = spec.resolve({k: (v, f"--{k}") for k, v in given.items()}, technical=True)
    ours = spec.build(values)
    ref = vmj.Rope.from_technical(2.0, 1.74, 0.8e6, 0.5, 0.8e11, 4.0, vmj.ConstantSpeed(10.0, -3.0))
    for name in ("m", "A", "e", "b", "d", "T"):
        assert float(getattr(ours, name)) == float(getattr(ref, name)), name
    assert values["a0"] == pytest.approx(0.01, rel=1e-15)


def test_force_runs_work_above_the_limit(capsys):
    argv = ["decay", "variable-mass", *VARIABLE_MASS, "--method", "energy", "--n", "100001"]
    assert main(argv) == 2
    assert "--force" in capsys.readouterr().err
    out = run_json(capsys, argv + ["--force"])
    assert out["stopped"] is True and len(out["amplitudes"]) == 10


def test_exponent_and_negative_values(capsys):
    out = run_json(
        capsys,
        [
            "decay",
            "variable-mass",
            "--m0",
            "5e0",
            "--c",
            "4.9e3",
            "--delta",
            "-3e0",
            "--eps",
            "1",
            "--mu",
            "5",
            "--f",
            "3e-1",
            "--a0",
            "6e-2",
            "--method",
            "energy",
            "--n",
            "3",
        ],
    )
    ref = vmj.turning_points(
        vmj.VariableMass(5, 4900, -3, 1, 5, vmj.MassProportional(0.3)), 0.06, 3, vmj.EnergyBalance()
    )
    np.testing.assert_allclose(out["amplitudes"], np.asarray(ref.amplitudes), rtol=1e-15)


# -- files: checked before any work, written atomically -------------------------------------------
def test_repeated_list_options_are_joined_not_overwritten(capsys):
    """`--set a=1 --set b=2` is `--set a=1,b=2` (argparse alone keeps the last silently); the
    commands' own checks then refuse a name given twice."""
    import argparse

    from vmj.cli import Joined

    p = argparse.ArgumentParser()
    p.add_argument("--set", action=Joined, default="")
    p.add_argument("--fit", action=Joined)
    args = p.parse_args(["--set", "m0=5", "--fit", "FT", "--set", "c=4900", "--fit", "mu"])
    assert (args.set, args.fit) == ("m0=5,c=4900", "FT,mu")
    assert p.parse_args([]).fit is None
    argv = ["sweep", "variable-mass", "--eps", "0,1", "--set", "m0=5,c=4900", "--set", "m0=5"]
    assert main(argv) == 2
    assert "--set gives m0 twice" in capsys.readouterr().err


def test_json_output_is_strict_json():
    """NaN and infinity become `null` (strict parsers refuse a bare `NaN`); NumPy values become
    Python ones."""
    from vmj.cli import jsonable

    obj = {"a": float("nan"), "b": np.float32(1.5), "c": np.array([1.0, np.inf]), "d": np.bool_(1)}
    text = json.dumps(jsonable(obj), allow_nan=False)
    assert json.loads(text) == {"a": None, "b": 1.5, "c": [1.0, None], "d": True}


def test_replacing_follows_links_and_writes_to_pipes_in_place(tmp_path):
    """A symbolic link stays a link (its target is replaced); a pipe or device (`/dev/null`) is
    written to, not replaced by a regular file."""
    target = tmp_path / "target.csv"
    target.write_text("old")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    with replacing(link) as tmp:
        Path(tmp).write_text("new")
    assert link.is_symlink() and target.read_text() == "new"
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
    try:
        assert check_writable(fifo, "--plot") == str(fifo)
        with replacing(fifo) as tmp:
            Path(tmp).write_text("through")
        assert stat.S_ISFIFO(os.stat(fifo).st_mode)
        assert os.read(reader, 100) == b"through"
    finally:
        os.close(reader)


def test_replacing_keeps_the_old_file_when_writing_fails(tmp_path):
    path = tmp_path / "out.csv"
    path.write_text("old")
    with pytest.raises(RuntimeError):
        with replacing(path) as tmp:
            with open(tmp, "w") as fh:
                fh.write("half")
            raise RuntimeError("disk full")
    assert path.read_text() == "old" and os.listdir(tmp_path) == ["out.csv"]
    with replacing(path) as tmp:
        with open(tmp, "w") as fh:
            fh.write("new")
    assert path.read_text() == "new" and os.listdir(tmp_path) == ["out.csv"]


def test_a_new_file_gets_the_usual_permissions(tmp_path):
    umask = os.umask(0o022)
    try:
        with replacing(tmp_path / "f.txt") as tmp:
            open(tmp, "w").close()
    finally:
        os.umask(umask)
    assert (os.stat(tmp_path / "f.txt").st_mode & 0o777) == 0o644


def test_output_paths_are_checked(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        check_writable(tmp_path / "no" / "x.csv", "--out")
    with pytest.raises(ValueError, match="is a directory"):
        check_writable(tmp_path, "--out")
    result = vmj.sweep(
        vmj.turning_points,
        vmj.grid(MODEL, eps=[0.0, 0.5]),
        a0=0.06,
        n=2,
        solver=vmj.EnergyBalance(),
    )
    with pytest.raises(ValueError, match="does not exist"):
        result.to_csv(str(tmp_path / "missing" / "s.csv"))
    result.to_csv(str(tmp_path / "s.csv"))
    assert os.listdir(tmp_path) == ["s.csv"]


def test_sweep_store_and_resume(tmp_path, capsys):
    pytest.importorskip("zarr")
    from vmj.cli import main

    store = str(tmp_path / "s.zarr")
    base = [
        "sweep",
        "variable-mass",
        "--eps",
        "0:1:3",
        "--mu",
        "0,9",
        "--set",
        "m0=5,c=4900,FT=14.7,a0=0.06,delta=1",
        "--n",
        "6",
    ]
    assert main(base + ["--store", store, "--out", str(tmp_path / "a.csv")]) == 0
    assert capsys.readouterr().out.endswith(f"; wrote {tmp_path / 'a.csv'}; stored in {store}\n")
    assert main(base + ["--store", store]) == 2
    assert "pass --resume to continue it" in capsys.readouterr().err
    assert main(base + ["--store", store, "--resume", "--out", str(tmp_path / "b.csv")]) == 0
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert main(base + ["--resume"]) == 2
    assert "--resume needs --store" in capsys.readouterr().err
    other = base[:2] + ["--eps", "0:1:4"] + base[4:]
    assert main(other + ["--store", store, "--resume"]) == 2
    assert "holds a different sweep" in capsys.readouterr().err


def test_linear_undamped_resonance_is_explained(capsys):
    """c = 0 and p = sqrt(k/m): forced_amplitude inf with the reason, the free part finite."""
    one = run_json(capsys, ["linear", "--m", "1", "--c", "0", "--k", "16", "--F0", "1", "--p", "4"])
    assert one["forced_amplitude"] is None and one["free_amplitude"] == pytest.approx(1 / 32)
    assert main(["linear", "--m", "1", "--c", "0", "--k", "16", "--F0", "1", "--p", "4"]) == 0
    assert "D = inf" in capsys.readouterr().out
    argv = ["sweep", "linear", "--c", "0,0.1", "--p", "3:5:3", "--set", "m=1,k=16,F0=1"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "forced_amplitude inf: 1;" in out and "undamped resonance (c = 0" in out


def test_sweep_figure_is_drawn_and_named(tmp_path, capsys):
    """`--plot` draws the swings over (eps, mu) and the summary names every file written."""
    fig, csv = tmp_path / "s.png", tmp_path / "s.csv"
    argv = ["sweep", "variable-mass", "--eps", "0:1:3", "--mu", "0:10:3", "--method", "energy"]
    argv += ["--set", "m0=5,c=4900,delta=3,FT=14.7,a0=0.06", "--out", str(csv), "--plot", str(fig)]
    assert main(argv) == 0
    assert capsys.readouterr().out.endswith(f"; wrote {csv}; wrote {fig}\n")
    assert (
        fig.stat().st_size > 10_000 and len(csv.read_text().splitlines()) == 2 + 9
    )  # (the layout line, the header)
