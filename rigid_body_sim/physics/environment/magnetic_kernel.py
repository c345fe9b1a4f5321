"""The magnetorquers' torque as the compiled loops see it: τ = m × B_body, with B the
Earth's field along the orbit at the instant and m the rods' held dipole.

The orbit does not depend on the attitude, so B_world is a function of time alone; it
lives in the magnetic slots of the environment array (``orbit.kernel``, MAG_*):

* model 1, the tilted dipole in closed form: the position from the orbit's conic, turned
  into the Earth-fixed frame by θ = θ0 + ω_E t, B = μ0/(4π r³)·[3(m·r̂)r̂ − m], turned back;
* model 2, a line B0 + Ḃ·(t − t0) that the engine re-anchors at each interval between
  events from a table of IGRF-14 values (``magnetic_field.FieldAlongOrbit``): IGRF's
  spherical harmonics cannot be compiled here, its values along the orbit can be.

The torque depends on the attitude and the time, never on ω: in the splittings its flow
at fixed attitude is a kick, like the gravity gradient's. Plain numerical Python compiled
by ``jit`` (NUMBA_DISABLE_JIT=1 runs it as Python).
"""
import math

from ..jit import depends_on, jit
from ..orbit import kernel as k

MU0_OVER_4PI = 1e-7  # T·m/A


@jit
def field_world(t, env):
    """B (T) at time t in the inertial frame, as three floats (model 1 or 2)."""
    if env[k.MAG_MODEL] == 2.0:
        dt = t - env[k.MAG_T0]
        return (env[k.MAG_B0] + env[k.MAG_B_RATE] * dt,
                env[k.MAG_B0 + 1] + env[k.MAG_B_RATE + 1] * dt,
                env[k.MAG_B0 + 2] + env[k.MAG_B_RATE + 2] * dt)
    ux, uy, uz, r = k.radial(env, t)
    angle = env[k.MAG_ANGLE0] + env[k.MAG_SPIN] * t
    c = math.cos(angle)
    s = math.sin(angle)
    mx = env[k.MAG_MOMENT]
    my = env[k.MAG_MOMENT + 1]
    mz = env[k.MAG_MOMENT + 2]
    # the Earth-fixed moment in the inertial frame (r_eci = R_z(θ) r_ecef)
    wx = c * mx - s * my
    wy = s * mx + c * my
    dot = 3.0 * (wx * ux + wy * uy + mz * uz)
    f = MU0_OVER_4PI / (r * r * r)
    return f * (dot * ux - wx), f * (dot * uy - wy), f * (dot * uz - mz)


@jit
def magnetorquer_torque(q, t, env):
    """τ = m × B_body (principal frame, N·m) as three floats: m the rods' dipole (principal
    frame, env[MAG_DIPOLE:+3]) and B_body = q⁻¹ B_world q (q normalised here: the RK loops'
    stages are not unit)."""
    mx = env[k.MAG_DIPOLE]
    my = env[k.MAG_DIPOLE + 1]
    mz = env[k.MAG_DIPOLE + 2]
    if mx == 0.0 and my == 0.0 and mz == 0.0:
        return 0.0, 0.0, 0.0
    ux, uy, uz = field_world(t, env)
    b0, b1, b2 = k.to_body(q, ux, uy, uz)          # the gravity gradient's rotation
    return my * b2 - mz * b1, mz * b0 - mx * b2, mx * b1 - my * b0


# they call the orbit's position and its rotation to the body (see jit.depends_on)
for _kernel in (field_world, magnetorquer_torque):
    depends_on(_kernel, k)
