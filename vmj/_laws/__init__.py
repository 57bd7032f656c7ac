"""Laws: friction, length profiles, forcing, and the restoring and dissipation laws of the
identification oscillator. Import the submodules directly."""
