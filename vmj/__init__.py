"""vmj: oscillators with dry (Coulomb) friction and time-varying parameters, in JAX.

Enable float64 before any computation (the `vmj` command line does it for you):

    import jax
    jax.config.update("jax_enable_x64", True)
"""

from ._models import Coulomb, FrictionLaw, MassProportional, VariableMass
from ._solution import RESULTS, DecaySequence, Trajectory
from ._solve import energy_balance, simulate, turning_points
from ._tables import paper_cells, paper_table
from ._sweep import Grid, SweepResult, grid, sweep
from ._host import retain_host_memory
from ._sensitivity import sensitivity
from ._stickslip import (StickSlip, StickSlipCycle, stick_slip_closed_form, stick_slip_cycle,
                         stick_slip_simulate)
from ._linear import (BaseMotion, Forcing, HarmonicForce, LinearOscillator, NoForcing,
                      linear_simulate)
from ._rope import KGF, Braking, ConstantSpeed, LengthProfile, Rope
from . import _rope_solve  # noqa: F401  (registers the rope's exact and smoothed solvers)
from ._rope_averaging import (action_amplitude, action_frequency, kbm_amplitude, kbm_frequency,
                              rope_energy_map)

__all__ = [
    "Grid",
    "SweepResult",
    "grid",
    "sweep",
    "retain_host_memory",
    "sensitivity",
    "Coulomb",
    "FrictionLaw",
    "MassProportional",
    "VariableMass",
    "RESULTS",
    "DecaySequence",
    "Trajectory",
    "energy_balance",
    "simulate",
    "turning_points",
    "paper_cells",
    "paper_table",
    "StickSlip",
    "StickSlipCycle",
    "stick_slip_cycle",
    "stick_slip_closed_form",
    "stick_slip_simulate",
    "LinearOscillator",
    "Forcing",
    "NoForcing",
    "HarmonicForce",
    "BaseMotion",
    "linear_simulate",
    "KGF",
    "Braking",
    "ConstantSpeed",
    "LengthProfile",
    "Rope",
    "action_amplitude",
    "action_frequency",
    "kbm_amplitude",
    "kbm_frequency",
    "rope_energy_map",
]

__version__ = "0.1.0"
