"""Every bad input answered: a table of bad inputs across every `vmj` command (and the Python API
where the same parameter enters). Each must give exactly one line on stderr, `vmj: error: ...`,
naming the parameter as the user spelled it (and its allowed range where it has one), exit status
2, nothing on stdout, no traceback and no output file.

The command line runs in-process (`vmj.cli.main`) for speed; a few cases run as subprocesses to
show that no traceback reaches the terminal. Every case is refused before any computation, so
the whole table runs in seconds.
"""

from __future__ import annotations

import os
import subprocess
import sys

import cli_args
import jax
import numpy as np
import pytest

import vmj
from vmj.cli import main

VM = ["decay", "variable-mass", *cli_args.VARIABLE_MASS, "--n", "3"]
ROPE = ["decay", "rope", *cli_args.ROPE]
SS = ["stick-slip", "--eps", "6.3", "--Omega", "0.7"]
LIN = ["linear", "--m", "1", "--c", "1", "--k", "14.5"]
SWEEP = [
    "sweep",
    "variable-mass",
    "--eps",
    "0:1:3",
    "--mu",
    "0:10:3",
    "--set",
    "m0=5,c=4900,delta=3,FT=14.7,a0=0.06",
    "--method",
    "energy",
]
TABLE1 = os.path.join("fits", "data", "table1_mu9_eps0.csv")
SENS = ["sensitivity", "variable-mass", *cli_args.VARIABLE_MASS, "--n", "3"]
FIT = ["--model", "oscillator"]


def put(argv, flag, value):
    """`argv` with `flag`'s value replaced (or the option added)."""
    argv = list(argv)
    if flag in argv:
        argv[argv.index(flag) + 1] = value
    else:
        argv += [flag, value]
    return argv


#: a sweep that the smoothed solver takes about 900 s for (22500 points x 2000 turning points)
SLOW_SWEEP = put(put(SWEEP, "--eps", "0:1:150"), "--mu", "0:10:150") + ["--n", "2000"]


def drop(argv, flag):
    argv = list(argv)
    i = argv.index(flag)
    del argv[i : i + 2]
    return argv


def with_set(argv, text):
    return put(argv, "--set", text)


RANGE = {
    "m0": "> 0 [kg]",
    "c": "> 0 [N/m]",
    "eps": "in [0, 1]",
    "mu": ">= 0 [kg/s]",
    "FT": ">= 0 [N]",
    "a0": "> 0 [m]",
}


def parameter_cases():
    """Zero, negative, NaN, infinite and absurdly large values of every decay parameter."""
    cases = []
    for flag, values in {
        "--m0": ["0", "-1", "nan", "inf", "1e300"],
        "--c": ["0", "-1", "nan", "-inf", "1e300"],
        "--delta": ["nan", "inf", "-1e300", "abc"],
        "--eps": ["-0.1", "1.5", "nan", "inf", "1e300"],
        "--mu": ["-1", "nan", "inf", "1e300"],
        "--FT": ["-1", "NaN", "inf", "1e300"],
        "--a0": ["0", "-0.06", "nan", "inf", "1e300", "1e-300"],
    }.items():
        for value in values:
            try:
                number = float(value)
            except ValueError:
                number = None
            if number is None:
                want = ["argument " + flag, "not a number"]
            elif not np.isfinite(number):
                want = ["argument " + flag, "not a finite number"]
            elif abs(number) > 1e20:
                want = ["argument " + flag, "magnitude at most 1e+20"]
            elif 0 < abs(number) < 1e-20:
                want = ["argument " + flag, "must be 0 or a number of magnitude at least 1e-20"]
            else:
                want = [flag + " must be finite and " + RANGE[flag[2:]]]
            cases.append((f"vm{flag}={value}", put(VM, flag, value), want))
    return cases


