"""One body at one time t on Python floats: the formulas of :mod:`.exact` without numpy's
per-call overhead, which (not arithmetic) dominates a single evaluation. The secular phases
are formed in long double as there (:mod:`.extended`); test_scalar_path_matches_vectorised
keeps the two paths in step.
"""
import math

import numpy as np
from scipy.special import ellipj, elliprf, elliprj

from .extended import LD, reduce_4pi


def closed(rate_l_ld, ws_ld, e, lhat, q0, m0, t):
    """Symmetric body or steady spin: q = exp(L̂ G t/I_t) ⊗ q0 ⊗ exp(e ω_s t), m turned by
    −ω_s t about e."""
    a = 0.5 * reduce_4pi(rate_l_ld * LD(t))
    b = 0.5 * reduce_4pi(ws_ld * LD(t))
    ex, ey, ez = e
    sb = math.sin(b)
    q = qmul(qmul((*(lhat * math.sin(a)), math.cos(a)), q0),
             (ex * sb, ey * sb, ez * sb, math.cos(b)))
    k = int(np.argmax(e))                               # m turns by −ω_s t about axis k
    i, j = (k + 1) % 3, (k + 2) % 3
    cb, sb2 = math.cos(2 * b), math.sin(2 * b)
    m = m0.copy()
    m[i], m[j] = cb * m[i] + sb2 * m[j], cb * m[j] - sb2 * m[i]
    return q, m


def moving(c, separatrix, t):
    """TorqueFreeSolution._moving for one elliptic or separatrix body (constants ``c``)."""
    tl = LD(t)
    u = c['lam_ld'] * tl + c['u0']
    if separatrix:
        uf = float(u)
        th = math.tanh(uf)
        ex = math.exp(-abs(uf))
        se = 2 * ex / (1 + ex * ex)
        rn = math.sqrt(c['N'])
        P = (c['u0'] + rn * math.atan(rn * th)) / (1 + c['N'])
        mw = (c['sigx'] * c['mx'] * se, c['s'] * c['G'] * th, c['sigd'] * c['mz'] * se)
        psi = math.atan2(mw[0], mw[1])
        secular = c['rate0_ld'] * tl + c['cphi_ld'] * c['lam_ld'] * tl / (1 + c['N_ld'])
    else:
        K, kp = c['K'], c['kp']
        two_k = 2 * c['K_ld']
        jl = np.rint(u / two_k)
        r_ld = u - two_k * jl
        r, j = float(r_ld), float(jl)
        ar = abs(r)
        near = ar > 0.5 * K
        sv, cv, dv, _ = ellipj(float(c['K_ld'] - abs(r_ld)) if near else ar, 1.0 - c['kp2'])
        sv, cv, dv = float(sv), float(cv), float(dv)
        sn = math.copysign(cv / dv if near else sv, r)
        cn, dn = (kp * sv / dv, kp / dv) if near else (cv, dv)
        s2, c2, d2 = sn * sn, cn * cn, dn * dn
        P = sn * float(elliprf(c2, d2, 1.0)) - \
            (c['N'] / 3.0) * sn * s2 * float(elliprj(c2, d2, 1.0, 1.0 + c['N'] * s2))
        par = -1.0 if j % 2 else 1.0
        mw = (c['mx'] * par * cn, c['s'] * c['my'] * par * sn, c['sigd'] * c['mz'] * dn)
        delta = math.atan2((c['my'] - c['mx']) * sn * cn, c['mx'] * c2 + c['my'] * s2)
        psi = 0.5 * math.pi - c['s'] * ((j % 4) * math.pi + math.atan2(sn, cn) + delta)
        secular = c['rate0_ld'] * tl + c['cphi_ld'] * (2 * jl * c['pic_ld'])
    phi = reduce_4pi(secular) + c['cphi'] * (P - c['P0'])
    theta = math.atan2(math.hypot(mw[0], mw[1]), mw[2])
    sp, cp = math.sin(0.5 * phi), math.cos(0.5 * phi)
    st, ct = math.sin(0.5 * theta), math.cos(0.5 * theta)
    ss, cs = math.sin(0.5 * psi), math.cos(0.5 * psi)
    x, y, z, w = st * cs, -st * ss, ct * ss, ct * cs
    return (cp * x - sp * y, cp * y + sp * x, cp * z + sp * w, cp * w - sp * z), mw, P


def qmul(p, q):
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return (pw * qx + px * qw + py * qz - pz * qy, pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw, pw * qw - px * qx - py * qy - pz * qz)
