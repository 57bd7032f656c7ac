"""The `vmj` command starts lean: help, version and argument errors without JAX; every option
documented; the persistent compilation cache configured by the entry point only."""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import subprocess
import sys

import pytest

import vmj
from vmj.cli import _app, main
from vmj.cli._options import FIGURE_FORMATS

HEAVY = ("jax", "diffrax", "matplotlib", "fits", "equinox")


def _fresh_python(code: str) -> str:
    """Run `code` in a new interpreter outside the repository (so the installed vmj is used)."""
    run = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        cwd=os.path.dirname(os.path.dirname(vmj.__file__)) + "/tests",
    )
    assert run.returncode == 0, run.stderr
    return run.stdout


def test_help_and_argument_errors_import_nothing_heavy():
    code = f"""
import sys
from vmj.cli import main
for argv in (["--help"], ["--version"], ["decay", "--help"], ["decay", "variable-mass", "--help"],
             ["decay", "rope", "--help"], ["table", "--help"], ["sweep", "rope", "--help"],
             ["sweep", "variable-mass", "--help"], ["sensitivity", "stick-slip", "--help"],
             ["stick-slip", "--help"], ["linear", "--help"], ["decay", "variable-mass", "--m0"],
             ["linear", "--m", "nan"], ["table", "7"], ["sweep", "linear", "--n", "0"]):
    try:
        main(argv)
    except SystemExit as e:
        assert e.code in (0, 2), (argv, e.code)
print([m for m in {HEAVY!r} if m in sys.modules])
"""
    assert _fresh_python(code).splitlines()[-1] == "[]"


def test_import_vmj_is_lazy_and_complete():
    code = f"""
import sys
import vmj
print([m for m in {HEAVY!r} if m in sys.modules])
assert set(vmj._table()) == set(vmj.__all__)
assert all(getattr(vmj, name) is not None for name in vmj.__all__)
assert "diffrax" not in sys.modules  # models, solvers, sweeps: diffrax only when a solve needs it
assert set(vmj.__all__) <= set(dir(vmj))
print(vmj.plot.__name__, vmj._checks.__name__)
try:
    vmj.no_such_name
except AttributeError as e:
    print("AttributeError", e)
"""
    lines = _fresh_python(code).splitlines()
    assert lines[0] == "[]"
    assert lines[1] == "vmj.plot vmj._checks"
    assert lines[2].startswith("AttributeError") and "no_such_name" in lines[2]


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"vmj {vmj.__version__}"
    assert importlib.metadata.version("vmj") == vmj.__version__


def _parsers():
    """Every parser of the command line, with its options added (as when it is named)."""
    top = _app.build_parser()
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    out = [("vmj", top)]
    for command in _app.COMMANDS:
        p = sub.choices[command.name]
        command.load().add_arguments(p)
        nested = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if nested:
            out += [(f"{command.name} {name}", q) for name, q in nested[0].choices.items()]
        else:
            out.append((command.name, p))
    return out


def test_every_option_has_help_with_unit_or_default():
    """--help shows what each option is; a number option states its unit, and an option with a
    default shows it."""
    from vmj.cli._options import HelpFormatter, count, number

    seen = 0
    for name, parser in _parsers():
        formatter = HelpFormatter(parser.prog)
        for action in parser._actions:
            if not action.option_strings or action.help == argparse.SUPPRESS:
                continue
            seen += 1
            text = formatter._get_help_string(action)
            assert text, (name, action.option_strings)
            if action.type in (number,) and name != "fit":
                assert "[" in text and "]" in text, (name, action.option_strings, text)
            if action.default not in (None, False, argparse.SUPPRESS) and action.nargs != 0:
                assert "(default: %(default)s)" in text, (name, action.option_strings)
            if action.type is count:
                assert "default" in text or action.required
    assert seen > 100


def test_figure_formats_are_ones_matplotlib_writes():
    from matplotlib.backend_bases import FigureCanvasBase

    assert set(FIGURE_FORMATS) <= set(FigureCanvasBase.get_supported_filetypes())