CASES = parameter_cases() + [
    # -- decay variable-mass: the friction law, the count, the method ---------------------------
    ("vm --f<0", put(drop(VM, "--FT"), "--f", "-0.3"), ["--f must be finite and >= 0"]),
    ("vm --f nan", put(drop(VM, "--FT"), "--f", "nan"), ["argument --f", "not a finite"]),
    ("vm --g 0", put(put(drop(VM, "--FT"), "--f", "0.3"), "--g", "0"), ["--g must be", "> 0"]),
    ("vm --g<0", put(put(drop(VM, "--FT"), "--f", "0.3"), "--g", "-9.81"), ["--g must be"]),
    ("vm --g inf", put(put(drop(VM, "--FT"), "--f", "0.3"), "--g", "inf"), ["argument --g"]),
    ("vm --g with --FT", put(VM, "--g", "9.81"), ["--g goes with --f"]),
    ("vm --FT and --f", put(VM, "--f", "0.3"), ["argument --f", "not allowed with"]),
    ("vm no friction law", drop(VM, "--FT"), ["one of the arguments --FT --f is required"]),
    ("vm --n 0", put(VM, "--n", "0"), ["argument --n", "integer >= 1"]),
    ("vm --n<0", put(VM, "--n", "-3"), ["argument --n", "integer >= 1"]),
    ("vm --n 2.5", put(VM, "--n", "2.5"), ["argument --n", "not an integer"]),
    ("vm --n 1e9", put(VM, "--n", "1e9"), ["argument --n", "not an integer"]),
    (
        "vm --n huge",
        put(VM, "--n", "1000000000"),
        ["--n 1000000000 turning points: refused above 1e+05", "--force"],
    ),
    ("vm --method", put(VM, "--method", "rk4"), ["argument --method", "invalid choice"]),
    ("vm unknown option", VM + ["--bogus", "1"], ["unrecognized arguments: --bogus"]),
    (
        "vm option twice",
        VM + ["--m0", "6"],
        ["argument --m0: given twice (5 and 6); give it once"],
    ),
    ("vm missing", VM[:4], ["required: --eps, --mu, --delta, --c, --a0"]),
    ("vm empty value", put(VM, "--mu", ""), ["argument --mu", "not a number"]),
    # -- decay rope -------------------------------------------------------------------------------
    ("rope --m 0", put(ROPE, "--m", "0"), ["--m must be finite and > 0 [kg] (got 0 kG s^2/m)"]),
    ("rope --m<0", put(ROPE, "--m", "-2"), ["--m must be finite and > 0"]),
    ("rope --m nan", put(ROPE, "--m", "nan"), ["argument --m", "not a finite"]),
    ("rope --A 0", put(ROPE, "--A", "0"), ["--A must be finite and > 0 [m^2]"]),
    ("rope --e 0", put(ROPE, "--e", "0"), ["--e must be finite and > 0 [Pa]"]),
    ("rope --e<0", put(ROPE, "--e", "-1"), ["--e must be"]),
    ("rope --d<0", put(ROPE, "--d", "-1"), ["--d must be finite and >= 0"]),
    ("rope --T<0", put(ROPE, "--T", "-4"), ["--T must be finite and >= 0 [Pa]"]),
    ("rope --T 1e300", put(ROPE, "--T", "1e300"), ["argument --T", "magnitude"]),
    ("rope --l0 0", put(ROPE, "--l0", "0"), ["--l0 must be finite and > 0 [m]"]),
    ("rope --l0<0", put(ROPE, "--l0", "-10"), ["--l0 must be"]),
    ("rope --u nan", put(ROPE, "--u", "nan"), ["argument --u", "not a finite"]),
    ("rope --a0 0", put(ROPE, "--a0", "0"), ["--a0 must be finite and > 0 [m] (got 0 cm)"]),
    ("rope --a0<0", put(ROPE, "--a0", "-1"), ["--a0 must be"]),
    ("rope --t1 0", put(ROPE, "--t1", "0"), ["--t1 must be finite and > 0 [s]"]),
    ("rope --t1<0", put(ROPE, "--t1", "-1"), ["--t1 must be"]),
    ("rope --t1 past lifetime", put(put(ROPE, "--u", "3"), "--t1", "4"), ["--t1 must be below"]),
    ("rope --t1 huge", put(ROPE, "--t1", "1e6"), ["half-swings before --t1", "--force"]),
    (
        "rope brake order",
        ROPE + ["--brake", "0.05", "0.01"],
        ["--brake T_STOP must be > --brake T_BRAKE [s]"],
    ),
    (
        "rope t_stop order",
        ROPE + ["--t_brake", "0.05", "--t_stop", "0.05"],
        ["--t_stop must be > --t_brake [s]"],
    ),
    (
        "rope --brake and --t_brake",
        ROPE + ["--brake", "0", "1", "--t_brake", "0"],
        ["--brake or --t_brake"],
    ),
    (
        "rope --brake twice",
        ROPE + ["--brake", "0", "1", "--brake", "0", "2"],
        ["--brake: given twice"],
    ),
    ("rope --t_brake alone", ROPE + ["--t_brake", "0.01"], ["--t_brake goes with --t_stop"]),
    (
        "rope kbm brake",
        ROPE + ["--method", "kbm", "--brake", "0", "0.05"],
        ["--method kbm needs a constant speed"],
    ),
    ("rope --units", put(ROPE, "--units", "imperial"), ["argument --units", "invalid choice"]),
    ("rope missing --t1", drop(ROPE, "--t1"), ["required: --t1"]),
    # -- stick-slip -------------------------------------------------------------------------------
    ("ss --eps 1", put(SS, "--eps", "1"), ["--eps must be finite and > 1"]),
    ("ss --eps<1", put(SS, "--eps", "0.5"), ["--eps must be"]),
    ("ss --eps nan", put(SS, "--eps", "nan"), ["argument --eps", "not a finite"]),
    ("ss --eps huge", put(SS, "--eps", "1e9"), ["--eps 1e+09 means", "--force"]),
    ("ss --Omega 0", put(SS, "--Omega", "0"), ["--Omega must be finite and > 0"]),
    ("ss --Omega<0", put(SS, "--Omega", "-2"), ["--Omega must be"]),
    ("ss --Omega inf", put(SS, "--Omega", "inf"), ["argument --Omega", "not a finite"]),
    ("ss --smoothing exact", SS + ["--smoothing", "1e-3"], ["--smoothing applies to --method"]),
    (
        "ss --smoothing<0",
        SS + ["--method", "smooth", "--smoothing", "-1"],
        ["--smoothing must be finite and > 0"],
    ),
    ("ss --method", SS + ["--method", "euler"], ["argument --method", "invalid choice"]),
    # -- linear -----------------------------------------------------------------------------------
    ("lin --m 0", put(LIN, "--m", "0"), ["--m must be finite and > 0 [kg]"]),
    ("lin --m<0", put(LIN, "--m", "-1"), ["--m must be"]),
    ("lin --c<0", put(LIN, "--c", "-1"), ["--c must be finite and >= 0 [N s/m]"]),
    ("lin --k 0", put(LIN, "--k", "0"), ["--k must be finite and > 0 [N/m]"]),
    ("lin --k 1e300", put(LIN, "--k", "1e300"), ["argument --k", "magnitude"]),
    ("lin --F0 alone", LIN + ["--F0", "1"], ["--F0 goes with --p"]),
    ("lin --p alone", LIN + ["--p", "15"], ["--p goes with --F0"]),
    ("lin --p 0", LIN + ["--F0", "1", "--p", "0"], ["--p must be finite and > 0 [1/s]"]),
    ("lin --k twice", LIN + ["--k", "15"], ["argument --k: given twice"]),
    ("lin --x0 nan", LIN + ["--x0", "nan"], ["argument --x0", "not a finite"]),
    ("lin --v0 inf", LIN + ["--v0", "-inf"], ["argument --v0", "not a finite"]),
    # -- table ------------------------------------------------------------------------------------
    ("table 5", ["table", "5"], ["argument N", "invalid choice"]),
    ("table abc", ["table", "abc"], ["argument N", "invalid int"]),
    ("table no N", ["table"], ["required: N"]),
    # -- sweep: axes ------------------------------------------------------------------------------
    ("sweep axis two parts", put(SWEEP, "--eps", "0:1"), ["--eps must be start:stop:count"]),
    ("sweep axis four parts", put(SWEEP, "--eps", "0:1:2:3"), ["--eps must be start:stop:count"]),
    ("sweep axis letters", put(SWEEP, "--eps", "a:b:3"), ["--eps: not a number: 'a'"]),
    ("sweep axis count 0", put(SWEEP, "--eps", "0:1:0"), ["--eps: count must be"]),
    ("sweep axis count x", put(SWEEP, "--eps", "0:1:x"), ["--eps: count must be"]),
    ("sweep axis count 1", put(SWEEP, "--eps", "0:1:1"), ["--eps: count must be"]),
    ("sweep axis empty", put(SWEEP, "--eps", ""), ["--eps: not a number: ''"]),
    ("sweep axis empty item", put(SWEEP, "--eps", "0,,1"), ["--eps: not a number: ''"]),
    ("sweep axis nan", put(SWEEP, "--eps", "nan:1:3"), ["--eps: not a finite number"]),
    (
        "sweep axis huge value",
        put(SWEEP, "--mu", "0,1e300"),
        ["--mu: must be a number of magnitude at most 1e+20"],
    ),
    (
        "sweep axis tiny value",
        put(SWEEP, "--mu", "0,1e-300"),
        ["--mu: must be 0 or a number of magnitude at least 1e-20"],
    ),
    (
        "sweep axis out of range",
        put(SWEEP, "--eps", "0:2:3"),
        ["--eps must be finite and in [0, 1] [-] (got 2)"],
    ),
    ("sweep axis negative", put(SWEEP, "--mu", "-1,0"), ["--mu must be finite and >= 0 [kg/s]"]),
    (
        "sweep axis twice",
        SWEEP + ["--eps", "0:1:2"],
        ["argument --eps: given twice (0:1:3 and 0:1:2)"],
    ),
    ("sweep unknown axis", SWEEP + ["--bogus", "0:1:2"], ["unrecognized arguments: --bogus"]),
    (
        "sweep no axis",
        ["sweep", "variable-mass", "--set", "m0=5,c=4900,delta=3,eps=0,mu=2,FT=1,a0=0.06"],
        ["give at least one axis"],
    ),
    # -- sweep: --set -----------------------------------------------------------------------------
    ("sweep set no =", with_set(SWEEP, "m0"), ["--set takes NAME=VALUE pairs"]),
    ("sweep set no name", with_set(SWEEP, "=5"), ["--set: a value without a name"]),
    ("sweep set twice", with_set(SWEEP, "m0=5,m0=6"), ["--set gives m0 twice"]),
    (
        "sweep set alias twice",
        with_set(SWEEP, "m0=5,c=4900,delta=3,FT=1,F=2,a0=0.06"),
        ["--set gives FT twice"],
    ),
    (
        "sweep set text",
        with_set(SWEEP, "m0=abc,c=4900,delta=3,FT=14.7,a0=0.06"),
        ["--set m0: not a number: 'abc'"],
    ),
    (
        "sweep set unknown",
        with_set(SWEEP, "m0=5,bogus=1"),
        ["--set: unknown parameter 'bogus' of variable-mass (known: eps, mu, delta, m0"],
    ),
    (
        "sweep set axis",
        with_set(SWEEP, "m0=1:2:3,c=4900,delta=3,FT=14.7,a0=0.06"),
        ["--set m0 has 3 values; --set takes one value; give --m0 for an axis"],
    ),
    (
        "sweep set a0 axis",
        with_set(SWEEP, "m0=5,c=4900,delta=3,FT=14.7,a0=0.01:0.02:2"),
        ["--set a0 has 2 values; --set takes one value; an initial condition is not swept"],
    ),
    (
        "sweep set and axis",
        with_set(SWEEP, "eps=0,m0=5,c=4900,delta=3,FT=14.7,a0=0.06"),
        ["eps is given both as --eps and in --set"],
    ),
    (
        "sweep set a0 missing",
        with_set(SWEEP, "m0=5,c=4900,delta=3,FT=14.7"),
        ["missing --set a0= (initial deflection [m])"],
    ),
    (
        "sweep set a0 0",
        with_set(SWEEP, "m0=5,c=4900,delta=3,FT=14.7,a0=0"),
        ["--set a0 must be finite and > 0 [m]"],
    ),
    (
        "sweep set m0<0",
        with_set(SWEEP, "m0=-5,c=4900,delta=3,FT=14.7,a0=0.06"),
        ["--set m0 must be finite and > 0 [kg]"],
    ),
    # -- sweep: size, outputs, options ------------------------------------------------------------
    (
        "sweep absurd size",
        put(put(SWEEP, "--eps", "0:1:100000"), "--mu", "0:10:100000"),
        ["sweep of 1e+10 points", "refused above 1 GiB", "--force"],
    ),
    (
        "sweep absurd axis",
        put(SWEEP, "--eps", "0:1:100000000000"),
        ["--eps has 1e+11 values", "--force"],
    ),
    (
        "sweep slow method",
        put(SLOW_SWEEP, "--method", "smooth"),
        ["takes about", "--method smooth", "--force"],
    ),
    ("sweep --n 0", SWEEP + ["--n", "0"], ["argument --n", "integer >= 1"]),
    ("sweep --chunk-size 0", SWEEP + ["--chunk-size", "0"], ["argument --chunk-size"]),
    (
        "sweep --plot axes",
        [
            "sweep",
            "variable-mass",
            "--mu",
            "0:10:3",
            "--c",
            "1,2",
            "--set",
            "m0=5,eps=0,delta=3,FT=14.7,a0=0.06",
            "--plot",
            "{tmp}/swings.png",
        ],
        ["--plot and --error-plot need the axes --eps and --mu", "(got --mu, --c)"],
    ),
    (
        "sweep --plot one eps",
        put(SWEEP, "--eps", "0.5") + ["--plot", "{tmp}/swings.png"],
        ["need at least 2 values of --eps and of --mu"],
    ),
    (
        "sweep --plot format",
        SWEEP + ["--plot", "{tmp}/swings.xyz"],
        ["argument --plot", "unknown figure format 'xyz'"],
    ),
    (
        "sweep --out missing dir",
        SWEEP + ["--out", "{tmp}/no/such/dir/s.csv"],
        ["argument --out", "does not exist"],
    ),
    ("sweep --out a directory", SWEEP + ["--out", "{tmp}"], ["argument --out", "is a directory"]),
    ("sweep --out empty", SWEEP + ["--out", ""], ["argument --out", "empty"]),
    (
        "sweep --out and --plot one file",
        SWEEP + ["--out", "{tmp}/s.png", "--plot", "{tmp}/s.png"],
        ["--out and --plot name the same file", "give two paths"],
    ),
    (
        "sweep --netcdf and --out one file",
        SWEEP + ["--netcdf", "{tmp}/s.nc", "--out", "{tmp}/./s.nc"],
        ["--out and --netcdf name the same file"],
    ),
    (
        "sweep --netcdf missing dir",
        SWEEP + ["--netcdf", "{tmp}/no/s.nc"],
        ["argument --netcdf", "does not exist"],
    ),
    (
        "sweep rope T<0",
        ["sweep", "rope", "--T", "-1,0", "--set", "m=2,A=1.74,e=0.8e6,l0=10,u=0,a0=1"],
        ["--T must be finite and >= 0"],
    ),
    (
        "sweep rope brake alone",
        ["sweep", "rope", "--T", "0,1", "--set", "m=2,A=1.74,e=0.8e6,l0=10,u=0,a0=1,t_brake=1"],
        ["--set t_brake goes with --t_stop"],
    ),
    (
        "sweep rope t_brake axis past t_stop",
        ["sweep", "rope", "--T", "0,1", "--t_brake", "0,2"]
        + ["--set", "m=2,A=1.74,e=0.8e6,l0=10,u=0,a0=1,t_stop=1"],
        ["--set t_stop must be > --t_brake [s] (got 1 <= 2)"],
    ),
    (
        "sweep rope a0 0",
        [
            "sweep",
            "rope",
            "--T",
            "0,1",
            "--set",
            "m=2,A=1.74,e=0.8e6,l0=10,u=0,a0=0",
            "--units",
            "technical",
        ],
        ["--set a0 must be finite and > 0"],
    ),
    (
        "sweep rope energy u",
        ["sweep", "rope", "--T", "0,1", "--u", "0,3", "--set", "m=2,A=1.74,e=0.8e6,l0=10,a0=1"]
        + ["--method", "energy"],
        ["--method energy", "needs --u 0 (got 3)"],
    ),
    (
        "sensitivity rope kbm",
        ["sensitivity", "rope", *cli_args.ROPE, "--wrt", "T", "--method", "kbm"],
        ["argument --method", "invalid choice: 'kbm'"],
    ),
    (
        "sweep stick-slip eps",
        ["sweep", "stick-slip", "--eps", "0.5:2:3", "--set", "Omega=1"],
        ["--eps must be finite and > 1"],
    ),
    (
        "sweep stick-slip missing",
        ["sweep", "stick-slip", "--eps", "2:3:3"],
        ["missing --Omega/--set Omega="],
    ),
    (
        "sweep linear m",
        ["sweep", "linear", "--m", "0:1:3", "--set", "c=1,k=1"],
        ["--m must be finite and > 0 [kg] (got 0)"],
    ),
    (
        "sweep linear x0",
        ["sweep", "linear", "--m", "1:2:3", "--set", "c=1,k=1,x0=nan"],
        ["--set x0: not a finite number"],
    ),
    ("sweep unknown model", ["sweep", "pendulum"], ["argument MODEL", "invalid choice"]),
    # -- sensitivity ------------------------------------------------------------------------------
    ("sens --wrt unknown", SENS + ["--wrt", "bogus"], ["--wrt: unknown parameter 'bogus'"]),
    ("sens --wrt empty", SENS + ["--wrt", ","], ["--wrt must name at least one parameter"]),
    ("sens --wrt twice", SENS + ["--wrt", "FT,F"], ["--wrt names FT twice"]),
    ("sens --wrt g", SENS + ["--wrt", "g"], ["--wrt g: --g is not part of the model"]),
    ("sens --wrt missing", SENS, ["required: --wrt"]),
    ("sens --mu<0", put(SENS, "--mu", "-2") + ["--wrt", "mu"], ["--mu must be finite and >= 0"]),
    (
        "sens --plot dir",
        SENS + ["--wrt", "mu", "--plot", "{tmp}/no/s.png"],
        ["argument --plot", "does not exist"],
    ),
    (
        "sens stick-slip a0",
        ["sensitivity", "stick-slip", "--eps", "6.3", "--Omega", "0.7", "--wrt", "a0"],
        ["--wrt: unknown parameter 'a0' of stick-slip"],
    ),
    (
        "sens stick-slip eps",
        ["sensitivity", "stick-slip", "--eps", "1", "--Omega", "0.7", "--wrt", "eps"],
        ["--eps must be finite and > 1"],
    ),
    (
        "sens rope t1",
        ["sensitivity", "rope"] + put(ROPE[2:], "--t1", "-1") + ["--wrt", "T"],
        ["--t1 must be"],
    ),
    # -- table and figure paths -------------------------------------------------------------------
    (
        "table --plot missing dir",
        ["table", "1", "--plot", "{tmp}/no/t.png"],
        ["argument --plot", "does not exist"],
    ),
    (
        "table --plot a directory",
        ["table", "1", "--plot", "{tmp}"],
        ["argument --plot", "is a directory"],
    ),
    (
        "table --plot format",
        ["table", "1", "--plot", "{tmp}/t.docx"],
        ["argument --plot", "unknown figure format"],
    ),
    # -- fit: files and options -------------------------------------------------------------------
    ("fit missing file", ["fit", "{tmp}/missing.csv"] + FIT, ["argument FILE", "no such file"]),
    ("fit a directory", ["fit", "{tmp}"] + FIT, ["argument FILE", "is a directory"]),
    ("fit empty name", ["fit", ""] + FIT, ["argument FILE", "empty file name"]),
    ("fit empty file", ["fit", "{tmp}/empty.csv"] + FIT, ["empty.csv", "empty"]),
    ("fit binary file", ["fit", "{tmp}/binary.csv"] + FIT, ["binary.csv", "not a text file"]),
    # (a file's encoding is the reader's to judge: Windows-1252 read, the bad cell named)
    ("fit latin-1 file", ["fit", "{tmp}/latin.csv"] + FIT, ["latin.csv", "line 3", "'9\u00e9'"]),
    ("fit header only", ["fit", "{tmp}/header.csv"] + FIT, ["header.csv", "no data rows"]),
    ("fit one row", ["fit", "{tmp}/onerow.csv"] + FIT, ["onerow.csv", "only 1 data row"]),
    ("fit non-numeric", ["fit", "{tmp}/text.csv"] + FIT, ["text.csv", "line 3", "amplitude"]),
    ("fit NaN row", ["fit", "{tmp}/nan.csv"] + FIT, ["nan.csv", "line 3", "not a finite"]),
    ("fit BOM bad row", ["fit", "{tmp}/bom.csv"] + FIT, ["bom.csv", "line 3", "'x'"]),
    ("fit CRLF bad row", ["fit", "{tmp}/crlf.csv"] + FIT, ["crlf.csv", "line 3", "'x'"]),
    (
        "fit --set nan",
        ["fit", "{tmp}/good.csv", "--model", "oscillator", "--set", "zeta=nan"],
        ["--set zeta: not a finite number"],
    ),
    (
        "fit --set 1e300",
        ["fit", "{tmp}/good.csv", "--model", "oscillator", "--set", "zeta=1e300"],
        ["--set zeta", "magnitude"],
    ),
    (
        "fit --set no =",
        ["fit", "{tmp}/good.csv", "--model", "oscillator", "--set", "zeta"],
        ["--set takes NAME=VALUE"],
    ),
    (
        "fit --fit empty",  # (was the default set)
        ["fit", "{tmp}/good.csv", "--fit", ""] + FIT,
        ["--fit NAME", "nothing to identify"],
    ),
    (
        "fit --adam-steps without adam",
        ["fit", "{tmp}/good.csv", "--adam-steps", "10"] + FIT,
        ["--adam-steps applies to --optimizer adam"],
    ),
    (
        "fit --adam-steps 0",
        ["fit", "{tmp}/good.csv", "--optimizer", "adam", "--adam-steps", "0"] + FIT,
        ["argument --adam-steps", "integer >= 1"],
    ),
    (
        "fit series of amplitudes",  # (the default set's note came first: two lines)
        ["fit", "{tmp}/good.csv", "--residuals", "series"] + FIT,
        ["good.csv", "needs a raw signal"],
    ),
    (
        "fit a peak table --decay all",  # (was "found only 0 turning points ... --signal-col")
        ["fit", "{tmp}/good.csv", "--decay", "all"] + FIT,
        ["good.csv", "a table of turning points", "--decay", "leave it out"],
    ),
    (
        "fit too few peaks",
        ["fit", "{tmp}/three.csv"] + FIT,
        ["three.csv", "3 turning points are too few", "--fit"],
    ),
    (
        "fit omega without times",
        ["fit", "{tmp}/three.csv", "--fit", "omega,zeta"] + FIT,
        ["omega can only be fitted from a record with times", "--fit"],
    ),
    (
        "fit --model",
        ["fit", "{tmp}/good.csv", "--model", "spring"],
        ["argument --model", "invalid choice"],
    ),
    (
        "fit --plot dir",
        ["fit", "{tmp}/good.csv", "--plot", "{tmp}/no/f.png"] + FIT,
        ["argument --plot", "does not exist"],
    ),
    # -- the command line itself ------------------------------------------------------------------
    ("no command", [], ["required: COMMAND"]),
    ("unknown command", ["dcay"], ["argument COMMAND", "invalid choice: 'dcay'"]),
    (
        "--cache-dir a file",
        ["--cache-dir", "{tmp}/good.csv"] + VM,
        ["--cache-dir", "cannot use", "good.csv"],
    ),
]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bad")
    content = {
        "empty.csv": b"",
        "binary.csv": bytes(range(256)) * 4,
        "latin.csv": b"k,amplitude\n1,10\n2,9\xe9\n",
        "header.csv": b"k,amplitude\n",
        "onerow.csv": b"k,amplitude\n1,10.0\n",
        "text.csv": b"k,amplitude\n1,10.0\n2,abc\n3,8.6\n4,7.9\n5,7.3\n",
        "nan.csv": b"k,amplitude\n1,10.0\n2,nan\n3,8.6\n4,7.9\n5,7.3\n",
        "bom.csv": b"\xef\xbb\xbfk,amplitude\n1,10.0\n2,x\n3,8.6\n",
        "crlf.csv": b"k,amplitude\r\n1,10.0\r\n2,x\r\n3,8.6\r\n",
        "good.csv": b"k,amplitude\n1,10.0\n2,9.3\n3,8.62\n4,7.95\n5,7.3\n6,6.67\n",
        "three.csv": b"k,amplitude\n0,10.0\n1,9.3\n2,8.62\n",
    }
    for name, data in content.items():
        (tmp / name).write_bytes(data)
    return tmp


