"""The `vmj` entry point: the list of commands, the parser, the JAX set-up, error handling.

The arguments are parsed before anything heavy is imported: a command's module is imported only
when that command is named (its options are added then), and JAX only when a command runs. So
`vmj --help`, `vmj COMMAND --help` and argument errors answer at once.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import os
import re
import sys
from dataclasses import dataclass

from .._exported import enable_exported_cache, exported_cache_directory
from ._options import LARGEST, SMALLEST, HelpFormatter

__all__ = ["COMMANDS", "main", "build_parser", "cache_directory"]


@dataclass(frozen=True)
class Command:
    """A command: its name, one line of help, and the module that defines it, with
    `add_arguments(parser)` and `run(args) -> int` (imported when the command is named);
    `synchronous`: JAX's CPU computations run in the calling thread; `accelerator`: the command
    runs on JAX's default device, an accelerator where there is one, unless it calls
    `on_cpu_if_small` with a small estimate of its work; the others run on the CPU
    (`_set_up_jax`)."""

    name: str
    help: str
    module: str
    synchronous: bool = True
    accelerator: bool = False

    def load(self):
        return importlib.import_module(self.module)


#: every command of `vmj`, in the order of `vmj --help` (`vmj fit` belongs to the fits package)
COMMANDS = (
    Command("decay", "turning points of a free decay (variable-mass, rope)", "vmj.cli._decay"),
    Command("table", "reproduce a table of the variable-mass paper", "vmj.cli._table"),
    Command(
        "sweep",
        "a decay or cycle over a grid of parameters (CSV, NetCDF, figures)",
        "vmj.cli._sweep",
        accelerator=True,
    ),
    Command(
        "sensitivity",
        "derivatives of the turning points with respect to parameters",
        "vmj.cli._sensitivity",
    ),
    Command(
        "stick-slip",
        "stick-slip limit cycle with instantaneous velocity reversal",
        "vmj.cli._stick_slip",
    ),
    Command(
        "linear",
        "linear one-degree-of-freedom oscillator: frequencies, decrement, responses",
        "vmj.cli._linear",
    ),
    Command(
        "fit", "identify friction and damping from a measured decay", "fits._cli", synchronous=False
    ),
)

CACHE_ENV = "VMJ_CACHE_DIR"
PLATFORMS_ENV = "JAX_PLATFORMS"  #: JAX's own choice of devices, which the command keeps
_OFF = ("off", "none", "0", "false", "no")

#: an accelerator's command estimated at less work than this runs on the CPU [s of the
#: estimate]. On a machine with an H200 the README's 1617-point `vmj sweep` (estimated 0.02 s)
#: took 2.98 s on the GPU against 2.07 s on its CPU repeated, 5.26 against 3.60 s in a fresh
#: cache (bench_cli.py --sweep, 2026-11-28): CUDA's start and the chunk's tracing cost the GPU
#: 0.9-1.7 s whatever the sweep's size. The estimates (`vmj sweep`'s) are 3 to 13 times the
#: warm sweeps' time on the 2-core development machine, so below 5 s of estimate the CPU's
#: computation takes about as long as the GPU's fixed cost or less; where a larger sweep
#: gains from the GPU was not measured.
CPU_SECONDS = 5.0

EPILOG = f"""\
Compiled and traced programs are kept in a persistent cache, so that a repeated command
  starts faster: ${{XDG_CACHE_HOME:-~/.cache}}/vmj/jax by default; --cache-dir PATH or
  {CACHE_ENV}=PATH moves it, --no-cache or {CACHE_ENV}=off switches it off.
Commands run on the CPU (a single solve or fit is faster there than on a GPU); 'vmj sweep'
  on JAX's default device, a GPU where there is one, unless its estimated time is under
  {CPU_SECONDS:g} s. {PLATFORMS_ENV}=cuda (or cpu) decides for every command.
Numbers must be finite, 0 or of magnitude {SMALLEST:g} to {LARGEST:g}, in the units shown in
  brackets.
