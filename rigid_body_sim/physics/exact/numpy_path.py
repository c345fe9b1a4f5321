"""The vectorised numpy path of :class:`.exact.TorqueFreeSolution` (``at_numpy``): the
same formulas as the compiled kernel, with the constants and secular phases in long double
(:mod:`.extended`) and scipy.special's ellipj/elliprf/elliprj, over many bodies and times
at once. It is the second opinion the compiled kernel is tested against. Its limits (see
exact.py): long double is plain double on macOS arm64/MSVC, and ellipj takes m = 1 − k'²,
which near the separatrix carries k'² only to eps/k'².
"""
import functools

import numpy as np

from .. import rotation
from .kernel import CLOSED as _CLOSED, SEPARATRIX as _SEPARATRIX
from .extended import LD, cel, reduce_4pi

# scipy.special is imported at the first evaluation, not with the module: every process
# that steps a body imports this one, most never take this path (rotation.py: start-up)
def ellipj(u, m):
    from scipy.special import ellipj as f
    return f(u, m)


def elliprf(x, y, z):
    from scipy.special import elliprf as f
    return f(x, y, z)


def elliprj(x, y, z, p):
    from scipy.special import elliprj as f
    return f(x, y, z, p)


@functools.lru_cache(maxsize=8)
def _frame_quaternions(order):
    """Signed permutations W (rows = working axes in caller indices), det +1, for frames A, B."""
    wa = np.eye(3)[list(order)]
    if np.linalg.det(wa) < 0:          # odd sort: flip the intermediate axis
        wa[1] *= -1.0
    wb = np.array([wa[2], -wa[1], wa[0]])
    return [(w, rotation.from_matrix(w.T)) for w in (wa, wb)]


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


class NumpyPath:
    """Mixin of TorqueFreeSolution: ``at_numpy`` and the constants it needs, set up on
    first use from the attributes __init__ leaves (moments, _q0, _m0, _kind, regime, _G,
    _order, _e, _me, _ie, _it)."""

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

    def at_numpy(self, t):
        """at(t) by the vectorised numpy path (long-double phases, scipy.special): the
        reference the compiled kernel is tested against."""
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
