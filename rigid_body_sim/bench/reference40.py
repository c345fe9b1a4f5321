"""40-digit reference for torque-free rigid-body motion (a bench/test helper; needs mpmath).

Nothing in the package imports this at runtime: mpmath is a test/bench dependency only.
It judges :mod:`rigid_body_sim.physics.exact` (float64) over long horizons, where no float64
integrator can serve as a reference. Inputs are float64 numbers converted *exactly* to mpf,
so the reference answers the same problem as the float64 code and the comparison shows the
code's error, not the rounding of its inputs.

Two independent routes, both at DPS digits (margin above the 40 claimed):

* :class:`Reference40` — the closed form evaluated with mpmath's own special functions
  (``ellipfun``, ``ellipf``, ``ellipk``, ``ellippi``), the textbook constants computed
  directly (at 60 digits the cancellations near the separatrix cost ~7 digits, harmless),
  none of exact.py's quarter-period or cancellation-free rewrites. Long horizons come from
  period arithmetic: u = λt + u0 = 2jK + r, |r| ≤ K, and am u = jπ + am r, evaluated at 60
  digits (j ≤ ~1e6 costs 6 of them). ``ellippi`` reduces am u by its own quasi-periodicity.
* :func:`ode_solution` — Euler's equations and the quaternion kinematics integrated by
  ``mpmath.odefun`` (Taylor series). It knows nothing of elliptic functions, so agreement
  at short times (to 1e-30, see test_reference40.py) checks the closed form's constants,
  signs and phase conventions; the period arithmetic then carries them to 1e6 s.

Conventions as in :mod:`rigid_body_sim.physics.dynamics`: q = (x, y, z, w) maps principal-
frame vectors to the inertial frame, m is the body angular momentum, Ω = m/I,
dm/dt = m × Ω, dq/dt = ½ q ⊗ (Ω, 0).
"""
import mpmath

DPS = 60
# Quaternion helpers on tuples (x, y, z, w) of mpf; the current mpmath precision applies.


def _qmul(p, q):
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return (pw * qx + px * qw + py * qz - pz * qy, pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw, pw * qw - px * qx - py * qy - pz * qz)


def _qconj(q):
    return (-q[0], -q[1], -q[2], q[3])


def _qaxis(axis, angle):
    """Rotation by ``angle`` about the unit vector ``axis`` (3 mpf)."""
    s, c = mpmath.sin(angle / 2), mpmath.cos(angle / 2)
    return (axis[0] * s, axis[1] * s, axis[2] * s, c)


def _qnormalise(q):
    n = mpmath.sqrt(sum(c * c for c in q))
    return tuple(c / n for c in q)


def _qrotate(q, v):
    x, y, z, _ = _qmul(_qmul(q, (v[0], v[1], v[2], 0)), _qconj(q))
    return (x, y, z)


