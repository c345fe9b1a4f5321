"""Lie–Poisson splitting (McLachlan 1993; Touma & Wisdom 1994; Reich 1994) and its compositions.

The free-body Hamiltonian H = Σ m_i²/(2 I_i) splits into three terms whose flows are
exact rotations: under m_i²/(2 I_i), m turns about principal axis e_i by −φ and the
attitude by +φ (q ← q ⊗ exp(φ e_i/2)), φ = m_i t / I_i, with m_i constant. Composing
them keeps |m| to round-off, is a Poisson map and time-reversible, and the attitude
never leaves the rotation group (unit quaternions from exact exponentials).

Axis order (``_ORDER``) sets the energy-error constant. Measured at h·|ω|max = 0.2 on
40 random bodies, the six orders span 4× in geometric mean and up to 33× on the standard
scene I = (2, 1, 2/3): putting the major axis outermost is worst throughout. We use
(minor, major, intermediate), the lowest geometric-mean error of the six.

Torque and dissipation enter by splitting too (Strang, symmetric):
    S(h) = D(h/2) K(h/2) F(h) K(h/2) D(h/2)
K: the torque kick m ← m + τ t (zero-order-held body torque; attitude unchanged).
D: dissipation. viscous: m_i ← m_i e^{−c t/I_i} (exact). double bracket: ṁ = w(m) × m with
   w = −α m×Ω, a rotation of m, advanced by the Lie midpoint rule (order 2) in substeps
   short enough for the stiffness, so |m| stays exact and T falls at any h.
Higher orders compose the conservative part (Yoshida triple jump → 4, Yoshida's 7-stage
solution A → 6); dissipation stays outside those compositions because their negative
substeps would run damping backwards (anti-damping), so with dissipation the coupling
error is second order.

Loops: one body runs ``splitting_kernel.splitting_run``; ``run`` on a batch runs
``splitting_batch_kernel.batch_run`` (bodies side by side, merged half-flows); ``step`` on a batch
stays on numpy (the reference the compiled loops are tested against).
"""
import functools
import math

import numpy as np

from .. import dynamics_kernel
from . import splitting_batch_kernel, splitting_kernel
from .base import Candidate, IntegrationError, Integrator, same_order

# Outer, middle, inner axis of the symmetric composition  a(h/2) b(h/2) c(h) b(h/2) a(h/2)
# as ranks of the principal moments (0 = smallest, 1 = intermediate, 2 = largest).
_ORDER = (0, 2, 1)
_BLOCK = 4096  # bodies per block in batch mode (fits temporaries in L2 cache)
INNER_LIMIT = splitting_kernel.INNER_LIMIT  # the rule is splitting_kernel.weak_damping


def _axis_flow(q, m, axis, t, moments, xp):
    """Exact flow of m_axis²/(2 I_axis) for time t (may be negative), in place.

    q = [x, y, z, w] and m = [m0, m1, m2] are lists of components: Python floats for one
    body (xp = math, ~10× faster than numpy on scalars) or (N,) arrays for a batch (xp =
    numpy). The rotation by φ uses half-angle identities: two trig calls instead of four.
    """
    b, c = (axis + 1) % 3, (axis + 2) % 3
    half = m[axis] * (0.5 * t / moments[axis])
    s, w = xp.sin(half), xp.cos(half)
    cos_phi, sin_phi = w * w - s * s, 2.0 * s * w
    mb, mc = m[b], m[c]
    m[b] = cos_phi * mb + sin_phi * mc          # m ← R_axis(−φ) m
    m[c] = cos_phi * mc - sin_phi * mb
    qa, qb, qc, qw = q[axis], q[b], q[c], q[3]  # q ← q ⊗ (sin(φ/2) e_axis, cos(φ/2))
    q[axis] = w * qa + s * qw
    q[b] = w * qb + s * qc
    q[c] = w * qc - s * qb
    q[3] = w * qw - s * qa