def test_cache_directory(monkeypatch, tmp_path):
    parse = _app.build_parser().parse_args
    argv = ["linear", "--m", "1", "--c", "1", "--k", "1"]
    monkeypatch.delenv("VMJ_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert _app.cache_directory(parse(argv)) == (str(tmp_path / "xdg" / "vmj" / "jax"), "default")
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert _app.cache_directory(parse(argv))[0] == str(tmp_path / "home" / ".cache" / "vmj" / "jax")
    monkeypatch.setenv("VMJ_CACHE_DIR", str(tmp_path / "env"))
    assert _app.cache_directory(parse(argv)) == (str(tmp_path / "env"), "VMJ_CACHE_DIR")
    assert _app.cache_directory(parse(["--cache-dir", "flag"] + argv)) == ("flag", "--cache-dir")
    assert _app.cache_directory(parse(argv + ["--cache-dir", "late"]))[0] == "late"
    assert _app.cache_directory(parse(["--no-cache"] + argv))[0] is None
    assert _app.cache_directory(parse(argv + ["--no-cache"]))[0] is None
    for off in ("off", "OFF", "0", "none"):
        monkeypatch.setenv("VMJ_CACHE_DIR", off)
        assert _app.cache_directory(parse(argv)) == (None, "VMJ_CACHE_DIR")


def test_no_cache_leaves_jax_configuration_alone(capsys):
    import jax

    before = jax.config.jax_compilation_cache_dir
    assert main(["--no-cache", "linear", "--m", "1", "--c", "1", "--k", "14.5", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["damping_ratio"] > 0
    assert jax.config.jax_compilation_cache_dir == before


def test_commands_run_on_the_cpu_and_large_sweeps_on_the_default_device(monkeypatch):
    """The process's own command runs on the CPU (a single solve or fit is faster there than
    on a GPU), `vmj sweep` too where its work is estimated under `CPU_SECONDS`, else on JAX's
    default device; `JAX_PLATFORMS` decides for every command; `main` called in-process
    leaves the caller's devices alone."""
    code = (
        "import sys, jax; from vmj.cli import main; "
        "sys.argv = ['vmj', '--no-cache', *sys.argv[1:]]; "
        "status = main(); print(status, jax.config.jax_platforms or 'default')"
    )
    linear = ["linear", "--m", "1", "--c", "1", "--k", "14.5", "--json"]
    sweep = ["sweep", "linear", "--m", "1", "--c", "1", "--k", "14.5,20", "--out", os.devnull]

    def platforms(argv, **env):
        environ = {k: v for k, v in os.environ.items() if k != "JAX_PLATFORMS"}
        run = subprocess.run(
            [sys.executable, "-c", code, *argv],
            capture_output=True,
            text=True,
            env={**environ, **env},
        )
        assert run.returncode == 0, run.stderr
        return run.stdout.split()[-2:]

    assert platforms(linear) == ["0", "cpu"]
    assert platforms(sweep) == ["0", "cpu"]  # (estimated 2e-7 s)
    assert platforms(linear, JAX_PLATFORMS="cpu,cuda") == ["0", "cpu,cuda"]
    assert platforms(sweep, JAX_PLATFORMS="cpu,cuda") == ["0", "cpu,cuda"]
    import jax

    before = jax.config.jax_platforms
    assert main(["--no-cache", *linear]) == 0
    assert main(["--no-cache", *sweep]) == 0
    assert jax.config.jax_platforms == before
    # the estimate's threshold, for the sweep of a process whose devices are vmj's to choose
    chosen = []
    monkeypatch.setattr(jax.config, "update", lambda name, value: chosen.append((name, value)))
    free = argparse.Namespace(device_by_work=True)
    _app.on_cpu_if_small(free, 1.01 * _app.CPU_SECONDS)
    _app.on_cpu_if_small(argparse.Namespace(), 0.0)
    assert chosen == []
    _app.on_cpu_if_small(free, 0.99 * _app.CPU_SECONDS)
    assert chosen == [("jax_platforms", "cpu")]


def test_an_unusable_cache_directory_is_refused(tmp_path, monkeypatch, capsys):
    a_file = tmp_path / "f"
    a_file.write_text("")
    monkeypatch.setenv("VMJ_CACHE_DIR", str(a_file))
    assert main(["linear", "--m", "1", "--c", "1", "--k", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vmj: error: VMJ_CACHE_DIR: cannot use") and err.count("\n") == 1


def _vmj(cache, *argv):
    """`vmj --cache-dir cache ...` in a process of its own, logging its compilations."""
    env = {**os.environ, "JAX_LOG_COMPILES": "1"}
    cmd = [sys.executable, "-m", "vmj.cli", "--cache-dir", str(cache), *argv]
    run = subprocess.run(cmd, capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stderr[-2000:]
    return run


@pytest.mark.parametrize(
    "argv, program",
    [
        (
            "decay variable-mass --m0 5 --c 4900 --delta 3 --eps 0 --mu 2 --FT 14.7 --a0 0.06 "
            "--n 2 --json",
            "_turning_points",
        ),
        # the fit's program calls LAPACK: its loaded executable needs LAPACK registered first
        # (unregistered, the repeat crashed)
        (
            "fit fits/data/table1_mu9_eps0.csv --model variable-mass --fit FT,mu "
            "--set m0=5,c=4900,delta=3,eps=0 --json",
            "_solve_lm",
        ),
        # forward mode through the exact solver, traced without guards (the concrete solve
        # before it checked the input)
        (
            "sensitivity variable-mass --m0 5 --c 4900 --delta 3 --eps 0 --mu 2 --FT 14.7 "
            "--a0 0.06 --n 2 --wrt FT,mu --json",
            "_decay_derivatives",
        ),
    ],
    ids=["decay", "fit", "sensitivity"],
)
def test_a_repeated_command_loads_its_compiled_program(tmp_path, argv, program):
    """The program that `vmj` compiles lands in its cache directory as an executable (it holds
    no host callback); a repeat, in a new process, loads it: no tracing, no compilation, the
    same answer."""
    cache = tmp_path / "cache"
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    argv = argv.replace("fits/data", os.path.join(root, "fits", "data")).split()
    first = _vmj(cache, *argv)
    compiled = f"Finished XLA compilation of jit({program})"
    assert compiled in first.stderr
    assert "uses host callbacks" not in first.stderr
    entries = os.listdir(cache / "exported")
    assert any(e.startswith(program) and e.endswith(".xla") for e in entries), entries
    again = _vmj(cache, *argv)
    assert again.stdout == first.stdout
    assert f"jit({program})" not in again.stderr


def test_a_repeated_sweep_loads_its_chunks_program(tmp_path):
    """`vmj sweep`'s chunk program is stored with the axes of its result's points (the energy
    balance's come last) and loaded by a repeat: no tracing, no compilation, the same file."""
    cache, out = tmp_path / "cache", [tmp_path / "first.csv", tmp_path / "again.csv"]
    argv = "sweep variable-mass --eps 0:1:3 --mu 0,5 --delta -3,3 --method energy --n 4 --set "
    argv = [*argv.split(), "m0=5,c=4900,FT=14.7,a0=0.06"]
    first = _vmj(cache, *argv, "--out", str(out[0]))
    assert "Finished XLA compilation of jit(_chunk_program)" in first.stderr
    assert any(e.startswith("_chunk_program") for e in os.listdir(cache / "exported"))
    again = _vmj(cache, *argv, "--out", str(out[1]))
    assert "jit(_chunk_program)" not in again.stderr
    assert out[1].read_text() == out[0].read_text() and out[0].read_text().count("\n") == 14


def test_the_command_settles_the_garbage_collector_only_for_its_own_process(capsys):
    """The process's own `vmj` freezes what start-up imported (the collector stays on); `main`
    called in-process leaves the caller's collector as it was."""
    code = (
        "import gc, sys; from vmj.cli import main; "
        "sys.argv = ['vmj', '--no-cache', 'linear', '--m', '1', '--c', '1', '--k', '14.5']; "
        "status = main(); print(status, gc.isenabled(), gc.get_freeze_count() > 1000)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.split()[-3:] == ["0", "True", "True"]
    import gc

    frozen = gc.get_freeze_count()
    assert main(["--no-cache", "linear", "--m", "1", "--c", "1", "--k", "14.5"]) == 0
    assert gc.isenabled() and gc.get_freeze_count() == frozen
    capsys.readouterr()


def test_the_command_compiles_its_loops_as_one_kernel_each(monkeypatch):
    """`vmj.one_kernel_loops` (which the command calls before JAX starts its backend) makes
    XLA compile a small `while` loop into one kernel; after the backend started it changes
    nothing and says so; an `XLA_FLAGS` of the user's is extended, never overridden."""
    code = (
        "import json, os, sys, vmj\n"
        "applied = vmj.one_kernel_loops() if sys.argv[1] == 'on' else None\n"
        "import jax, jax.numpy as jnp\n"
        "loop = lambda x: jax.lax.fori_loop(0, 3, lambda i, y: jnp.sin(y) + y, x)\n"
        "text = jax.jit(loop).lower(jnp.ones(256)).compile().as_text()\n"
        "late = vmj.one_kernel_loops()\n"
        "print(json.dumps([applied, late, 'xla_cpu_small_call' in text, "
        "os.environ.get('XLA_FLAGS', '')]))"
    )
    environ = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}

    def run(mode):
        done = subprocess.run(
            [sys.executable, "-c", code, mode], capture_output=True, text=True, env=environ
        )
        assert done.returncode == 0, done.stderr
        return json.loads(done.stdout.splitlines()[-1])

    applied, late, one_kernel, flags = run("on")
    assert (applied, late, one_kernel) == (True, True, True)  # (late: the option is set)
    assert flags == "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=65536"
    _, late, one_kernel, flags = run("off")  # XLA's default: a kernel per operation
    assert (late, one_kernel, flags) == (False, False, "")

    from jax._src import xla_bridge

    from vmj import _host

    monkeypatch.setattr(xla_bridge, "backends_are_initialized", lambda: False)
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/d --xla_backend_extra_options=a=1")
    assert _host.one_kernel_loops(4096) is True
    assert os.environ["XLA_FLAGS"] == (
        "--xla_dump_to=/tmp/d --xla_backend_extra_options=a=1,"
        "xla_cpu_small_while_loop_byte_threshold=4096"
    )
    monkeypatch.setenv(
        "XLA_FLAGS", "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=0"
    )
    assert _host.one_kernel_loops() is True  # the user's choice stays
    assert os.environ["XLA_FLAGS"].endswith("=0")
    monkeypatch.delenv("XLA_FLAGS")
    assert main(["--no-cache", "linear", "--m", "1", "--c", "1", "--k", "14.5", "--json"]) == 0
    assert os.environ["XLA_FLAGS"].endswith("xla_cpu_small_while_loop_byte_threshold=65536")
    for bad in (-1, 2**63, 1.5, True, "1G"):
        with pytest.raises(ValueError, match="limit must be an integer number of bytes"):
            vmj.one_kernel_loops(bad)
