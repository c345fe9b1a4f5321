"""The setup (``python -m rigid_body_sim.compiled``) compiles what only a scene's features
reach, so that neither a user's first run of that scene nor each test worker compiles it."""
import json
import os
import subprocess
import sys

PROBE = r'''
import json
from rigid_body_sim import compiled
from rigid_body_sim.engine import closed_loop
from rigid_body_sim.physics.integrators import dop853_dense, gyrostat_kernel, splitting_kernel
runs = compiled.warm_scenes()
loops = {'closed_loop_run': closed_loop.closed_loop_run,
         'gyrostat_run': gyrostat_kernel.gyrostat_run,
         'dop853_dense.advance': dop853_dense.advance,
         'splitting_run': splitting_kernel.splitting_run}
print(json.dumps([runs, {name: len(f.signatures) for name, f in loops.items()}]))
'''


def test_every_scene_and_method_runs_and_their_loops_are_loaded():
    """In a fresh process (nothing loaded before), the scenes' warm-up runs every built-in
    scene with each method it accepts and loads the loops that only scenes reach: the
    closed loop of a law, the gyrostat's wheels, dop853 with an orbit's environment torque
    (these were compiled inside test workers before: ~30 kernels at 5-30 CPU-s each)."""
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE='1')
    out = subprocess.run([sys.executable, '-c', PROBE], capture_output=True, text=True,
                         timeout=600, env=env)
    assert out.returncode == 0, out.stderr
    runs, loaded = json.loads(out.stdout.strip().splitlines()[-1])
    # 13 single-body scenes x (10 methods + auto) x (offline, live), less those refused
    assert runs >= 200, runs
    # dop853's loop twice: the free body's types and an orbit's environment's
    assert loaded['dop853_dense.advance'] >= 2, loaded
    # the gyrostat's twice: the wheels' and CMGs' types, and wheels in an orbit (no scene
    # has those; compiled in test_facets' worker before, ~5-7 CPU-s)
    assert loaded['gyrostat_run'] >= 2, loaded
    assert all(count > 0 for count in loaded.values()), loaded


def test_the_scenes_warm_up_runs_once_per_sources(tmp_path, monkeypatch):
    """Its stamp: a second setup with the same sources skips the runs (make test calls the
    setup each time); a changed source runs them again."""
    from rigid_body_sim import compiled
    from rigid_body_sim.physics.auto import calibration
    monkeypatch.setattr(calibration, 'cache_dir', lambda: str(tmp_path))
    runs = []
    monkeypatch.setattr(compiled, 'warm_scenes', lambda: runs.append(1) or 1)
    compiled._warm_scenes_once()
    compiled._warm_scenes_once()
    assert runs == [1]
    (tmp_path / 'scenes_warmed.sha256').write_text('another source\n')
    compiled._warm_scenes_once()
    assert runs == [1, 1]
