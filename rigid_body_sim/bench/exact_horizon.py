"""``exact`` (float64) against the 40-digit reference at t = 1e3 s and 1e6 s, per torque-free
scene: the bench scenes without torque or dissipation and the torque-free config/ scenes.

The reference (:mod:`.reference40`, mpmath) starts from the very float64 numbers that
``exact`` gets, so the error shown is the code's, not the inputs' rounding. The float64
floor of a phase ω·t is eps·|ω|·t (2.2e-9 rad for 10 rad/s over 1e6 s), which is why
``exact`` carries its secular phases in extended precision.
"""
import math
from dataclasses import dataclass

import numpy as np

from .common import cpu
from .scenes import SCENES

HORIZONS = ((1e3, 1e-12), (1e6, 1e-9))          # (t in s, required attitude error in rad)
CONFIG_SCENES = ('tennis_racket', 'symmetric_top', 'rigid_earth')
FIELDS = ('scene', 'regime', 't', 'attitude_error', 'momentum_error', 'required', 'verdict',
          'omega_max', 'float64_floor', 'cpu_exact_s', 'cpu_reference_s')


@dataclass(frozen=True)
class Case:
    name: str
    moments: np.ndarray       # principal moments (float64, as exact gets them)
    q0: np.ndarray            # principal frame → inertial
    m0: np.ndarray            # body angular momentum, principal frame

    @property
    def omega_max(self):
        return float(np.linalg.norm(self.m0) / np.min(self.moments))


def cases():
    """Every torque-free scene as the float64 principal-frame state the engine would hand
    to ``exact``; config scenes are named 'config/<name>'."""
    from ..engine import EngineConfig
    from ..scene import load
    out = [Case(s.name, np.asarray(s.moments, float), s.q0_array, s.m0)
           for s in SCENES if s.torque_free]
    for name in CONFIG_SCENES:
        config = EngineConfig.from_parameters(load(name).simulator)
        body = config.body
        out.append(Case('config/' + name, np.asarray(body.principal_moments, float),
                        body.attitude_to_principal(config.attitude),
                        body.principal_moments * body.to_principal(config.angular_velocity)))
    return out


def case(name):
    return next(c for c in cases() if c.name == name)


def measure(c, horizons=HORIZONS):
    """One row per horizon: exact's attitude error (rad) and relative |Δm|/|m| there."""
    from ..physics.exact import TorqueFreeSolution
    from .reference40 import Reference40, attitude_error, vector_error
    t0 = cpu()
    ref = Reference40(c.moments, c.q0, c.m0)
    ref_s = cpu() - t0
    sol = TorqueFreeSolution(c.moments, c.q0, c.m0)
    g = float(np.linalg.norm(c.m0))
    rows = []
    for t, required in horizons:
        t0 = cpu()
        q, m = sol.at(t)
        ex_s = cpu() - t0
        t0 = cpu()
        q_ref, m_ref = ref.at(t)
        err = attitude_error(q, q_ref)
        rows.append({'scene': c.name, 'regime': str(sol.regime), 't': t, 'attitude_error': err,
                     'momentum_error': vector_error(m, m_ref) / g, 'required': required,
                     'verdict': 'PASS' if err <= required else 'MISS',
                     'omega_max': c.omega_max,
                     'float64_floor': float(np.finfo(float).eps * c.omega_max * t),
                     'cpu_exact_s': ex_s, 'cpu_reference_s': ref_s + cpu() - t0})
    return rows


def ode_check(name='intermediate_axis', t=10.0, dps=40):
    """(closed form vs mpmath.odefun at t: attitude, relative momentum error) for one scene;
    the reference's own cross-check (≈6 s of CPU at t = 10 s, 40 digits, near-separatrix
    scene; ≈4 s at 34 digits)."""
    from .reference40 import Reference40, attitude_error, ode_solution, vector_error
    c = case(name)
    q, m = Reference40(c.moments, c.q0, c.m0).at(t)
    q_ode, m_ode = ode_solution(c.moments, c.q0, c.m0, t, dps)
    return attitude_error(q_ode, q), vector_error(m_ode, m) / float(np.linalg.norm(c.m0))


def _label(t):
    return f'1e{round(math.log10(t))}'


def run(quick, log=print):
    """(rows, targets rows). The reference costs milliseconds per point; the ODE cross-check
    runs to t = 1 s in --quick, 10 s otherwise."""
    from . import targets
    try:
        import mpmath  # noqa: F401  (test/bench dependency, see requirements.txt)
    except ImportError:
        note = 'not measured: mpmath (a test/bench dependency) is not installed'
        log(f'  {note}')
        return [], [targets.simple(f'exact attitude error at t = {_label(t)} s', float('nan'),
                                   req, None, note) for t, req in HORIZONS]
    rows = []
    for c in cases():
        rows += measure(c)
    t_check = 1.0 if quick else 10.0
    att, mom = ode_check(t=t_check)
    check = (f'reference checked vs mpmath.odefun at t = {t_check:g} s: '
             f'{max(att, mom):.1g}')
    log(f'  reference: mpmath closed form at 60 digits from the float64 inputs; {check}')
    out = []
    for t, required in HORIZONS:
        for r in (r for r in rows if r['t'] == t):
            log(f'  {r["verdict"]:4s} t = {_label(t)} s {r["scene"]:22s} {r["regime"]:9s} '
                f'attitude {r["attitude_error"]:.2e} rad (required {required:g}; '
                f'eps·|ω|max·t {r["float64_floor"]:.1e}), |Δm|/|m| {r["momentum_error"]:.1e}')
            note = f'vs 40-digit reference; {r["regime"]}'
            out.append(targets.simple(
                f'exact attitude error at t = {_label(t)} s', r['attitude_error'], required,
                r['attitude_error'] <= required,
                note + (f'; {check}' if r['scene'] == 'intermediate_axis' else ''),
                scene=r['scene']))
    return rows, out
