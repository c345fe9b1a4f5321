"""Lint at the ROS line length (99 columns), as ROS packages' ament_flake8 tests do, and
the modules' size."""
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.fast  # make check

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_ruff_is_clean():
    ruff = os.path.join(os.path.dirname(sys.executable), 'ruff')
    out = subprocess.run([ruff, 'check', '--no-cache', 'rigid_body_sim', 'test', 'launch',
                          'setup.py'], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-2000:]


def test_modules_stay_under_about_400_lines():
    """CONTRIBUTING: modules stay under about 400 lines (split by responsibility)."""
    package = os.path.join(ROOT, 'rigid_body_sim')
    over = {}
    for folder, _, files in os.walk(package):
        for name in files:
            path = os.path.join(folder, name)
            rel = os.path.relpath(path, package).replace(os.sep, '/')
            if name.endswith('.py'):
                with open(path, encoding='utf-8') as f:
                    lines = sum(1 for _ in f)
                if lines > 400:
                    over[rel] = lines
    assert not over, over
