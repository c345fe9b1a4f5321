"""Exact torque-free rigid-body motion at any time t, in closed form (no stepping).

Conventions as in :mod:`.dynamics`: q (x, y, z, w) maps principal-frame vectors to the
inertial frame, m is the body angular momentum, Ω = m/I, dm/dt = m × Ω, dq/dt = ½ q ⊗ (Ω, 0).

Relabelling. ``moments`` may come in any order. Each body is solved in a *working* frame
(x, y, z) obtained from the caller's axes by a signed permutation W with det W = +1
(m_work = W m, q_work = q ⊗ w, w the quaternion of Wᵀ), so handedness and the ODE's form
are preserved and results are mapped back exactly. With sorted moments I1 < I2 < I3:
case A and the separatrix use (x, y, z) = (1, ±2, 3); case B uses (x, y, z) = (3, ∓2, 1)
(one sign flip restores det +1, the ± absorbs an odd sort). z is always the "dn axis" d,
whose momentum m_z never changes sign, and in this frame the case-A formulas below hold
verbatim for case B too (Ix > Iy > Iz there; every ratio keeps its sign).

Formulas (working frame, Δj = G² − 2T·Ij = Σ_{i≠j} m_i²(I_i − I_j)/I_i, free of cancellation):
  m_x = Mx cn u, m_y = s·My sn u, m_z = σd·Mz dn u,  u = λt + u0,
  Mx² = Ix(−Δz)/(Iz − Ix), My² = Iy(−Δz)/(Iz − Iy), Mz² = Iz·Δx/(Iz − Ix),
  λ² = (Iz − Iy)Δx/(IxIyIz), k'² = 1 − k² = Δy(Iz − Ix)/[Δx(Iz − Iy)],
  σd = sign m_z(0), s = σd·sign(Iz − Iy) (forced by the ODE), u0 = F(atan2(sn0, cn0) | k²).
Attitude: Q = C·Rz(φ)·Rx(θ)·Rz(ψ) (space z along L), tan ψ = m_x/m_y, cos θ = m_z/G,
  φ(t) = (G/Iz)t + (G/Iz)(Iz − Ix)/(Ix λ)·[P(u) − P(u0)],  P(u) = Π(−N; am u | k²),
  N = Iz(Iy − Ix)/[Ix(Iz − Iy)] > 0 (a constant of the body; 1 + N sn² > 0, no principal value).
  (Landau–Lifshitz §37 / Leroy's corrections; the sign of φ̇ is that of L, verified vs DOP853.)
  P via Carlson with u = 2jK + r, |r| ≤ K: P(u) = 2j·Π(−N|k²) + P(r),
  P(r) = s R_F(c², d², 1) − (N/3) s³ R_J(c², d², 1, 1 + N s²)  (s, c, d = sn, cn, dn of r),
  K = cel(k', 1), Π(−N|k²) = cel(k', 1 + N) (Bulirsch's complete integral, from k' directly).
  For |r| > K/2 sn, cn, dn come from the quarter-period identities at K − |r|
  (cn = k' sd, dn = k' nd), so the small values near the separatrix carry the exact k'.
  ψ is made continuous in t: ψ = π/2 − s(A + δ), A = am u = jπ + am r,
  δ = atan2((My − Mx) sn cn, Mx cn² + My sn²) (|δ| < π/2).
Separatrix (Δy ≈ 0, frame A): m = (σx Mx sech u, σxσd G tanh u, σd Mz sech u), λ = σ the
  intermediate-axis growth rate, P(u) = [u + √N atan(√N tanh u)]/(1 + N); m_x, m_z signs
  independent.
Symmetric / spherical bodies and steady spins (any axis): with e the symmetry (or spin) axis,
  I_t the transverse moment and ω_s = m_e(1/I_e − 1/I_t) the body-frame precession rate,
  q(t) = exp(L̂ G t/I_t) ⊗ q0 ⊗ exp(e ω_s t), m(t) = exp(−e ω_s t) m0 (the two flows commute).

Regime classification (relative tolerances, per body):
  * moments equal when |Ii − Ij| ≤ MOMENT_RTOL·max I (1e-12): 'spherical' / 'symmetric';
    a nearly-symmetric body beyond that is solved by the elliptic branch;
  * 'separatrix' when |Δ2| ≤ SEPARATRIX_RTOL·Σ|terms of Δ2| (16 eps), i.e. when the sign of
    G² − 2T·I2 is not determined by the input; otherwise 'A' (Δ2 > 0) or 'B' (Δ2 < 0);
  * 'steady_spin' when the momentum off the nearest principal axis is ≤ STEADY_RTOL·G
    (1e-100, i.e. zero in practice, chosen only to keep m_i² clear of underflow: the elliptic
    branch resolves any perturbation, including the exponentially growing one about the
    intermediate axis, k'² down to ~1e-200); G = 0 (rest) counts here too.
  Near the separatrix the *problem* is ill-conditioned: k'² follows from m by cancellation, so
  an input rounded to eps moves the motion by ~eps/k'² after the first passage near the saddle
  (DOP853 at rtol 1e-12 differs by 2e-8 at k' = 1e-4); the formulas add nothing worse.

Long horizons. The phases grow without bound (λt, (G/Iz)t and 2j·cphi·Π reach ~1e7 rad at
t = 1e6 s), so float64 rates, each a few eps off, would move them by ~eps·|ω|·t (2e-9 rad at
10 rad/s), Π's error is multiplied by j, and near the separatrix k'² comes from Δy by
cancellation. :meth:`TorqueFreeSolution.at` therefore evaluates with the compiled kernel
(:mod:`.exact_kernel`): rates, K, Π and k'² in double-double (:mod:`.exact_constants`, ~1e-32
relative, on every platform), u = 2jK + r and the secular part of φ modulo 4π formed and
reduced there, ψ taking jπ modulo 4π; the Jacobi and Carlson functions
(:mod:`.elliptic_kernel`) see only |r| ≤ K in float64, with k'² passed as such (no 1 − m).
Against a 40-digit reference (bench/reference40.py) the attitude error is ≤ 4.3e-15 rad at
1e3 s and ≤ 1.2e-14 at 1e6 s on every torque-free scene, and ≤ 6.1e-14 beside the
separatrix at k'² down to 2e-13 (test_exact_longhorizon.py).

:meth:`TorqueFreeSolution.at_numpy` keeps the vectorised numpy path (constants and phases
in long double, :mod:`.extended`; scipy.special): the reference the kernel is tested
against, and bulk evaluation when numba's JIT is disabled. Its accuracy is that of long
double (plain double on macOS arm64/MSVC) and of k'² = 1 − m in float64: ≤ 1.7e-12 rad at
1e6 s on the scenes, but up to 2.4e-9 rad at 1e3 s beside the separatrix.

The output quaternion is continuous in t (no sign jumps).
"""
import functools
import math

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.special import ellipj, elliprf, elliprj

