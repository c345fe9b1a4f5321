"""The command line as users meet it: options checked by name, pipes, unstable steps.

Real processes of the installed ``rigid-body-sim``, ``replay`` and friends where the process
is the point (pipes, the installed script); what a command says and its exit code in this
test's process (cli_inprocess.run_cli: an interpreter's start-up less each, issue 32).
"""
import math
import subprocess

import numpy as np
import pytest

from cli_inprocess import run_cli
from ros_helpers import venv_exe

from rigid_body_sim.physics import Dissipation, Dynamics
from rigid_body_sim.physics.integrators.stability import check_step, largest_stable_step


def _run(*args, timeout=120):
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize('args,option', [
    (['run', 'tennis_racket', '--duration', 'inf'], '--duration'),
    (['run', 'tennis_racket', '--duration', '-5'], '--duration'),
    (['run', 'tennis_racket', '--duration', 'nan'], '--duration'),
    (['run', 'tennis_racket', '--step', '0'], '--step'),
    (['run', 'tennis_racket', '--accuracy', '2'], '--accuracy'),
    (['run', 'tennis_racket', '--integrator', 'rk5'], '--integrator'),
    (['demo', '--duration', '0'], '--duration'),
])
def test_numeric_options_are_checked_by_name(args, option):
    """The error names the option and its range, not the scene file; exit code 2."""
    out = run_cli(*args)  # argparse's exit 2 and its message, as the process gives them
    assert out.returncode == 2
    assert f'argument {option}' in out.stderr and 'config/' not in out.stderr, out.stderr
    assert 'Traceback' not in out.stderr


def test_replay_options_are_checked_by_name():
    out = _run(venv_exe('replay'), 'nowhere', '--rate', 'inf')
    assert out.returncode == 2 and 'argument --rate' in out.stderr, out.stderr


def test_a_closed_pipe_ends_quietly():
    """The reader goes away before the first line (as `| head` does): no traceback."""
    proc = subprocess.Popen([venv_exe('rigid-body-sim'), 'scenes', '--paths'],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(60) == 141 and 'Traceback' not in err and err == '', err


def test_unstable_steps_are_refused_or_warned_before_the_run():
    """RK4 far beyond its imaginary-axis limit 2√2/(|ω|/2) is refused before any step,
    naming the largest stable step; Euler (unstable at any step for free rotation) gets a
    warning with the growth over the run; a stable RK4 step passes silently."""
    out = run_cli('run', 'rigid_earth', '--integrator', 'rk4',
                  '--step', '86400', '--set', 'publish_rate=1.1574074074e-05',  # one a day
                  '--no-bag', '--no-plots')
    assert out.returncode == 2 and 'largest stable step here is 7.7' in out.stderr, out.stderr
    assert 'steps' not in out.stdout  # refused before the run
    out = run_cli('run', 'tennis_racket', '--integrator', 'euler', '--no-bag', '--no-plots')
    assert out.returncode == 0 and out.stderr.startswith('warning: euler') and \
        'unstable for free rotation at any step' in out.stderr, out.stderr
    out = run_cli('run', 'tennis_racket', '--integrator', 'rk4', '--duration', '2',
                  '--no-bag', '--no-plots')
    assert out.returncode == 0 and out.stderr == '', out.stderr


def test_stability_limits_are_the_textbook_ones():
    """Spin about a principal axis: the quaternion mode is ±i|ω|/2, so RK4's limit is
    h = 2√2 / (|ω|/2) (no other mode is faster for a sphere); a stiff double bracket puts
    a mode on the negative real axis, where RK4's limit is h·λ = 2.785."""
    sphere = Dynamics(np.array([1.0, 1.0, 1.0]))
    m = np.array([0.0, 0.0, 3.0])  # |ω| = 3 rad/s
    limit = largest_stable_step('rk4', sphere, m, 10.0)
    assert limit == pytest.approx(2 * math.sqrt(2) / 1.5, rel=1e-6)
    assert largest_stable_step('euler', sphere, m, 1.0) < 1e-6
    stiff = Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation('double_bracket', 100.0))
    m = np.array([1e-3, 1e-3, 1.0])
    lam = stiff.dissipation_stiffness(float(np.linalg.norm(m)))
    h = largest_stable_step('rk4', stiff, m, 1.0)
    assert h * lam == pytest.approx(2.785, rel=0.01)
    assert check_step('splitting2', stiff, m, 10.0, 100.0) == ('ok', None)


def test_the_offline_modules_import_without_numba_or_the_bag_writer():
    """engine, physics and bag resolve their names on first use: a fresh process importing
    the offline run's module, BagError and the rotation helpers (what a refused argument or
    scene file reaches first) loads neither numba, scipy, mcap nor the engine's core."""
    import sys
    proc = subprocess.run([sys.executable, '-c', (
        'import sys; from rigid_body_sim import bag_sink, offline, run_cli; '
        'from rigid_body_sim.bag.errors import BagError; '
        'from rigid_body_sim.physics import rotation, body; '
        'print(sorted(m for m in ("numba", "scipy", "mcap", "rigid_body_sim.engine.core", '
        '"rigid_body_sim.physics.integrators") if m in sys.modules))')],
        capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().splitlines()[-1] == '[]'


def test_the_tools_that_run_nodes_import_without_numba():
    """The tools that start nodes and report (bench.common's report and best_of) run no
    kernel themselves: importing them (their --help, their whole run) loads no numba."""
    import sys
    tools = ('lockstep', 'lockstep_floor', 'fleet', 'flood_report', 'recovery', 'two_hosts')
    proc = subprocess.run([sys.executable, '-c', (
        'import importlib, sys; '
        f'[importlib.import_module("rigid_body_sim.tools." + t) for t in {tools!r}]; '
        'importlib.import_module("rigid_body_sim.bench.common"); '
        'print("numba" in sys.modules)')], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().splitlines()[-1] == 'False'


@pytest.mark.parametrize('package', ['rigid_body_sim.engine', 'rigid_body_sim.physics',
                                     'rigid_body_sim.bag'])
def test_the_packages_names_resolve_on_first_use(package):
    """Every name a package exports is there when asked for (and listed by dir()); a name
    it does not have raises AttributeError naming it."""
    import importlib
    module = importlib.import_module(package)
    for name in module.__all__:
        assert getattr(module, name) is not None, name
        assert name in dir(module)
    with pytest.raises(AttributeError, match='no_such_name'):
        module.no_such_name  # noqa: B018
