"""The engine's health report: what a live node puts in /diagnostics and an offline run in
its summary. Drift is measured from the baseline the engine sets at every start of a
torque-free stretch (reset, set_state, dissipation change, torque released)."""
import numpy as np

from .config import NS


def diagnostics(engine, state, baseline) -> dict:
    """The physics' health of ``engine`` (an Engine, read through its public face) in
    ``state`` (its State record): method, step, invariants and their drift over the
    current torque-free stretch since ``baseline`` = (T0, L0 inertial, t0 ns), quaternion
    norm error, dissipated energy, command counters. T in J, |L| in kg·m²/s, drifts
    relative; L's drift is of the inertial vector."""
    T, L = engine.kinetic_energy, engine.angular_momentum
    T0, L0, t0 = baseline
    n0, n = float(np.linalg.norm(L0)), float(np.linalg.norm(L))
    applied = torque_on = state.tau_body is not None
    na = 'n/a (torque applied)'
    if engine.actuators is not None:  # allocated torque is internal: H is still kept
        torque_on = state.tau_p is not None
    if engine.dynamics.environment is not None:  # the environment's torque acts all along
        torque_on = True
        na = f'n/a (environment torque: {", ".join(engine.environment_terms)})'

    def rel(a, b):
        return (a - b) / b if b > 0 else 0.0

    c = engine.command
    return {
        'integrator': engine.method, 'integrator_reason': engine.reason,
        'step': engine.step_max, 'publish_rate': NS / engine.config.sample_period_ns,
        'sim_time': engine.t, 'kinetic_energy': T, 'angular_momentum_norm': n,
        'drift_since': t0 / NS,
        'kinetic_energy_drift': na if torque_on else
        'n/a (actuators do work)' if engine.actuators is not None else rel(T, T0),
        'angular_momentum_norm_drift': na if torque_on else rel(n, n0),
        'angular_momentum_inertial_drift': na if torque_on else
        (float(np.linalg.norm(L - L0)) / n0 if n0 > 0 else 0.0),
        'quaternion_norm_error': abs(float(np.linalg.norm(state.q)) - 1.0),
        'energy_dissipated': max(0.0, T0 - T)
        if engine.dynamics.dissipation.active and not torque_on else 0.0,
        'torque_applied': applied,
        'commands_accepted': c.accepted, 'commands_saturated': c.saturated,
        'commands_timed_out': c.timed_out,
        'selection_pending': engine.selection_pending,
        **({} if engine.actuators is None else
           engine.actuators.diagnostics(state.m, engine.dynamics.moments)),
    }
