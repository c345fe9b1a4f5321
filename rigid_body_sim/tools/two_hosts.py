"""Two hosts on one machine: the closed loop across a network link, and its isolation.

``sudo python -m rigid_body_sim.tools.two_hosts [--seconds 15] [--out docs/bench]``

Needs root (it creates network namespaces) and iproute2, and says so otherwise. Two
network namespaces stand for two machines, joined by a veth pair (10.77.0.1 ↔ 10.77.0.2,
multicast routed over it as on a LAN). DDS runs over UDP only: shared memory, which
DDS would otherwise use between processes of one machine, is not available between two.

* host A runs the simulator, host B the controller and the recorder, on the slew scene.
  With ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` (the ROS 2 default) the loop must close
  across the link: the recorder on B has the simulator's samples (losses counted from gaps
  in their stamps; samples published before B discovered A counted apart), the
  controller's torques, and the body ends at the target.
* The same with ``LOCALHOST``: each host only sees itself, so B records nothing of A.

Prints a table and one JSON line; ``--out DIR`` also writes DIR/two_hosts.json.
"""
from . import argument_parser
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np

from ..bench.common import report

SCENE = 'slew'
SUBNET = '10.77.0'


def _ip(*args, ns=None):
    cmd = ['ip', *(['netns', 'exec', ns, 'ip'] if ns else []), *args]
    subprocess.run(cmd, check=True, capture_output=True, text=True)


class Hosts:
    """Two namespaces joined by a veth pair; removed on exit, whatever happens."""

    def __init__(self):
        tag = f'{os.getpid() % 100000}'
        self.names = (f'rbs_a{tag}', f'rbs_b{tag}')
        self.links = (f'rbsa{tag}', f'rbsb{tag}')

    def __enter__(self):
        a, b = self.names
        for ns in self.names:
            _ip('netns', 'add', ns)
        _ip('link', 'add', self.links[0], 'type', 'veth', 'peer', 'name', self.links[1])
        for k, (ns, link) in enumerate(zip(self.names, self.links)):
            _ip('link', 'set', link, 'netns', ns)
            _ip('addr', 'add', f'{SUBNET}.{k + 1}/24', 'dev', link, ns=ns)
            _ip('link', 'set', link, 'up', ns=ns)
            _ip('link', 'set', 'lo', 'up', ns=ns)
            _ip('route', 'add', '224.0.0.0/4', 'dev', link, ns=ns)  # DDS discovery multicast
        return self

    def __exit__(self, *exc):
        for ns in self.names:  # deleting a namespace deletes its end of the veth pair
            subprocess.run(['ip', 'netns', 'del', ns], capture_output=True)

    def start(self, host: int, argv, env, log):
        return subprocess.Popen(['ip', 'netns', 'exec', self.names[host], *argv], env=env,
                                stdout=log, stderr=subprocess.STDOUT, start_new_session=True)


def _exe(name):
    path = os.path.join(sys.prefix, 'lib', 'rigid_body_sim', name)
    return [path] if os.path.exists(path) else [sys.executable, '-m',
                                                 f'rigid_body_sim.nodes.{name}']


def _stop(proc, timeout=10.0):
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    try:
        return proc.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        return proc.wait()


