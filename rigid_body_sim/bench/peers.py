"""Peer simulators on the same scenes, same metrics, same process.

* scipy ``solve_ivp`` RK45 and DOP853 (always): the same principal-frame ODE as ours,
  y = (q x y z w, m), with a right-hand side on Python floats (the fastest plain-Python
  form); q is renormalised once at the end, as a user would.
* MuJoCo (``--peers``): one body on a free joint, inertial frame = principal frame
  (``<inertial diaginertia="I1 I2 I3">``), gravity off. Conventions (MuJoCo docs, "free
  joint"; checked here against the exact solution to 1e-14): qpos[3:7] is the body→world
  quaternion in (w, x, y, z) order, qvel[3:6] the angular velocity in the body (local)
  frame, and qfrc_applied[3:6] a torque in the body frame. So q_ours = (qpos[4:7],
  qpos[3]) and ω = m / I. Integrators Euler (semi-implicit), RK4, implicitfast;
  ``mj_step(nstep=n)`` runs the steps in C.
* Basilisk (``--peers``): ``spacecraft.Spacecraft`` hub only (mass 1, IHubPntBc_B =
  diag(I)), attitude as MRPs σ_BN where [BN] maps inertial components to body components,
  the transpose of our body→inertial matrix; σ_BN = C2MRP(R(q)ᵀ) in, R = MRP2C(σ)ᵀ out
  (Basilisk's RigidBodyKinematics, which also handles its shadow-set switching).
  ω_BN_B is the body-frame rate = m / I. Torque through ``extForceTorque.extTorquePntB_B``
  (body frame). Integrators svIntegratorRK4 (fixed step = task period) and RKF45/RKF78
  (adaptive within each task period, relTol = rtol, absTol = rtol·1e-3).

Model construction (XML compile, Basilisk InitializeSimulation) is outside the timed
region; for ours, integrator construction is inside (it is tiny).
"""
import contextlib
import math
from typing import Callable, Dict

import numpy as np

# bsk and mujoco (pinned in requirements-peers.txt, `make venv` installs them) are installed
# without their dependencies: bsk caps matplotlib below our pin, mujoco asks for its viewer.
INSTALL_HINT = ".venv/bin/pip install --no-deps -r requirements-peers.txt"


class PeerMethod:
    def __init__(self, name, kind, run: Callable, supports: Callable, stages=None):
        self.name, self.kind, self.run, self.supports, self.stages = (
            name, kind, run, supports, stages)


def _rhs_factory(scene):
    i1, i2, i3 = (float(v) for v in scene.moments)
    d = scene.dissipation
    alpha = d.coefficient if d.active and d.model == 'double_bracket' else 0.0
    visc = d.coefficient if d.active and d.model == 'viscous' else 0.0

    def rhs(_t, y, tau=(0.0, 0.0, 0.0)):
        qx, qy, qz, qw, m1, m2, m3 = y
        w1, w2, w3 = m1 / i1, m2 / i2, m3 / i3
        c1, c2, c3 = m2 * w3 - m3 * w2, m3 * w1 - m1 * w3, m1 * w2 - m2 * w1
        d1, d2, d3 = c1 + tau[0], c2 + tau[1], c3 + tau[2]
        if alpha:
            d1 += alpha * (m2 * c3 - m3 * c2)
            d2 += alpha * (m3 * c1 - m1 * c3)
            d3 += alpha * (m1 * c2 - m2 * c1)
        if visc:
            d1 -= visc * w1
            d2 -= visc * w2
            d3 -= visc * w3
        return np.array((0.5 * (qw * w1 + qy * w3 - qz * w2),
                         0.5 * (qw * w2 - qx * w3 + qz * w1),
                         0.5 * (qw * w3 + qx * w2 - qy * w1),
                         -0.5 * (qx * w1 + qy * w2 + qz * w3), d1, d2, d3))
    return rhs


def _scipy(method):
    def run(scene, rtol):
        from scipy.integrate import solve_ivp
        rhs = _rhs_factory(scene)
        y = np.r_[scene.q0_array, scene.m0]
        nfev = 0
        if scene.control is None:
            sol = solve_ivp(rhs, (0.0, scene.t_end), y, method=method, rtol=rtol, atol=rtol * 1e-3)
            if not sol.success:
                raise RuntimeError(sol.message)
            y, nfev = sol.y[:, -1], sol.nfev
        else:
            moments = np.asarray(scene.moments, float)
            period = scene.control.period
            for k in range(int(round(scene.t_end / period))):
                q = y[:4] / math.sqrt(float(np.dot(y[:4], y[:4])))
                tau = tuple(float(v) for v in scene.control.torque(moments, q, y[4:]))
                sol = solve_ivp(rhs, (0.0, period), y, method=method, rtol=rtol,
                                atol=rtol * 1e-3, args=(tau,))
                if not sol.success:
                    raise RuntimeError(sol.message)
                y, nfev = sol.y[:, -1], nfev + sol.nfev
        q = y[:4] / np.linalg.norm(y[:4])
        return q, y[4:].copy(), nfev
    return run


