"""Benchmark scenes (data only): bodies, initial states, horizons, step and tolerance grids.

All states are principal-frame, as in :mod:`rigid_body_sim.physics.dynamics`: q (x, y, z, w)
maps principal-frame vectors to the inertial frame, m = I ω is the body angular momentum.
"""
from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional, Tuple

import numpy as np

from ..physics import Dissipation, rotation

if TYPE_CHECKING:  # imported where a scene's dynamics are built: it loads numba, and the
    from ..physics import Dynamics  # bench's --help lists these scenes without it


@dataclass(frozen=True)
class Control:
    """The attitude control law, torque zero-order held over ``period`` s.

    slew: τ = −k_p ⊙ e − k_d ⊙ ω, e = vec(q_target* ⊗ q) with q_e.w ≥ 0; detumble:
    τ = −k_d ⊙ ω; k_p = 2Iω_n², k_d = 2ζω_nI (the law of :mod:`rigid_body_sim.control`
    without saturation or gyro compensation). Principal frame = body frame here.
    """
    target: Tuple[float, float, float, float]
    natural_frequency: float = 0.5
    damping_ratio: float = 1.0
    period: float = 0.1
    mode: str = 'slew'

    def torque(self, moments, q, m):
        kd = 2.0 * self.damping_ratio * self.natural_frequency * moments
        if self.mode == 'detumble':
            return -kd * (m / moments)
        target = np.asarray(self.target, float)
        e = rotation.multiply(rotation.conjugate(target), q)
        if e[3] < 0.0:
            e = -e
        kp = 2.0 * moments * self.natural_frequency ** 2
        return -kp * e[:3] - kd * (m / moments)


@dataclass(frozen=True)
class Scene:
    name: str
    title: str
    moments: Tuple[float, float, float]
    omega0: Tuple[float, float, float]
    t_end: float
    q0: Tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    dissipation: Dissipation = Dissipation()
    control: Optional[Control] = None
    # fixed-step grid, as h·|ω|max (dimensionless, rad per step); adaptive grid, rtol
    h_omega: Tuple[float, ...] = (1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001,
                                  5e-4, 2e-4, 1e-4)
    rtols: Tuple[float, ...] = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
    description: str = ''
    budget_scale: float = 1.0  # CPU budget per method relative to the others (long scenes)

    @property
    def dynamics(self) -> 'Dynamics':
        from ..physics import Dynamics
        return Dynamics(np.array(self.moments, float), self.dissipation)

    @property
    def m0(self) -> np.ndarray:
        return np.array(self.moments, float) * np.array(self.omega0, float)

    @property
    def q0_array(self) -> np.ndarray:
        q = np.array(self.q0, float)
        return q / np.linalg.norm(q)

    @property
    def torque_free(self) -> bool:
        return self.control is None and not self.dissipation.active

    @property
    def omega_max(self) -> float:
        """|ω|max over the motion: |L|/I_min bounds it (|m| is constant or falls)."""
        return float(np.linalg.norm(self.m0) / min(self.moments))

    @property
    def stiffness(self) -> float:
        """Dissipation stiffness α|L|²(1/I_min − 1/I_max), 1/s (0 without dissipation)."""
        return self.dynamics.dissipation_stiffness(float(np.linalg.norm(self.m0)))

    def steps(self, quick: bool):
        """Fixed step sizes h (s), coarse to fine; with control they divide the control period."""
        out = []
        for x in self.h_omega:
            h = x / self.omega_max
            if self.control is not None:  # here h_omega holds h / control period
                n = max(1, int(round(1.0 / x)))
                h = self.control.period / n
            else:
                n = max(1, int(round(self.t_end / h)))
                h = self.t_end / n
            if not out or h < out[-1] * 0.99:
                out.append(h)
        return out


def _unit(v):
    v = np.asarray(v, float)
    return tuple(v / np.linalg.norm(v))


_SLEW_TARGET = tuple(np.r_[np.sin(np.pi / 4) * np.array(_unit((1.0, 1.0, 1.0))),
                           np.cos(np.pi / 4)])

