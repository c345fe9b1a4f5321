"""The simulator node's status: its one-line summary and its diagnostics.

One status for the simulation (``attitude_simulator: simulation``): pacing, deadlines,
lockstep, faults and resets. With the unnamed spacecraft alone (a scene without
``spacecraft``) it also holds that spacecraft's physics and command counts, as it always
has. Otherwise the simulation's status counts the spacecraft and the commands that reached
none (``commands_rejected.unknown_spacecraft``), and each spacecraft has a status of its
own (``attitude_simulator: <name>``) with its physics and command counts, and its
``inertia`` (the viewer draws a spawned one's body from it). Without any
spacecraft (all deleted) the simulation's status says so (WARN) and runs on.
"""
import time

from diagnostic_msgs.msg import DiagnosticArray

from ..engine import NS
from .common import diagnostic_status
from .sensor_messages import sensors_summary

DIAGNOSTICS_PERIOD_S = 1.0   # wall clock


def summary(sim) -> str:
    p, crafts = sim._p, sim.crafts
    duration = 'until stopped' if p['duration'] == 0 else f"{p['duration']:g} s"
    rtf = 'as fast as possible' if p['real_time_factor'] == 0 else \
        f'{p["real_time_factor"]:g}x real time'
    if len(crafts) == 1 and not crafts[0].name:
        e = crafts[0].engine
        physics = f'integrator {e.method} ({e.reason}), step {e.step_max:.6g} s'
        frames = f'frames {p["frame_id"]} <- {p["child_frame_id"]}'
        sensors = sensors_summary(e.config.sensors)
    else:
        physics = f'{len(crafts)} spacecraft ({", ".join(c.entity for c in crafts) or "none"})'
        frames = f'frames {p["frame_id"]} <- <name>/{p["child_frame_id"]}'
        sensors = ''
    return (f'{sim.get_name()}: {physics}, publish {NS / sim._period_ns:g} Hz, {rtf}, '
            f'clock {"on" if p["publish_clock"] else "off"}, {frames}, qos {p["qos"]}, '
            f'duration {duration}' + sensors)


def _craft_counts(craft) -> dict:
    """A spacecraft's command counts, its joint commands', and the messages built per topic
    (only topics with subscribers are built)."""
    hold = craft.engine.magnetics.hold if craft.dipoles is not None else None
    return {**craft.commands.counts(),
            **(craft.joints.counts() if craft.joints is not None else {}),
            **({'dipole_commands_accepted': hold.accepted,
                'dipole_commands_saturated': hold.saturated, **craft.dipoles.counts(),
                'magnetorquer_dipole': ' '.join(f'{v:.6g}' for v in
                                                craft.engine.magnetics.dipole()),
                'magnetorquer_torque': ' '.join(f'{v:.6g}' for v in
                                                craft.engine.magnetics.torque(
                                                    craft.engine.t, craft.engine.attitude))}
               if hold is not None else {}),
            **{f'messages_built.{k}': n for k, n in craft.msgs.built().items()},
            **({'orbit_messages_published': craft.orbit.published}
               if craft.orbit is not None else {})}


def diagnostics(sim) -> DiagnosticArray:
    """The DiagnosticArray to publish now; resets the per-period counters."""
    now, t_ns, crafts = time.monotonic(), sim.t_ns, sim.crafts
    wall0, t0 = sim._last_diag
    achieved = (t_ns - t0) / NS / (now - wall0) if now > wall0 else 0.0
    sim._last_diag = (now, t_ns)
    sim._next_diag_wall = now + DIAGNOSTICS_PERIOD_S
    single = len(crafts) == 1 and not crafts[0].name
    values = {**(crafts[0].engine.diagnostics() if single else {
        'spacecraft': len(crafts), 'spacecraft_names': ', '.join(c.entity for c in crafts)}),
        'real_time_factor_target': sim._p['real_time_factor'],
        **(sim._lockstep_values() if sim._lockstep else {}),
        'real_time_factor_achieved': achieved,
        **(_craft_counts(crafts[0]) if single else {
            'commands_rejected.unknown_spacecraft':
                sim._commands.rejected['unknown_spacecraft']}),
        'messages_published': sim._published,  # state topics, /tf included
        **sim._acks.values(),  # the waits for acknowledgements (sim_acks)
        'missed_deadlines': sim._missed,
        # kernels first loaded after t = 0 (each a stall of the loop; warm_live prevents it)
        'kernels_loaded_after_t0': sim.kernels_after_t0(),
        'missed_deadlines_in_period': sim._missed - sim._missed_at_last_diag,
        'worst_lateness_in_period': sim._worst_late,
        'deadline_tolerance': sim._p['deadline_tolerance'],
        'fault': sim._fault or '', 'resets': sim._resets}
    missed = sim._missed - sim._missed_at_last_diag
    if sim._fault:
        level, message = 'ERROR', f'stopped: {sim._fault}'
    elif sim._lockstep and sim._held is not None and sim._paused_reported:
        level, message = 'WARN', (f'lockstep: paused at t = {sim._held / NS:.9g} s, '
                                  f'waiting for {sim._held_missing()} stamped '
                                  f'{sim._held_stamp()}')
    elif not crafts:
        level, message = 'WARN', (f'running without spacecraft (all deleted), t = '
                                  f'{t_ns / NS:.3f} s; spawn one with spawn_entity')
    elif sim.finished:
        level, message = 'OK', f'duration reached at t = {t_ns / NS:.6g} s'
    elif missed:
        level, message = 'WARN', (
            f'{missed} missed deadlines in the last {now - wall0:.2g} s (published up to '
            f'{sim._worst_late * 1e3:.0f} ms late, tolerance '
            f'{sim._p["deadline_tolerance"] * 1e3:.0f} ms)')
    else:
        level, message = 'OK', f'running, t = {t_ns / NS:.3f} s' + (
            '' if single else f', {len(crafts)} spacecraft')
    sim._missed_at_last_diag = sim._missed
    sim._worst_late = 0.0  # worst lateness per diagnostics period
    name, hardware = sim.get_name(), sim.get_fully_qualified_name()
    status = [diagnostic_status(f'{name}: simulation', hardware, level, message, values)]
    if not single:
        for c in crafts:
            e = c.engine
            if c.fault:
                level, text = 'ERROR', f'stopped: {c.fault}'
            elif sim._fault:
                level, text = 'WARN', 'held: another spacecraft stopped the simulation'
            else:
                level, text = 'OK', 'finished' if e.finished else 'running'
            status.append(diagnostic_status(
                f'{name}: {c.entity}', hardware, level, f'{text}, t = {e.t:.3f} s, integrator '
                f'{e.method}', {**e.diagnostics(), **_craft_counts(c),
                                'inertia': [float(x) for x in c.p['inertia']]}))
    array = DiagnosticArray(status=status)
    array.header.stamp.sec, array.header.stamp.nanosec = divmod(sim.stamp_ns(t_ns), NS)
    return array
