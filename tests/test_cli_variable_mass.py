"""The `vmj decay variable-mass` and `vmj table` commands: JSON contract, text output, errors."""

import json
import subprocess
import sys

import numpy as np
import pytest
from cli_args import VARIABLE_MASS_MODEL

import vmj
from vmj.cli import main

BASE = ["decay", "variable-mass", *VARIABLE_MASS_MODEL, "--a0", "0.06"]
ARGS = BASE + ["--FT", "14.7"]


def with_value(argv, flag, value):
    argv = list(argv)
    if flag in argv:
        argv[argv.index(flag) + 1] = value
    else:
        argv += [flag, value]
    return argv


def run(capsys, argv):
    code = main(argv)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_decay_json_lists_only_reached_turning_points(capsys):
    code, out, _ = run(capsys, ARGS + ["--n", "12", "--json"])
    assert code == 0
    data = json.loads(out)
    assert set(data) == {"model", "method", "times", "amplitudes", "crossed", "stopped"}
    assert data["model"] == "variable-mass" and data["method"] == "exact"
    assert len(data["times"]) == len(data["amplitudes"]) == len(data["crossed"]) == 10
    assert data["stopped"] is True and data["crossed"][-1] is False
    seq = vmj.turning_points(vmj.VariableMass(5, 4900, 3, 0, 2, vmj.Coulomb(14.7)), 0.06, 12)
    np.testing.assert_allclose(data["amplitudes"], np.asarray(seq.amplitudes)[:10], rtol=1e-15)


@pytest.mark.parametrize("method", ["energy", "smooth"])
def test_decay_methods(capsys, method):
    code, out, _ = run(capsys, BASE + ["--f", "0.3", "--n", "5", "--method", method, "--json"])
    data = json.loads(out)
    assert code == 0 and data["method"] == method and len(data["amplitudes"]) == 5


def test_decay_text_table(capsys):
    code, out, _ = run(capsys, ARGS + ["--n", "3"])
    assert code == 0
    assert "crossed" in out and "status:" in out and len(out.splitlines()) == 5


@pytest.mark.parametrize(
    "flag,value,name",
    [
        ("--m0", "0", "--m0"),
        ("--c", "-1", "--c"),
        ("--eps", "2", "--eps"),
        ("--mu", "-1", "--mu"),
        ("--FT", "-3", "--FT"),
        ("--a0", "0", "--a0"),
    ],
)
def test_decay_bad_input_exits_2_with_one_line(capsys, flag, value, name):
    code, out, err = run(capsys, with_value(ARGS, flag, value))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith(f"vmj: error: {name} must be")


def test_max_substeps_reaches_a_fast_growing_mass(capsys):
    """A mass growing by 300 kg/s needs more than the default 8 substeps in its first swing:
    the status names the option, which the exact solver takes and the others refuse."""
    fast = with_value(ARGS, "--delta", "300") + ["--n", "12", "--json"]
    code, out, _ = run(capsys, fast)
    data = json.loads(out)
    assert code == 0 and data["times"] == [] and "raise --max-substeps" in data["message"]
    code, out, _ = run(capsys, fast + ["--max-substeps", "16"])
    data = json.loads(out)
    assert code == 0 and len(data["times"]) == 12 and "message" not in data
    code, out, err = run(capsys, fast + ["--max-substeps", "16", "--method", "smooth"])
    assert code == 2 and err.startswith("vmj: error: --max-substeps applies to --method exact")


def test_a_shrinking_mass_names_the_commands_options(capsys):
    """The status of a mass that runs out names the exact method and its substeps as the
    command spells them (the library's message says vmj.Exact and max_substeps)."""
    code, out, _ = run(capsys, with_value(ARGS, "--delta", "-100") + ["--n", "12", "--json"])
    message = json.loads(out)["message"]
    assert code == 0 and "reaches zero" in message
    assert "--method exact" in message and "a larger --max-substeps" in message
    assert "vmj.Exact" not in message and " max_substeps" not in message


def test_nan_argument_exits_2(capsys):
    with pytest.raises(SystemExit) as e:
        main(with_value(ARGS, "--mu", "nan"))
    assert e.value.code == 2
    assert "not a finite number" in capsys.readouterr().err


def test_table_json(capsys):
    code, out, _ = run(capsys, ["table", "3", "--json"])
    data = json.loads(out)
    assert code == 0 and data["table"] == 3
    keys = {
        "k",
        "mu",
        "eps",
        "delta",
        "paper_energy_cm",
        "paper_monograph_cm",
        "energy_cm",
        "exact_cm",
        "exact_crossed",
    }
    assert all(set(r) == keys for r in data["rows"]) and len(data["rows"]) == 30
    worst = max(abs(r["exact_cm"] - r["paper_monograph_cm"]) for r in data["rows"])
    assert worst < 0.002


def test_table_text_and_figure(capsys, tmp_path):
    path = tmp_path / "t1.png"
    code, out, _ = run(capsys, ["table", "1", "--plot", str(path)])
    assert code == 0 and path.stat().st_size > 10_000
    assert "largest |vmj EB - paper EB|" in out and "2.212" in out


def test_console_script_runs_in_float64():
    """The installed entry point enables float64 itself (no configuration by the user)."""
    code = (
        "import sys; from vmj.cli import main; import jax; sys.argv=['vmj']; "
        "main(['decay','variable-mass','--m0','5','--c','4900','--delta','0','--eps','0',"
        "'--mu','0','--FT','14.7','--a0','0.06','--n','2','--json']); "
        "print(jax.config.jax_enable_x64)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    data, flag = out.stdout.strip().splitlines()
    assert flag == "True"
    amps = json.loads(data)["amplitudes"]
    assert amps[0] - amps[1] == pytest.approx(2 * 14.7 / 4900, rel=1e-12)


@pytest.mark.parametrize(
    "argv,message",
    [
        (["stick-slip", "--eps", "1e9", "--Omega", "1"], "--eps 1e+09 means"),
        (
            [
                "fit",
                "fits/data/table1_mu9_eps0.csv",
                "--fit",
                "FT,mu",
                "--set",
                "m0=5,m0=4,c=4900,delta=3,eps=0",
            ],
            "--set gives m0 twice",
        ),
        (
            [
                "sweep",
                "variable-mass",
                "--eps",
                "0:1:1",
                "--mu",
                "0",
                "--delta",
                "0",
                "--set",
                "m0=5,c=4900,FT=14.7,a0=0.06",
                "--out",
                "unused.csv",
            ],
            "count must be",
        ),
    ],
)
def test_other_commands_refuse_bad_input(capsys, argv, message):
    code, out, err = run(capsys, argv)
    assert code == 2 and out == "" and message in err
