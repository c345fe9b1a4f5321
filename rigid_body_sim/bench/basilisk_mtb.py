"""Basilisk's magnetorquers in a centred-dipole field: its half of the comparison.

Issue 30 compares Basilisk's ``MtbEffector`` with our magnetorquers at equal attitude error;
``basilisk_mtb_compare`` sweeps both on one scene. This module is Basilisk's side.

What Basilisk simulates here (test/test_bench_basilisk_mtb.py checks each against the
closed forms to 1e-12):

* the spacecraft of :func:`basilisk_gg.build` (hub, point-mass Earth with our μ, its
  gravity gradient optional), RK4 or RKF78;
* ``magneticFieldCenteredDipole``: B_P = (R/r)³ [3 r̂ (r̂·c) − c] with c = (g₁¹, h₁¹, g₁⁰)
  (T) and R the field model's reference radius: for R = 6371.2 km (IGRF's) and c = IGRF's
  degree 1 this is μ0/(4π r³)[3(m·r̂)r̂ − m] with m = (4π/μ0) R³ c, the tilted dipole of
  the orbit-environment notes, in the Earth-fixed frame;
* the Earth's turn: [PN] = R3(θ0 + ω_E t) through a planet-state message that this harness
  writes before each field update (there is no SPICE without its kernels, which Basilisk
  fetches over the network);
* ``MtbEffector``: three rods along the body axes, τ = m_cmd × B_B (its −B̃ G_t m), each
  rod saturated at ``max_dipole``; the command held (``MTBCmdMsg``).

What a comparison must know: Basilisk evaluates the field once per update of the field
module (``field_period``) and ``MtbEffector`` holds that inertial B over the period while
the attitude moves. Its torque is a zero-order hold in the field, first-order in
``field_period`` whatever the integrator; ours evaluates B at each stage. Sweeping Basilisk
means shrinking ``field_period`` with the step, at the cost of this Python loop (one
``ExecuteSimulation`` per field update).
"""
import math
from dataclasses import dataclass

import numpy as np

from . import basilisk_gg
from .common import cpu

IGRF_RADIUS = 6371.2e3  # m: the field model's reference radius


@dataclass(frozen=True)
class MtbSetup:
    """A Basilisk magnetorquer run: the gravity-gradient harness's ``base`` (body, orbit,
    initial state, sample period, duration), the dipole field and the held command."""
    base: basilisk_gg.Setup
    coefficients: tuple       # (g10, g11, h11), T, at ``radius``
    dipole: tuple             # A·m², body frame: the held command of the three rods
    theta0: float = 0.0       # rad: the Earth's rotation angle at t = 0 (GMST at the epoch)
    earth_rate: float = 7.2921150e-5  # rad/s
    radius: float = IGRF_RADIUS
    max_dipole: float = 1e9   # A·m² per rod
    field_period: float = 1.0  # s: how often Basilisk evaluates the field
    gravity_gradient: bool = True

    def earth_to_inertial(self, t):
        """[NP] at t: the Earth-fixed frame → the inertial one (a turn about z)."""
        a = self.theta0 + self.earth_rate * t
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class _Modules:
    """The field module, the rods, their messages and the planet-state writer."""

    def __init__(self, mtb, sim, sc, period_ns):
        from Basilisk.architecture import messaging
        from Basilisk.simulation import MtbEffector, magneticFieldCenteredDipole
        self.mtb = mtb
        field = magneticFieldCenteredDipole.MagneticFieldCenteredDipole()
        field.ModelTag = 'centred_dipole'
        field.g10, field.g11, field.h11 = (float(v) for v in mtb.coefficients)
        field.planetRadius = mtb.radius
        field.addSpacecraftToModel(sc.scStateOutMsg)
        self.planet = messaging.SpicePlanetStateMsg()
        self.payload = messaging.SpicePlanetStateMsgPayload()
        self.payload.PlanetName = 'earth'
        self.write_planet(0.0)
        field.planetPosInMsg.subscribeTo(self.planet)
        rods = MtbEffector.MtbEffector()
        rods.ModelTag = 'magnetorquers'
        config = messaging.MTBArrayConfigMsgPayload()
        config.numMTB = 3
        config.GtMatrix_B = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        config.maxMtbDipoles = [float(mtb.max_dipole)] * 3
        self.config = messaging.MTBArrayConfigMsg().write(config)
        command = messaging.MTBCmdMsgPayload()
        command.mtbDipoleCmds = [float(v) for v in mtb.dipole]
        self.command = messaging.MTBCmdMsg().write(command)
        rods.mtbCmdInMsg.subscribeTo(self.command)
        rods.mtbParamsInMsg.subscribeTo(self.config)
        rods.magInMsg.subscribeTo(field.envOutMsgs[0])
        sc.addDynamicEffector(rods)
        # the default priority, created after the dynamics' process: it runs after it, so the
        # field is evaluated at the state just reached (a priority other than -1 would put
        # it first; -10 hangs ExecuteSimulation in bsk 2.12.1)
        sim.CreateNewProcess('environment').addTask(sim.CreateNewTask('env', period_ns))
        sim.AddModelToTask('env', field)
        sim.AddModelToTask('env', rods)
        self.field, self.rods = field, rods

    def write_planet(self, t):
        """The Earth's orientation [PN] at t (position and rates zero: the Earth at N)."""
        self.payload.J20002Pfix = self.mtb.earth_to_inertial(t).T.tolist()
        self.planet.write(self.payload)


def build(mtb, integrator='rk4', param=1.0, attitude=None, position=None):
    """(sim, modules, recorder): Basilisk's magnetorquer simulation of ``mtb``, initialised."""
    from Basilisk.utilities import macros
    held = {}

    def extra(sim, sc):
        held['m'] = _Modules(mtb, sim, sc, macros.sec2nano(mtb.field_period))
        return held['m']

    sim, _, _, rec = basilisk_gg.build(mtb.base, integrator, param, attitude, position,
                                       extra, mtb.gravity_gradient)
    return sim, held['m'], rec


def field_and_torque(mtb, attitude, position, t):
    """(B in the inertial frame, T; the rods' torque in the body frame, N·m) at a state and
    sim time t: the field module's update at that state, then the rods' torque."""
    from Basilisk.utilities import macros
    sim, modules, _ = build(mtb, attitude=attitude, position=position)
    modules.write_planet(t)
    sim.ConfigureStopTime(macros.sec2nano(0.0))
    sim.ExecuteSimulation()  # t = 0: the state message, then the field module reads it
    b = np.array(modules.field.envOutMsgs[0].read().magField_N, float)
    modules.rods.computeForceTorque(0.0, 0.0)
    torque = np.array(modules.rods.torqueExternalPntB_B, float).ravel()
    del sim
    return b, torque


def run(mtb, integrator, param):
    """(CPU s, sample times s, attitude (n, 4) body → inertial, position (n, 3)): the
    planet's orientation written before each field update, as the run goes."""
    from Basilisk.utilities import macros
    sim, modules, rec = build(mtb, integrator, param)
    n = int(round(mtb.base.duration / mtb.field_period))
    t0 = cpu()
    for k in range(n + 1):
        modules.write_planet(k * mtb.field_period)
        sim.ConfigureStopTime(macros.sec2nano(k * mtb.field_period))
        sim.ExecuteSimulation()
    elapsed = cpu() - t0
    return (elapsed, np.asarray(rec.times(), float) / 1e9,
            basilisk_gg.mrp_to_quat(rec.sigma_BN), np.asarray(rec.r_BN_N, float))
