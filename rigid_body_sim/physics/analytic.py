"""Analytic expectations that the plots draw beside the simulation (and the tests check).

All in the principal frame (moments (3,), ω and L components along the principal axes),
SI units. The torque-free solution itself is :mod:`.exact`; these are its headline numbers
and the classic laws of the scenes: flips, free precession, nutation under dissipation,
the Euler wobble and the critically damped slew.
"""
import numpy as np

from .exact import MOMENT_RTOL, TorqueFreeSolution

SIDEREAL_DAY = 86164.0905  # s


def flip_interval(moments, angular_velocity) -> float:
    """2K(k)/λ, s: the time between sign changes of ω along the intermediate axis (inf
    when it never changes sign: a symmetric body, a steady spin)."""
    moments = np.asarray(moments, float)
    m0 = moments * np.asarray(angular_velocity, float)
    return float(TorqueFreeSolution(moments, (0.0, 0.0, 0.0, 1.0), m0).flip_interval)


def symmetry_axis(moments):
    """Index of the symmetry axis of an axisymmetric body (the moment that differs from
    the two equal ones), or None when no two moments are equal (or all three are)."""
    m = np.asarray(moments, float)
    tol = MOMENT_RTOL * m.max()
    equal = [abs(m[(i + 1) % 3] - m[(i + 2) % 3]) <= tol for i in range(3)]
    return equal.index(True) if sum(equal) == 1 else None


def precession_rates(moments, angular_velocity):
    """(body-cone rate, space-cone rate), rad/s, of an axisymmetric body.

    Body cone: ω turns about the symmetry axis in the body at (I_s − I_t) ω_s / I_t
    (signed, right-handed about the axis). Space cone: the symmetry axis turns about L
    in space at |L| / I_t."""
    moments = np.asarray(moments, float)
    s = symmetry_axis(moments)
    if s is None:
        raise ValueError(f'moments {moments.tolist()} are not axisymmetric')
    w = np.asarray(angular_velocity, float)
    i_s, i_t = moments[s], moments[(s + 1) % 3]
    return float((i_s - i_t) * w[s] / i_t), float(np.linalg.norm(moments * w) / i_t)


def nutation_rate(moments, coefficient, momentum_norm) -> float:
    """c, 1/s, of tan θ = tan θ0·exp(c t) for an axisymmetric body under double-bracket
    dissipation (coefficient α, s/(kg·m²)) at constant |L|: c = α|L|²(1/I_s − 1/I_t).
    θ is the angle between L and the symmetry axis; c > 0 for a minor-axis (prolate) spinner."""
    moments = np.asarray(moments, float)
    s = symmetry_axis(moments)
    if s is None:
        raise ValueError(f'moments {moments.tolist()} are not axisymmetric')
    i_s, i_t = moments[s], moments[(s + 1) % 3]
    return float(coefficient * momentum_norm ** 2 * (1.0 / i_s - 1.0 / i_t))


def nutation_angle(theta0, rate, t):
    """θ(t), rad, from tan θ = tan θ0·exp(c t) (θ in [0, π/2])."""
    return np.arctan(np.tan(theta0) * np.exp(rate * np.asarray(t, float)))


def euler_wobble_period(moments, spin_rate) -> float:
    """Period, s, of the free (Euler) wobble of an oblate symmetric body spinning at
    ``spin_rate`` (rad/s): 2π / |(C − A) ω_s / A|; A/(C − A) sidereal days for the Earth."""
    body_rate = precession_rates(moments, _along_symmetry(moments, spin_rate))[0]
    return float(2 * np.pi / abs(body_rate))


def _along_symmetry(moments, spin_rate):
    w = np.zeros(3)
    w[symmetry_axis(moments)] = spin_rate
    return w


def critical_response(theta0, rate0, natural_frequency, t):
    """The linear critically damped response θ'' + 2ω_nθ' + ω_n²θ = 0 from θ(0) = θ0,
    θ'(0) = rate0: returns (θ(t), θ'(t))."""
    t = np.asarray(t, float)
    wn = float(natural_frequency)
    b = rate0 + wn * theta0
    decay = np.exp(-wn * t)
    return (theta0 + b * t) * decay, (b - wn * (theta0 + b * t)) * decay


def eigenaxis_slew(theta0, rate0, natural_frequency, damping_ratio, t):
    """The quaternion PD law (k_p = 2Iω_n², k_d = 2ζω_nI) about a fixed eigen-axis:
    θ'' = −2ω_n² sin(θ/2) − 2ζω_n θ', which is critically damped for ζ = 1 as θ → 0
    (see :func:`critical_response`). Returns (θ(t), θ'(t)), rad and rad/s."""
    from scipy.integrate import solve_ivp
    t = np.asarray(t, float)
    wn, zeta = float(natural_frequency), float(damping_ratio)

    if not t.size or t[-1] <= 0.0:  # a slew that begins at a run's last sample: no span
        return np.full(t.shape, float(theta0)), np.full(t.shape, float(rate0))

    def rhs(_, y):
        return (y[1], -2 * wn ** 2 * np.sin(0.5 * y[0]) - 2 * zeta * wn * y[1])
    sol = solve_ivp(rhs, (0.0, float(t[-1]) if t.size else 0.0), (theta0, rate0),
                    t_eval=t, rtol=1e-10, atol=1e-12, method='DOP853')
    return sol.y[0], sol.y[1]


def libration_frequencies(moments, mean_motion):
    """Small librations about the orbit frame (circular orbit, gravity gradient), principal
    moments (I_x, I_y, I_z) on LVLH's x (along track), y (orbit normal), z (nadir): the
    pitch at n·√(3(I_x − I_z)/I_y) and the two roll–yaw roots of
    ω⁴ − (1 + 3k_R + k_R k_Y)n²ω² + 4k_R k_Y n⁴ = 0, k_R = (I_y − I_z)/I_x,
    k_Y = (I_y − I_x)/I_z (Wie §6.3; Hughes §9), rad/s: (pitch, (low, high)). NaN where
    the motion is not oscillatory (outside the stable regions)."""
    ix, iy, iz = (float(v) for v in moments)
    n = float(mean_motion)
    with np.errstate(invalid='ignore'):
        pitch = n * np.sqrt(3.0 * (ix - iz) / iy)
        k_r, k_y = (iy - iz) / ix, (iy - ix) / iz
        b = 1.0 + 3.0 * k_r + k_r * k_y
        c = 4.0 * k_r * k_y
        disc = np.sqrt(b * b - 4.0 * c)
        roots = np.sqrt(np.array([(b - disc) / 2.0, (b + disc) / 2.0])) * n
    return float(pitch), (float(roots[0]), float(roots[1]))