def _rotate_about(m, theta, xp):
    """m ← exp([θ]×) m (Rodrigues), on component lists, stable for small |θ|."""
    a2 = theta[0] * theta[0] + theta[1] * theta[1] + theta[2] * theta[2]
    a = xp.sqrt(a2)
    half = 0.5 * a
    sinc_half = (xp.sinc(half / math.pi) if xp is np
                 else (math.sin(half) / half if half > 1e-8 else 1.0 - half * half / 6))
    s1 = sinc_half * xp.cos(half)          # sin(a)/a
    s2 = 0.5 * sinc_half * sinc_half       # (1 − cos a)/a²
    c = 1.0 - a2 * s2                      # cos a
    dot = theta[0] * m[0] + theta[1] * m[1] + theta[2] * m[2]
    tx = theta[1] * m[2] - theta[2] * m[1]
    ty = theta[2] * m[0] - theta[0] * m[2]
    tz = theta[0] * m[1] - theta[1] * m[0]
    m[0] = c * m[0] + s1 * tx + s2 * dot * theta[0]
    m[1] = c * m[1] + s1 * ty + s2 * dot * theta[1]
    m[2] = c * m[2] + s1 * tz + s2 * dot * theta[2]


def _bracket_velocity(m, dt, moments, alpha):
    """θ = dt·w(m), w = −α m×Ω: the rotation that the double bracket applies to m."""
    o0, o1, o2 = m[0] / moments[0], m[1] / moments[1], m[2] / moments[2]
    k = -alpha * dt
    return [k * (m[1] * o2 - m[2] * o1), k * (m[2] * o0 - m[0] * o2), k * (m[0] * o1 - m[1] * o0)]


def _double_bracket_flow(m, t, moments, alpha, xp):
    """ṁ = α m×(m×Ω) = w(m)×m, w = −α m×Ω, for time t > 0, in place; keeps |m| exactly.

    Lie midpoint (order 2): m_half = exp(t/2·w(m)) m; m ← exp(t·w(m_half)) m. Substeps
    keep α|m|²t(1/I_min − 1/I_max) ≤ 0.5, where the linearised flow is well resolved.
    Returns the number of substeps.
    """
    norm2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2]
    norm2 = float(np.max(norm2)) if xp is np else norm2
    rate = alpha * norm2 * (1.0 / min(moments) - 1.0 / max(moments))
    n = max(1, int(math.ceil(rate * t / 0.5)))
    dt = t / n
    for _ in range(n):
        m_half = list(m)
        _rotate_about(m_half, _bracket_velocity(m, 0.5 * dt, moments, alpha), xp)
        _rotate_about(m, _bracket_velocity(m_half, dt, moments, alpha), xp)
    return n


