"""The documentation runs as written: every ```python block of README.md and docs/*.md (one fresh
process per file, float64) and the `vmj` commands of their ```sh blocks; the site builds with
`mkdocs build --strict` (no broken link or cross-reference), with every public name in the API
reference. (The examples: tests/test_examples.py.)

Snippets and commands run in a scratch directory that looks like the repository root to them
(`fits/` links to the package, so `fits/data/80P.txt` resolves; `out/` exists, as after
`make demo`): whatever they write stays there, never in the repository.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
SHELLS = ("sh", "shell", "bash", "console")

_FENCE = re.compile(
    r"^(?P<indent>[ \t]*)```(?P<lang>[\w+-]*)[^\n]*\n(?P<body>.*?)^(?P=indent)```[ \t]*$",
    re.MULTILINE | re.DOTALL,
)


# -- reading the pages --------------------------------------------------------------------------
def code_blocks(path: Path, langs: tuple[str, ...]) -> list[str]:
    """The fenced code blocks of `path` in one of `langs`, dedented, in order."""
    text = path.read_text(encoding="utf-8")
    return [textwrap.dedent(m["body"]) for m in _FENCE.finditer(text) if m["lang"] in langs]


LONG = "# long-running"  #: first line of a block that takes minutes: run by `make test-long`


def _is_long(block: str) -> bool:
    return block.lstrip().startswith(LONG)


def python_source(path: Path, long: bool = False) -> str:
    """Every ```python block of `path`, in order, as one program: the long-running blocks
    (first line `# long-running ...`) when `long`, the others otherwise."""
    return "\n\n".join(b for b in code_blocks(path, ("python",)) if _is_long(b) == long)


# Commands the pages show that are not cheap enough to run here, with where they are tested.
EXPENSIVE = {
    # compiles the exact variable-mass model's fit (~30 s); tests/test_cli_variable_mass.py
    # runs the same fit and checks its numbers
    ("fit", "fits/data/table1_mu9_eps0.csv"),
}


def vmj_commands(path: Path, long: bool = False) -> list[list[str]]:
    """The arguments of each `vmj ...` command in the shell blocks of `path` (continuation lines
    joined, `$ ` prompts and `# comments` dropped; other commands, output lines and the commands
    in `EXPENSIVE` skipped): those of the long-running blocks when `long`, the others otherwise."""
    commands = []
    for block in code_blocks(path, SHELLS):
        if _is_long(block) != long:
            continue
        for line in block.replace("\\\n", " ").splitlines():
            line = line.strip().removeprefix("$ ")
            if line.startswith("vmj "):
                args = shlex.split(line, comments=True)[1:]
                if tuple(args[:2]) not in EXPENSIVE:
                    commands.append(args)
    return commands


def scratch(tmp_path: Path) -> Path:
    """A directory that looks like the repository root to the snippets: `fits` (the package,
    with its shipped records) and an empty `out/`."""
    (tmp_path / "out").mkdir(parents=True)
    (tmp_path / "fits").symlink_to(ROOT / "fits", target_is_directory=True)
    return tmp_path


def environment(**extra) -> dict:
    env = dict(os.environ, JAX_ENABLE_X64="1", MPLBACKEND="Agg", **extra)
    # compiled programs shared with the test suite's own cache (tests/conftest.py)
    env.setdefault(
        "JAX_COMPILATION_CACHE_DIR", env.get("VMJ_CACHE_DIR", str(ROOT / ".pytest_cache" / "jax"))
    )
    env.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
    return env


def run(args: list[str], cwd: Path, timeout: float, **env) -> subprocess.CompletedProcess:
    got = subprocess.run(
        args, cwd=cwd, env=environment(**env), capture_output=True, text=True, timeout=timeout
    )
    assert got.returncode == 0, (
        f"{' '.join(map(str, args))} failed ({got.returncode}):\n{got.stdout[-3000:]}\n"
        f"{got.stderr[-6000:]}"
    )
    return got


