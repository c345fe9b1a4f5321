"""Checks on a recorded bag's header stamps: does it hold every sample from the simulator's
t = 0, without a gap?"""
from rclpy.serialization import deserialize_message

from rigid_body_sim.bag.reader import iter_messages
from rigid_body_sim.bag.schema import message_class

# the simulator's per-sample topics (the sensors' have their own rates)
STATE_TOPICS = ('attitude', 'pose', 'transform', 'odometry', 'angular_velocity',
                'angular_momentum', 'angular_momentum_body', 'kinetic_energy', 'imu', 'tf')


def recorded_stamps(bag):
    """({topic: [header stamp ns, ...] in bag order}, stamp of the simulator's t = 0 from
    its first diagnostics in the bag, or None)."""
    stamps, origin = {}, None
    for m in iter_messages(str(bag)):
        msg = deserialize_message(m.data, message_class(m.type))
        if m.topic.endswith('/diagnostics'):
            for status in msg.status:
                values = {kv.key: kv.value for kv in status.values}
                if origin is None and status.name.startswith('attitude_simulator'):
                    # its header stamp is that of sim time sim_time; stamps advance by
                    # sim time / rtf (1 as fast as possible)
                    rtf = float(values['real_time_factor_target']) or 1.0
                    origin = msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec - \
                        round(float(values['sim_time']) * 1e9 / rtf)
            continue
        header = msg.transforms[0].header if m.topic.endswith('/tf') else \
            getattr(msg, 'header', None)
        if header is not None and m.topic.rsplit('/', 1)[-1] in STATE_TOPICS:
            stamps.setdefault(m.topic, []).append(header.stamp.sec * 10 ** 9
                                                  + header.stamp.nanosec)
    return stamps, origin


def gaps_from_t0(bag, period_ns, count=None):
    """Problems (empty = none): a state topic whose first stamp is not the simulator's t = 0,
    with a gap (two stamps more than ``period_ns`` apart), or (``count``) not that many."""
    stamps, origin = recorded_stamps(bag)
    problems = [] if origin is not None else ['no simulator diagnostics in the bag']
    if not stamps:
        problems.append('no state topic in the bag')
    for topic, values in sorted(stamps.items()):
        if origin is not None and abs(values[0] - origin) > period_ns // 2:
            problems.append(f'{topic}: first stamp {(values[0] - origin) * 1e-9:+.4f} s '
                            'from t = 0')
        steps = {b - a for a, b in zip(values, values[1:])}
        # a gap is a step longer than the period (stamps are rounded to 1 ns); a shorter one
        # is an extra sample at an event (a command expiring when the controller stops)
        if any(step > period_ns + 1 for step in steps):
            problems.append(f'{topic}: steps {sorted(steps)[-5:]} ns, expected {period_ns}')
        if count is not None and len(values) != count:
            problems.append(f'{topic}: {len(values)} samples, expected {count}')
    return problems
