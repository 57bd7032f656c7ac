"""The exported-program cache of the compiled entry points (vmj/_exported.py), as the `vmj`
command uses it: a repeat loads the exported program instead of tracing and answers bit for bit
the same; a corrupted entry or a changed source is exported again; `--no-cache` writes nothing;
a plain `import vmj` leaves it off."""

from __future__ import annotations

import os

import jax
import pytest

import vmj._exported as exported
import vmj._integrate as entry
from vmj.cli import main

DECAY = [
    "decay",
    "variable-mass",
    "--m0",
    "5",
    "--c",
    "4900",
    "--delta",
    "3",
    "--eps",
    "0",
    "--mu",
    "2",
    "--FT",
    "14.7",
    "--a0",
    "0.06",
    "--n",
    "3",
    "--json",
]


@pytest.fixture
def exports(monkeypatch):
    """The number of programs exported (traced) so far; the process starts with nothing loaded,
    as a new process would."""
    count = [0]
    export = exported._export

    def counting(jitted, specs):
        count[0] += 1
        return export(jitted, specs)

    monkeypatch.setattr(exported, "_export", counting)
    monkeypatch.setattr(entry._turning_points, "loaded", {})
    names = ("jax_compilation_cache_dir", "jax_persistent_cache_min_compile_time_secs")
    config = {name: getattr(jax.config, name) for name in names}  # `main` sets them
    yield count
    exported._environment.cache_clear()  # (a test may change the source hash)
    for name, value in config.items():
        jax.config.update(name, value)


def _run(capsys, *argv) -> str:
    assert main(list(argv)) == 0
    return capsys.readouterr().out


def _entries(cache) -> list:
    return sorted(os.listdir(cache / "exported"))


def test_a_repeat_loads_the_exported_program_and_answers_the_same(tmp_path, capsys, exports):
    cache = tmp_path / "cache"
    first = _run(capsys, "--cache-dir", str(cache), *DECAY)
    assert exports[0] == 1
    (name,) = _entries(cache)
    assert name.startswith("_turning_points-") and name.endswith(".exported")
    assert exported.exported_cache_directory() is None  # switched on only while `main` runs

    entry._turning_points.loaded.clear()  # a new process
    again = _run(capsys, "--cache-dir", str(cache), *DECAY)
    assert exports[0] == 1  # loaded, not traced
    assert again == first
    assert _run(capsys, "--no-cache", *DECAY) == first  # the plain `jax.jit`, bit for bit


def test_a_corrupted_entry_is_exported_again(tmp_path, capsys, exports):
    cache = tmp_path / "cache"
    first = _run(capsys, "--cache-dir", str(cache), *DECAY)
    (name,) = _entries(cache)
    path = cache / "exported" / name
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF  # one flipped byte
    path.write_bytes(bytes(data))
    entry._turning_points.loaded.clear()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports[0] == 2  # the damaged entry was not used ...
    assert path.read_bytes() != bytes(data)  # ... and was written anew
    path.write_bytes(b"not an entry")
    entry._turning_points.loaded.clear()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports[0] == 3
    entry._turning_points.loaded.clear()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports[0] == 3  # the rewritten entry is used
    assert _entries(cache) == [name]  # (no temporary file left behind)


def test_a_changed_source_misses(tmp_path, capsys, exports, monkeypatch):
    cache = tmp_path / "cache"
    first = _run(capsys, "--cache-dir", str(cache), *DECAY)
    monkeypatch.setattr(exported, "_source_hash", lambda package: f"{package} edited")
    exported._environment.cache_clear()
    entry._turning_points.loaded.clear()
    assert _run(capsys, "--cache-dir", str(cache), *DECAY) == first
    assert exports[0] == 2
    assert len(_entries(cache)) == 2


def test_no_cache_writes_nothing(tmp_path, capsys, exports, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("VMJ_CACHE_DIR", str(cache))
    _run(capsys, "--no-cache", *DECAY)
    monkeypatch.setenv("VMJ_CACHE_DIR", "off")
    _run(capsys, *DECAY)
    assert exports[0] == 0
    assert not cache.exists()


def test_static_arguments_are_described_the_same_in_every_process():
    from fits._models import SPACES

    text = exported._stable((SPACES["variable-mass"], "exact", 8, 200))
    assert " at 0x" not in text and "fits._models._variable_mass" in text
    assert exported._stable({"b": 1, "a": (2.0, None)}) == "{'a': tuple(2.0, None), 'b': 1}"