def _always(scene):
    return True


def _no_dissipation(scene):
    return not scene.dissipation.active


def _damper(scene):
    """The scene's internal damping as a body-frame torque of m (principal = body frame
    here), for peers without the model; None without dissipation. Plain floats: it runs
    in a MuJoCo callback at every stage, where numpy's per-call cost would be the peer's."""
    d = scene.dissipation
    if not d.active:
        return None
    i1, i2, i3 = (float(v) for v in scene.moments)
    c = float(d.coefficient)
    if d.model == 'double_bracket':
        def double_bracket(m1, m2, m3):
            w1, w2, w3 = m1 / i1, m2 / i2, m3 / i3
            c1, c2, c3 = m2 * w3 - m3 * w2, m3 * w1 - m1 * w3, m1 * w2 - m2 * w1
            return c * (m2 * c3 - m3 * c2), c * (m3 * c1 - m1 * c3), c * (m1 * c2 - m2 * c1)
        return double_bracket
    return lambda m1, m2, m3: (-c * m1 / i1, -c * m2 / i2, -c * m3 / i3)


def mujoco_model(moments, h, integrator):
    """A free body of unit mass with principal ``moments`` at the origin, no gravity."""
    import mujoco
    i, h = [float(v) for v in moments], float(h)  # repr of a numpy float is not XML
    xml = (f'<mujoco><option timestep="{h!r}" gravity="0 0 0" integrator="{integrator}"/>'
           f'<worldbody><body><freejoint/><inertial pos="0 0 0" mass="1" '
           f'diaginertia="{i[0]!r} {i[1]!r} {i[2]!r}"/></body></worldbody></mujoco>')
    return mujoco.MjModel.from_xml_string(xml)


@contextlib.contextmanager
def mujoco_damping(damper, moments):
    """MuJoCo has no internal-dissipation model: a user adds its torque in the passive-force
    callback, which every stage of RK4 calls (set once a step in ``qfrc_applied`` it would be
    held across the stages and make RK4 first order). The free joint's rate and generalised
    force are in the body frame."""
    import mujoco
    i1, i2, i3 = (float(v) for v in moments)

    def passive(_model, data):
        w = data.qvel
        t1, t2, t3 = damper(w[3] * i1, w[4] * i2, w[5] * i3)
        f = data.qfrc_passive
        f[3] += t1
        f[4] += t2
        f[5] += t3
    mujoco.set_mjcb_passive(passive)
    try:
        yield
    finally:
        mujoco.set_mjcb_passive(None)


def _mujoco(integrator, stages):
    def run(scene, h):
        import mujoco
        from .common import cpu
        i = scene.moments
        model = mujoco_model(i, h, integrator)
        data = mujoco.MjData(model)
        q0 = scene.q0_array
        moments = np.asarray(i, float)
        data.qpos[3:7] = (q0[3], q0[0], q0[1], q0[2])
        data.qvel[3:6] = scene.m0 / moments
        damper = _damper(scene)
        t0 = cpu()
        n = int(round(scene.t_end / h))
        if damper is not None:
            with mujoco_damping(damper, moments):
                mujoco.mj_step(model, data, nstep=n)
        elif scene.control is None:
            mujoco.mj_step(model, data, nstep=n)
        else:
            period = scene.control.period
            n_sub = int(round(period / h))
            n = 0
            for _ in range(int(round(scene.t_end / period))):
                q = np.r_[data.qpos[4:7], data.qpos[3]]
                data.qfrc_applied[3:6] = scene.control.torque(moments, q,
                                                              data.qvel[3:6] * moments)
                mujoco.mj_step(model, data, nstep=n_sub)
                n += n_sub
        elapsed = cpu() - t0
        q = np.r_[data.qpos[4:7], data.qpos[3]]
        # MuJoCo resets an unstable simulation and carries on: count that as a blow-up.
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
            raise RuntimeError('MuJoCo reported an unstable simulation (bad qacc) and reset it')
        if not np.all(np.isfinite(q)) or not np.all(np.isfinite(data.qvel)):
            raise RuntimeError('non-finite state')
        return q / np.linalg.norm(q), data.qvel[3:6] * moments, n * stages, elapsed
    return run