from . import rotation
from . import exact_kernel
from .extended import LD, cel, reduce_4pi

MOMENT_RTOL = 1e-12
SEPARATRIX_RTOL = 16 * np.finfo(float).eps
STEADY_RTOL = 1e-100

_CLOSED, _ELLIPTIC, _SEPARATRIX = 0, 1, 2


@functools.lru_cache(maxsize=8)
def _frame_quaternions(order):
    """Signed permutations W (rows = working axes in caller indices), det +1, for frames A, B."""
    wa = np.eye(3)[list(order)]
    if np.linalg.det(wa) < 0:          # odd sort: flip the intermediate axis
        wa[1] *= -1.0
    wb = np.array([wa[2], -wa[1], wa[0]])
    return [(w, Rotation.from_matrix(w.T).as_quat()) for w in (wa, wb)]


def _carlson_pi(sn, cn, dn, n_):
    """Π(−N; am r | k²) for |am r| ≤ π/2, Carlson form."""
    s2 = sn * sn
    return (sn * elliprf(cn * cn, dn * dn, 1.0)
            - (n_ / 3.0) * sn * s2 * elliprj(cn * cn, dn * dn, 1.0, 1.0 + n_ * s2))


def _qz_qx_qz(phi, theta, psi):
    """Quaternion of Rz(φ)·Rx(θ)·Rz(ψ)."""
    sp, cp = np.sin(0.5 * phi), np.cos(0.5 * phi)
    st, ct = np.sin(0.5 * theta), np.cos(0.5 * theta)
    ss, cs = np.sin(0.5 * psi), np.cos(0.5 * psi)
    x, y, z, w = st * cs, -st * ss, ct * ss, ct * cs        # Rx(θ)·Rz(ψ)
    return np.stack((cp * x - sp * y, cp * y + sp * x, cp * z + sp * w, cp * w - sp * z), axis=-1)


