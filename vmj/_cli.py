"""The `vmj` command line. Its JSON output is a contract: other tools parse it.

Float64 is enabled here, before any computation. Bad input prints one line to stderr and
exits with status 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

COMMANDS = {}  #: name -> (add_arguments(parser), run(args) -> int)


def command(name: str, help: str):
    def wrap(pair):
        COMMANDS[name] = (help, *pair)
        return pair

    return wrap


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"not a finite number: {text!r}")
    return value


def parse_set(text: str | None) -> dict:
    """`NAME=VALUE[,NAME=VALUE...]` of `--set` as `{name: text}`; a name given twice is an error."""
    out = {}
    for item in filter(None, (s.strip() for s in (text or "").split(","))):
        if "=" not in item:
            raise ValueError(f"--set takes NAME=VALUE pairs separated by commas (got {item!r})")
        name, value = (s.strip() for s in item.split("=", 1))
        if name in out:
            raise ValueError(f"--set gives {name} twice")
        out[name] = value
    return out


def _emit(obj, as_json: bool, text: str) -> None:
    print(json.dumps(obj) if as_json else text)


# -- vmj decay variable-mass --------------------------------------------------------------------
def _decay_variable_mass_args(p):
    p.add_argument("--m0", type=_number, required=True, help="initial mass [kg]")
    p.add_argument("--c", type=_number, required=True, help="stiffness [N/m]")
    p.add_argument("--delta", type=_number, required=True, help="mass rate [kg/s]")
    p.add_argument("--eps", type=_number, required=True, help="reactivity coefficient in [0, 1]")
    p.add_argument("--mu", type=_number, required=True, help="viscous coefficient [kg/s]")
    law = p.add_mutually_exclusive_group(required=True)
    law.add_argument("--FT", type=_number, help="constant dry friction force [N]")
    law.add_argument("--f", type=_number, help="friction coefficient (F = f g m(t))")
    p.add_argument("--g", type=_number, default=9.81, help="gravity [m/s^2] for --f")
    p.add_argument("--a0", type=_number, required=True, help="initial deflection [m]")
    p.add_argument("--n", type=int, default=12, help="number of turning points")
    p.add_argument("--method", choices=("exact", "smooth", "energy"), default="exact")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _decay_variable_mass(args) -> int:
    import vmj

    law = vmj.Coulomb(args.FT) if args.FT is not None else vmj.MassProportional(args.f, args.g)
    model = vmj.VariableMass(args.m0, args.c, args.delta, args.eps, args.mu, law)
    seq = vmj.turning_points(model, args.a0, args.n, method=args.method)
    got = seq.reached()
    out = {
        "model": "variable-mass",
        "method": args.method,
        "times": got["times"].tolist(),
        "amplitudes": got["amplitudes"].tolist(),
        "crossed": got["crossed"].tolist(),
        "stopped": bool(seq.stopped),
    }
    if bool(seq.failed):
        out["message"] = seq.message
    lines = [f"{'k':>3} {'t [s]':>12} {'|x| [m]':>14} {'crossed':>8}"]
    for k, (t, a, c) in enumerate(zip(out["times"], out["amplitudes"], out["crossed"]), 1):
        lines.append(f"{k:>3} {t:12.6f} {a:14.8f} {'yes' if c else 'no *':>8}")
    lines.append(f"status: {seq.message}")
    _emit(out, args.json, "\n".join(lines))
    return 0


DECAY_MODELS = {"variable-mass": (_decay_variable_mass_args, _decay_variable_mass)}


def _decay_args(p):
    sub = p.add_subparsers(dest="model", required=True, metavar="MODEL")
    for name, (add, run) in DECAY_MODELS.items():
        q = sub.add_parser(name, help=f"decay of the {name} model")
        add(q)
        q.set_defaults(run=run)


command("decay", "turning points of a free decay")((_decay_args, lambda a: a.run(a)))


# -- vmj table N --------------------------------------------------------------------------------
def _table_args(p):
    p.add_argument("N", type=int, choices=(1, 2, 3, 4), help="table number of the paper")
    p.add_argument("--json", action="store_true")
    p.add_argument("--plot", metavar="PATH", help="write a figure (PNG) to PATH")


def _star(crossed: bool) -> str:
    return " " if crossed else "*"


def _table(args) -> int:
    from ._tables import paper_table

    rows = paper_table(args.N)
    if args.plot:
        from .plot import plot_table

        plot_table(args.N, rows, args.plot)
    if args.json:
        keys = ("k", "mu", "eps", "delta", "paper_energy_cm", "paper_monograph_cm", "energy_cm",
                "exact_cm", "exact_crossed")
        print(json.dumps({"table": args.N, "rows": [{k: r[k] for k in keys} for r in rows]}))
        return 0
    lines = [f"Table {args.N} (amplitudes in cm; * = the swing did not pass x = 0)",
             f"{'mu':>4} {'eps':>4} {'k':>3} | {'paper EB':>9} {'vmj EB':>9} | "
             f"{'monograph':>10} {'vmj exact':>10}"]
    for r in sorted(rows, key=lambda r: (r["mu"], r["eps"], r["k"])):
        pe = f"{r['paper_energy_cm']:.3f}{'*' if r['paper_energy_star'] else ' '}"
        pm = f"{r['paper_monograph_cm']:.3f}{'*' if r['paper_monograph_star'] else ' '}"
        lines.append(
            f"{r['mu']:>4g} {r['eps']:>4g} {r['k']:>3} | {pe:>9} "
            f"{r['energy_cm']:8.3f}{_star(r['energy_crossed'])} | {pm:>10} "
            f"{r['exact_cm']:9.4f}{_star(r['exact_crossed'])}" + ("  !" if r["note"] else "")
        )
    eb = max(rows, key=lambda r: abs(r["energy_cm"] - r["paper_energy_cm"]))
    clean = [r for r in rows if not r["note"]]
    ex = max(clean, key=lambda r: abs(r["exact_cm"] - r["paper_monograph_cm"]))
    lines += [
        "",
        f"largest |vmj EB - paper EB|: {abs(eb['energy_cm'] - eb['paper_energy_cm']):.4f} cm "
        f"(mu={eb['mu']:g}, eps={eb['eps']:g}, k={eb['k']})",
        f"largest |vmj exact - monograph| (cells without a note): "
        f"{abs(ex['exact_cm'] - ex['paper_monograph_cm']):.4f} cm "
        f"(mu={ex['mu']:g}, eps={ex['eps']:g}, k={ex['k']})",
    ]
    for r in rows:
        if r["note"]:
            lines.append(f"! mu={r['mu']:g} eps={r['eps']:g} k={r['k']}: {r['note']}; "
                         f"vmj exact {r['exact_cm']:.4f}{_star(r['exact_crossed'])}")
    print("\n".join(lines))
    return 0


command("table", "reproduce a table of the variable-mass paper")((_table_args, _table))


# -- commands defined in other modules register themselves on import ------------------------
# (each such module imports `command`/`DECAY_MODELS` from here and is listed once below)
COMMAND_MODULES = ("vmj._cli_stickslip", "vmj._cli_sweep", "vmj._cli_rope", "vmj._cli_fit")


# -- entry point --------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    import importlib

    for name in COMMAND_MODULES:
        importlib.import_module(name)
    parser = argparse.ArgumentParser(
        prog="vmj", description="Oscillators with dry friction and time-varying parameters."
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (help, add, run) in COMMANDS.items():
        p = sub.add_parser(name, help=help)
        add(p)
        p.set_defaults(command_run=run)
    return parser


def main(argv=None) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)
    from ._host import retain_host_memory

    retain_host_memory()  # XLA's per-chunk buffers reused, not page-faulted again (sweeps)
    parser = build_parser()
    args = parser.parse_args(argv)
    import equinox as eqx

    try:
        return args.command_run(args)
    except ValueError as e:
        print(f"vmj: error: {e}", file=sys.stderr)
        return 2
    except eqx.EquinoxRuntimeError as e:  # a value check inside jitted code (bad input too)
        tag = "EquinoxRuntimeError: "
        said = [ln.split(tag, 1)[1] for ln in str(e).splitlines() if tag in ln]
        print(f"vmj: error: {said[-1] if said else 'invalid input'}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
