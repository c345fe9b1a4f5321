"""The demo's node processes: started as ``ros2 run`` would, watched while the run goes on,
stopped at its end.

A node that exits before the demo stops it is *lost*: the demo names it at once with its
exit code and the last lines of its log, and exits non-zero. The simulator ending its own
``duration`` is the one exit that is not a loss; a node stopped by someone else's SIGINT
exits 0, so the exit code alone does not tell a finished run from one cut short.
"""
import os
import signal
import subprocess
import sys
import time

# The hardware_id of the demo's own nodes' statuses on /diagnostics (their fully qualified
# names): /diagnostics is one topic for the whole ROS domain, and a simulator of another
# graph in it (another namespace, a test's fixture) says 'attitude_simulator' too.
SIMULATOR_ID = '/attitude_simulator'
CONTROLLER_ID = '/attitude_controller'
TAIL_LINES = 5  # of a lost node's log, in the report
# A simulator that ended its run on its own: the other nodes keep running this long (wall
# s) before they are stopped. A reliable message a reader lost on the way (its full
# shared-memory queue, on a loaded machine) goes again only after its writer's next
# heartbeat (20 ms in lockstep, process.heartbeat_profile): a controller stopped as soon as
# the simulator exited took its last commands with it (a formation's leader: 19 of its 20
# lockstep commands in the bag, the simulator had all 20; a fresh clone's suite).
WRITERS_GRACE_S = 1.0
STARTUP_TIMEOUT = 60.0  # wall s for the first sample (imports, kernels from cache, discovery)


def _executable(name):
    """The installed node executable (ament layout), else the module behind it."""
    path = os.path.join(sys.prefix, 'lib', 'rigid_body_sim', name)
    return ([path] if os.path.exists(path)
            else [sys.executable, '-m', f'rigid_body_sim.nodes.{name}'])


class Process:
    """One node, executable ``name``, its stdout and stderr in ``<log_dir>/<name>.log``;
    a formation's controllers: ``controller_<craft>.log``, named ``controller <craft>``."""

    def __init__(self, name, args, log_dir, craft=''):
        exe, self.name = name, f'{name} {craft}' if craft else name
        self.log_path = os.path.join(log_dir, f'{name}_{craft}.log' if craft else f'{name}.log')
        self.log = open(self.log_path, 'wb')
        self.proc = subprocess.Popen(_executable(exe) + args, stdout=self.log,
                                     stderr=subprocess.STDOUT, start_new_session=True)
        self.lost = None  # its exit code, when it exited before the demo stopped it

    def exited(self) -> bool:
        return self.proc.poll() is not None

    def stop(self, timeout=10.0):
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self.log.close()
        return self.proc.returncode

    def tail(self, n=TAIL_LINES):
        """The last ``n`` non-empty lines of its log: what it said before it exited."""
        try:
            with open(self.log_path, errors='replace') as f:
                lines = [line.rstrip() for line in f if line.strip()]
        except OSError:
            return []
        return lines[-n:]


def controllers_file(controllers, out) -> str:
    """A params file of a formation's controllers' own values (``launch_plan.controllers``:
    body frame, inertia), one section per spacecraft namespace: read after the scene's,
    these sections win over its ``/**/attitude_controller`` (a ``-p`` value would not)."""
    import yaml
    path = os.path.join(out, 'controllers.yaml')
    with open(path, 'w') as f:
        yaml.safe_dump({f'/{c.namespace}/attitude_controller': {'ros__parameters': c.parameters}
                        for c in controllers}, f)
    return path


def shown_spacecraft(scene, controllers) -> str:
    """The spacecraft of a formation that the status line and the summary show ('' for a
    scene of one): the first one with a controller that moves at t = 0, else the first."""
    if not scene.spacecraft:
        return ''
    names = [c.namespace for c in controllers] or list(scene.spacecraft)
    moving = [n for n in names if any(scene.spacecraft[n].get(
        'initial_angular_velocity', scene.simulator['initial_angular_velocity']))]
    return (moving or names)[0]


def check_lost(procs, sim):
    """The nodes other than the simulator ``sim`` that exited since the last look: each is
    marked lost and reported now. The simulator's exit is judged at the end
    (:func:`judge_simulator`), once its last samples have arrived."""
    found = []
    for p in procs:
        if p is not sim and p.lost is None and p.exited():
            p.lost = p.proc.returncode
            report_lost(p)
            found.append(p)
    return found


def judge_simulator(sim, t, end, period):
    """Whether the simulator, which exited on its own, is lost: it is unless its last sample
    (sim time ``t`` s, from stamps of ~1.8e9 s: 2.4e-7 s apart as doubles) is its
    ``duration`` ``end`` (0: it runs until stopped), to half a publish ``period``."""
    if sim is None or sim.lost is not None or not sim.exited():
        return False
    if sim.proc.returncode == 0 and end > 0 and t >= end - 0.5 * period:
        return False
    sim.lost = sim.proc.returncode
    report_lost(sim, f' at t = {t:.2f} s of its {end:g} s' if end > 0 else f' at t = {t:.2f} s')
    return True


def report_lost(p, when=''):
    code = p.proc.returncode
    why = ' (0: a SIGINT or SIGTERM from outside the demo)' if code == 0 else ''
    print(f'\ndemo: the {p.name} node exited with {code}{when}{why} before the end of the '
          f'run (log: {p.log_path}); its last lines:', flush=True)
    for line in p.tail():
        print(f'    | {line}', flush=True)


def wait_for_nodes(node, executor, names, procs):
    """Until ``names`` (fully qualified) are in the graph with their subscriptions (or one
    of ``procs`` has exited, or STARTUP_TIMEOUT): they then exist well before the
    simulator starts."""
    deadline = time.monotonic() + STARTUP_TIMEOUT
    while time.monotonic() < deadline and all(p.proc.poll() is None for p in procs):
        present = {ns.rstrip('/') + '/' + n: (n, ns)
                   for n, ns in node.get_node_names_and_namespaces()}
        if set(names) <= set(present) and all(
                node.get_subscriber_names_and_types_by_node(*present[n]) for n in names):
            return
        executor.spin_once(timeout_sec=0.1)


def stop_nodes(procs, spin, sim_ended: bool, interrupted: bool) -> dict:
    """Stop every node but the recorder (``procs[0]``, stopped last by the caller), the
    simulator among them; {name: exit code}. ``spin(seconds)`` turns the demo's own node.
    After a run the simulator ended on its own, the others get WRITERS_GRACE_S first (their
    last messages reach the recorder); then, the nodes stopped, the last messages of their
    shutdown get 1 s (0.2 s after Ctrl-C)."""
    if sim_ended and not interrupted:
        spin(WRITERS_GRACE_S)
    codes = {p.name: p.stop() for p in procs[1:]}
    spin(0.2 if interrupted else 1.0)
    return codes
