"""Lint at the ROS line length (99 columns), as ROS packages' ament_flake8 tests do."""
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
