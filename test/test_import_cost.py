"""--help (the CLI's, the nodes', the bench's and every tool's), parsing a scene file,
checking parameters and the demo's summary without plots never import numba (issue 32).

numba's start-up (~0.35 CPU-s, with the scipy.linalg it imports) was paid by every --help
and every refused input: the specs took constants from the kernels' modules. Those now
live in numba-free modules (physics/choices.py, physics/orbit/layout.py, control_params.py,
engine/actuator_specs.py); this keeps them there. One fresh interpreter runs the steps in
order and names the first that loaded numba.
"""
import json
import os
import subprocess
import sys


_STEPS = r'''
import contextlib, io, json, sys
steps = []

def step(name, fn):
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        try:
            fn()
        except SystemExit:
            pass
    steps.append([name, 'numba' in sys.modules])

def cli(*argv):
    from rigid_body_sim import cli
    return lambda: cli.main(list(argv))

def node_help(name):
    def answer():
        from rigid_body_sim.nodes import usage
        assert usage.answer(name, [name, '--help']) == 0
    return answer

def module_help(name):  # `python -m name --help`
    def answer():
        import runpy
        sys.argv = [name, '--help']
        runpy.run_module(name, run_name='__main__', alter_sys=False)
    return answer

def load(name):
    def parse():
        from rigid_body_sim.scene import load
        load(name, ['integrator=rk4', 'dissipation.model=viscous'], '/')
    return parse

def refused():
    from rigid_body_sim.scene import SceneError, load
    try:
        load('tennis_racket', ['dissipation.model=sticky'], '/')
    except SceneError:
        return
    raise AssertionError('an unknown dissipation model was accepted')

step('rigid-body-sim --help', cli('--help'))
for sub in ('run', 'campaign', 'demo', 'bench'):
    step(f'rigid-body-sim {sub} --help', cli(sub, '--help'))
for name in ('simulator', 'controller', 'recorder', 'viewer', 'replay'):
    step(f'{name} --help', node_help(name))
step('import the viewer node', lambda: __import__('rigid_body_sim.nodes.viewer'))
import pkgutil, rigid_body_sim.tools
TOOLS = sorted(m.name for m in pkgutil.iter_modules(rigid_body_sim.tools.__path__))
for tool in TOOLS:
    step(f'python -m rigid_body_sim.tools.{tool} --help',
         module_help(f'rigid_body_sim.tools.{tool}'))
for scene in ('tennis_racket', 'wheel_slew', 'cmg_slew', 'slew'):
    step(f'parse the scene file {scene}', load(scene))
step('a refused scene value', refused)

def demo_summary_without_plots():  # `demo --no-plots`: the summary needs no kernel
    from rigid_body_sim import demo_summary
    from rigid_body_sim.scene import load
    demo_summary.summarize(load('slew', [], '/'), '/nonexistent/bag', '/tmp', None, None, {},
                           {'recorder': 'recorder.log'}, False, plots=False)
step('the demo summary without plots', demo_summary_without_plots)
print(json.dumps([len(TOOLS), steps]))
'''


def test_help_and_scene_parsing_do_not_import_numba():
    out = subprocess.run([sys.executable, '-c', _STEPS], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    tools, steps = json.loads(out.stdout.strip().splitlines()[-1])
    assert tools >= 15 and len(steps) == 17 + tools, steps
    first = next((name for name, loaded in steps if loaded), None)
    assert first is None, f'{first} imported numba'


_KERNELS = r'''
import json, sys
import numpy as np
from rigid_body_sim.engine import Engine, EngineConfig
from rigid_body_sim.physics import jit
from numba.core import base
refreshes = []  # numba's registries' refresh, by the contexts it ran on
refresh = base.BaseContext.refresh
base.BaseContext.refresh = lambda self: (refreshes.append(1), refresh(self))[1]
for _ in Engine(EngineConfig.from_parameters({'duration': 0.05})).run():
    pass
loaded = {name: name in sys.modules for name in ('scipy.linalg', 'coverage')}
loading = len(refreshes)
import numba  # numba's BLAS still works when a kernel asks for it (compiled here, not cached)
dot = numba.njit(lambda a, b: np.dot(a, b))
a = np.arange(9.0).reshape(3, 3)
print(json.dumps([jit.COMPILED, jit.signatures(), loaded, bool(np.array_equal(dot(a, a), a @ a)),
                  [loading, len(refreshes)]]))
'''


def test_loading_kernels_imports_neither_scipy_linalg_nor_coverage():
    """numba's start-up without ``import coverage`` (no coverage run in the process) and
    without ``import scipy.linalg`` for its BLAS check (physics/numba_start.py): 0.22 of
    the ~0.7 CPU-s numba cost each simulator and CLI run. np.dot still compiles and runs.
    Nor its registries' refresh while kernels load from the cache (~0.1-0.2 CPU-s of each
    simulator's start); the compilation of np.dot then refreshes them itself."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(('COVERAGE', 'NUMBA_D'))}
    out = subprocess.run([sys.executable, '-c', _KERNELS], capture_output=True, text=True,
                         timeout=300, env=env)
    assert out.returncode == 0, out.stderr
    compiled, signatures, loaded, dot_ok, (loading, after) = json.loads(
        out.stdout.strip().splitlines()[-1])
    assert compiled and signatures > 0, (compiled, signatures)
    assert loaded == {'scipy.linalg': False, 'coverage': False}, loaded
    assert dot_ok
    assert loading == 0 and after > 0, (loading, after)


def test_the_figures_module_leaves_scipy_optimize_to_orbit_scenes():
    """Every run that writes figures imports ``rigid_body_sim.plots``; scipy.optimize and
    scipy.spatial (0.3 CPU-s) are imported only where an orbit scene's figure fits or
    rotates (plots/orbit.py); test_plots draws those."""
    code = ('import json, sys; import rigid_body_sim.plots; '
            'print(json.dumps(sorted(m for m in sys.modules if m.startswith('
            '("scipy.optimize", "scipy.spatial")))))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []


_REFUSED_NODE = r'''
import contextlib, io, json, sys
from rigid_body_sim.nodes import simulator
runs = []
for args in sys.argv[1:]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = simulator.main(['--ros-args', *json.loads(args)])
    runs.append([code, 'numba' in sys.modules])
from rigid_body_sim.physics import jit  # what a started node then loads: numba is there
print(json.dumps([runs, 'numba' in sys.modules]))
'''


def test_a_simulator_refused_for_its_parameters_exits_without_importing_numba(tmp_path):
    """The simulator node's module and its checks of the parameters load no numba (~0.4
    CPU-s of each start): it loads with the first spacecraft's engine (nodes/spacecraft.py,
    sim_warm.py, sim_lockstep.py, orbit_messages.py import the physics where they use it).
    A refused params file, a refused value in a file and an out-of-range -p each exit 2,
    numba still unimported; importing the kernels' settings then does load it."""
    typo = tmp_path / 'typo.yaml'
    typo.write_text('attitude_simulator:\n  ros__parameters:\n    intertia_typo: [1.0]\n')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    inertia: [1.0, 2.0, 30.0]\n')
    cases = [['--params-file', str(typo)], ['--params-file', str(bad)],
             ['-p', 'publish_rate:=-1.0']]
    out = subprocess.run([sys.executable, '-c', _REFUSED_NODE, *map(json.dumps, cases)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    runs, loaded_after = json.loads(out.stdout.strip().splitlines()[-1])
    assert runs == [[2, False]] * len(cases), (runs, out.stderr)
    assert loaded_after, 'numba was not importable: the check above proved nothing'
