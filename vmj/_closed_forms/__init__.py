"""Closed forms, one file per source paper: Olshansky (variable mass), Osinski (rope),
Belokobylsky & Koronatov (stick-slip). Pure functions of a model; import the submodules
directly."""
