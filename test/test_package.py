"""The package as users install it: the venv as an ament prefix, colcon build, executables."""
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

from ros_helpers import venv_exe


REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
NODES = ('simulator', 'controller', 'recorder', 'replay')


def _run(cmd, env=None, timeout=60, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, **(env or {})), **kw)


def test_venv_is_an_ament_prefix_for_this_package():
    prefix = sys.prefix
    assert os.path.isfile(
        os.path.join(prefix, 'share/ament_index/resource_index/packages/rigid_body_sim'))
    for rel in ('share/rigid_body_sim/package.xml', 'share/rigid_body_sim/config/default.yaml',
                'share/rigid_body_sim/launch/sim.launch.py'):
        assert os.path.isfile(os.path.join(prefix, rel)), rel
    for exe in NODES:
        path = os.path.join(prefix, 'lib', 'rigid_body_sim', exe)
        assert os.access(path, os.X_OK), path
    # ament_index resolves without AMENT_PREFIX_PATH exported by hand
    # (importing the package adds it)
    env = {k: v for k, v in os.environ.items() if k != 'AMENT_PREFIX_PATH'}
    code = ('import rigid_body_sim\n'
            'from ament_index_python import get_package_prefix, get_package_share_directory\n'
            'print(get_package_prefix("rigid_body_sim")); '
            'print(get_package_share_directory("geometry_msgs"))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, env=env,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split()
    assert os.path.realpath(lines[0]) == os.path.realpath(prefix)
    assert lines[1].startswith(prefix)


def test_cli_lists_its_subcommands():
    out = _run([os.path.join(os.path.dirname(sys.executable), 'rigid-body-sim'), '--help'])
    assert out.returncode == 0
    for sub in ('run', 'scenes', 'demo', 'bag', 'bench', 'campaign'):
        assert sub in out.stdout, sub


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory):
    """colcon build (colcon from PyPI) of a copy of this repo's tracked files in a temp
    workspace."""
    ws = tmp_path_factory.mktemp('ws')
    files = _run(['git', 'ls-files'], cwd=REPO).stdout.split()
    if not files:  # not a git checkout (e.g. an sdist): copy the package sources
        files = [os.path.relpath(os.path.join(d, f), REPO) for d, _, fs in os.walk(REPO)
                 for f in fs if '.venv' not in d and '.git' not in d]
    for rel in files:
        dst = ws / 'src' / 'rigid_body_sim' / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(os.path.join(REPO, rel), dst)
    colcon = os.path.join(os.path.dirname(sys.executable), 'colcon')
    out = _run([colcon, 'build', '--event-handlers', 'console_direct-'], cwd=ws, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    return ws / 'install' / 'rigid_body_sim'


def test_colcon_build_installs_the_ament_layout(colcon_install):
    prefix = colcon_install
    for exe in NODES:
        assert os.access(prefix / 'lib' / 'rigid_body_sim' / exe, os.X_OK), exe
    assert (prefix / 'share/ament_index/resource_index/packages/rigid_body_sim').is_file()
    assert (prefix / 'share/rigid_body_sim/package.xml').is_file()
    assert (prefix / 'share/rigid_body_sim/config/default.yaml').is_file()
    assert (prefix / 'share/rigid_body_sim/launch/sim.launch.py').is_file()
    # ament_index finds the colcon prefix first when it is on AMENT_PREFIX_PATH
    # (as setup.bash does)
    code = ('from ament_index_python import get_package_prefix; '
            'print(get_package_prefix("rigid_body_sim"))')
    out = _run([sys.executable, '-c', code],
               env={'AMENT_PREFIX_PATH': f'{prefix}{os.pathsep}{sys.prefix}'})
    assert out.returncode == 0, out.stderr
    assert os.path.realpath(out.stdout.strip()) == os.path.realpath(prefix)


@pytest.mark.parametrize('where', ['venv', 'colcon'])
def test_installed_simulator_starts_publishes_and_stops_on_sigint(where, request, ros_process,
                                                                   namespace, rclpy_node):
    from geometry_msgs.msg import QuaternionStamped
    from ros_helpers import spin_until
    if where == 'venv':
        exe, env = venv_exe('simulator'), {}
    else:
        prefix = request.getfixturevalue('colcon_install')
        exe = str(prefix / 'lib' / 'rigid_body_sim' / 'simulator')
        env = {'AMENT_PREFIX_PATH': f'{prefix}{os.pathsep}{sys.prefix}'}
    proc = ros_process(exe, '--ros-args', '-r', f'__ns:={namespace}', env=env)
    got = []
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude', got.append, 10)
    assert spin_until(rclpy_node, lambda: len(got) >= 3, 30.0), proc.output()
    assert proc.stop() == 0, proc.output()
    assert 'Traceback' not in proc.output()


# The installed controller and recorder stopping cleanly on SIGINT (exit 0, no traceback)
# while they run: test_signals.py, which signals the same executables in a running graph
# (issue 32: this file started each once more for it).


def test_replay_help_and_bad_path_are_clean():
    out = _run([venv_exe('replay'), '--help'])
    assert out.returncode == 0 and '--rate' in out.stdout
    out = _run([venv_exe('replay'), '/nonexistent/bag'])
    assert out.returncode != 0 and 'Traceback' not in out.stderr + out.stdout
    assert textwrap.shorten(out.stderr, 200)  # one clear line


def test_launch_file_ends_with_the_simulation_and_follows_the_plan():
    """launch/ can't run here (no `launch` on PyPI): its syntax, that it builds its nodes
    from launch_plan.plan, and that it registers OnProcessExit on the simulator emitting
    Shutdown (so the launch ends with the simulation and the recorder is stopped)."""
    import ast
    path = os.path.join(REPO, 'launch', 'sim.launch.py')
    text = open(path).read()
    tree = ast.parse(text, path)
    calls = {n.func.id if isinstance(n.func, ast.Name) else n.func.attr: n
             for n in ast.walk(tree) if isinstance(n, ast.Call)}
    assert {'plan', 'OnProcessExit', 'EmitEvent', 'Shutdown', 'RegisterEventHandler',
            'Node'} <= set(calls)
    on_exit = calls['OnProcessExit']
    target = next(kw.value for kw in on_exit.keywords if kw.arg == 'target_action')
    assert ast.unparse(target) == "nodes['simulator']"
    assert "default_value='auto'" in text and "default_value='default'" in text
    # a formation's controllers: each node in the namespace the plan gives it
    node = calls['Node']
    assert ast.unparse(next(kw.value for kw in node.keywords if kw.arg == 'namespace')) == \
        'p.namespace or None'
    # every argument of the plan is a launch argument, passed in the plan's order
    import inspect
    from rigid_body_sim.launch_plan import plan
    declared = [n.args[0].value for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', '') == 'DeclareLaunchArgument']
    assert declared == list(inspect.signature(plan).parameters)
    assert [ast.unparse(a) for a in calls['plan'].args] == [f"arg('{a}')" for a in declared]
    setup_text = open(os.path.join(REPO, 'setup.py')).read()
    for exe in ('simulator', 'controller', 'recorder'):
        assert f"'{exe} = rigid_body_sim.nodes.entry:{exe}'" in setup_text


@pytest.mark.parametrize('exe', NODES)
def test_bad_ros_arguments_end_a_node_with_the_reason(exe, tmp_path):
    """A malformed remap rule: rclpy.init refuses it; the node exits with 2 and a line
    naming the node and rcl's reason (after rcl's own error line), no traceback."""
    args = [str(tmp_path)] if exe == 'replay' else []
    out = _run([venv_exe(exe), *args, '--ros-args', '-r', 'no_separator'])
    assert out.returncode == 2, out.stdout + out.stderr
    assert 'Traceback' not in out.stdout + out.stderr
    [line] = [s for s in out.stderr.splitlines() if 'cannot initialise ROS' in s]
    assert line.startswith('[FATAL] [') and 'no_separator' in line, line
