"""Every executable answers -h/--help without starting ROS or writing a file; arguments
that cannot work get a clear error before ROS starts (issue 33)."""
import json
import os
import subprocess
import sys
import time

import pytest
from cli_inprocess import run_cli
from ros_helpers import venv_exe

from rigid_body_sim.engine import specs
from rigid_body_sim.node_interfaces import RECORDER_PARAMETERS as RECORDER
from rigid_body_sim.viewer.specs import VIEWER

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.dirname(sys.executable)
NODE_SPECS = {'simulator': specs.SIMULATOR_DECLARED, 'controller': specs.CONTROLLER,
              'recorder': RECORDER, 'viewer': VIEWER}


def run(cmd, cwd, timeout=120, env=None):
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ, **(env or {})))


def wait_output(proc, text, timeout=60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if text in proc.output():
            return True
        if proc.poll() is not None:
            break
        time.sleep(0.05)
    raise AssertionError(f'{text!r} not in output:\n{proc.output()}')


@pytest.mark.parametrize('flag', ['--help', '-h'])
@pytest.mark.parametrize('name', sorted(NODE_SPECS))
def test_node_help_lists_parameters_topics_and_an_example_and_starts_nothing(tmp_path, name,
                                                                             flag):
    res = run([venv_exe(name), flag, '--ros-args', '-p', 'output:=x'], tmp_path)
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert os.listdir(tmp_path) == []          # no bag, no file named --help
    assert '[INFO]' not in res.stdout + res.stderr  # no node came up
    for spec in NODE_SPECS[name]:                # from the specs the node declares
        assert f'  {spec.name} (' in out, spec.name
    assert 'Topics' in out and 'Example:' in out
    example = out[out.index('Example:'):].split('\n')[1].split()
    assert example[0] == os.path.join(BIN, name)  # the venv's script: cwd is not the repo
    assert 'ros2 run' not in out


def test_simulator_help_gives_units_ranges_defaults_and_how_to_take_a_scene(tmp_path):
    out = run([venv_exe('simulator'), '--help'], REPO).stdout
    text = ' '.join(out.split())
    assert 'accuracy (number, rad), default 1e-06' in text
    assert '>= 1e-15 and <= 1' in text
    assert 'integrator (text), default \'auto\'' in text
    assert '--params-file config/<scene>.yaml' in text
    assert '~/reset (std_srvs/Trigger)' in text and 'pub attitude' in text
    # run from the checkout, the example is spelled as the README spells it
    assert '.venv/bin/simulator --ros-args --params-file config/tennis_racket.yaml' in text \
        or f'{BIN}/simulator --ros-args --params-file config/tennis_racket.yaml' in text


def test_replay_help_is_spelled_for_the_venv_and_writes_nothing(tmp_path):
    res = run([venv_exe('replay'), '--help'], tmp_path)
    assert res.returncode == 0, res.stderr
    assert 'ros2 run' not in res.stdout and '--topics' in res.stdout
    assert f'Example: {os.path.join(BIN, "replay")} ' in ' '.join(res.stdout.split())
    assert os.listdir(tmp_path) == []


def test_cli_help_names_the_nodes_as_the_venv_runs_them(tmp_path):
    res = run([venv_exe('rigid-body-sim'), '--help'], tmp_path)
    assert res.returncode == 0, res.stderr
    assert 'ros2 run' not in res.stdout
    assert os.path.join(BIN, 'simulator') in res.stdout


def test_layout_help_writes_no_file_and_a_dash_path_is_refused(tmp_path):
    res = run([sys.executable, '-m', 'rigid_body_sim.viewer.layout', '--help'], tmp_path)
    assert res.returncode == 0, res.stderr
    assert 'usage:' in res.stdout and os.listdir(tmp_path) == []
    res = run([sys.executable, '-m', 'rigid_body_sim.viewer.layout', '--', '-o'], tmp_path)
    assert res.returncode == 2 and 'starts with "-"' in res.stderr
    assert os.listdir(tmp_path) == []
    res = run([sys.executable, '-m', 'rigid_body_sim.viewer.layout', 'l.json'], tmp_path)
    assert res.returncode == 0 and os.listdir(tmp_path) == ['l.json']


def test_bag_writer_refuses_a_directory_starting_with_a_dash(tmp_path, monkeypatch):
    from rigid_body_sim.bag import BagError, BagWriter
    monkeypatch.chdir(tmp_path)
    with pytest.raises(BagError, match='starts with "-"'):
        BagWriter('--help')
    assert os.listdir(tmp_path) == []


def test_recorder_refuses_a_dash_output_and_writes_under_out_by_default(tmp_path, ros_process,
                                                                         namespace):
    res = run([venv_exe('recorder'), '--ros-args', '-r', f'__ns:={namespace}',
               '-p', 'output:=--help'], tmp_path)
    assert res.returncode == 1 and 'starts with "-"' in res.stderr, res.stderr
    assert os.listdir(tmp_path) == []
    rec = ros_process(venv_exe('recorder'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'config_timeout:=0.1', cwd=str(tmp_path))
    wait_output(rec, 'recording to')
    assert rec.stop() == 0, rec.output()
    assert os.listdir(tmp_path) == ['out'], os.listdir(tmp_path)
    bags = os.listdir(tmp_path / 'out')
    assert len(bags) == 1 and bags[0].startswith('rigid_body_sim_'), bags


@pytest.mark.parametrize('name', ['simulator', 'controller', 'recorder', 'viewer', 'replay'])
def test_a_missing_params_file_is_named_without_rcl_internals(tmp_path, name):
    args = [str(tmp_path)] if name == 'replay' else []
    res = run([venv_exe(name), *args, '--ros-args', '--params-file', 'config/no_such.yaml'],
              tmp_path)
    assert res.returncode == 2, res.stdout + res.stderr
    assert '--params-file config/no_such.yaml: no such file' in res.stderr, res.stderr
    assert '.c:' not in res.stderr and 'Traceback' not in res.stderr


def test_scene_parameter_on_a_node_says_how_nodes_take_a_scene(tmp_path, namespace):
    res = run([venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
               '-p', 'scene:=tennis_racket'], REPO)
    assert res.returncode == 2, res.stdout + res.stderr
    out = res.stdout + res.stderr
    assert '--params-file config/<scene>.yaml' in out and 'seed' not in out, out


def test_numbers_that_may_be_negative_parse_and_get_a_range_error(tmp_path):
    # the command's status and message, in this process (an interpreter less, issue 32)
    res = run_cli('run', 'explorer1', '--accuracy', '-1e-3', '--out', tmp_path / 'o',
                  cwd=tmp_path)
    assert res.returncode == 2
    assert 'expected one argument' not in res.stderr
    assert "--accuracy: must be a finite number >= 1e-15 and <= 1, got '-1e-3'" in res.stderr
    from rigid_body_sim.cli import ArgumentParser, number
    p = ArgumentParser()
    p.add_argument('--x', type=number())
    for text, value in (('-1e-3', -1e-3), ('-2', -2.0), ('-.5E+2', -50.0), ('-1.5e3', -1500.0)):
        assert p.parse_args(['--x', text]).x == value


def test_a_scene_typo_gets_did_you_mean(tmp_path):
    res = run_cli('run', 'tenis_racket', '--out', tmp_path / 'o', cwd=tmp_path)
    assert res.returncode != 0
    assert 'did you mean tennis_racket?' in res.stdout + res.stderr, res.stderr


def test_missing_numba_warns_once_unless_jit_is_disabled(tmp_path):
    fake = tmp_path / 'numba'
    fake.mkdir()
    (fake / '__init__.py').write_text('raise ImportError("numba broken for this test")\n')
    code = ('import rigid_body_sim.physics.jit as k, rigid_body_sim.physics.exact.kernel; '
            'print(k.COMPILED)')
    env = {'PYTHONPATH': os.pathsep.join([str(tmp_path)] + [p for p in os.environ.get(
        'PYTHONPATH', '').split(os.pathsep) if p])}
    warned = run([sys.executable, '-c', code], tmp_path, env=dict(env, NUMBA_DISABLE_JIT=''))
    assert warned.returncode == 0, warned.stderr
    assert warned.stdout.strip() == 'False'
    assert warned.stderr.count('kernels run uncompiled') == 1, warned.stderr
    assert 'numba broken for this test' in warned.stderr
    quiet = run([sys.executable, '-c', code], tmp_path, env=dict(env, NUMBA_DISABLE_JIT='1'))
    assert quiet.returncode == 0 and 'uncompiled' not in quiet.stderr, quiet.stderr


def _doc_texts():
    """The README and every docs page: what users copy commands from."""
    import glob
    paths = [os.path.join(REPO, 'README.md')] + sorted(glob.glob(os.path.join(REPO, 'docs',
                                                                            '*.md')))
    return {os.path.relpath(p, REPO): open(p, encoding='utf-8').read() for p in paths}


def test_readme_commands_work_as_printed_in_the_venv():
    """Shell lines in the README's and the docs' code blocks that run the package's commands
    carry the venv's prefix (or are the full install's ros2 run)."""
    lines = []
    for text in _doc_texts().values():
        block = False
        for line in text.splitlines():
            if line.lstrip().startswith('```'):
                block = not block
            elif block:
                lines.append(line.strip())
    bare = [line for line in lines
            if line.startswith(('rigid-body-sim ', 'python -m rigid_body_sim',
                                'python3 -m rigid_body_sim.bench'))]
    assert bare == []


def _readme_modules():
    import re
    text = '\n'.join(_doc_texts().values())
    return sorted(set(re.findall(r'python3? -m (rigid_body_sim(?:\.\w+)+)', text)))


_HELP = {}

# `python -m module --help` for many modules in one interpreter: numpy, scipy and numba
# (third-party, most of each run's CPU) are imported once, then each module runs in a forked
# child as `python -m` runs it (runpy, alter_sys; its own package not yet imported, so
# runpy's RuntimeWarning still shows), in its own directory, its output in files.
_FORKED_HELP = """
import json, os, runpy, sys, traceback
import numba, numpy, scipy.integrate  # noqa: F401
codes = {}
for module, cwd, out, err in json.load(sys.stdin):
    sys.stdout.flush(); sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            for fd, path in ((1, out), (2, err)):
                os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), fd)
            os.chdir(cwd)
            sys.argv = [module, '--help']
            try:
                runpy.run_module(module, run_name='__main__', alter_sys=True)
                code = 0
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else exc.code is not None
                if isinstance(exc.code, str):
                    print(exc.code, file=sys.stderr)
        except BaseException:
            traceback.print_exc()
        finally:
            sys.stdout.flush(); sys.stderr.flush()
            os._exit(int(code))
    codes[module] = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
print(json.dumps(codes))
"""


def module_help(module, tmp_path_factory):
    """(result, files it left) of ``python -m module --help`` run in an empty directory:
    once per module, shared by the tests that check the README's modules and the tools
    (loadfile keeps this file on one worker). The first call runs every such module's."""
    if module not in _HELP:
        modules = sorted(set(_readme_modules()) | {f'rigid_body_sim.tools.{name}'
                                                   for name in _tool_names()} | {module})
        logs = tmp_path_factory.mktemp('help_output')
        jobs = [(m, str(tmp_path_factory.mktemp('help')), str(logs / f'{m}.out'),
                 str(logs / f'{m}.err')) for m in modules]
        res = subprocess.run([sys.executable, '-c', _FORKED_HELP], input=json.dumps(jobs),
                             capture_output=True, text=True, timeout=600)
        assert res.returncode == 0, res.stderr[-3000:]
        codes = json.loads(res.stdout)
        for m, cwd, out, err in jobs:
            with open(out) as o, open(err) as e:
                result = subprocess.CompletedProcess([sys.executable, '-m', m, '--help'],
                                                     codes[m], o.read(), e.read())
            _HELP[m] = result, os.listdir(cwd)
    return _HELP[module]


@pytest.mark.parametrize('module', _readme_modules())
def test_every_module_the_readme_runs_answers_help_and_writes_nothing(tmp_path_factory, module):
    res, files = module_help(module, tmp_path_factory)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.startswith('usage:'), res.stdout[:500]
    assert files == []
    # runpy warns when the package imported the module before running it as __main__
    assert 'RuntimeWarning' not in res.stderr, res.stderr[-2000:]


def _tool_names():
    import pkgutil

    import rigid_body_sim.tools
    return sorted(m.name for m in pkgutil.iter_modules(rigid_body_sim.tools.__path__))


@pytest.mark.parametrize('name', _tool_names())
def test_every_tool_has_a_one_line_docstring_and_help_that_writes_nothing(tmp_path_factory,
                                                                          name):
    import importlib
    module = f'rigid_body_sim.tools.{name}'
    doc = importlib.import_module(module).__doc__
    summary, rest = (doc.split('\n', 1) + [''])[:2]
    assert summary.endswith('.') and rest.startswith('\n'), f'{module}: {summary!r}'
    res, files = module_help(module, tmp_path_factory)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.startswith(f'usage: python -m {module} '), res.stdout[:500]
    assert ' '.join(summary.split()) in ' '.join(res.stdout.split())
    assert files == []


def test_bench_holds_the_suite_and_the_tools_are_apart():
    """A module of ``rigid_body_sim.bench`` that runs alone is one the suite imports (a section
    with its own entry point); standalone tools live in ``rigid_body_sim.tools``."""
    import glob
    bench_dir = os.path.join(REPO, 'rigid_body_sim', 'bench')
    code = ('import sys, rigid_body_sim.bench.suite; '
            'print(" ".join(m for m in sys.modules if m.startswith("rigid_body_sim.")))')
    loaded = set(run([sys.executable, '-c', code], REPO).stdout.split())
    assert 'rigid_body_sim.bench.sections' in loaded
    assert not any(m.startswith('rigid_body_sim.tools') for m in loaded)  # suite runs them apart
    for path in glob.glob(os.path.join(bench_dir, '*.py')):
        with open(path, encoding='utf-8') as f:
            if "__name__ == '__main__'" in f.read():
                name = os.path.basename(path)[:-3]
                assert f'rigid_body_sim.bench.{name}' in loaded, f'{name} belongs in tools/'
