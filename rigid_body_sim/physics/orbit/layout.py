"""Where each value sits in the kernels' element array ``env`` (float64, SIZE): the slots
only, free of numba, so that the specs that fill it (the orbit, the field, sunlight) load
without the compiled loops; ``kernel`` re-exports them (``kernel.ON``). The meaning of each
slot is in ``kernel``'s docstring.
"""
ON, MU, A, E, INC, RAAN, ARGP, M0, T0, RAAN_RATE, ARGP_RATE, M_RATE = range(12)
# magnetic (magnetic_kernel): [MAG_MODEL] 0 no magnetorquer torque, 1 the tilted dipole in
# closed form, 2 the field as a line B0 + Ḃ·(t − MAG_T0) re-anchored per interval (IGRF);
# the Earth's dipole (A·m², ECEF), the rotation angle at t = 0 and the spin rate; the
# line's B0 and Ḃ (T, T/s, inertial) and its anchor; the rods' dipole (A·m², principal)
MAG_MODEL = M_RATE + 1
MAG_MOMENT = MAG_MODEL + 1                      # 3 slots
MAG_ANGLE0, MAG_SPIN = MAG_MOMENT + 3, MAG_MOMENT + 4
MAG_B0 = MAG_SPIN + 1                           # 3 slots
MAG_B_RATE = MAG_B0 + 3                         # 3 slots
MAG_T0 = MAG_B_RATE + 3
MAG_DIPOLE = MAG_T0 + 1                         # 3 slots
MAG_END = MAG_DIPOLE + 3
# sunlight, drag
(SRP_ON, DRAG_ON, SHADOW, SUN_L0, SUN_G0, SUN_EPS, DENSITY, RHO_REF, H_REF, SCALE_HEIGHT,
 N_FACETS, SIZE) = range(MAG_END, MAG_END + 12)
