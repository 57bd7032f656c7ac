"""`vmj table N`: a table of the variable-mass paper, reproduced."""

from __future__ import annotations

from ._options import emit, figure_path

__all__ = ["add_arguments", "run"]


def add_arguments(p) -> None:
    p.add_argument("N", type=int, choices=(1, 2, 3, 4), help="table number of the paper")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--plot",
        metavar="PATH",
        type=figure_path,
        help="write a figure to PATH (format from the extension: png, pdf, svg, ...)",
    )


def _star(crossed: bool) -> str:
    return " " if crossed else "*"


def run(args) -> int:
    import vmj

    rows = vmj.paper_table(args.N)
    if args.plot:
        from vmj.plot import plot_table

        plot_table(args.N, rows, args.plot)
    if args.json:
        keys = (
            "k",
            "mu",
            "eps",
            "delta",
            "paper_energy_cm",
            "paper_monograph_cm",
            "energy_cm",
            "exact_cm",
            "exact_crossed",
        )
        emit({"table": args.N, "rows": [{k: r[k] for k in keys} for r in rows]}, True, "")
        return 0
    lines = [
        f"Table {args.N} (amplitudes in cm; * = the swing did not pass x = 0)",
        f"{'mu':>4} {'eps':>4} {'k':>3} | {'paper EB':>9} {'vmj EB':>9} | "
        f"{'monograph':>10} {'vmj exact':>10}",
    ]
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
            lines.append(
                f"! mu={r['mu']:g} eps={r['eps']:g} k={r['k']}: {r['note']}; "
                f"vmj exact {r['exact_cm']:.4f}{_star(r['exact_crossed'])}"
            )
    print("\n".join(lines))
    return 0