class TorqueFreeSolution:
    """Closed-form torque-free motion of one body or a batch sharing principal ``moments``.

    ``q0`` (4,) or (N, 4), ``m0`` (3,) or (N, 3) at t = 0; ``at(t)`` returns (q, m) with t
    broadcast against the batch shape. Attributes (batch-shaped): kinetic_energy,
    angular_momentum_norm, regime (str), omega_period, flip_interval (ω along the middle
    axis changes sign every flip_interval; inf where it never does).
    """

    def __init__(self, moments, q0, m0):
        moments = np.asarray(moments, float)
        if moments.shape != (3,) or not np.all(np.isfinite(moments)) or np.any(moments <= 0.0):
            raise ValueError(f'moments must be 3 finite positive values, got {moments.tolist()}')
        q0 = rotation.validated(q0, 'q0')
        m0 = np.asarray(m0, float)
        if m0.shape[-1:] != (3,) or m0.ndim > 2 or not np.all(np.isfinite(m0)):
            raise ValueError(f'm0 must be finite with shape (3,) or (N, 3), got {m0.shape}')
        if q0.ndim > 2:
            raise ValueError(f'q0 must have shape (4,) or (N, 4), got {q0.shape}')
        self.batch_shape = np.broadcast_shapes(q0.shape[:-1], m0.shape[:-1])
        q0 = np.broadcast_to(q0, self.batch_shape + (4,)).reshape(-1, 4)
        m0 = np.broadcast_to(m0, self.batch_shape + (3,)).reshape(-1, 3)
        self.moments = moments
        self._q0, self._m0 = q0, m0
        n = len(m0)

        G = np.linalg.norm(m0, axis=-1)
        T = 0.5 * np.sum(m0 * m0 / moments, axis=-1)
        order = np.argsort(moments, kind='stable')
        i1, i2, i3 = moments[order]
        scale = moments.max()
        eq12, eq23 = i2 - i1 <= MOMENT_RTOL * scale, i3 - i2 <= MOMENT_RTOL * scale

        regime = np.empty(n, dtype=object)
        kind = np.full(n, _ELLIPTIC)
        omega_period = np.full(n, np.inf)
        flip = np.full(n, np.inf)

        # Closed-form branch: symmetry/spin axis e (caller frame), transverse moment It.
        e = np.zeros((n, 3))
        it = np.ones(n)
        if eq12 and eq23:
            kind[:] = _CLOSED
            regime[:] = 'spherical'
            e[:, order[2]] = 1.0
            it[:] = moments.mean()
        elif eq12 or eq23:
            kind[:] = _CLOSED
            regime[:] = 'symmetric'
            axis = order[2] if eq12 else order[0]
            e[:, axis] = 1.0
            it[:] = 0.5 * (i1 + i2) if eq12 else 0.5 * (i2 + i3)
        else:
            ms = m0[:, order]
            j = np.argmax(np.abs(ms), axis=-1)
            off = np.abs(ms)
            off[np.arange(n), j] = 0.0
            perp = np.linalg.norm(off, axis=-1)
            steady = perp <= STEADY_RTOL * G
            kind[steady] = _CLOSED
            regime[steady] = 'steady_spin'
            e[np.flatnonzero(steady), order[j[steady]]] = 1.0
            it[steady] = moments[order[j[steady]]]
            # Δ2 as a sum of two terms of opposite sign; its own round-off sets the tolerance.
            t1, t3 = ms[:, 0] ** 2 * (i1 - i2) / i1, ms[:, 2] ** 2 * (i3 - i2) / i3
            d2 = t1 + t3
            sep = ~steady & (np.abs(d2) <= SEPARATRIX_RTOL * (np.abs(t1) + t3))
            kind[sep] = _SEPARATRIX
            regime[sep] = 'separatrix'
            ell = ~steady & ~sep
            regime[ell & (d2 > 0)] = 'A'
            regime[ell & (d2 < 0)] = 'B'
        self.regime = regime.reshape(self.batch_shape) if self.batch_shape else regime[0]
        self._kind = kind

        # --- closed-form constants
        c = kind == _CLOSED
        me = np.sum(m0 * e, axis=-1)
        ie = np.where(c, e @ moments, 1.0)
        self._e = e
        self._ws = np.where(c, me * (1.0 / ie - 1.0 / it), 0.0)
        self._me, self._ie, self._it = me, ie, it        # the kernel's double-double rates
        body_rate = np.abs(self._ws)
        omega_period[c] = np.where(body_rate[c] > 0,
                                   2 * np.pi / np.where(body_rate[c] > 0, body_rate[c], 1.0),
                                   np.inf)
        flip[c] = 0.5 * omega_period[c]

        self._G, self._order = G, order
        self._numpy_ready = False                        # at_numpy's constants, on first use

        # The compiled kernel's constants (double-double, exact_kernel.pack); its anchor
        # C = q0 ⊗ w ⊗ E(0)* and P0 = P_r(u0) come from the very code of at(t), so at(0)
        # returns q0 to round-off whatever φ(0) is (2j0·cphi·Π need not vanish).
        self._rows = exact_kernel.pack(self)             # built and anchored
        self._row0 = self._rows[0]                       # at(t)'s one-body fast path
        el = kind == _ELLIPTIC                           # periods from the kernel's 2K/λ
        flip[el] = self._rows[el, exact_kernel.TK_H] / self._rows[el, exact_kernel.LAM_H]
        omega_period[el] = 2 * flip[el]
        shape = self.batch_shape
        self.kinetic_energy = T.reshape(shape)
        self.angular_momentum_norm = G.reshape(shape)
        self.omega_period = omega_period.reshape(shape)
        self.flip_interval = flip.reshape(shape)

    def _numpy_setup(self):
        """The numpy path's constants (long double, scipy), built on at_numpy's first call."""
        n, kind, regime = len(self._kind), self._kind, np.asarray(self.regime).ravel()
        q0, m0, G, order = self._q0, self._m0, self._G, self._order
        c, me, ie, it = kind == _CLOSED, self._me, self._ie, self._it
        # The rates multiply t: kept in long double too (see .extended).
        g_ld = np.sqrt(np.sum(m0.astype(LD) ** 2, axis=-1))
        self._ws_ld = np.where(c, me.astype(LD) * (1 / ie.astype(LD) - 1 / it.astype(LD)), 0)
        self._rate_l_ld = np.where(c, g_ld / it, 0)
        # L̂ in space; at rest any axis will do (the rate is 0).
        lhat = rotation.rotate(q0, m0 / np.where(G > 0, G, 1.0)[:, None])
        self._lhat = np.where((G > 0)[:, None], lhat, [0.0, 0.0, 1.0])
        # --- elliptic and separatrix constants (only for those bodies; others keep dummies)
        self._W = np.tile(np.eye(3), (n, 1, 1))
        self._w = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        frames = _frame_quaternions(tuple(order.tolist()))
        for which, mask in ((0, (kind != _CLOSED) & (regime != 'B')), (1, regime == 'B')):
            self._W[mask], self._w[mask] = frames[which]
        names = ('N', 'sigd', 'sigx', 's', 'lam', 'u0', 'mx', 'my', 'mz', 'kp2', 'kp', 'K', 'pic',
                 'rate0', 'cphi', 'G', 'P0', 'lam_ld', 'K_ld', 'pic_ld', 'rate0_ld', 'cphi_ld',
                 'N_ld')
        const = {k: np.ones(n, LD if k.endswith('_ld') else float) for k in names}
        idx = np.flatnonzero(kind != _CLOSED)
        if idx.size:
            for k, v in self._elliptic_constants(kind[idx], self._W[idx], m0[idx], G[idx]).items():
                const[k][idx] = v
        for k in names:
            setattr(self, '_' + k, const[k])

        self._C = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))  # anchor as the kernel's
        if idx.size:
            self._P0[idx] = 0.0
            self._P0[idx] = self._moving(idx, np.zeros(idx.size))[2]
            e0 = self._moving(idx, np.zeros(idx.size))[0]
            self._C[idx] = rotation.multiply(
                rotation.multiply(self._q0[idx], self._w[idx]), rotation.conjugate(e0))
        self._numpy_ready = True

    def _elliptic_constants(self, kind, W, m0, G):
        """Constants of the elliptic (A, B) and separatrix bodies, in their working frames.
        Those that multiply t or the half-period count j are kept in long double (``*_ld``)."""
        mw = np.einsum('nij,nj->ni', W, m0)             # exact: W is a signed permutation
        ix, iy, iz = (np.abs(W) @ self.moments).T      # working moments
        lx, ly, lz = (v.astype(LD) for v in (ix, iy, iz))
        sq = mw.astype(LD) ** 2
        dx = sq[:, 1] * (ly - lx) / ly + sq[:, 2] * (lz - lx) / lz
        dy = sq[:, 0] * (lx - ly) / lx + sq[:, 2] * (lz - ly) / lz
        dz = sq[:, 0] * (lx - lz) / lx + sq[:, 1] * (ly - lz) / ly
        g = np.sqrt(np.sum(sq, axis=-1))
        sp = kind == _SEPARATRIX
        n_ld = lz * (ly - lx) / (lx * (lz - ly))
        c = dict(N=n_ld.astype(float), G=G, P0=np.zeros(len(G)), N_ld=n_ld)
        c['sigd'] = np.where(mw[:, 2] < 0, -1.0, 1.0)
        c['sigx'] = np.where(mw[:, 0] < 0, -1.0, 1.0)
        with np.errstate(divide='ignore', invalid='ignore'):   # separatrix rows are replaced below
            lam = np.sqrt((lz - ly) * dx / (lx * ly * lz))
            mx = np.sqrt(lx * -dz / (lz - lx)).astype(float)
            my = np.sqrt(ly * -dz / (lz - ly)).astype(float)
            mz = np.sqrt(lz * dx / (lz - lx)).astype(float)
            kp2 = np.where(sp, 0.5, dy * (lz - lx) / (dx * (lz - ly)))
        # On the separatrix Δy = 0 exactly: My = G, λ = σ, and m_x, m_z carry independent signs.
        c['mx'] = np.where(sp, G * np.sqrt(ix * (iz - iy) / (iy * (iz - ix))), mx)
        c['mz'] = np.where(sp, G * np.sqrt(iz * (iy - ix) / (iy * (iz - ix))), mz)
        c['my'] = np.where(sp, G, my)
        c['s'] = np.where(sp, c['sigx'], 1.0) * c['sigd'] * np.sign(iz - iy)
        lam = np.where(sp, (g / ly) * np.sqrt((lz - ly) * (ly - lx) / (lx * lz)), lam)
        kp = np.sqrt(kp2)
        # K = cel(k', 1), Π(−N|k²) = cel(k', 1 + N): from k' directly, no cancellation.
        K, pic = cel(np.stack((kp, kp)), np.stack((np.ones_like(n_ld), 1 + n_ld)))
        rate0 = g / lz
        cphi = rate0 * (lz - lx) / (lx * lam)
        c.update(lam_ld=lam, K_ld=K, pic_ld=pic, rate0_ld=rate0, cphi_ld=cphi)
        c.update({k: v.astype(float) for k, v in (('lam', lam), ('K', K), ('pic', pic),
                                                    ('rate0', rate0), ('cphi', cphi),
                                                    ('kp2', kp2), ('kp', kp))})
        # u0 = F(am u0), am u0 from (cn, sn) = (m_x/Mx, m_y/(s My)), reduced to |am| ≤ π/2.
        ang = np.arctan2(mw[:, 1] / (c['s'] * c['my']), mw[:, 0] / c['mx'])
        turn = np.where(np.abs(ang) > 0.5 * np.pi, np.sign(ang), 0.0)
        sr, cr = np.sin(ang - turn * np.pi), np.cos(ang - turn * np.pi)
        u0 = turn * 2 * c['K'] + sr * elliprf(cr * cr, cr * cr + c['kp2'] * sr * sr, 1.0)
        with np.errstate(divide='ignore', invalid='ignore'):
            c['u0'] = np.where(sp, np.arcsinh(c['s'] * mw[:, 1] / np.hypot(mw[:, 0], mw[:, 2])),
                               u0)
        return c

    def _moving(self, b, t):
        """Working-frame E(t) = Rz(φ)Rx(θ)Rz(ψ), m_work and P_r for elliptic/separatrix
        bodies b, where P(u) = (secular part, in long double) + P_r; P0 holds P_r(u0)."""
        tl = np.asarray(t, LD)
        u = self._lam_ld[b] * tl + self._u0[b]         # long double: λt reaches ~1e7
        sep = self._kind[b] == _SEPARATRIX
        if np.all(sep):
            return self._separatrix(b, tl, u)
        mx, my, mz, s, sigd = self._mx[b], self._my[b], self._mz[b], self._s[b], self._sigd[b]
        K, kp, kp2, N = self._K[b], self._kp[b], self._kp2[b], self._N[b]
        two_k = 2 * self._K_ld[b]
        j = np.rint(u / two_k)
        r_ld = u - two_k * j                             # |r| ≤ K, exact to ~eps_ld·|u|
        r = r_ld.astype(float)
        ar = np.abs(r)
        near = ar > 0.5 * K
        sv, cv, dv, _ = ellipj(np.where(near, (self._K_ld[b] - np.abs(r_ld)).astype(float), ar),
                               1.0 - kp2)
        sn = np.copysign(np.where(near, cv / dv, sv), r)
        cn = np.where(near, kp * sv / dv, cv)
        dn = np.where(near, kp / dv, dv)
        P = _carlson_pi(sn, cn, dn, N)
        # φ = rate0·t + cphi·(2j·Π(−N|k²) + P_r − P0): the secular terms grow without bound,
        # so they are summed in long double and reduced modulo 4π.
        secular = self._rate0_ld[b] * tl + self._cphi_ld[b] * (2 * j * self._pic_ld[b])
        j = j.astype(float)
        par = 1.0 - 2.0 * (j % 2)
        m = np.stack((mx * par * cn, s * my * par * sn, sigd * mz * dn), axis=-1)
        A = (j % 4) * np.pi + np.arctan2(sn, cn)         # ψ enters as ψ/2: jπ modulo 4π
        delta = np.arctan2((my - mx) * sn * cn, mx * cn * cn + my * sn * sn)
        psi = 0.5 * np.pi - s * (A + delta)
        phi = reduce_4pi(secular) + self._cphi[b] * (P - self._P0[b])
        theta = np.arctan2(np.hypot(m[..., 0], m[..., 1]), m[..., 2])
        E = _qz_qx_qz(phi, theta, psi)
        if np.any(sep):
            Es, ms, Ps = self._separatrix(b, tl, u)
            E, m, P = (np.where(sep[:, None], Es, E), np.where(sep[:, None], ms, m),
                       np.where(sep, Ps, P))
        return E, m, P

    def _separatrix(self, b, tl, u):
        """P(u) = [u + √N atan(√N tanh u)]/(1 + N): secular part λt/(1 + N) in long double."""
        N = self._N[b]
        u = u.astype(float)
        th = np.tanh(u)
        ex = np.exp(-np.abs(u))
        se = 2 * ex / (1 + ex * ex)                      # sech without overflow
        rn = np.sqrt(N)
        P = (self._u0[b] + rn * np.arctan(rn * th)) / (1 + N)
        m = np.stack((self._sigx[b] * self._mx[b] * se, self._s[b] * self._G[b] * th,
                      self._sigd[b] * self._mz[b] * se), axis=-1)
        psi = np.arctan2(m[..., 0], m[..., 1])
        secular = (self._rate0_ld[b] * tl
                   + self._cphi_ld[b] * self._lam_ld[b] * tl / (1 + self._N_ld[b]))
        phi = reduce_4pi(secular) + self._cphi[b] * (P - self._P0[b])
        theta = np.arctan2(np.hypot(m[..., 0], m[..., 1]), m[..., 2])
        return _qz_qx_qz(phi, theta, psi), m, P

    def at(self, t):
        """(q, m) at time(s) t (s), t broadcast against the batch shape: the compiled
        kernel (:mod:`.exact_kernel`). With JIT disabled, large evaluations take the
        vectorised numpy path instead (same formulas; the kernel would be a Python loop)."""
        if not self.batch_shape and isinstance(t, (float, int, np.floating, np.integer)):
            t = float(t)
            if not math.isfinite(t):
                raise ValueError(f'time must be finite, got {t}')
            return exact_kernel.at_one(self._row0, t)
        t = np.asarray(t, float)
        if not np.all(np.isfinite(t)):
            raise ValueError(f'time must be finite, got {t}')
        shape = np.broadcast_shapes(t.shape, self.batch_shape)
        if not exact_kernel.COMPILED and np.prod(shape, dtype=int) > 64:
            return self.at_numpy(t)
        if not self.batch_shape:
            q, m = exact_kernel.at_times(self._rows[0], np.ascontiguousarray(t.ravel()))
            return q.reshape(shape + (4,)), m.reshape(shape + (3,))
        n = len(self._kind)
        body = np.broadcast_to(np.arange(n).reshape(self.batch_shape), shape).ravel()
        tt = np.ascontiguousarray(np.broadcast_to(t, shape).ravel())
        q = np.empty((tt.size, 4))
        m = np.empty((tt.size, 3))
        exact_kernel.evaluate(self._rows, body, tt, q, m)
        return q.reshape(shape + (4,)), m.reshape(shape + (3,))

    def at_numpy(self, t):
        """at(t) by the vectorised numpy path (long-double phases, scipy.special): the
        reference the compiled kernel is tested against, and JIT-less bulk evaluation."""
        if not self._numpy_ready:
            self._numpy_setup()
        t = np.asarray(t, float)
        if not np.all(np.isfinite(t)):
            raise ValueError(f'time must be finite, got {t}')
        shape = np.broadcast_shapes(t.shape, self.batch_shape)
        n = len(self._kind)
        body = np.broadcast_to(np.arange(n).reshape(self.batch_shape), shape).ravel()
        tt = np.broadcast_to(t, shape).ravel()
        q = np.empty((tt.size, 4))
        m = np.empty((tt.size, 3))
        closed = self._kind[body] == _CLOSED
        for sel in (np.flatnonzero(closed), np.flatnonzero(~closed)):
            if sel.size == 0:
                continue
            b, ts = body[sel], tt[sel]
            if closed[sel[0]]:
                tl = ts.astype(LD)                       # angles reduced in long double
                spin = self._e[b] * reduce_4pi(self._ws_ld[b] * tl)[:, None]
                q[sel] = rotation.multiply(
                    rotation.multiply(
                        rotation.exp(self._lhat[b] * reduce_4pi(self._rate_l_ld[b] * tl)[:, None]),
                        self._q0[b]),
                    rotation.exp(spin))
                m[sel] = rotation.rotate(rotation.exp(-spin), self._m0[b])
            else:
                E, mw, _ = self._moving(b, ts)
                qs = rotation.multiply(rotation.multiply(self._C[b], E),
                                       rotation.conjugate(self._w[b]))
                q[sel] = qs
                m[sel] = np.einsum('nji,nj->ni', self._W[b], mw)
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        return q.reshape(shape + (4,)), m.reshape(shape + (3,))