def closed_loop(hosts: Hosts, discovery_range: str, seconds: float, workdir: str) -> dict:
    """Simulator on host A, controller and recorder on host B; returns what B recorded."""
    from rclpy.serialization import deserialize_message
    from geometry_msgs.msg import QuaternionStamped

    from ..bag.reader import iter_messages
    from ..physics import rotation
    from ..scene import load, resolve
    scene = resolve(SCENE)
    loaded = load(scene)
    rate = loaded.simulator['publish_rate']
    env = dict(os.environ, ROS_DOMAIN_ID=str(random.randint(120, 200)),
               ROS_AUTOMATIC_DISCOVERY_RANGE=discovery_range,
               FASTDDS_BUILTIN_TRANSPORTS='UDPv4')
    env.pop('ROS_STATIC_PEERS', None)
    bag = os.path.join(workdir, f'bag_{discovery_range.lower()}')
    logs = {name: open(os.path.join(workdir, f'{name}_{discovery_range}.log'), 'w')
            for name in ('simulator', 'controller', 'recorder')}
    params = ['--params-file', scene]
    procs = {'recorder': hosts.start(1, _exe('recorder') + [
        '--ros-args', '-p', f'output:={bag}', '-p', f'scene:={SCENE}'], env, logs['recorder']),
        'controller': hosts.start(1, _exe('controller') + ['--ros-args', *params], env,
                                  logs['controller'])}
    time.sleep(2.0)  # B listening before A starts, as in the demo
    # the duration in a second params file: a -p loses against the scene's node section
    # (rcl lets a node-specific entry win over the /** one -p makes), so an earlier
    # version of this bench always ran the scene's 15 s whatever --seconds said
    duration = os.path.join(workdir, 'duration.yaml')
    with open(duration, 'w') as f:
        f.write(f'/**/attitude_simulator:\n  ros__parameters:\n    duration: {float(seconds)!r}\n')
    procs['simulator'] = hosts.start(0, _exe('simulator') + [
        '--ros-args', *params, '--params-file', duration], env, logs['simulator'])
    try:
        procs['simulator'].wait(seconds + 60)
    finally:
        codes = {name: _stop(p) for name, p in reversed(list(procs.items()))}
        for f in logs.values():
            f.close()
    attitude, stamps, torques = [], [], 0
    if os.path.isdir(bag):
        for m in iter_messages(bag):
            if m.topic == '/attitude':
                msg = deserialize_message(m.data, QuaternionStamped)
                attitude.append(msg.quaternion)
                stamps.append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
            elif m.topic == '/torque_command':
                torques += 1
    expected = int(round(seconds * rate)) + 1
    # samples are stamped exactly one period apart: a gap after the first received one is
    # a loss on the way; what is missing before it was published before B had discovered A
    period_ns = round(1e9 / rate)
    gaps = sum(int(d) // period_ns - 1 for d in np.diff(sorted(stamps))) if stamps else 0
    error = None
    if attitude:
        q = attitude[-1]
        target = loaded.controller['target_attitude']
        d = rotation.multiply(rotation.conjugate(target), [q.x, q.y, q.z, q.w])
        error = math.degrees(2 * math.atan2(math.sqrt(sum(c * c for c in d[:3])), abs(d[3])))
    return {'discovery_range': discovery_range, 'exit_codes': codes,
            'attitude_received_on_b': len(attitude), 'attitude_published_on_a': expected,
            'lost_after_first': gaps,
            'not_yet_discovered_at_start': max(0, expected - len(attitude) - gaps),
            'torque_commands_recorded_on_b': torques, 'final_pointing_error_deg': error}


def main(argv=None) -> int:
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--seconds', type=float, default=15.0,
                        help='simulated seconds of the slew (real time; default 15)')
    parser.add_argument('--out', help='directory for two_hosts.json (e.g. docs/bench)')
    args = parser.parse_args(argv)
    if not math.isfinite(args.seconds) or args.seconds <= 0:
        parser.error(f'--seconds {args.seconds}: must be a positive number')
    if os.geteuid() != 0 or shutil.which('ip') is None:
        print('two_hosts: needs root and iproute2 (it creates two network namespaces joined '
              'by a veth pair); run it with sudo', file=sys.stderr)
        return 2
    results = []
    try:
        with tempfile.TemporaryDirectory(prefix='rbs_two_hosts_') as workdir, Hosts() as hosts:
            for discovery_range in ('SUBNET', 'LOCALHOST'):
                results.append(closed_loop(hosts, discovery_range, args.seconds, workdir))
    except KeyboardInterrupt:
        print('two_hosts: interrupted; namespaces removed', file=sys.stderr)
        return 130
    for r in results:
        err = r['final_pointing_error_deg']
        print(f"{r['discovery_range']:>9}: B received {r['attitude_received_on_b']} of "
              f"{r['attitude_published_on_a']} samples from A ({r['lost_after_first']} lost "
              f"after the first, {r['not_yet_discovered_at_start']} before discovery), "
              f"{r['torque_commands_recorded_on_b']} torque commands, final pointing error "
              f"{'n/a' if err is None else f'{err:.4f}°'}, exit codes {r['exit_codes']}")
    report({'command': 'sudo python -m rigid_body_sim.tools.two_hosts --seconds '
            f'{args.seconds:g}', 'results': results}, args.out, 'two_hosts.json')
    return 0


if __name__ == '__main__':
    sys.exit(main())
