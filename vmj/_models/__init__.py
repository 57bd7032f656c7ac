"""Models: one file per physical system, each an `equinox.Module` implementing the abstract
bases of `_base.py`. Import the submodules directly (this package imports nothing)."""