# -- the pages' snippets and commands ------------------------------------------------------------
def _id(path: Path) -> str:
    return str(path.relative_to(ROOT))


# The pages' snippets and commands run in ONE process (its start-up, about 2 s of importing JAX
# and vmj, paid once; a call that two pages make, traced once): each page's program with fresh
# globals (`runpy`, as `python snippets.py` runs it) in a scratch directory of its own, its
# figures closed after it; the commands of one page through the installed `vmj` entry point,
# each as `vmj ARGS` would run it. A page that fails is reported with its own traceback and
# output, and the pages after it still run. (A process per page: 105 s of CPU for the pages'
# snippets on 2 cores; one process: 70 s.)
_RUN_PAGES = """
import contextlib, io, json, os, runpy, sys, traceback
from importlib.metadata import entry_points

def python(job):
    try:
        runpy.run_path("snippets.py", run_name="__main__")
    except SystemExit as e:
        if e.code not in (0, None):
            raise
    if "matplotlib.pyplot" in sys.modules:
        sys.modules["matplotlib.pyplot"].close("all")

def commands(job):
    (vmj,) = entry_points(group="console_scripts", name="vmj")
    main = vmj.load()
    for args in job["commands"]:
        print("$ vmj " + " ".join(args), flush=True)
        out = io.StringIO()
        try:
            with contextlib.redirect_stdout(out):
                code = main(args)
        except SystemExit as e:
            code = e.code
        print(out.getvalue(), flush=True)
        if code not in (0, None):
            raise RuntimeError(f"vmj {' '.join(args)} exited with status {code}")
        if "--json" in args:
            json.loads(out.getvalue())  # one JSON document, nothing else on stdout

jobs, report = json.load(sys.stdin)
for job in jobs:
    os.chdir(job["dir"])
    log = io.StringIO()
    try:
        with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
            {"python": python, "vmj": commands}[job["kind"]](job)
        failure = None
    except BaseException:
        failure = traceback.format_exc()
    with open(report, "a", encoding="utf-8") as f:
        f.write(json.dumps([job["kind"], job["page"], failure, log.getvalue()[-3000:]]) + "\\n")
"""


def python_job(page: Path, where: Path, long: bool = False) -> dict:
    """The job of running the ```python blocks of `page` (the long-running ones when `long`)
    as `python snippets.py` in the scratch directory `where`."""
    (where / "snippets.py").write_text(python_source(page, long), encoding="utf-8")
    return {"kind": "python", "page": _id(page), "dir": str(where)}


def vmj_job(page: Path, where: Path, long: bool = False) -> dict:
    """The job of running the `vmj` commands of `page` (those of the long-running blocks when
    `long`) in the scratch directory `where`."""
    return {
        "kind": "vmj",
        "page": _id(page),
        "dir": str(where),
        "commands": vmj_commands(page, long),
    }