def _basilisk(cls_name, adaptive, stages=None):
    def run(scene, param):
        from Basilisk.architecture import bskLogging
        from Basilisk.simulation import extForceTorque, spacecraft, svIntegrators
        from Basilisk.utilities import RigidBodyKinematics as rbk
        from Basilisk.utilities import SimulationBaseClass, macros
        from scipy.spatial.transform import Rotation

        from .common import cpu
        bskLogging.setDefaultLogLevel(bskLogging.BSK_WARNING)
        moments = np.asarray(scene.moments, float)
        if scene.control is not None:
            task = scene.control.period if adaptive else param
        else:
            task = min(scene.t_end, 10.0) if adaptive else param
        sim = SimulationBaseClass.SimBaseClass()
        proc = sim.CreateNewProcess('p')
        proc.addTask(sim.CreateNewTask('t', macros.sec2nano(task)))
        sc = spacecraft.Spacecraft()
        sc.hub.mHub = 1.0
        sc.hub.IHubPntBc_B = np.diag(moments).tolist()
        bn = Rotation.from_quat(scene.q0_array).as_matrix().T
        sc.hub.sigma_BNInit = [[float(v)] for v in rbk.C2MRP(bn)]
        sc.hub.omega_BN_BInit = [[float(v)] for v in scene.m0 / moments]
        integ = getattr(svIntegrators, cls_name)(sc)
        if adaptive:
            integ.relTol = param
            integ.absTol = param * 1e-3
        sc.setIntegrator(integ)
        sim.AddModelToTask('t', sc)
        ext = None
        if scene.control is not None:
            ext = extForceTorque.ExtForceTorque()
            sc.addDynamicEffector(ext)
            sim.AddModelToTask('t', ext)
        sim.InitializeSimulation()

        def state():
            st = sc.scStateOutMsg.read()
            r = rbk.MRP2C(np.array(st.sigma_BN, float)).T
            return Rotation.from_matrix(r).as_quat(), np.array(st.omega_BN_B, float) * moments

        t0 = cpu()
        if scene.control is None:
            sim.ConfigureStopTime(macros.sec2nano(scene.t_end))
            sim.ExecuteSimulation()
        else:
            period = scene.control.period
            for k in range(int(round(scene.t_end / period))):
                q, m = state()
                ext.extTorquePntB_B = [[float(v)] for v in scene.control.torque(moments, q, m)]
                sim.ConfigureStopTime(macros.sec2nano((k + 1) * period))
                sim.ExecuteSimulation()
        elapsed = cpu() - t0
        q, m = state()
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(m))):
            raise RuntimeError('non-finite state')
        nfev = float('nan') if stages is None else stages * int(round(scene.t_end / param))
        return q, m, nfev, elapsed
    return run


def scipy_methods() -> Dict[str, PeerMethod]:
    return {'scipy_rk45': PeerMethod('scipy_rk45', 'adaptive', _scipy('RK45'), _always),
            'scipy_dop853': PeerMethod('scipy_dop853', 'adaptive', _scipy('DOP853'), _always)}


def optional_methods():
    """({name: PeerMethod}, [messages]) for MuJoCo and Basilisk, whichever is installed."""
    import importlib.util
    methods, notes = {}, []
    if importlib.util.find_spec('mujoco') is not None:
        import mujoco
        notes.append(f'mujoco {mujoco.__version__}')
        for name, integ, stages in (('mujoco_euler', 'Euler', 1), ('mujoco_rk4', 'RK4', 4),
                                    ('mujoco_implicitfast', 'implicitfast', 1)):
            methods[name] = PeerMethod(name, 'fixed', _mujoco(integ, stages), _always, stages)
    else:
        notes.append('mujoco not installed')
    if importlib.util.find_spec('Basilisk') is not None:
        try:
            from importlib.metadata import version
            notes.append(f'bsk {version("bsk")}')
        except Exception:  # noqa: BLE001 - version is informative only
            notes.append('bsk (version unknown)')
        methods['bsk_rk4'] = PeerMethod('bsk_rk4', 'fixed', _basilisk('svIntegratorRK4', False, 4),
                                        _no_dissipation, 4)
        methods['bsk_rkf45'] = PeerMethod('bsk_rkf45', 'adaptive',
                                          _basilisk('svIntegratorRKF45', True), _no_dissipation)
        methods['bsk_rkf78'] = PeerMethod('bsk_rkf78', 'adaptive',
                                          _basilisk('svIntegratorRKF78', True), _no_dissipation)
    else:
        notes.append('Basilisk (bsk) not installed')
    return methods, notes
