"""Shared by the campaign tests: the CLI, a spec from a scene, row comparison."""
import subprocess
import sys

from rigid_body_sim.campaign import dispersions as disp
from rigid_body_sim.campaign.cli import _same
from rigid_body_sim.campaign.runner import CampaignSpec
from rigid_body_sim.scene import load

CLI = [sys.executable, '-m', 'rigid_body_sim.cli', 'campaign']
SHORT = ['--set', 'duration=8.0']  # detumbled (to 0.01 rad/s) by ~6 s


def cli(*args, timeout=300, **kw):
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=timeout,
                          **kw)


def spec_for(scene, sets=(), dispersions=(), seed=0, runs=10, **kw):
    s = load(scene, list(sets))
    return CampaignSpec.create(s, [disp.parse(t) for t in dispersions], seed, runs, **kw)


def rows_equal(a, b):
    """Rows identical bit for bit, CPU time aside; the differing keys otherwise."""
    return [k for k in a if k != 'cpu_time' and not _same(a[k], b.get(k))]
