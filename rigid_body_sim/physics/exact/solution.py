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
(:mod:`.kernel`): rates, K, Π and k'² in double-double (:mod:`.constants`, ~1e-32
relative, on every platform), u = 2jK + r and the secular part of φ modulo 4π formed and
reduced there, ψ taking jπ modulo 4π; the Jacobi and Carlson functions
(:mod:`.elliptic_kernel`) see only |r| ≤ K in float64, with k'² passed as such (no 1 − m).
Against a 40-digit reference (bench/reference40.py) the attitude error is ≤ 1.5e-14 rad at
1e3 s and ≤ 5.4e-15 at 1e6 s on every torque-free scene, and ≤ 6.1e-14 beside the
separatrix at k'² down to 2e-13 (test_exact_longhorizon.py).

:meth:`TorqueFreeSolution.at_numpy` keeps the vectorised numpy path (constants and phases
in long double, :mod:`.extended`; scipy.special): the reference the kernel is tested
against. Its accuracy is that of long
double (plain double on macOS arm64/MSVC) and of k'² = 1 − m in float64: ≤ 1.7e-12 rad at
1e6 s on the scenes, but up to 2.4e-9 rad at 1e3 s beside the separatrix.

The output quaternion is continuous in t (no sign jumps).
"""
import math

import numpy as np

from .. import rotation
from ..jit import COMPILED
from . import build as exact_build, grid_kernel, kernel as exact_kernel
from .build import MOMENT_RTOL, SEPARATRIX_RTOL, STEADY_RTOL  # one rule, both paths
from .kernel import CLOSED as _CLOSED, ELLIPTIC as _ELLIPTIC, SEPARATRIX as _SEPARATRIX
from .numpy_path import NumpyPath

__all__ = ['TorqueFreeSolution', 'MOMENT_RTOL', 'SEPARATRIX_RTOL', 'STEADY_RTOL']


class TorqueFreeSolution(NumpyPath):
    """Closed-form torque-free motion of one body or a batch sharing principal ``moments``.

    ``q0`` (4,) or (N, 4), ``m0`` (3,) or (N, 3) at t = 0; ``at(t)`` returns (q, m) with t
    broadcast against the batch shape. Attributes (batch-shaped): kinetic_energy,
    angular_momentum_norm, regime (str), omega_period, flip_interval (ω along the middle
    axis changes sign every flip_interval; inf where it never does).
    """

    def __init__(self, moments, q0, m0):
        # a writable copy: the kernels are compiled for one array type, and a read-only
        # view (Dynamics.moments) would load a second specialisation in mid-run
        moments = np.array(moments, float)
        if moments.shape != (3,) or not all(v > 0.0 and v < math.inf for v in moments.tolist()):
            raise ValueError(f'moments must be 3 finite positive values, got {moments.tolist()}')
        q0 = rotation.validated(q0, 'q0')
        m0 = np.asarray(m0, float)
        if m0.shape[-1:] != (3,) or m0.ndim > 2 or not (
                all(map(math.isfinite, m0.tolist())) if m0.ndim == 1 else np.all(np.isfinite(m0))):
            raise ValueError(f'm0 must be finite with shape (3,) or (N, 3), got {m0.shape}')
        if q0.ndim > 2:
            raise ValueError(f'q0 must have shape (4,) or (N, 4), got {q0.shape}')
        if q0.ndim == 1 and m0.ndim == 1:
            self._one_body(moments, q0, m0)
            return
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

        # The compiled kernel's constants (double-double, exact_build.pack); its anchor
        # C = q0 ⊗ w ⊗ E(0)* and P0 = P_r(u0) come from the very code of at(t), so at(0)
        # returns q0 to round-off whatever φ(0) is (2j0·cphi·Π need not vanish).
        self._rows = exact_build.pack(self)             # built and anchored
        self._row0 = self._rows[0]                       # at(t)'s one-body fast path
        self._grid = None                                # at_grid's (dt, offsets table)
        el = kind == _ELLIPTIC                           # periods from the kernel's 2K/λ
        flip[el] = self._rows[el, exact_kernel.TK_H] / self._rows[el, exact_kernel.LAM_H]
        omega_period[el] = 2 * flip[el]
        shape = self.batch_shape
        self.kinetic_energy = T.reshape(shape)
        self.angular_momentum_norm = G.reshape(shape)
        self.omega_period = omega_period.reshape(shape)
        self.flip_interval = flip.reshape(shape)

    def _one_body(self, moments, q0, m0):
        """__init__ for one body (q0 (4,), m0 (3,)): the batch path's classification and
        constants in float arithmetic, the same operations in the same order, so every
        attribute is bit-identical to it (test_exact_one_body.py); numpy's per-call cost
        on arrays of one was most of an exact run's set-up (~0.19 ms, now ~0.02)."""
        self.batch_shape = ()
        self.moments = moments
        # read-only (1, n) views, as broadcast_to gave: the kernels' argument types
        self._q0, self._m0 = q0.reshape(1, 4), m0.reshape(1, 3)
        self._q0.flags.writeable = self._m0.flags.writeable = False
        inertia, m = moments.tolist(), m0.tolist()
        g = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
        energy = 0.5 * (m[0] * m[0] / inertia[0] + m[1] * m[1] / inertia[1]
                        + m[2] * m[2] / inertia[2])
        order = sorted(range(3), key=inertia.__getitem__)          # stable, as argsort's
        i1, i2, i3 = (inertia[o] for o in order)
        scale = max(inertia)
        eq12, eq23 = i2 - i1 <= MOMENT_RTOL * scale, i3 - i2 <= MOMENT_RTOL * scale
        kind, regime, axis, it = _ELLIPTIC, None, None, 1.0
        if eq12 and eq23:
            kind, regime, axis = _CLOSED, 'spherical', order[2]
            it = (inertia[0] + inertia[1] + inertia[2]) / 3          # moments.mean()
        elif eq12 or eq23:
            kind, regime, axis = _CLOSED, 'symmetric', order[2] if eq12 else order[0]
            it = 0.5 * (i1 + i2) if eq12 else 0.5 * (i2 + i3)
        else:
            ms = [m[o] for o in order]
            off = [abs(v) for v in ms]
            j = max(range(3), key=off.__getitem__)                    # argmax: the first
            off[j] = 0.0
            if math.sqrt(off[0] * off[0] + off[1] * off[1] + off[2] * off[2]) <= STEADY_RTOL * g:
                kind, regime, axis = _CLOSED, 'steady_spin', order[j]
                it = inertia[axis]
            else:
                t1, t3 = ms[0] * ms[0] * (i1 - i2) / i1, ms[2] * ms[2] * (i3 - i2) / i3
                d2 = t1 + t3
                if abs(d2) <= SEPARATRIX_RTOL * (abs(t1) + t3):
                    kind, regime = _SEPARATRIX, 'separatrix'
                elif d2 > 0:
                    regime = 'A'
                elif d2 < 0:
                    regime = 'B'
        e = [0.0, 0.0, 0.0]
        ie, ws = 1.0, 0.0
        if axis is not None:
            e[axis] = 1.0
            ie = inertia[axis]
        me = m[0] * e[0] + (0.0 + m[1] * e[1] + m[2] * e[2])   # np.sum's order and zero signs
        if kind == _CLOSED:
            ws = me * (1.0 / ie - 1.0 / it)
        self.regime = regime
        self._kind = np.array([kind])
        self._e = np.array([e])
        self._ws, self._me, self._ie, self._it = (np.array([ws]), np.array([me]),
                                                  np.array([ie]), np.array([it]))
        self._G, self._order = np.array([g]), np.array(order)
        self._numpy_ready = False
        self._rows = exact_build.pack(self)
        self._row0 = self._rows[0]
        self._grid = None
        period = flip = math.inf
        if kind == _CLOSED:
            period = 2 * np.pi / abs(ws) if abs(ws) > 0 else math.inf
            flip = 0.5 * period
        elif kind == _ELLIPTIC:                          # periods from the kernel's 2K/λ
            flip = self._row0[exact_kernel.TK_H] / self._row0[exact_kernel.LAM_H]
            period = 2 * flip
        self.kinetic_energy = np.array(energy)
        self.angular_momentum_norm = np.array(g)
        self.omega_period = np.array(period)
        self.flip_interval = np.array(flip)

    def at(self, t):
        """(q, m) at time(s) t (s), t broadcast against the batch shape: the compiled
        kernel (:mod:`.kernel`), also with JIT disabled (then a Python loop, but the
        same numbers whatever the number of times: the numpy path differs near the
        separatrix, see at_numpy)."""
        if not self.batch_shape and isinstance(t, (float, int, np.floating, np.integer)):
            t = float(t)
            if not math.isfinite(t):
                raise ValueError(f'time must be finite, got {t}')
            return exact_kernel.at_one(self._row0, t)
        t = np.asarray(t, float)
        if not np.all(np.isfinite(t)):
            raise ValueError(f'time must be finite, got {t}')
        shape = np.broadcast_shapes(t.shape, self.batch_shape)
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

    def at_grid(self, t, dt, out=None):
        """(q (n, 4), m (n, 3)) of one body at the times t (n,) spaced by dt (s), as a
        sampler's grid (its times rounded to float64 are fine): :meth:`at` of those
        times to round-off (~1e-14 rad; where the problem is ill-conditioned, beside the
        separatrix, both as far from the 40-digit reference), in ~1/8 of its time
        (:mod:`.grid_kernel`). Where the grid does not apply, :meth:`at` itself.
        ``out``: (q, m) arrays of those shapes to write into (returned)."""
        if self.batch_shape:
            raise ValueError(f'at_grid takes one body, this solution has {self.batch_shape}')
        t = np.ascontiguousarray(t, dtype=float)
        dt = float(dt)
        if t.ndim != 1 or not np.all(np.isfinite(t)) or not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'at_grid needs finite times (n,) and dt > 0, got shape '
                             f'{t.shape} and dt {dt}')
        if self._grid is None or self._grid[0] != dt:     # the offsets' table, once per dt
            h = grid_kernel.half_width(self._row0, dt)
            self._grid = (dt, grid_kernel.offsets(self._row0, dt, h) if h >= 2 else
                          np.empty((0, 5)))
        q, m = (np.empty((len(t), 4)), np.empty((len(t), 3))) if out is None else out
        if q.shape != (len(t), 4) or m.shape != (len(t), 3):
            raise ValueError(f'at_grid out must be ({len(t)}, 4) and ({len(t)}, 3) arrays, got '
                             f'{q.shape} and {m.shape}')
        grid_kernel.at_grid(self._row0, t, dt, self._grid[1], q, m)
        return q, m

def warm():
    """Compile (or load from the cache) the exact kernels (exact_kernel, exact_build) on one
    body of each kind."""
    for moments, m0 in (((1.0, 2.0, 3.0), (0.1, 1.0, 0.2)), ((1.0, 2.0, 3.0), (0.0, 1.0, 0.0)),
                        ((2.0, 3.0, 6.0), (1.0, 0.5, 1.0))):      # elliptic, steady, separatrix
        sol = TorqueFreeSolution(moments, (0.0, 0.0, 0.0, 1.0), m0)
        sol.at(0.5)
        sol.at(np.array([0.5, 1.0]))
        sol.at_grid(0.5 + 0.01 * np.arange(64), 0.01)
        exact_build.flow(np.array(moments), np.array([0.0, 0.0, 0.0, 1.0]), np.array(m0),
                         0.5, np.empty(4), np.empty(3))
    TorqueFreeSolution((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0),
                       ((0.1, 1.0, 0.2), (0.3, 0.2, 0.1))).at(0.5)
    return COMPILED
