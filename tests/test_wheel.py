"""The built wheel works anywhere: `python -m build` makes an sdist and from it a wheel, which is
installed into a fresh virtual environment outside the repository; there `vmj table 1`, `vmj fit`
on the record shipped with fits, and the README's Python snippets run.

The fresh environment gets the wheel with `--no-deps`; the dependencies come from this
environment's site-packages, appended to its path by a `.pth` file (no network). A `.pth` line
only adds a directory: the editable install of this checkout found there is not activated, so
`vmj` and `fits` come from the wheel (checked).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest
from test_docs import ROOT, environment, python_source

pytestmark = pytest.mark.slow


def sh(args, cwd, timeout=300, **env) -> str:
    got = subprocess.run(
        [str(a) for a in args],
        cwd=cwd,
        env=environment(**env),
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert got.returncode == 0, (
        f"{' '.join(map(str, args))} failed ({got.returncode}):\n"
        f"{got.stdout[-3000:]}\n{got.stderr[-6000:]}"
    )
    return got.stdout


@pytest.fixture(scope="module")
def venv(tmp_path_factory) -> Path:
    """A fresh virtual environment with the wheel installed; returns its bin/ directory."""
    tmp = tmp_path_factory.mktemp("wheel")
    dist = tmp / "dist"
    sh([sys.executable, "-m", "build", "--no-isolation", "--outdir", dist, ROOT], tmp)
    (wheel,) = dist.glob("vmj-*-py3-none-any.whl")

    env = tmp / "venv"
    sh([sys.executable, "-m", "venv", "--without-pip", env], tmp)
    python = env / "bin" / "python"
    sh(
        [
            sys.executable,
            "-m",
            "pip",
            "--python",
            python,
            "install",
            "--quiet",
            "--no-deps",
            "--no-index",
            wheel,
        ],
        tmp,
    )
    site = Path(
        sh([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp).strip()
    )
    ours = {sysconfig.get_paths()[k] for k in ("purelib", "platlib")}
    (site / "dependencies.pth").write_text("\n".join(sorted(ours)) + "\n")
    return env / "bin"


def test_wheel_installs_packages_and_data(venv, tmp_path):
    """vmj and fits import from the wheel, with their data and `py.typed` markers."""
    out = sh(
        [
            venv / "python",
            "-c",
            """
import json, vmj, fits
from importlib.resources import files
from importlib.metadata import version
shipped = [str(p) for p in (files("vmj") / "py.typed", files("fits") / "py.typed",
           files("vmj") / "data" / "olshansky_tables.csv", files("fits") / "data" / "80P.txt",
           files("fits") / "data" / "table1_mu9_eps0.csv") if p.is_file()]
print(json.dumps({"vmj": vmj.__file__, "fits": fits.__file__, "shipped": shipped,
                  "version": version("vmj"), "__version__": vmj.__version__,
                  "cells": len(vmj.paper_cells())}))
""",
        ],
        tmp_path,
    )
    got = json.loads(out)
    env = str(venv.parent)
    assert got["vmj"].startswith(env) and got["fits"].startswith(env), got
    assert len(got["shipped"]) == 5 and all(p.startswith(env) for p in got["shipped"]), got
    assert got["version"] == got["__version__"]
    assert got["cells"] > 100


def test_wheel_command_line(venv, tmp_path):
    """The `vmj` script of the wheel: the paper's table 1 and a fit of the shipped pendulum
    record (the README's numbers: zeta = 0.00598, xF = 0.016 deg)."""
    table = sh([venv / "vmj", "table", "1"], tmp_path)
    assert "mu=9 eps=0 k=3" in table  # the misprint's note
    record = sh(
        [
            venv / "python",
            "-c",
            "from importlib.resources import files; print(files('fits') / 'data' / '80P.txt')",
        ],
        tmp_path,
    ).strip()
    fit = json.loads(
        sh([venv / "vmj", "fit", record, "--series", "--model", "oscillator", "--json"], tmp_path)
    )
    assert fit["converged"]
    assert fit["params"]["zeta"] == pytest.approx(0.00598, rel=0.01)
    assert fit["params"]["xF"] == pytest.approx(0.0159, rel=0.05)


@pytest.mark.long  # the same snippets run from the repository in tests/test_docs.py
def test_wheel_runs_readme_snippets(venv, tmp_path):
    """The README's Python snippets, in a directory outside the repository."""
    (tmp_path / "readme.py").write_text(python_source(ROOT / "README.md"), encoding="utf-8")
    sh([venv / "python", "readme.py"], tmp_path, timeout=600)
    assert os.path.getsize(tmp_path / "sweep.csv") > 0