def _quat_of_signed_permutation(rows):
    """Quaternion of the proper rotation matrix whose rows are ``rows`` (entries 0, ±1)."""
    r = [[mpmath.mpf(v) for v in row] for row in rows]
    tr = r[0][0] + r[1][1] + r[2][2]
    # Shepperd's choice of the largest of w², x², y², z² keeps the division well away from 0.
    cand = [tr, r[0][0] - r[1][1] - r[2][2], r[1][1] - r[0][0] - r[2][2],
            r[2][2] - r[0][0] - r[1][1]]
    k = max(range(4), key=lambda i: cand[i])
    s = 2 * mpmath.sqrt(1 + cand[k])
    if k == 0:
        q = ((r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s, s / 4)
    elif k == 1:
        q = (s / 4, (r[0][1] + r[1][0]) / s, (r[0][2] + r[2][0]) / s, (r[2][1] - r[1][2]) / s)
    elif k == 2:
        q = ((r[0][1] + r[1][0]) / s, s / 4, (r[1][2] + r[2][1]) / s, (r[0][2] - r[2][0]) / s)
    else:
        q = ((r[0][2] + r[2][0]) / s, (r[1][2] + r[2][1]) / s, s / 4, (r[1][0] - r[0][1]) / s)
    return q


def _mpf_exact(values):
    """float64 values → mpf exactly (mpf(float) is exact; no decimal round trip); mpf kept."""
    return [v if isinstance(v, mpmath.mpf) else mpmath.mpf(float(v)) for v in values]


def _sign(x):
    return 1 if x > 0 else -1


class Reference40:
    """Closed-form torque-free motion from float64 ``moments`` (3,), ``q0`` (4,), ``m0`` (3,).

    ``at(t)`` returns (q, m) as tuples of mpf, good to ~40 digits for |t| up to ~1e6 s and
    more. Regimes: symmetric/spherical bodies and pure spins about a principal axis in closed
    form; otherwise the elliptic solution (both sides of the separatrix). A state exactly on
    the separatrix is refused (no bench scene is; it would need the tanh/sech branch).
    """

    def __init__(self, moments, q0, m0):
        with mpmath.workdps(DPS):
            self._setup(_mpf_exact(moments), _mpf_exact(q0), _mpf_exact(m0))

    def _setup(self, inertia, q0, m0):
        self.moments, self.m0 = inertia, m0
        self.q0 = _qnormalise(q0)
        g2 = sum(c * c for c in m0)
        t2 = sum(c * c / i for c, i in zip(m0, inertia))     # 2T
        self.G = mpmath.sqrt(g2)
        self.omega_period = mpmath.inf
        order = sorted(range(3), key=lambda i: inertia[i])
        i1, i2, i3 = (inertia[i] for i in order)
        on_axis = [i for i in range(3) if all(m0[j] == 0 for j in range(3) if j != i)]
        if i1 == i2 or i2 == i3 or on_axis or g2 == 0:
            self.regime = 'closed'
            # Symmetry axis e (the unique moment), transverse moment It; a spherical body or
            # a pure spin is the same formula with any It (the two rotations coincide).
            if i1 == i2 == i3 or on_axis or g2 == 0:
                e_idx, it = (on_axis[0] if on_axis else order[2]), inertia[order[0]]
            elif i1 == i2:
                e_idx, it = order[2], i1
            else:
                e_idx, it = order[0], i3
            self._e = tuple(mpmath.mpf(1 if k == e_idx else 0) for k in range(3))
            self._ws = m0[e_idx] * (1 / inertia[e_idx] - 1 / it)
            self._rate_l = self.G / it
            lhat = _qrotate(self.q0, [c / self.G for c in m0]) if g2 else (0, 0, 1)
            self._lhat = lhat
            return
        # Which side of the separatrix: the sign of Δ2 = G² − 2T·I2, times I1·I3, a
        # polynomial in the inputs that 100 digits hold exactly (3 × 53-bit products).
        with mpmath.workdps(100):
            m1, m3 = m0[order[0]], m0[order[2]]
            d2 = m1 * m1 * (i1 - i2) * i3 + m3 * m3 * (i3 - i2) * i1
        if d2 == 0:
            raise ValueError('state exactly on the separatrix: not supported by the reference')
        self.regime = 'A' if d2 > 0 else 'B'
        # Working frame: x the cn axis, y the middle (sn) axis, z the dn axis d, whose m_z
        # never changes sign; y's sign makes the frame right-handed, so Euler's equations
        # keep their form there.
        c_ax, d_ax = (order[0], order[2]) if d2 > 0 else (order[2], order[0])
        rows = [[1 if k == a else 0 for k in range(3)] for a in (c_ax, order[1], d_ax)]
        det = mpmath.det(mpmath.matrix(rows))
        if det < 0:
            rows[1] = [-v for v in rows[1]]
        self._rows = rows
        self._p = _quat_of_signed_permutation(rows)
        mw = [sum(r[k] * m0[k] for k in range(3)) for r in rows]
        ix, iy, iz = (inertia[a] for a in (c_ax, order[1], d_ax))
        a_ = t2 * iz - g2          # 2T·Iz − G²  (both signs flip together in case B)
        b_ = g2 - t2 * ix          # G² − 2T·Ix
        self._Mx = mpmath.sqrt(ix * a_ / (iz - ix))
        self._My = mpmath.sqrt(iy * a_ / (iz - iy))
        self._Mz = mpmath.sqrt(iz * b_ / (iz - ix))
        self._lam = mpmath.sqrt((iz - iy) * b_ / (ix * iy * iz))
        self._k2 = (iy - ix) * a_ / ((iz - iy) * b_)
        self._sd = _sign(mw[2])
        self._sy = self._sd * _sign(iz - iy)              # forced by ṁ_x = m_y m_z (1/Iz − 1/Iy)
        self._K = mpmath.ellipk(self._k2)
        am0 = mpmath.atan2(mw[1] / (self._sy * self._My), mw[0] / self._Mx)
        self._u0 = mpmath.ellipf(am0, self._k2)
        self.omega_period = 4 * self._K / self._lam
        # φ̇ = G/Iz + (G/Iz)(2T·Iz − G²)/(G² − m_z²), with G² − m_z² = (G² − Mz²)(1 + N sn²u)
        gm = g2 - self._Mz ** 2
        self._N = self._Mz ** 2 * self._k2 / gm
        self._rate0 = self.G / iz
        self._cphi = self._rate0 * a_ / (self._lam * gm)
        self._P0 = mpmath.ellippi(-self._N, am0, self._k2)
        e0 = self._moving(mpmath.mpf(0))[0]
        self._C = _qmul(_qmul(self.q0, _qconj(self._p)), _qconj(e0))

    def _moving(self, t):
        """(E(t) = Rz(φ)Rx(θ)Rz(ψ), m in the working frame)."""
        u = self._lam * t + self._u0
        j = int(mpmath.nint(u / (2 * self._K)))
        r = u - 2 * j * self._K                            # |r| ≤ K: cn r ≥ 0
        sn, cn, dn = (mpmath.ellipfun(f, r, m=self._k2) for f in ('sn', 'cn', 'dn'))
        am = j * mpmath.pi + mpmath.atan2(sn, cn)
        par = -1 if j % 2 else 1                           # sn, cn change sign every 2K
        mw = (self._Mx * par * cn, self._sy * self._My * par * sn, self._sd * self._Mz * dn)
        phi = self._rate0 * t + self._cphi * (mpmath.ellippi(-self._N, am, self._k2) - self._P0)
        theta = mpmath.atan2(mpmath.hypot(mw[0], mw[1]), mw[2])
        psi = mpmath.atan2(mw[0], mw[1])
        z, x = (0, 0, 1), (1, 0, 0)
        e = _qmul(_qmul(_qaxis(z, phi), _qaxis(x, theta)), _qaxis(z, psi))
        return e, mw

    def at(self, t):
        """(q, m) at time t (float64 taken exactly, or mpf), as tuples of mpf."""
        with mpmath.workdps(DPS):
            t = mpmath.mpf(t)
            if self.regime == 'closed':
                spin = _qaxis(self._e, self._ws * t)
                q = _qmul(_qmul(_qaxis(self._lhat, self._rate_l * t), self.q0), spin)
                m = _qrotate(_qconj(spin), self.m0)
                return q, m
            e, mw = self._moving(t)
            q = _qmul(_qmul(self._C, e), self._p)
            m = tuple(sum(self._rows[k][i] * mw[k] for k in range(3)) for i in range(3))
            return q, m


def ode_solution(moments, q0, m0, t, dps=40):
    """(q, m) at t from ``mpmath.odefun`` (Taylor series) on dm/dt = m × Ω,
    dq/dt = ½ q ⊗ (Ω, 0): no elliptic functions, an independent check of the closed form.
    Cost grows with t·|Ω| and dps: ≈6 s of CPU for 10 s at |Ω| ≈ 2 rad/s."""
    with mpmath.workdps(dps):
        inertia, m = _mpf_exact(moments), _mpf_exact(m0)
        q = list(_qnormalise(_mpf_exact(q0)))

        def rhs(_, y):
            w = [y[4 + k] / inertia[k] for k in range(3)]
            dq = _qmul(y[:4], (w[0], w[1], w[2], 0))
            return [c / 2 for c in dq] + [y[5] * w[2] - y[6] * w[1], y[6] * w[0] - y[4] * w[2],
                                          y[4] * w[1] - y[5] * w[0]]

        y = mpmath.odefun(rhs, 0, q + m)(mpmath.mpf(t))
        return tuple(y[:4]), tuple(y[4:])


def attitude_error(q, q_ref):
    """Rotation angle (rad, float) between attitude ``q`` (float64 or mpf, x y z w) and the
    reference, computed in mpmath so that 1e-15 rad is resolved; sign-invariant."""
    with mpmath.workdps(DPS):
        a = _qnormalise(_mpf_exact(q))
        d = _qmul(_qconj(_qnormalise(q_ref)), a)
        return float(2 * mpmath.atan2(mpmath.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2),
                                      abs(d[3])))


def vector_error(v, v_ref):
    """max |v_i − v_ref_i| as a float, in mpmath."""
    with mpmath.workdps(DPS):
        return float(max(abs(a - b) for a, b in zip(_mpf_exact(v), v_ref)))
