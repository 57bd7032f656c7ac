"""fits: identification of dry friction, rope friction and damping from measured decay."""