def run_cli(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as e:  # argument errors exit from argparse
        code = e.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_the_table_is_large_and_covers_every_command():
    assert len(CASES) >= 100
    assert len({name for name, _, _ in CASES}) == len(CASES)
    commands = {argv[0] for _, argv, _ in CASES if argv and not argv[0].startswith("-")}
    assert commands >= {"decay", "table", "sweep", "sensitivity", "stick-slip", "linear", "fit"}


@pytest.mark.parametrize("name,argv,want", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_clear_line(name, argv, want, files, capsys):
    argv = [a.replace("{tmp}", str(files)) for a in argv]
    before = sorted(os.listdir(files))
    code, out, err = run_cli(argv, capsys)
    assert code == 2, err
    assert out == ""
    assert err.startswith("vmj: error: ") and err.endswith("\n") and err.count("\n") == 1, err
    assert "Traceback" not in err
    for text in want:
        assert text in err, err
    assert sorted(os.listdir(files)) == before  # no output (or temporary) file left behind


@pytest.mark.parametrize(
    "argv",
    [
        ["decay", "variable-mass", "--m0", "nan"],  # an argument error
        put(VM, "--FT", "-1"),  # a value error after parsing
        ["fit", "{tmp}/header.csv", "--model", "oscillator"],  # a bad input file
    ],
)
def test_no_traceback_reaches_the_terminal(argv, files):
    argv = [a.replace("{tmp}", str(files)) for a in argv]
    run = subprocess.run([sys.executable, "-m", "vmj.cli", *argv], capture_output=True, text=True)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.startswith("vmj: error: ") and run.stderr.count("\n") == 1, run.stderr
    assert "Traceback" not in run.stderr


# -- the same parameters through the Python API: ValueError naming the parameter ---------------
def _vm(**change):
    p = dict(m0=5.0, c=4900.0, delta=3.0, eps=0.0, mu=2.0, friction=vmj.Coulomb(14.7))
    p.update(change)
    return p


API = [
    ("m0", lambda: vmj.VariableMass(**_vm(m0=0.0)), "m0 must be finite and > 0"),
    ("c", lambda: vmj.VariableMass(**_vm(c=-1.0)), "c must be finite and > 0"),
    ("eps", lambda: vmj.VariableMass(**_vm(eps=1.5)), "eps must be finite and in [0, 1]"),
    ("mu", lambda: vmj.VariableMass(**_vm(mu=float("nan"))), "mu must be finite"),
    ("delta", lambda: vmj.VariableMass(**_vm(delta=float("inf"))), "delta must be finite"),
    ("F", lambda: vmj.Coulomb(-1.0), "F must be finite and >= 0"),
    ("f", lambda: vmj.MassProportional(-0.3), "f must be finite and >= 0"),
    ("g", lambda: vmj.MassProportional(0.3, 0.0), "g must be finite and > 0"),
    ("a0", lambda: vmj.turning_points(vmj.VariableMass(**_vm()), 0.0, 3), "a0 must be finite"),
    ("n", lambda: vmj.turning_points(vmj.VariableMass(**_vm()), 0.06, 0), "n must be an integer"),
    (
        "a0 complex",
        lambda: vmj.turning_points(vmj.VariableMass(**_vm()), 1 + 1j, 3),
        "a real number",
    ),
    ("a0 text", lambda: vmj.turning_points(vmj.VariableMass(**_vm()), "x", 3), "a0 must be"),
    (
        "a0 array",  # was taken and broke the result's shapes (count (2,), message a TypeError)
        lambda: vmj.turning_points(vmj.VariableMass(**_vm()), np.array([0.06, 0.03]), 3),
        "a0 must be a scalar (got shape",
    ),
    (
        "a0 array, energy balance",  # was an error from inside lax.scan
        lambda: vmj.turning_points(
            vmj.VariableMass(**_vm()), np.array([0.06]), 3, vmj.EnergyBalance()
        ),
        "a0 must be a scalar (got shape",
    ),
    (
        "complex field",  # the real part was kept with only a ComplexWarning
        lambda: vmj.Coulomb(np.complex128(14.7 + 1e-20j)),
        "vmj's parameters are real numbers",
    ),
    (
        "n traced",  # was "n must be an integer >= 1 (got JitTracer(~int64[]))"
        lambda: jax.jit(lambda n: vmj.turning_points(vmj.VariableMass(**_vm()), 0.06, n))(3),
        "n must be a static integer >= 1",
    ),
    (
        "kbm a0 array",  # was 'Gradient only defined for scalar-output functions'
        lambda: vmj.kbm_amplitude(vmj.Rope.paper(u=3.0, T=4.0), [0.01, 0.04], [0.0, 1.0]),
        "a0 must be a scalar (got shape",
    ),
    (
        "t1 array",  # was 'Cannot stack arrays with different numbers of dimensions'
        lambda: vmj.simulate(vmj.VariableMass(**_vm()), -0.06, 0.0, [0.1, 0.2]),
        "t1 must be a scalar (got shape",
    ),
    (
        "n beyond memory",  # the process was killed for want of memory (n = 10**9, 24 GiB)
        lambda: vmj.turning_points(vmj.VariableMass(**_vm()), 0.06, 10**15),
        "the results of n = 1000000000000000: about 3.2e.07 GB, more than the",
    ),
    (
        "n_save beyond memory",
        lambda: vmj.simulate(vmj.VariableMass(**_vm()), -0.06, 0.0, 0.1, n_save=10**15),
        "the results of n_save = 1000000000000000: about",
    ),
    ("Omega", lambda: vmj.StickSlip(6.3, 0.0), "Omega must be finite and > 0"),
    ("stick-slip eps", lambda: vmj.StickSlip(1.0, 1.0), "eps must be finite and > 1"),
    (
        "T",
        lambda: vmj.Rope(2.0, 1e-4, 1e11, 0.0, 0.0, -1.0, vmj.ConstantSpeed(10.0)),
        "T must be finite and >= 0",
    ),
    ("l0", lambda: vmj.ConstantSpeed(0.0), "l0 must be finite and > 0"),
    ("t_stop", lambda: vmj.Braking(10.0, 1.0, 2.0, 1.0), "t_stop must be > t_brake [s]"),
    (
        "grid t_brake past t_stop",
        lambda: vmj.grid(
            vmj.Rope(2.0, 1e-4, 1e11, 0.0, 0.0, 0.0, vmj.Braking(10.0, 1.0, 0.5, 1.0)),
            t_brake=[0.0, 2.0],
        ),
        "t_stop must be > t_brake [s]",
    ),
    ("k", lambda: vmj.LinearOscillator(1.0, 1.0, 0.0), "k must be finite and > 0"),
    (
        "grid axis",
        lambda: vmj.grid(vmj.VariableMass(**_vm()), eps=[0.0, 2.0]),
        "eps must be finite and in [0, 1]",
    ),
    (
        "grid axis of strings",  # was taken: eps = [0.1, 0.2]
        lambda: vmj.grid(vmj.VariableMass(**_vm()), eps=["0.1", "0.2"]),
        "each value of grid axis eps must be a number, not an array holding booleans or strings",
    ),
    (
        "grid axis of booleans",  # was taken: F = [1.0, 1.0]
        lambda: vmj.grid(vmj.VariableMass(**_vm()), F=[True, True]),
        "each value of grid axis F must be a number",
    ),
    (
        "grid name",
        lambda: vmj.grid(vmj.VariableMass(**_vm()), bogus=[0.0]),
        "'bogus' is not a parameter",
    ),
    (
        "sweep chunk",
        lambda: vmj.sweep(
            vmj.turning_points,
            vmj.grid(vmj.VariableMass(**_vm()), eps=[0.0]),
            a0=0.06,
            n=2,
            chunk_size=0,
            solver=vmj.EnergyBalance(),
        ),
        "chunk_size must be an integer >= 1",
    ),
    (
        "sensitivity wrt",
        lambda: vmj.sensitivity(
            lambda m, a0, n: vmj.turning_points(m, a0, n).amplitudes,
            vmj.VariableMass(**_vm()),
            ["bogus"],
            a0=0.06,
            n=2,
        ),
        "'bogus' is not a parameter",
    ),
    ("fit outlier_sigma", lambda: _fit(outlier_sigma=0.0), "outlier_sigma must be a finite number"),
    ("fit max_steps", lambda: _fit(max_steps=0), "max_steps must be an integer >= 1"),
    ("fit adam_steps", lambda: _fit(adam_steps=-1), "adam_steps must be an integer >= 1"),
    ("fit bounds", lambda: _fit(bounds={"FT": 3.0}), "bounds['FT'] must be a pair"),
    ("fit given", lambda: _fit(given=[1, 2]), "given: a dict of parameter values"),
    ("fit free", lambda: _fit(free="mu,bogus"), "unknown parameter 'bogus'"),
    ("fit twice", lambda: _fit(twice=True, shared=("FT", "mu")), "is given twice"),
]


def _fit(**kw):
    """`fits.fit` of the table-1 record with the keyword arguments `kw` (refused before any
    computation)."""
    import fits

    record = fits.read_record(os.path.join(os.path.dirname(__file__), "..", TABLE1))
    args = {"free": ("FT", "mu"), "given": dict(m0=5, c=4900, delta=3, eps=0), **kw}
    records = [record, fits.read_record(record.source)] if args.pop("twice", False) else record
    return fits.fit(records, "variable-mass", args.pop("free"), **args)


def test_a_concrete_integer_array_is_an_integer():
    """`n = jnp.array(3)` (a concrete 0-d integer array, e.g. from `jnp.argmax`) was refused as
    not an integer."""
    m, energy = vmj.VariableMass(**_vm()), vmj.EnergyBalance()
    assert vmj.turning_points(m, 0.06, np.int64(3), energy).positions.shape == (3,)
    assert vmj.turning_points(m, 0.06, jax.numpy.array(3), energy).positions.shape == (3,)


@pytest.mark.parametrize("name,call,message", API, ids=[a[0] for a in API])
def test_python_api_raises_value_error_naming_the_parameter(name, call, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("(", r"\(")):
        call()


def test_bom_and_crlf_files_are_read_like_plain_ones(files):
    import fits

    plain = (files / "good.csv").read_bytes()
    variants = {
        "good_bom.csv": b"\xef\xbb\xbf" + plain,
        "good_crlf.csv": plain.replace(b"\n", b"\r\n"),
    }
    ref = fits.read_record(str(files / "good.csv"))
    for name, data in variants.items():
        path = files.parent / name
        path.write_bytes(data)
        rec = fits.read_record(str(path))
        np.testing.assert_array_equal(rec.positions, ref.positions)
        np.testing.assert_array_equal(rec.k, ref.k)


# -- booleans and strings are not numbers ---------------------------------------------------------
#: valid arguments of every model, law and solver class in `vmj.__all__` (a class added there
#: without an entry here fails `test_every_public_constructor_is_covered`)
VALID = {
    "VariableMass": dict(m0=5.0, c=4900.0, delta=3.0, eps=0.0, mu=2.0, friction=vmj.Coulomb(14.7)),
    "Rope": dict(
        m=19.6, A=1.74e-4, e=7.845e10, b=0.0, d=7.845e15, T=3.9e5, length=vmj.ConstantSpeed(10.0)
    ),
    "Oscillator": dict(omega=6.0),
    "LinearOscillator": dict(m=1.0, c=0.1, k=10.0),
    "StickSlip": dict(eps=2.5, Omega=0.5, time_scale=1.0, angle_scale=1.0),
    "Coulomb": dict(F=1.0),
    "MassProportional": dict(f=0.3, g=9.81),
    "AffineFriction": dict(FT=1.0, f=0.3, g=9.81),
    "LinearRestoring": dict(),
    "PolynomialRestoring": dict(b2=0.1, b3=0.1),
    "SineRestoring": dict(b2=0.0, b3=0.0, w=1.0),
    "ViscousDamping": dict(zeta=0.1),
    "CoulombDamping": dict(xF=0.01, xS=0.02),
    "QuadraticDamping": dict(cq=0.1),
    "ConstantSpeed": dict(l0=10.0, u=1.0),
    "Braking": dict(l0=10.0, u=1.0, t_brake=1.0, t_stop=2.0),
    "NoForcing": dict(),
    "HarmonicForce": dict(F0=1.0, p=2.0),
    "BaseMotion": dict(Y0=0.01, p=2.0),
    "Exact": dict(max_substeps=8),
    "Smoothed": dict(smoothing=1e-4, rtol=1e-10, max_steps=1000),
    "EnergyBalance": dict(),
    "ClosedForm": dict(),
}
NUMBERS = [(c, p) for c, kw in VALID.items() for p, v in kw.items() if isinstance(v, float | int)]
NOT_NUMBERS = [True, np.bool_(True), np.array([True, False]), "1", b"1"]


def test_every_public_constructor_is_covered():
    import inspect

    classes = {
        name: obj
        for name in vmj.__all__
        if inspect.isclass(obj := getattr(vmj, name))
        and issubclass(obj, (vmj.AbstractParams, vmj.AbstractSolver))
    }
    # the constructible ones: the leaves (the others are the abstract bases)
    concrete = {
        name
        for name, obj in classes.items()
        if not any(o is not obj and issubclass(o, obj) for o in classes.values())
    }
    assert concrete == set(VALID)
    for name, kw in VALID.items():
        getattr(vmj, name)(**kw)  # the valid arguments are valid


@pytest.mark.filterwarnings("ignore:A JAX array is being set as static")
@pytest.mark.parametrize("cls,param", NUMBERS, ids=[f"{c}.{p}" for c, p in NUMBERS])
def test_booleans_and_strings_are_refused_naming_the_parameter(cls, param):
    """`vmj.VariableMass(m0=True, ...)` built a model with `m0 = 1.0`, and numeric strings
    (`"5"`, `b"5"`) converted silently (`vmj.Smoothed` took `rtol="1e-10"`, `max_steps=True`,
    and `vmj.turning_points` `a0=True`). Each is now a `ValueError` naming the parameter and
    saying a number (or an integer) is expected."""
    for bad in NOT_NUMBERS:
        with pytest.raises((ValueError, TypeError), match=rf"^{param} must be ") as info:
            getattr(vmj, cls)(**{**VALID[cls], param: bad})
        assert "number" in str(info.value) or "integer" in str(info.value), str(info.value)


def test_the_entry_points_refuse_a_boolean_release():
    model = vmj.Oscillator.linear(6.0, 0.1, 0.001)
    with pytest.raises(ValueError, match="^a0 must be a number"):
        vmj.turning_points(model, True, 3)


@pytest.mark.parametrize("cls", list(VALID))
def test_numbers_of_every_kind_keep_working(cls):
    """Python ints, NumPy scalars and 0-d arrays, JAX arrays, and tracers under `jax.jit`,
    `jax.vmap` and `jax.grad` are numbers (the fields that set array shapes or tolerances are
    static: Python numbers only)."""
    import dataclasses

    import jax.numpy as jnp

    make = getattr(vmj, cls)
    static = {f.name for f in dataclasses.fields(make) if f.metadata.get("static", False)}
    for param, value in VALID[cls].items():
        if not isinstance(value, float | int):
            continue
        if param in static:
            make(**{**VALID[cls], param: int(value) if isinstance(value, int) else value})
            continue
        for number in (np.float64(value), np.array(value), jnp.asarray(value), np.float32(value)):
            make(**{**VALID[cls], param: number})
        if float(value).is_integer():
            make(**{**VALID[cls], param: int(value)})

        def build(v, param=param):
            return jnp.sum(jnp.asarray(getattr(make(**{**VALID[cls], param: v}), param)))

        assert float(jax.jit(build)(value)) == pytest.approx(value)
        assert np.allclose(jax.vmap(build)(jnp.array([value, value])), value)
        assert np.isfinite(float(jax.grad(build)(value)))
