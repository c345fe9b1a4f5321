"""The demo's summary: the recorded run read back on the simulator's time origin (one
origin for the summary and the plots, from the stamps and the simulator's diagnostics),
the phases, the free phase's drift, and why a run that ended early shows a large error."""
import math
import re

import numpy as np


def stamp_origin(stamp, sim_time, time_scale) -> int:
    """The stamp (ns) of the simulator's t = 0, from one of its diagnostics: the header
    stamp is that of sim time ``sim_time`` (s, as text), stamps advance by sim time /
    ``time_scale``."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec - round(float(sim_time) * 1e9 / time_scale)



def phase_hint(watcher, scene, slew_start):
    """Why the pointing error is still large, when the run ended before the slew."""
    if not scene.controlled or watcher.ended_in() == 'off':
        return ''
    if watcher.ended_in() == 'slew':
        from .control import critical_settling_time
        wn = np.mean(scene.controller.get('natural_frequency', 0.5))
        settle = critical_settling_time(wn)
        if not np.isfinite(slew_start) or watcher.t - slew_start >= settle:
            return ''
        return (f' — the slew began at t = {slew_start:.2f} s and settles to 2 % in '
                f'5.83/ω_n = {settle:.1f} s (try a longer --duration)')
    free = scene.controller.get('mission.free_time', 0.0)
    exit_rate = scene.controller.get('mission.detumble_exit_rate', 0.0)
    if watcher.ended_in() in ('detumble', 'bdot', 'controlled'):
        if not exit_rate > 0.0:  # a detumble scene: no slew follows, nothing to point at
            return (' — a detumble damps the rate and points nowhere: the error is the '
                    'attitude where the tumble stopped, not the controller\'s')
        return (f' — the slew had not begun: it follows once |ω| < {exit_rate:g} rad/s; the '
                'error is the tumble\'s, not the controller\'s (try a longer --duration)')
    return (f' — the slew had not begun: the free phase lasts {free:g} s, then the detumble; '
            'the error is the tumble\'s, not the controller\'s (try a longer --duration)')



def drift(values):
    if len(values) < 2 or values[0] == 0:
        return math.nan
    v = np.asarray(values)
    return float(np.max(np.abs(v - v[0])) / abs(v[0]))



def bag_samples(bag, scene, prefix=''):
    """The recorded state as plot samples, and the end of the free phase (s), or None.

    Topics are joined by their header stamps (every topic of one sample carries the same
    stamp). Time is sim time from the simulator's t = 0: its diagnostics in the bag say
    which stamp that is (``stamp_origin``; with ``publish_clock`` stamps are sim time), so
    a bag that missed the first samples still has the right times. ``prefix``: a
    formation's spacecraft's namespace ('/leader'), for its topics."""
    from rclpy.serialization import deserialize_message
    from .bag.reader import iter_messages
    from .bag.schema import message_class
    from .demo_nodes import SIMULATOR_ID
    p = scene.simulator
    rtf = 1.0 if p['publish_clock'] else (p['real_time_factor'] or 1.0)
    series = {'/attitude': {}, '/angular_velocity': {}, '/angular_momentum': {}}
    names = {prefix + t: t for t in list(series) + ['/torque_command']}
    first_torque = None  # stamp of the first nonzero command: the end of the free phase
    commands = []  # (stamp, torque): held from its stamp on
    origin = 0 if p['publish_clock'] else None
    for m in iter_messages(bag, topics=list(names) + ['/diagnostics']):
        msg = deserialize_message(m.data, message_class(m.type))
        topic = names.get(m.topic, m.topic)
        if topic == '/diagnostics':
            for status in msg.status:
                values = {kv.key: kv.value for kv in status.values}
                # the demo's simulator's: the bag has every simulator's of the domain
                if origin is None and status.hardware_id == SIMULATOR_ID and \
                        'sim_time' in values:
                    origin = stamp_origin(msg.header.stamp, values['sim_time'], rtf)
            continue
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        if topic == '/torque_command':
            v = msg.vector
            if first_torque is None and (v.x or v.y or v.z):
                first_torque = stamp
            commands.append((stamp, (v.x, v.y, v.z)))
        elif topic == '/attitude':
            o = msg.quaternion
            series[topic][stamp] = (o.x, o.y, o.z, o.w)
        else:
            v = msg.vector
            series[topic][stamp] = (v.x, v.y, v.z)
    stamps = sorted(set.intersection(*(set(v) for v in series.values())))
    if len(stamps) < 2:
        return None, None
    t0 = stamps[0] if origin is None else origin
    w = np.array([series['/angular_velocity'][s] for s in stamps])
    torque = np.zeros_like(w)
    if commands:
        commands.sort(key=lambda c: c[0])
        k = np.searchsorted([c[0] for c in commands], stamps, side='right') - 1
        held = np.array([c[1] for c in commands])
        torque[k >= 0] = held[k[k >= 0]]
    body = body_of(scene)
    samples = {'t': (np.array(stamps) - t0) * 1e-9 * rtf,
               'attitude': np.array([series['/attitude'][s] for s in stamps]),
               'angular_velocity': w,
               'angular_momentum': np.array([series['/angular_momentum'][s] for s in stamps]),
               'kinetic_energy': 0.5 * np.einsum('ni,ij,nj->n', w, body.inertia, w),
               'torque': torque}
    free_end = np.inf if first_torque is None else (first_torque - t0) * 1e-9 * rtf
    return samples, free_end



def body_of(scene):
    from .engine import EngineConfig
    return EngineConfig.from_parameters(scene.simulator).body



def free_phase(samples, free_end):
    """(samples, relative drift of T, of |L|) of the recorded free phase: the samples
    before ``free_end``, on the same time origin as the phases and control.png (the live
    monitor's own count would include samples that arrived before the first command)."""
    free = samples['t'] < free_end
    L = np.linalg.norm(samples['angular_momentum'][free], axis=1)
    return int(np.count_nonzero(free)), drift(samples['kinetic_energy'][free]), drift(L)



def last_line(path):
    """The last non-empty line of a log (what a node said before it exited)."""
    try:
        with open(path, errors='replace') as f:
            lines = [line.strip() for line in f if line.strip()]
    except OSError:
        return ''
    return lines[-1] if lines else ''


def spacecraft_lines(bag, crafts, prefix):
    """A formation's spacecraft in the bag: each one's samples and commands (the shown
    one's, at ``prefix``, are the plots')."""
    from .bag.reader import iter_messages
    counts = {(c, t): 0 for c in crafts for t in ('attitude', 'torque_command')}
    for m in iter_messages(bag, topics=[f'/{c}/{t}' for c, t in counts]):
        craft, _, topic = m.topic.strip('/').partition('/')
        counts[craft, topic] += 1
    return [f'  spacecraft {c}: {counts[c, "attitude"]} samples, {counts[c, "torque_command"]} '
            'commands recorded' + (' (the plots\')' if f'/{c}' == prefix else '')
            for c in crafts]


# the simulator's last word on a lockstep run (sim_lockstep.py): how many control instants
# it held until a command came
EXCHANGES = re.compile(r'lockstep: (\d+) exchanges')


def lockstep_exchanges(sim_log):
    """The control instants a lockstep simulator answered (its log's last count), or None
    when it did not say (not lockstep, or it did not end its run)."""
    try:
        with open(sim_log, errors='replace') as f:
            found = EXCHANGES.findall(f.read())
    except OSError:
        return None
    return int(found[-1]) if found else None


def lost_commands(bag, topics, exchanges):
    """{topic: commands missing}: in lockstep the simulator stepped past a control instant
    only once it had that instant's command from each controller, so each command topic
    (``topics``) must hold at least ``exchanges`` messages; fewer is a loss on the way
    to the recorder (a recorder paused for a moment once kept 1 of 21), never silent."""
    from .bag.reader import iter_messages
    counts = dict.fromkeys(topics, 0)
    for m in iter_messages(bag, topics=list(topics)):
        counts[m.topic] += 1
    return {t: exchanges - n for t, n in counts.items() if n < exchanges}


def summarize(scene, bag, out, watcher, target, failed, logs, interrupted, prefix='',
              crafts=(), plots=True, commands=None) -> int:
    """Print the demo's summary from the bag, on the simulator's time origin, and write
    the plots; 1 when the bag is unreadable or a node failed (``failed``: name → exit
    code; ``logs``: name → log path), else 0. A formation (``crafts``, their names):
    ``scene`` is the shown spacecraft's (``scene.spacecraft_scene``), its topics under
    ``prefix``, and a line per spacecraft says what the bag holds of it. ``plots``
    False: no plots (``demo --no-plots``; they cost ~2 CPU-s). ``commands`` (lockstep):
    the command topics, each checked against the simulator's exchanges (``lost_commands``):
    a topic short of them fails the demo (1), named with what it lacks."""
    from .bag.errors import BagError
    from .bag.reader import read_info
    samples, free_end, bag_error = None, None, None
    try:
        info = read_info(bag)
        samples, free_end = bag_samples(bag, scene, prefix)
    except BagError as exc:
        bag_error = exc
    from .control import slew_begins  # not from plots: they import numba (issue 32)
    slew = slew_begins(samples, free_end, scene.controller) \
        if samples is not None and scene.controlled else np.inf
    print('demo: summary' + (' (interrupted)' if interrupted else ''))
    for name, code in failed.items():  # what the node said last: usually why
        print(f'  {name}: exited with {code}: {last_line(logs[name])} (log: {logs[name]})')
    if watcher is not None and watcher.t0 is not None:
        # the phase hint would guess at a cause; a failed node has its own
        print(f'  ended at t = {watcher.t:.2f} s (sim time) in the {watcher.ended_in()} phase'
              + ('' if failed else phase_hint(watcher, scene, slew)))
        print(f'  final pointing error: {watcher.error_deg():.4f}° '
              f'(target {np.round(target, 6).tolist()})')
        count, drift_T, drift_L = free_phase(samples, free_end) if samples is not None \
            else (len(watcher.free['T']), drift(watcher.free['T']), drift(watcher.free['L']))
        print(f'  free phase: {count} samples, relative drift T {drift_T:.2e}, '
              f'|L| {drift_L:.2e}' if count > 1 else '  free phase: none (torque from t = 0)')
    elif watcher is not None:
        print('  no sample from the simulator')
    if samples is not None and scene.controlled:
        phases = [f'free until {free_end:.2f} s' if np.isfinite(free_end) else 'free']
        phases += [f'slew from {slew:.2f} s'] if np.isfinite(slew) else []
        print('  phases (sim time from the simulator\'s t = 0, as in control.png): '
              + ', '.join(phases))
    if bag_error is not None:
        print(f'  bag: not readable ({bag_error}); recorder log: {logs["recorder"]}')
        return 1
    print(f'  messages recorded: {info.message_count} on {len(info.topics)} topics, '
          f'{info.duration_s:.2f} s — bag: {bag}')
    for line in spacecraft_lines(bag, crafts, prefix) if crafts else ():
        print(line)
    exchanges = lockstep_exchanges(logs['simulator']) if commands and 'simulator' in logs \
        else None
    lost = lost_commands(bag, commands, exchanges) if exchanges is not None else {}
    for topic, n in lost.items():
        print(f'  lost: {topic}: the bag holds {exchanges - n} of the {exchanges} commands the '
              f'simulator was answered with (recorder log: {logs["recorder"]})')
    if samples is not None and plots:
        from .plots import write_plots
        for path in write_plots(samples, body_of(scene), out, f'{scene.name} (live)', free_end,
                                scene):
            print(f'  plot: {path}')
    return 1 if failed or lost else 0