def run_pages(jobs: list[dict], report: Path, timeout: float) -> dict:
    """Run `jobs` in one process: `{(kind, page): None, or the page's output and traceback}`;
    a page that the process did not get to has the process's own end."""
    import json

    got = subprocess.run(
        [sys.executable, "-c", _RUN_PAGES],
        input=json.dumps([jobs, str(report)]),
        env=environment(),
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    done = {}
    if report.exists():
        for line in report.read_text(encoding="utf-8").splitlines():
            kind, page, failure, log = json.loads(line)
            done[kind, page] = None if failure is None else f"{log}\n{failure}"
    for job in jobs:
        done.setdefault(
            (job["kind"], job["page"]),
            f"the process ended ({got.returncode}) before this page:\n{got.stdout[-3000:]}\n"
            f"{got.stderr[-6000:]}",
        )
    return done


@pytest.fixture(scope="module")
def pages_run(tmp_path_factory) -> dict:
    """Every page's snippets and every page's commands, from one process (`run_pages`)."""
    where = lambda: scratch(tmp_path_factory.mktemp("page"))  # noqa: E731
    jobs = [python_job(p, where()) for p in PAGES if python_source(p)]
    jobs += [vmj_job(p, where()) for p in PAGES if vmj_commands(p)]
    return run_pages(jobs, tmp_path_factory.mktemp("report") / "pages.jsonl", timeout=1800)


@pytest.mark.slow
@pytest.mark.parametrize("page", [p for p in PAGES if python_source(p)], ids=_id)
def test_python_snippets_run(page, pages_run):
    failure = pages_run["python", _id(page)]
    assert failure is None, f"the snippets of {_id(page)} failed:\n{failure}"


@pytest.mark.slow
@pytest.mark.parametrize("page", [p for p in PAGES if vmj_commands(p)], ids=_id)
def test_vmj_commands_run(page, pages_run):
    failure = pages_run["vmj", _id(page)]
    assert failure is None, f"the commands of {_id(page)} failed:\n{failure}"


def _long_page_runs(job, what: str, tmp_path) -> None:
    """A page's long-running `job` (`python_job` or `vmj_job` with `long=True`), in a process
    of its own."""
    failure = run_pages([job], tmp_path / "report.jsonl", timeout=3600)[job["kind"], job["page"]]
    assert failure is None, f"the long-running {what} of {job['page']} failed:\n{failure}"


@pytest.mark.long
@pytest.mark.parametrize("page", [p for p in PAGES if python_source(p, long=True)], ids=_id)
def test_long_python_snippets_run(page, tmp_path):
    _long_page_runs(python_job(page, scratch(tmp_path / "page"), long=True), "snippets", tmp_path)


@pytest.mark.long
@pytest.mark.parametrize("page", [p for p in PAGES if vmj_commands(p, long=True)], ids=_id)
def test_long_vmj_commands_run(page, tmp_path):
    _long_page_runs(vmj_job(page, scratch(tmp_path / "page"), long=True), "commands", tmp_path)


# -- the site ------------------------------------------------------------------------------------
def test_site_builds_strict(tmp_path):
    """`mkdocs build --strict`: no broken link, anchor or cross-reference (docstrings included)."""
    run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        ROOT,
        timeout=300,
        NO_MKDOCS_2_WARNING="1",
    )
    assert (tmp_path / "site" / "api" / "models" / "index.html").is_file()


def _documented(prefix: str) -> set[str]:
    text = "\n".join(p.read_text(encoding="utf-8") for p in (DOCS / "api").glob("*.md"))
    return set(re.findall(rf"^::: {prefix}\.(\w+)\s*$", text, re.MULTILINE))


def test_api_reference_is_complete():
    """Every name of `vmj.__all__` and `fits.__all__` has its `::: name` block (a name that fits
    re-exports from vmj is documented once, under vmj)."""
    import fits
    import vmj

    missing = set(vmj.__all__) - _documented("vmj")
    missing |= {
        f"fits.{n}"
        for n in fits.__all__
        if n not in _documented("fits")
        and not (n in vmj.__all__ and getattr(fits, n) is getattr(vmj, n))
    }
    assert not missing, f"not in docs/api/*.md: {sorted(missing)}"
    unknown = (_documented("vmj") - set(vmj.__all__) - {"plot"}) | (
        _documented("fits") - set(fits.__all__)
    )
    assert not unknown, f"docs/api/*.md documents names that are not public: {sorted(unknown)}"


def test_site_lists_every_page():
    """Every page of docs/ is in the site's navigation (mkdocs only warns about the others)."""
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    pages = {str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md")}
    assert not {p for p in pages if f": {p}" not in nav}, "pages missing from mkdocs.yml's nav"


def test_readme_links_resolve():
    """The README's relative links and images point at files of the repository."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [t for t in targets if not re.match(r"[a-z]+://", t)]
    assert local, "the README links to docs/"
    assert not [t for t in local if not (ROOT / t).exists()], "broken README links"
