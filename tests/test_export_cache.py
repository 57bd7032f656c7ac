"""The exported-program cache of the compiled entry points (vmj/_exported.py), as the `vmj`
command uses it: a repeat loads the executable instead of tracing, lowering and compiling, and
answers bit for bit the same; a corrupted entry or a changed source is exported (or compiled)
again, an executable that fails is compiled anew; `--no-cache` writes nothing; a plain
`import vmj` leaves it off."""

from __future__ import annotations

import os

import jax
import pytest
from cli_args import VARIABLE_MASS

import vmj._exported as exported
import vmj._integrate as entry
from vmj.cli import main

DECAY = ["decay", "variable-mass", *VARIABLE_MASS, "--n", "3", "--json"]


@pytest.fixture
def exports(monkeypatch):
    """The numbers of programs exported (traced) and compiled so far, `[exported, compiled]`;
    the process starts with nothing loaded, as a new process would."""
    count = [0, 0]
    export, compile_ = exported._export, exported._compile

    def counting(jitted, specs):
        count[0] += 1
        return export(jitted, specs)

    def compiling(*args):
        count[1] += 1
        return compile_(*args)

    monkeypatch.setattr(exported, "_export", counting)
    monkeypatch.setattr(exported, "_compile", compiling)
    monkeypatch.setattr(entry._turning_points, "loaded", {})
    jax.clear_caches()  # (as in a new process: no executable of another test's to reuse)
    names = ("jax_compilation_cache_dir", "jax_persistent_cache_min_compile_time_secs")
    config = {name: getattr(jax.config, name) for name in names}  # `main` sets them
    yield count
    exported._environment.cache_clear()  # (a test may change the source hash)
    for name, value in config.items():
        jax.config.update(name, value)


def _new_process() -> None:
    """Forget what was loaded and compiled, as a new process starts."""
    entry._turning_points.loaded.clear()
    jax.clear_caches()


def _run(capsys, *argv) -> str:
    assert main(list(argv)) == 0
    return capsys.readouterr().out


def _entries(cache) -> list:
    return sorted(os.listdir(cache / "exported"))


def test_a_repeat_loads_the_executable_and_answers_the_same(tmp_path, capsys, exports):
    cache = tmp_path / "cache"
    first = _run(capsys, "--cache-dir", str(cache), *DECAY)
    assert exports == [1, 1]
    program, executable = _entries(cache)
    assert program.startswith("_turning_points-") and program.endswith(".exported")
    assert executable == program.replace(".exported", ".xla")
    assert exported.exported_cache_directory() is None  # switched on only while `main` runs

    _new_process()
    again = _run(capsys, "--cache-dir", str(cache), *DECAY)
    assert exports == [1, 1]  # loaded: neither traced nor compiled
    assert again == first
    assert _run(capsys, "--no-cache", *DECAY) == first  # the plain `jax.jit`, bit for bit


def _damage(path) -> bytes:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF  # one flipped byte
    path.write_bytes(bytes(data))
    return bytes(data)


def test_a_corrupted_entry_is_written_again(tmp_path, capsys, exports):
    cache = tmp_path / "cache"
    first = _run(capsys, "--cache-dir", str(cache), *DECAY)
    names = _entries(cache)
    program, executable = (cache / "exported" / name for name in names)
    damaged = _damage(executable)  # compiled again from the exported program
    _new_process()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports == [1, 2]
    assert executable.read_bytes() != damaged
    damaged = _damage(program)
    executable.unlink()  # exported again
    _new_process()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports == [2, 3]
    assert program.read_bytes() != damaged
    program.write_bytes(b"not an entry")
    executable.write_bytes(b"not an entry")
    _new_process()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports == [3, 4]
    _new_process()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports == [3, 4]  # the rewritten entries are used
    assert _entries(cache) == names  # (no temporary file left behind)


def test_an_executable_that_fails_to_run_is_compiled_anew(tmp_path, capsys, exports, monkeypatch):
    """(jaxlib 0.10 serialized an executable loaded from the compilation cache without the code
    of some kernels: it loaded, and failed when run.)"""
    cache = tmp_path / "cache"
    first = _run(capsys, "--cache-dir", str(cache), *DECAY)

    def broken(*args):
        raise jax.errors.JaxRuntimeError("NOT_FOUND: Function wrapped_rsqrt not found")

    from jax.experimental import serialize_executable

    monkeypatch.setattr(serialize_executable, "deserialize_and_load", lambda *a, **k: broken)
    _new_process()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports == [1, 2]  # compiled anew from the exported program


def test_a_changed_source_misses(tmp_path, capsys, exports, monkeypatch):
    cache = tmp_path / "cache"
    first = _run(capsys, "--cache-dir", str(cache), *DECAY)
    monkeypatch.setattr(exported, "_source_hash", lambda package: f"{package} edited")
    exported._environment.cache_clear()
    _new_process()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports == [2, 2]
    assert len(_entries(cache)) == 4


def test_no_cache_writes_nothing(tmp_path, capsys, exports, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("VMJ_CACHE_DIR", str(cache))
    _run(capsys, "--no-cache", *DECAY)
    monkeypatch.setenv("VMJ_CACHE_DIR", "off")
    _run(capsys, *DECAY)
    assert exports == [0, 0]
    assert not cache.exists()


def test_static_arguments_are_described_the_same_in_every_process():
    from fits._models import SPACES

    text = exported._stable((SPACES["variable-mass"], "exact", 8, 200))
    assert " at 0x" not in text and "fits._models._variable_mass" in text
    assert exported._stable({"b": 1, "a": (2.0, None)}) == "{'a': tuple(2.0, None), 'b': 1}"
    # a lambda or a local function has no name of its own (two in one module would share
    # one): described with its address, so never cached
    assert " at 0x" in exported._stable(lambda m: m)
    assert " at 0x" in exported._stable((test_no_cache_writes_nothing, _local()))


def _local():
    def f(m):
        return m

    return f
