"""Numerical primitives shared by the closed forms and the solvers: the root finder, truncated
power series, the diffrax wrapper and the decay scan. Import the submodules directly."""
