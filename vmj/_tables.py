"""The four amplitude tables of the variable-mass paper (Olshansky & Olshansky), as package data,
and their reproduction by vmj's energy-balance and exact solvers."""

from __future__ import annotations

import csv
from importlib import resources

import numpy as np

from ._integrate import turning_points
from ._laws._friction import Coulomb, MassProportional
from ._models._variable_mass import VariableMass
from ._solvers._closed import EnergyBalance

__all__ = ["PAPER", "paper_cells", "paper_model", "paper_table"]

#: parameters common to the four tables (SI units)
PAPER = {"m0": 5.0, "c": 4900.0, "a0": 0.06, "FT": 14.7, "f": 0.3, "g": 9.81}
"""The data common to the variable-mass paper's tables: `m0` [kg], `c` [N/m], `a0` [m], `F_T`
[N] (tables 1-2), `f` [-] and `g` [m/s^2] (tables 3-4)."""


def paper_cells(table: int | None = None) -> list[dict]:
    """The published cells (amplitudes in cm, `*` marks as booleans, the erratum note)."""
    text = resources.files("vmj").joinpath("data/olshansky_tables.csv").read_text()
    rows = []
    for r in csv.DictReader(text.splitlines()):
        if table is not None and int(r["table"]) != table:
            continue
        rows.append(
            {
                "table": int(r["table"]),
                "friction": r["friction"],
                "delta": float(r["delta_kg_s"]),
                "mu": float(r["mu_kg_s"]),
                "eps": float(r["eps"]),
                "k": int(r["k"]),
                "paper_energy_cm": float(r["energy_balance_cm"]),
                "paper_energy_star": r["energy_balance_star"] == "1",
                "paper_monograph_cm": float(r["monograph_cm"]),
                "paper_monograph_star": r["monograph_star"] == "1",
                "note": r["note"],
            }
        )
    return rows


def paper_model(friction: str, delta: float, eps: float, mu: float) -> VariableMass:
    law = (
        Coulomb(PAPER["FT"]) if friction == "constant" else MassProportional(PAPER["f"], PAPER["g"])
    )
    return VariableMass(PAPER["m0"], PAPER["c"], delta, eps, mu, law)


def paper_table(table: int, n: int = 12) -> list[dict]:
    """Every cell of table `table` (1-4) with vmj's energy-balance and exact values.

    Row keys: `k, mu, eps, delta` and `paper_energy_cm, paper_monograph_cm` (as printed),
    `paper_energy_star, paper_monograph_star, note`, and vmj's `energy_cm, energy_crossed,
    exact_cm, exact_crossed` (the tables' `*` is `not crossed`).
    """
    if table not in (1, 2, 3, 4):
        raise ValueError(f"table must be 1, 2, 3 or 4 (got {table!r})")
    cells = paper_cells(table)
    columns = sorted({(c["delta"], c["mu"], c["eps"]) for c in cells})
    friction = cells[0]["friction"]
    # one top-level call per column and solver: the same two compiled programs for every
    # column, checked on the host and free of host callbacks (so the persistent cache keeps
    # them for the next `vmj table`)
    solved = {}
    for delta, mu, eps in columns:
        model = paper_model(friction, delta, eps, mu)
        solved[delta, mu, eps] = (
            turning_points(model, PAPER["a0"], n, EnergyBalance()),
            turning_points(model, PAPER["a0"], n),
        )
    out = []
    for cell in cells:
        energy, exact = solved[cell["delta"], cell["mu"], cell["eps"]]
        k = cell["k"] - 1
        out.append(
            {
                **{key: cell[key] for key in ("k", "mu", "eps", "delta")},
                **{key: cell[key] for key in cell if key.startswith("paper_") or key == "note"},
                "energy_cm": float(abs(np.asarray(energy.positions)[k]) * 100),
                "energy_crossed": bool(np.asarray(energy.crossed)[k]),
                "exact_cm": float(abs(np.asarray(exact.positions)[k]) * 100),
                "exact_crossed": bool(np.asarray(exact.crossed)[k]),
            }
        )
    return out
