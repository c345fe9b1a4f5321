"""The simulator's ``cpu_affinity``: every thread of its process (its own and Fast DDS's)
on the one CPU core given, and a core it cannot run on refused at start-up with the
reason (``nodes/process.py``: ``pin_process``; docs/live-nodes.md says what it changes in
lockstep). Real processes: the simulator node, and a child Python for the refusals.
"""
import os
import subprocess
import sys

import pytest

from ros_helpers import venv_exe, wait_output

from rigid_body_sim.nodes.process import pin_process


def _cores(text: str) -> set:
    """'0-2,5' (Linux's CPU list) as {0, 1, 2, 5}."""
    out = set()
    for part in text.strip().split(','):
        lo, _, hi = part.partition('-')
        out.update(range(int(lo), int(hi or lo) + 1))
    return out


def _thread_cores(pid: int) -> dict:
    """{(thread id, its name): the cores it may run on} for every thread of ``pid``."""
    out = {}
    for tid in os.listdir(f'/proc/{pid}/task'):
        try:
            with open(f'/proc/{pid}/task/{tid}/comm') as f:
                name = f.read().strip()
            with open(f'/proc/{pid}/task/{tid}/status') as f:
                line = next(x for x in f if x.startswith('Cpus_allowed_list:'))
        except (FileNotFoundError, ProcessLookupError):  # the thread ended meanwhile
            continue
        out[(tid, name)] = _cores(line.split(':', 1)[1])
    return out


def test_the_simulator_runs_every_thread_on_its_cpu_affinity(ros_process, namespace):
    """With ``cpu_affinity: N`` every thread of the simulator's process, Fast DDS's
    receivers and timed events among them, may run on core N only; the same node without
    it keeps the cores its parent had (so the pin is the parameter's doing)."""
    allowed = os.sched_getaffinity(0)
    core = max(allowed)
    args = ('--ros-args', '-r', f'__ns:={namespace}', '-p', 'duration:=600.0')
    pinned = ros_process(venv_exe('simulator'), *args, '-p', f'cpu_affinity:={core}',
                         env={'PYTHONUNBUFFERED': '1'})
    free = ros_process(venv_exe('simulator'), *args, '-r', '__node:=free_simulator',
                       env={'PYTHONUNBUFFERED': '1'})
    for proc in (pinned, free):  # built, parameters applied, middleware threads up
        assert wait_output(proc, 'kernels loaded', 180), proc.output()[-3000:]
    got = _thread_cores(pinned.pid)
    assert any(name.startswith('dds.') for _, name in got), got  # the middleware's too
    assert all(cores == {core} for cores in got.values()), got
    others = _thread_cores(free.pid)
    assert others and all(cores == allowed for cores in others.values()), others


def test_a_core_the_machine_does_not_have_ends_the_simulator_with_the_reason(ros_process,
                                                                            namespace):
    """``cpu_affinity`` past the machine's cores: exit code 2 and a message naming the
    parameter, the value and the cores there are, before anything runs."""
    count = os.cpu_count()
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', f'cpu_affinity:={count + 3}', env={'PYTHONUNBUFFERED': '1'})
    assert sim.wait(120) == 2, sim.output()[-3000:]
    out = sim.output()
    assert f'cpu_affinity = {count + 3}: no such CPU core for this process: this machine ' \
        f'has {count} (0-{count - 1})' in out, out[-3000:]
    assert 'starting at t = 0' not in out


def _child(code: str, cores=None) -> subprocess.CompletedProcess:
    """``code`` run by a child Python, on ``cores`` (None: the parent's)."""
    return subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120, preexec_fn=None if cores is None else
                          (lambda: os.sched_setaffinity(0, cores)))


def test_pin_process_refuses_a_core_outside_the_set_it_was_started_with():
    """A core the machine has but the process was not started on (taskset, a cgroup's
    cpuset) is refused with the cores it may use; -1 changes nothing."""
    allowed = sorted(os.sched_getaffinity(0))
    if len(allowed) < 2:
        pytest.skip('needs two cores this process may run on')
    got = _child('from rigid_body_sim.nodes.process import pin_process\n'
                 f'pin_process({allowed[1]}, "cpu_affinity")', cores={allowed[0]})
    assert got.returncode != 0
    assert f'ValueError: cpu_affinity = {allowed[1]}: no such CPU core for this process: ' \
        f'this process may run on {allowed[0]} only' in got.stderr, got.stderr
    before = os.sched_getaffinity(0)
    pin_process(-1)
    assert os.sched_getaffinity(0) == before


def test_the_lockstep_benchmark_runs_both_processes_on_one_core(monkeypatch):
    """``tools.lockstep --cpu N``: the simulator gets ``cpu_affinity: N`` and the
    controller is started on core N; the run still exchanges every period, and the CPU
    row's note says where they ran."""
    from rigid_body_sim.tools import lockstep
    core = max(os.sched_getaffinity(0))
    started = []
    popen = lockstep.subprocess.Popen

    def spy(cmd, **kwargs):  # each node's start: what its child runs first
        if '--ros-args' in cmd:
            node = cmd[cmd.index('--ros-args') - 1]
            started.append((node.rsplit('.', 1)[-1].rsplit('/', 1)[-1],
                            kwargs.get('preexec_fn')))
        return popen(cmd, **kwargs)
    monkeypatch.setattr(lockstep.subprocess, 'Popen', spy)
    got = lockstep.exchange(50.0, 0.0, 0.4, cpu=core)
    assert got['exchanges'] == 20, got
    kinds = dict(started)  # the simulator pins itself (its parameter), the controller not
    assert sorted(kinds) == ['controller', 'simulator'] and kinds['simulator'] is None
    pinned = subprocess.run([sys.executable, '-c', 'import os\nprint(sorted('
                             'os.sched_getaffinity(0)))'], capture_output=True, text=True,
                            timeout=120, preexec_fn=kinds['controller'])
    assert pinned.stdout.strip() == str([core]), pinned
    over = lockstep.overrides(0.0, 1.0, 50.0, core)
    try:
        with open(over) as f:
            assert f'cpu_affinity: {core}\n' in f.read()
    finally:
        os.unlink(over)
    fast = {'sim_cpu_per_period_us': 90.0, 'sim_thread_cpu_per_period_us': 70.0,
            'sim_threads_us': {'main': 70.0}}
    rows = [{'control_rate_hz': 100.0, 'as_fast_as_possible': fast,
             'real_time': {'achieved_rate_hz': 100.0}}]
    assert lockstep.targets_from(rows, [1.0, 2.0], core)[0]['note'].endswith(
        f'load 1.0-2.0; both on CPU {core}')
    assert 'both on CPU' not in lockstep.targets_from(rows, [1.0, 2.0])[0]['note']


def test_the_floor_tool_runs_both_processes_on_one_core():
    """``tools.lockstep_floor --cpu N``: the bare rclpy node's process runs on core N (it
    says so itself), the controller it starts with it, and the exchange still runs;
    without it the process keeps this one's cores."""
    from rigid_body_sim.tools.lockstep_floor import floor
    allowed = sorted(os.sched_getaffinity(0))
    got = floor('SYNCHRONOUS', True, 20, 1, 'default', 'waitset', cpu=allowed[-1])
    assert got['exchanges'] == 20 and got['cpu_per_exchange_us'] > 0, got
    assert got['cpus_runs'] == [[allowed[-1]]], got
    free = floor('SYNCHRONOUS', True, 20, 1, 'default', 'waitset')
    assert free['cpus_runs'] == [allowed], free
