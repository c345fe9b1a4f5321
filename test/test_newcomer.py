"""What a newcomer meets first: --help lists the choices and units, the demo's status line
never shows NaN, and a setup stage says what it does and shows its log only on failure."""
import math
import os
import subprocess
import sys

import pytest

from rigid_body_sim.physics import DISSIPATION_MODELS, INTEGRATORS
from rigid_body_sim.scene import list_scenes

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CLI = os.path.join(os.path.dirname(sys.executable), 'rigid-body-sim')


@pytest.mark.parametrize('command', ['run', 'demo'])
def test_help_lists_scenes_integrators_dissipation_models_and_units(command):
    out = subprocess.run([CLI, command, '--help'], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    text = ' '.join(out.stdout.split())  # argparse wraps lines anywhere
    for name in list(INTEGRATORS) + list(DISSIPATION_MODELS) + [n for n, _, _ in list_scenes()]:
        assert name in text, f'{command} --help does not name {name}'
    assert 'simulated seconds' in text and 'SI' in text and 'rad/s' in text


class _FakeNode:
    def create_subscription(self, *args):
        return None


def _at(w, t):
    """Put the watcher's last sample at sim time ``t`` after the simulator's t = 0 (its
    diagnostics give that stamp; here 100 s)."""
    w.origin = 100.0
    w.stamp = w.origin + t / w.time_scale
    w.t0 = w.stamp if w.t0 is None else w.t0


def test_demo_status_line_is_empty_until_the_first_sample_then_has_no_nan():
    import numpy as np

    from rigid_body_sim.demo_watch import Watcher as _Watcher
    from rigid_body_sim.nodes.common import qos_profile  # noqa: F401 - rclpy importable
    w = _Watcher(_FakeNode(), np.array([0.0, 0.0, 0.0, 1.0]), time_scale=2.0)
    assert w.status() == ''
    w.q, w.w, w.L, w.T = np.array([0.0, 0.0, 0.0, 1.0]), np.ones(3), np.ones(3), 1.5
    _at(w, 0.0)
    line = w.status()
    assert line.startswith('t =') and 'nan' not in line.lower() and 'rtf' not in line
    assert line.endswith('[free]') and w.ended_in() == 'free'
    w.rtf = 0.02  # the first report's rate spans the start-up wait: not shown before 1 s
    assert 'rtf' not in w.status()
    _at(w, 2.0)
    w.rtf, w.phase = 1.0, 'slew'
    assert 'rtf  1.00' in w.status() and w.ended_in() == 'slew'
    # from the simulator's diagnostics: its first report spans start-up and is not shown
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    fresh = _Watcher(_FakeNode(), np.array([0.0, 0.0, 0.0, 1.0]), time_scale=1.0)

    def report(rtf):
        return DiagnosticArray(status=[DiagnosticStatus(
            name='attitude_simulator: simulation', hardware_id='/attitude_simulator',
            values=[KeyValue(key='real_time_factor_achieved', value=str(rtf))])])
    fresh._on_diag(report(0.02))
    assert np.isnan(fresh.rtf)
    fresh._on_diag(report(0.998))
    assert fresh.rtf == 0.998
    # a simulator of another graph in the ROS domain (another namespace) reports on the same
    # /diagnostics: its time origin and rate are not the demo's simulator's
    fresh._on_diag(DiagnosticArray(status=[DiagnosticStatus(
        name='attitude_simulator: simulation', hardware_id='/other/attitude_simulator',
        values=[KeyValue(key='sim_time', value='30.0'),
                KeyValue(key='real_time_factor_achieved', value='0.5')])]))
    assert fresh.rtf == 0.998 and fresh.origin is None


def test_setup_stage_is_one_line_and_shows_the_log_only_on_failure(tmp_path):
    log = tmp_path / 'setup.log'
    step = os.path.join(REPO, '.ci', 'step.sh')
    ok = subprocess.run(['sh', step, str(log), 'stage A', 'sh', '-c', 'echo noisy banner'],
                        capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0
    assert ok.stdout.startswith('stage A …') and 'done (' in ok.stdout
    assert 'noisy banner' not in ok.stdout and 'noisy banner' in log.read_text()
    bad = subprocess.run(['sh', step, str(log), 'stage B', 'sh', '-c', 'echo why >&2; exit 3'],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 3
    assert 'stage B … failed after' in bad.stdout and 'why' in bad.stdout


def test_make_venv_skips_a_pyenv_shim_of_a_missing_version_quietly(tmp_path):
    """pyenv puts shims on PATH for versions it has not installed; running one prints
    'pyenv: python3.12: command not found'. The probe must skip it without that line."""
    shim = tmp_path / 'python3.12'
    shim.write_text('#!/bin/sh\necho "pyenv: python3.12: command not found" >&2\nexit 127\n')
    shim.chmod(0o755)
    venv = tmp_path / 'venv'
    # PYTHON= a missing one, so the probe walks the list; stop after choosing (no venv made):
    # a venv that exists with pip short-circuits, so give it a fake one after the probe
    env = dict(os.environ, PATH=f'{tmp_path}:{os.environ["PATH"]}')
    script = open(os.path.join(REPO, '.ci', 'make_venv.sh')).read()
    probe = script.split('rm -rf "$VENV"')[0] + 'echo "chose $PY"\n'
    out = subprocess.run(['sh', '-c', probe, 'make_venv', str(venv)], capture_output=True,
                         text=True, env=env, timeout=60)
    assert out.returncode == 0, out.stderr
    assert 'pyenv' not in out.stderr + out.stdout and 'chose python3' in out.stdout
    assert 'chose python3.12' not in out.stdout


def test_demo_summary_explains_an_unfinished_run():
    import numpy as np

    from rigid_body_sim.demo_watch import Watcher as _Watcher
    from rigid_body_sim.demo_summary import phase_hint as _phase_hint
    from rigid_body_sim.scene import load
    scene = load(os.path.join(REPO, 'config', 'default.yaml'))
    w = _Watcher(_FakeNode(), np.array([0.0, 0.0, 0.0, 1.0]))
    _at(w, 10.0)
    assert 'free phase lasts 17 s' in _phase_hint(w, scene, math.nan)
    w.phase = 'slew'
    _at(w, 24.0)  # the slew began at 20 s (the summary takes that from the bag)
    assert 'settles to 2 % in 5.83/ω_n = 7.3 s' in _phase_hint(w, scene, 20.0)
    _at(w, 40.0)
    assert _phase_hint(w, scene, 20.0) == ''
    w.phase = 'detumble'  # the default mission: the slew follows the detumble
    assert 'it follows once |ω| <' in _phase_hint(w, scene, math.nan)
    detumble = load(os.path.join(REPO, 'config', 'detumble.yaml'))  # no slew follows
    hint = _phase_hint(w, detumble, math.nan)
    assert 'points nowhere' in hint and 'slew had not begun' not in hint, hint
