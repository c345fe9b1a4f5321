"""The Basilisk harness (bench/basilisk_gg.py) simulates the physics ours does.

The same gravity-gradient torque at a state to 1e-12 relative, the same initial state and
sample instants, and bsk imported by the section only (never by the suite's imports).
"""
import subprocess
import sys

import numpy as np
import pytest

from rigid_body_sim.bench import basilisk_gg as bg
from rigid_body_sim.physics import rotation
from rigid_body_sim.physics.orbit import kernel

ATTITUDES = ([0.1, 0.2, 0.3, 0.927], [0.3, -0.5, 0.2, 0.787], [-0.9, 0.1, 0.3, -0.3],
             [0.6, 0.7, -0.2, 0.1])  # the last two: |σ| > 1 before the short set is taken


@pytest.fixture(scope='module', params=bg.SCENES, ids=lambda s: s.name)
def scene(request):
    return request.param, bg.Setup.of(request.param.scene_file())


def test_bsk_is_installed_with_the_venv():
    """requirements-peers.txt pins it: the bench compares against it on every run."""
    assert bg.installed() == '2.12.1'


def test_the_gravity_gradient_torque_is_ours_to_1e_12(scene):
    setup = scene[1]
    env = setup.orbit.elements(0.0)
    env[kernel.ON] = 1.0
    checked = 0
    for t in (0.0, 1234.5, 0.37 * setup.duration, setup.duration):
        r, _ = setup.orbit.state(t)
        for q in ATTITUDES:
            q = np.asarray(q, float) / np.linalg.norm(q)
            ours = np.array(kernel.gravity_gradient_torque(q, t, env, setup.moments))
            theirs = bg.torque(setup, q, r)
            assert np.linalg.norm(ours) > 1e-9  # a real torque, not two zeros
            assert np.linalg.norm(theirs - ours) <= 1e-12 * np.linalg.norm(ours), (t, q)
            checked += 1
    assert checked == 16


def test_mrp_and_quaternion_are_the_same_rotation():
    """σ_BN in, q body → inertial out: Basilisk's own MRP2C against ours, either sign of q."""
    from Basilisk.utilities import RigidBodyKinematics as rbk
    for q in ATTITUDES:
        q = np.asarray(q, float) / np.linalg.norm(q)
        sigma = bg.quat_to_mrp(q)
        assert np.linalg.norm(sigma) <= 1.0
        body_to_inertial = np.asarray(rbk.MRP2C(sigma)).T
        assert np.allclose(body_to_inertial @ np.eye(3), rotation.rotate(q, np.eye(3)).T,
                           atol=1e-15)
        assert rotation.angle_between(bg.mrp_to_quat(sigma), q) < 1e-15


def test_both_start_from_the_same_state_and_sample_at_the_same_instants(scene):
    """Basilisk's recorder: the scene's sample rate, from the same initial attitude and
    orbit; a short RKF78 run stays on our dop853 run (the same physics along the way)."""
    from rigid_body_sim.offline import simulate
    scene, setup = scene
    short = bg.Setup(**{**setup.__dict__, 'duration': 300.0})
    _, t, q, r = bg.run_basilisk(short, 'rkf78', 1e-12)
    assert np.array_equal(t, np.arange(0.0, 300.0 + 1.0, short.sample_period))
    assert rotation.angle_between(q[0], setup.attitude) < 1e-15
    assert np.allclose(r[0], setup.r0, rtol=0.0, atol=1e-8)
    ours = simulate(scene.scene_file(), duration=300.0, integrator='dop853',
                    integrator_options={'rtol': 1e-13, 'atol': 1e-16}).samples
    assert len(ours) == len(q)
    assert np.max(rotation.angle_between(ours.attitude, q)) < 1e-10
    assert bg.orbit_error(short, t, r) < 1e-12


def test_the_suite_imports_no_basilisk():
    code = ('import sys, rigid_body_sim.bench, rigid_body_sim.bench.basilisk_gg; '
            'print(any(m.split(".")[0] == "Basilisk" for m in sys.modules))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == 'False'


def _target_row(target, scene, verdict='PASS', measured=12.0):
    return {'target': target, 'scene': scene, 'level': 1e-6, 'ours_method': 'splitting6',
            'ours_cpu_s': 0.001, 'peer_method': 'bsk_rk4', 'peer_cpu_s': measured * 0.001,
            'measured': measured, 'required': 10.0, 'verdict': verdict, 'note': ''}


def test_a_section_run_alone_replaces_its_rows_in_a_full_runs_tables(tmp_path):
    """``python -m rigid_body_sim.bench.basilisk_gg --out DIR`` puts its rows in DIR's
    targets.csv and targets.md in place of its old ones, after the work-precision rows,
    and the summary renders them with what Basilisk reached (basilisk.csv)."""
    import csv

    from rigid_body_sim.bench import report, targets
    from rigid_body_sim.bench.common import write_csv
    old = [_target_row('cpu ratio best peer / best ours', 'tumble'),
           _target_row(bg.TARGET, 'gravity_gradient', 'MISS', 3.0),
           _target_row('kernels ready from the cache (warm start, CPU s)', '')]
    write_csv(tmp_path / 'targets.csv', targets.FIELDS, old)
    (tmp_path / 'targets.md').write_text('Measured on: a machine\n\nRegenerate: `rigid-body-sim '
                                         'bench --out x`\n\n| table |\n')
    write_csv(tmp_path / 'basilisk.csv', bg.FIELDS, [
        bg._row('gravity_gradient', 'bsk_rkf78', 'peer', 'rtol', 1e-8, 0.13, 2.5e-13, 1e-15,
                2001)])
    new = [_target_row(bg.TARGET, 'gravity_gradient', 'PASS', 15.0),
           _target_row(bg.TARGET, 'gravity_gradient', 'MISS', 4.0)]
    report.replace_targets(str(tmp_path), bg.TARGET, new)
    with open(tmp_path / 'targets.csv', newline='') as f:
        rows = list(csv.DictReader(f))
    assert [(r['target'][:9], r['measured']) for r in rows] == [
        ('cpu ratio', '12'), ('Basilisk ', '15'), ('Basilisk ', '4'), ('kernels r', '12')]
    md = (tmp_path / 'targets.md').read_text()
    assert md.startswith('Measured on: a machine\n\nRegenerate: `rigid-body-sim bench --out x`')
    assert 'rigid_body_sim.bench.basilisk_gg' in md and md.count(bg.TARGET) == 3
    summary = report.render(str(tmp_path))
    assert 'gravity_gradient: 4–15× (1 MISS of 2 levels; Basilisk reaches 2.5e-13 rad' in summary