class Splitting2(Integrator):
    """Strang splitting of the free body into exact axis rotations: order 2, Lie–Poisson.

    Keeps |m| and |q| to round-off at any step; energy error O(h²), bounded, no drift.
    """
    name = 'splitting2'
    order = 2
    orders = same_order(2)     # compositions: theirs with weak damping, 2 with stiff
    stages = 1                 # = len(weights)
    loop_code = 0
    auto = Candidate((0.092, 0.23), 0.30)
    kernel_modules = (splitting_kernel, splitting_batch_kernel)
    environment = True  # a kick at fixed attitude at the kick's instant (splitting_kernel)
    environment_evaluations = 2  # two kicks per stage (splitting_kernel): 2·len(weights)
    preserves = frozenset({'angular_momentum_norm', 'unit_quaternion', 'poisson',
                           'time_reversible'})
    stability = 'no step-size limit for free rotation (error bounded, |m| exact at any h)'
    # Composition weights of the Strang step (Yoshida); (1.0,) is Strang itself.
    weights = (1.0,)

    def __init__(self, dynamics):
        super().__init__(dynamics)
        self._moments_list = [float(i) for i in dynamics.moments]
        # plain Python (auto builds one per candidate to ask its order; numpy's per-call
        # cost made that 7 µs); sorted() is stable like argsort(kind='stable')
        ranks = sorted(range(3), key=self._moments_list.__getitem__)
        self._axes = tuple(ranks[r] for r in _ORDER)
        d = dynamics.dissipation
        self._model = dynamics_kernel.MODEL_CODES[d.model] if d.active else 0
        self._coefficient = d.coefficient

    @functools.cached_property
    def _kernel_args(self):
        """(weights, axes, moments) as arrays for the compiled loops, built on first use."""
        return (np.array(self.weights, dtype=float), np.array(self._axes),
                np.array(self.dynamics.moments, dtype=float))

    def inner_dissipation(self, m, h) -> bool:
        """Whether damping goes inside every stage of the composition (symmetric flow): for
        compositions (order 4, 6) when damping is weak at step h, |w|·h·λ ≤ INNER_LIMIT with
        λ the dissipation stiffness; the composition then keeps its order. Otherwise it
        stays outside (no stage runs damping backwards) and the coupling is order 2.
        The rule is ``splitting_kernel.weak_damping``, which the closed loop uses too."""
        if self._model == 0 or len(self.weights) == 1:
            return False
        if np.ndim(m) == 1:  # one body, asked per step size by auto: plain floats
            x, y, z = m.tolist() if isinstance(m, np.ndarray) else m
            return bool(self._weak_damping(math.sqrt(x * x + y * y + z * z), h))
        return bool(self._weak_damping(float(np.max(np.linalg.norm(m, axis=-1))), h))

    def _weak_damping(self, norm, h):
        """|w|·h·λ(|m|) ≤ INNER_LIMIT for one momentum norm."""
        return self._weak(self.dynamics, norm, h)

    def _weak_bodies(self, norms, h):
        """The same for each of a batch's momentum norms (an array of bools)."""
        out = np.empty(len(norms), dtype=bool)
        splitting_kernel.weak_damping_bodies(np.ascontiguousarray(norms, dtype=float), float(h),
                                             float(max(map(abs, self.weights))),
                                             self._kernel_args[2], self._model,
                                             float(self._coefficient), out)
        return out

    @classmethod
    def _weak(cls, dynamics, norm, h):
        d = dynamics.dissipation
        return splitting_kernel.weak_damping(
            float(norm), float(h), float(max(map(abs, cls.weights))), dynamics.moments,
            dynamics_kernel.MODEL_CODES[d.model], float(d.coefficient))

    @classmethod
    def order_on(cls, dynamics, momentum_norm, h) -> int:
        """The order at step h (see inner_dissipation): a composition keeps its own only
        with the damping inside, where it is weak; the damping outside couples at order 2."""
        if not dynamics.dissipation.active or len(cls.weights) == 1 or \
                cls._weak(dynamics, momentum_norm, h):
            return super().order_on(dynamics, momentum_norm, h)
        return 2

    def _kernel(self, q, m, h, n, tau, has_tau, t0=0.0):
        weights, axes, moments = self._kernel_args
        failed, evals = splitting_kernel.splitting_run(q, m, h, n, weights, axes, moments, tau,
                                                       has_tau, self._model, self._coefficient,
                                                       self.inner_dissipation(m, h), t0,
                                                       self.dynamics.environment)
        self.nfev += evals
        return failed

    def loop_spec(self):
        return self._kernel_args[0], self._kernel_args[1]

    def run(self, q, m, h, n, torque=None, t0=0.0):
        """One body: the compiled loop (splitting_kernel); a batch (q (..., 4), m (..., 3),
        torque (3,) shared or (..., 3) per body): the compiled batch loop
        (splitting_batch_kernel), every body as if run alone — damping's substeps and
        inner/outer placement are chosen per body, where the numpy ``step`` on a batch
        chooses them once for the batch."""
        if np.ndim(q) == 1 and np.ndim(m) == 1:
            return self._run_kernel(self._kernel, q, m, h, n, torque, t0)
        self._one_body_only(q, t0)
        return self._run_batch(q, m, h, n, torque, t0)

    def _run_batch(self, q, m, h, n, torque, t0):
        if not (np.isfinite(h) and h > 0.0):
            raise IntegrationError(self.name, h, t0, 'step must be finite and positive')
        q, m = np.asarray(q, float), np.asarray(m, float)
        shape = np.broadcast_shapes(q.shape[:-1], m.shape[:-1])
        # np.array copies: the kernel works in place on C-contiguous (N, 4) and (N, 3).
        q = np.array(np.broadcast_to(q, shape + (4,)).reshape(-1, 4), order='C')
        m = np.array(np.broadcast_to(m, shape + (3,)).reshape(-1, 3), order='C')
        if torque is None or np.ndim(torque) == 1:
            tau = np.zeros((1, 3)) if torque is None else np.array(torque, float).reshape(1, 3)
        else:
            tau = np.array(np.broadcast_to(torque, shape + (3,)).reshape(-1, 3), float, order='C')
        if self._model != 0 and len(self.weights) > 1:  # each body's own inner/outer choice
            inner = self._weak_bodies(np.linalg.norm(m, axis=-1), h)
        else:
            inner = np.zeros(1, dtype=bool)
        weights, axes, moments = self._kernel_args
        failed, body, evals = splitting_batch_kernel.batch_run(
            q, m, float(h), int(n), weights, axes, moments, tau, torque is not None,
            self._model, self._coefficient, inner)
        self.nfev += evals
        if failed >= 0:
            raise IntegrationError(self.name, h, t0 + (failed + 1) * h,
                                   f'state became non-finite (the method diverged), body {body}')
        return q.reshape(shape + (4,)), m.reshape(shape + (3,))

    def _step(self, q, m, h, torque, t):
        """D(h/2) · [composition of K a b c b a K] · D(h/2) on component lists.

        One body runs on Python floats (~10× faster than numpy on scalars); a batch runs
        on (N,) component arrays in blocks small enough for the CPU cache (temporaries of
        10⁶ bodies would be memory-bound).
        """
        if q.ndim == 1:  # the compiled loop, one step (the finiteness check is step()'s)
            q, m = q.copy(), m.copy()
            tau = np.zeros(3) if torque is None else np.broadcast_to(torque, (3,)).astype(float)
            self._kernel(q, m, h, 1, tau, torque is not None, t)
            return q, m
        self._one_body_only(q, t)
        shape = np.broadcast_shapes(q.shape[:-1], m.shape[:-1])
        q_flat = np.broadcast_to(q, shape + (4,)).reshape(-1, 4)
        m_flat = np.broadcast_to(m, shape + (3,)).reshape(-1, 3)
        t_flat = None if torque is None else np.broadcast_to(torque, shape + (3,)).reshape(-1, 3)
        q_out, m_out = np.empty_like(q_flat), np.empty_like(m_flat)
        for lo in range(0, len(q_flat), _BLOCK):
            sl = slice(lo, lo + _BLOCK)
            qc = [q_flat[sl, i].copy() for i in range(4)]
            mc = [m_flat[sl, i].copy() for i in range(3)]
            tc = None if t_flat is None else [t_flat[sl, i] for i in range(3)]
            self._components_step(qc, mc, h, tc, np)
            for i in range(4):
                q_out[sl, i] = qc[i]
            for i in range(3):
                m_out[sl, i] = mc[i]
        return q_out.reshape(shape + (4,)), m_out.reshape(shape + (3,))

    def _components_step(self, qc, mc, h, tc, xp):
        inner = self.inner_dissipation(np.stack(mc, axis=-1), h)
        if not inner:
            self._dissipate_components(mc, 0.5 * h, xp)
        self._compose(qc, mc, h, tc, xp, inner)
        if not inner:
            self._dissipate_components(mc, 0.5 * h, xp)
        self.nfev += len(self.weights)

    def _compose(self, qc, mc, h, tc, xp, inner=False):
        moments = self._moments_list
        a, b, c = self._axes
        for w in self.weights:
            hw = w * h
            if inner:
                self._dissipate_symmetric(mc, 0.5 * hw, xp)
            if tc is not None:
                for i in range(3):
                    mc[i] = mc[i] + (0.5 * hw) * tc[i]
            _axis_flow(qc, mc, a, 0.5 * hw, moments, xp)
            _axis_flow(qc, mc, b, 0.5 * hw, moments, xp)
            _axis_flow(qc, mc, c, hw, moments, xp)
            _axis_flow(qc, mc, b, 0.5 * hw, moments, xp)
            _axis_flow(qc, mc, a, 0.5 * hw, moments, xp)
            if tc is not None:
                for i in range(3):
                    mc[i] = mc[i] + (0.5 * hw) * tc[i]
            if inner:
                self._dissipate_symmetric(mc, 0.5 * hw, xp)

    def _dissipate_symmetric(self, mc, t, xp):
        """D(t), time-symmetric (t of either sign): see
        dynamics_kernel._double_bracket_symmetric."""
        d = self.dynamics.dissipation
        moments = self._moments_list
        if d.model == 'viscous':
            for i in range(3):
                mc[i] = mc[i] * xp.exp(-d.coefficient * t / moments[i])
            return
        m0 = list(mc)
        _rotate_about(mc, _bracket_velocity(m0, t, moments, d.coefficient), xp)
        scale = xp.sqrt(m0[0] * m0[0] + m0[1] * m0[1] + m0[2] * m0[2])
        self.nfev += 1
        for _ in range(dynamics_kernel.SYMMETRIC_MAX_ITER):
            mid = [0.5 * (m0[i] + mc[i]) for i in range(3)]
            new = list(m0)
            _rotate_about(new, _bracket_velocity(mid, t, moments, d.coefficient), xp)
            change = sum(abs(new[i] - mc[i]) for i in range(3))
            mc[:] = new
            self.nfev += 1
            if np.all(change <= dynamics_kernel.SYMMETRIC_TOL * scale):
                break

    def _dissipate_components(self, mc, t, xp):
        d = self.dynamics.dissipation
        if not d.active:
            return
        moments = self._moments_list
        if d.model == 'viscous':
            for i in range(3):
                mc[i] = mc[i] * xp.exp(-d.coefficient * t / moments[i])
        else:
            self.nfev += 2 * _double_bracket_flow(mc, t, moments, d.coefficient, xp)

    def _dissipate(self, m, t):
        """D(t) on an (…, 3) array (used by integrators that reuse this splitting)."""
        m = np.array(m, float)
        xp = math if m.ndim == 1 else np
        mc = [float(v) for v in m] if m.ndim == 1 else [m[..., i].copy() for i in range(3)]
        self._dissipate_components(mc, t, xp)
        return np.array(mc) if m.ndim == 1 else np.stack(mc, axis=-1)


