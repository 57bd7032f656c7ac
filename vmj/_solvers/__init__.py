"""Solvers: the exact half-swing solver, the smoothed diffrax solver, closed-form evaluation,
the shared decay scan and root finder. Import the submodules directly."""
