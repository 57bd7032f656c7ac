"""Command-line arguments that several command-line tests share, spelled once."""

#: the paper's variable-mass oscillator without its friction and release: m0 = 5 kg,
#: c = 4900 N/m, delta = 3 kg/s, eps = 0, mu = 2 kg/s
VARIABLE_MASS_MODEL = "--m0 5 --c 4900 --delta 3 --eps 0 --mu 2".split()
#: the same with constant friction F_T = 14.7 N, released from a0 = 0.06 m
VARIABLE_MASS = [*VARIABLE_MASS_MODEL, "--FT", "14.7", "--a0", "0.06"]
#: a hoisting rope without its speed and release, in the rope paper's technical units
#: (`--units technical`: m in kG s^2/m, A in cm^2, e, d, T in kG/cm^2, l0 in m)
ROPE_MODEL = "--m 2 --A 1.74 --e 0.8e6 --d 0.8e11 --T 4 --l0 10".split()
#: the same lowered at 3 m/s, released from 1 cm for 0.05 s, in technical units
ROPE = [*ROPE_MODEL, "--u", "-3", "--a0", "1", "--t1", "0.05", "--units", "technical"]