# Like the Hairer–Lubich–Wanner test body (GNI §VII.5, I = (2, 1, 2/3),
# m0 = (cos 1.1, 0, sin 1.1)), but physically realisable: (2, 1, 2/3) violates the triangle
# inequality I1 ≤ I2 + I3, which MuJoCo rejects. Here I = (2, 1.5, 1) and
# m0 = (cos 1.1, 0.2, sin 1.1).
_GEN_I = (2.0, 1.5, 1.0)
_GEN_W = tuple(np.array([np.cos(1.1), 0.2, np.sin(1.1)]) / np.array(_GEN_I))

SCENES = (
    Scene('tumble', 'generic torque-free tumble', _GEN_I, _GEN_W, 100.0,
          q0=(0.1, -0.2, 0.3, 0.9),
          description='I = (2, 1.5, 1) kg·m², m0 = (cos 1.1, 0.2, sin 1.1) kg·m²/s, 100 s'),
    Scene('intermediate_axis', 'tumble near the intermediate axis', (1.0, 2.0, 3.0),
          (1e-3, 2.0, 1e-3), 1000.0,
          description='I = (1, 2, 3) kg·m², ω0 = (1e-3, 2, 1e-3) rad/s, 1000 s '
                      '(Dzhanibekov flips)'),
    Scene('symmetric_top', 'symmetric top', (1.0, 1.0, 2.0), (0.3, 0.1, 1.0), 100.0,
          q0=(0.0, 0.3, 0.0, 0.95),
          description='I = (1, 1, 2) kg·m², ω0 = (0.3, 0.1, 1) rad/s, 100 s'),
    Scene('dissipation', 'internal (double-bracket) dissipation', (1.0, 2.0, 3.0),
          _unit((0.3, 0.3, 0.9)), 50.0,
          dissipation=Dissipation('double_bracket', 0.1),
          description='I = (1, 2, 3), ω0 ∝ (0.3, 0.3, 0.9) rad/s, α = 0.1 s/(kg·m²), 50 s'),
    Scene('stiff_dissipation', 'stiff double-bracket dissipation', (1.0, 2.0, 3.0),
          tuple(np.array(_unit((1e-3, 1e-3, 1.0))) / np.array((1.0, 2.0, 3.0))), 5.0,
          dissipation=Dissipation('double_bracket', 1000.0),
          h_omega=(0.02, 0.01, 0.005, 0.002, 0.001, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5),
          description='I = (1, 2, 3), |L| = 1 started 1e-3 off the major axis, α = 1000 '
                      '(stiffness α|L|²(1/I_min − 1/I_max) = 667 /s), 5 s'),
    Scene('slew', 'controlled slew, zero-order-held torque', (1.0, 2.0, 3.0),
          (0.01, -0.02, 0.01), 20.0,
          control=Control(_SLEW_TARGET, natural_frequency=0.5, period=0.1),
          h_omega=(1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001),
          description='I = (1, 2, 3), 90° about (1, 1, 1)/√3, PD ω_n = 0.5 rad/s, ζ = 1, '
                      'torque held over 0.1 s, 20 s'),
    Scene('detumble', 'rate damping from a fast tumble', (1.0, 2.0, 3.0),
          (0.8, -0.6, 0.5), 15.0, q0=(0.1, -0.2, 0.3, 0.9),
          control=Control((0.0, 0.0, 0.0, 1.0), natural_frequency=0.5, period=0.1,
                          mode='detumble'),
          h_omega=(1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002, 0.001),
          description='I = (1, 2, 3), ω0 = (0.8, −0.6, 0.5) rad/s, τ = −2ζω_n I ω with '
                      'ω_n = 0.5 rad/s, ζ = 1, torque held over 0.1 s, 15 s'),
)

# Explorer 1's first 690 s (a tenth of config/explorer1.yaml's orbit): a fast prolate
# minor-axis spinner whose weak internal damping slowly raises the nutation angle.
SCENES = SCENES + (
    Scene('explorer1', 'Explorer 1: minor-axis spin with weak internal damping',
          (0.04, 0.2, 0.2), (62.83185307179586, 0.21934681498568484, 0.0), 690.0,
          dissipation=Dissipation('double_bracket', 1.0678e-05),
          h_omega=(1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002),
          rtols=(1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10),
          description='I = (0.04, 0.2, 0.2) kg·m², 10 rev/s about the minor axis with 1° '
                      'nutation, double bracket α = 1.0678e-5, first 690 s',
          budget_scale=8.0),  # 43,000 turns: peers need seconds per run to reach 1e-3
)

SCENE_BY_NAME = {s.name: s for s in SCENES}