_YOSHIDA4_OUTER = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
# Yoshida (1990) 7-stage 6th-order solution A: w1, w2, w3, and w0 = 1 − 2(w1 + w2 + w3).
_Y6 = (-1.17767998417887, 0.235573213359357, 0.784513610477560)


class Splitting4(Splitting2):
    """Yoshida triple-jump composition of ``splitting2``: order 4, Lie–Poisson."""
    name = 'splitting4'
    order = 4
    orders = same_order(4)
    stages = 3
    environment_evaluations = 6
    # under a control law (Candidate.torque): E/((hΩ)⁴·ΩT) ≤ 1.4e-3 on 12 generated detumble
    # scenes (seeds 7 and 20261126, up to 1.8·10⁵ rad; no growth beyond linear), set 3× above
    auto = Candidate((0.24, 0.83), 0.07, call=(2.5, 11.0), torque=(4e-3, 0.0))
    weights = (_YOSHIDA4_OUTER, 1.0 - 2.0 * _YOSHIDA4_OUTER, _YOSHIDA4_OUTER)


class Splitting6(Splitting2):
    """Yoshida's 7-stage composition (solution A) of ``splitting2``: order 6, Lie–Poisson."""
    name = 'splitting6'
    order = 6
    orders = same_order(6)
    stages = 7
    environment_evaluations = 14
    # under a control law (Candidate.torque): E/((hΩ)⁶·ΩT) ≤ 1.5e-5 on the same 12 detumble
    # scenes as splitting4's, set 3× above
    auto = Candidate((0.52, 1.96), 1.2e-3, call=(2.5, 11.0), torque=(5e-5, 0.0))
    weights = (_Y6[2], _Y6[1], _Y6[0], 1.0 - 2.0 * sum(_Y6), _Y6[0], _Y6[1], _Y6[2])