Bad input prints one line 'vmj: error: ...' and exits with status 2.
Run 'vmj COMMAND --help' for the options of a command (units in brackets)."""


#: what an option's value may look like when it starts with a minus sign: a number with an
#: exponent, an axis (`-3:3:7`, `-1,0,1`), `-inf`; argparse alone takes `-1e3` for an option
NEGATIVE = re.compile(
    r"^-((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?([:,].*)?|inf|infinity|nan)$", re.IGNORECASE
)


#: the namespace attribute in which `_Once` keeps the options given so far (removed after
#: parsing)
_GIVEN = "_vmj_given"


class _Once(argparse._StoreAction):
    """An option with a value may be given once: argparse keeps the last of `--m0 5 --m0 6`
    silently (a list option such as `--set` joins its values instead: `Joined`)."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault(_GIVEN, {})
        shown = " ".join(
            f"{v:g}" if isinstance(v, float) else str(v)
            for v in (values if isinstance(values, list) else [values])
        )
        if self.dest in given:
            raise argparse.ArgumentError(
                self, f"given twice ({given[self.dest]} and {shown}); give it once"
            )
        given[self.dest] = shown
        super().__call__(parser, namespace, values, option_string)


class _Parser(argparse.ArgumentParser):
    """An argument error is one line on stderr (`vmj: error: ...`), exit status 2; negative
    numbers with exponents and axes are values, not options; an option with a value may be
    given once (`_Once`)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE
        self.register("action", None, _Once)
        self.register("action", "store", _Once)

    def parse_known_args(self, args=None, namespace=None):
        namespace, rest = super().parse_known_args(args, namespace)
        namespace.__dict__.pop(_GIVEN, None)
        return namespace, rest

    def error(self, message):
        where = self.prog.removeprefix("vmj").strip()
        self.exit(
            2, f"vmj: error: {where + ': ' if where else ''}{message} (see '{self.prog} --help')\n"
        )


class _Commands(argparse._SubParsersAction):
    """Subcommands whose options are added only when the command is named."""

    def __call__(self, parser, namespace, values, option_string=None):
        name = values[0]
        command = next((c for c in COMMANDS if c.name == name), None)
        sub = self._name_parser_map.get(name)
        if command is not None and sub.get_default("command_run") is None:  # once per parser
            module = command.load()
            module.add_arguments(sub)
            add_global_options(sub, nested=True)
            sub.set_defaults(
                command_run=module.run,
                synchronous=command.synchronous,
                accelerator=command.accelerator,
            )
        super().__call__(parser, namespace, values, option_string)


def add_global_options(parser, nested: bool = False) -> None:
    """`--cache-dir` and `--no-cache`, accepted before or after the command (a command module
    calls this for the subcommands it adds itself)."""
    if any("--no-cache" in a.option_strings for a in parser._actions):
        return
    default = argparse.SUPPRESS if nested else None
    parser.add_argument(
        "--cache-dir",
        metavar="PATH",
        default=default,
        help=f"persistent compilation cache directory (default: ${CACHE_ENV}, "
        "else $XDG_CACHE_HOME/vmj/jax or ~/.cache/vmj/jax)",
    )
    parser.add_argument(
        "--no-cache",
        action="store_true",
        default=argparse.SUPPRESS if nested else False,
        help=f"do not use the persistent compilation cache (also: {CACHE_ENV}=off)",
    )


def build_parser() -> argparse.ArgumentParser:
    import vmj

    parser = _Parser(
        prog="vmj",
        formatter_class=HelpFormatter,
        epilog=EPILOG,
        description="Oscillators with dry friction and time-varying parameters.",
    )
    parser.add_argument("--version", action="version", version=f"vmj {vmj.__version__}")
    add_global_options(parser)
    parser.register("action", "commands", _Commands)
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", action="commands", parser_class=_Parser
    )
    for command in COMMANDS:
        sub.add_parser(
            command.name, help=command.help, description=command.help, formatter_class=HelpFormatter
        )
    return parser


def cache_directory(args) -> tuple[str | None, str]:
    """The persistent cache directory (`None`: off) and where the choice came from."""
    if getattr(args, "no_cache", False):
        return None, "--no-cache"
    if getattr(args, "cache_dir", None) is not None:
        return args.cache_dir, "--cache-dir"
    env = os.environ.get(CACHE_ENV, "").strip()
    if env.lower() in _OFF:
        return None, CACHE_ENV
    if env:
        return env, CACHE_ENV
    base = os.environ.get("XDG_CACHE_HOME", "").strip() or os.path.join(
        os.path.expanduser("~"), ".cache"
    )
    return os.path.join(base, "vmj", "jax"), "default"


def on_cpu_if_small(args, seconds: float) -> None:
    """For an accelerator's command run as the process's own, `JAX_PLATFORMS` unset: the CPU as
    its device where its work is estimated at under `CPU_SECONDS` (called before anything is
    placed on a device)."""
    if getattr(args, "device_by_work", False) and seconds < CPU_SECONDS:
        import jax

        jax.config.update("jax_platforms", "cpu")


def _set_up_jax(args, process: bool = False) -> None:
    """XLA's loops as one kernel each, float64, synchronous dispatch, the persistent compilation
    cache, host memory reuse (entry point only); for the process's own command (`process`), the
    CPU as its device unless `JAX_PLATFORMS` says otherwise or the command is for an accelerator
    (which then decides from its work: `on_cpu_if_small`)."""
    from .._host import one_kernel_loops

    # (before JAX starts its backend: a single solve's loops as one kernel each)
    one_kernel_loops()
    import jax

    if process and not os.environ.get(PLATFORMS_ENV):
        if getattr(args, "accelerator", False):
            args.device_by_work = True
        else:
            # a single solve's loops test their exit on the host at every iteration: on a
            # machine with an H200, `vmj fit` (bench_cli.py) repeated in 3.35 s on its CPU
            # against 5.24 s on the GPU (a fresh cache: 12.2 against 18.0 s), one warm solve
            # 0.09-0.14 against 2.7 ms (docs/performance.md)
            jax.config.update("jax_platforms", "cpu")
    jax.config.update("jax_enable_x64", True)
    # run each compiled call in the calling thread: handing it to JAX's dispatch thread costs
    # a single solve more than its arithmetic (docs/performance.md); sweeps run their chunks
    # in threads of their own, so nothing waits on it. Not for `vmj fit`: its long batched
    # solves ran 2.6 times slower per step in the calling thread
    jax.config.update("jax_cpu_enable_async_dispatch", not getattr(args, "synchronous", True))
    path, source = cache_directory(args)
    if path is not None:
        try:
            if os.path.exists(path) and not os.path.isdir(path):
                raise OSError(f"{path!r} is not a directory")
            os.makedirs(path, exist_ok=True)
            if not os.access(path, os.W_OK | os.X_OK):
                raise OSError(f"{path!r} is not writable")
        except OSError as e:
            if source != "default":
                raise ValueError(
                    f"{source}: cannot use {path!r} as the compilation cache ({e})"
                ) from None
            print(f"vmj: warning: compilation cache off ({e})", file=sys.stderr)
            path = None
    if path is not None:
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update(
            "jax_persistent_cache_min_compile_time_secs", 0.0
        )  # every program: a loaded one beats even a 0.1 s compile
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    # the traced programs too: a repeated command skips tracing (vmj/_exported.py)
    enable_exported_cache(None if path is None else os.path.join(path, "exported"))
    from .._host import retain_host_memory

    retain_host_memory()  # XLA's per-chunk buffers reused, not page-faulted again (sweeps)


@contextlib.contextmanager
def _settled(process: bool):
    """For the process's own command (`argv` not given): JAX, equinox and vmj's models imported
    with Python's cyclic garbage collector paused, and everything then alive moved to its
    permanent generation (`gc.freeze`), so that the command's collections no longer traverse
    JAX's objects (a repeated `vmj table 1`: 0.78 -> 0.58 s, docs/performance.md). A `main`
    called in-process leaves the caller's collector alone."""
    if not process:
        yield
        return
    gc.disable()
    try:
        yield
        import vmj._integrate  # noqa: F401 (JAX, equinox, the models and solvers)
    finally:
        gc.freeze()
        gc.enable()


def _one_line(error: BaseException) -> str:
    return (
        "; ".join(ln.strip() for ln in str(error).splitlines() if ln.strip())
        or type(error).__name__
    )


def main(argv=None) -> int:
    """Run `vmj` with `argv` (default: `sys.argv[1:]`); returns the exit status. Argument
    errors, `--help` and `--version` exit through `SystemExit` (status 2 or 0), as argparse
    does."""
    args = build_parser().parse_args(argv)
    exported = exported_cache_directory()  # restored on return (`main` run in-process)
    try:
        with _settled(argv is None):
            _set_up_jax(args, process=argv is None)
        return args.command_run(args)
    except ValueError as e:  # bad input, found by vmj's checks or the command's
        print(f"vmj: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader of our output went away (`vmj ... | head`)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as e:  # reading or writing a file failed
        print(f"vmj: error: {_one_line(e)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("vmj: interrupted", file=sys.stderr)
        return 130
    finally:
        enable_exported_cache(exported)
