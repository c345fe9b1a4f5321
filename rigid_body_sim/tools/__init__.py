"""Standalone measurement tools, each a ``python -m rigid_body_sim.tools.<name>`` program.

Load, soak, faults and hosts against the live nodes (flood, flood_report, soak, recovery,
two_hosts, recorder_load, live_simulator, lockstep, lockstep_floor, viewer, pointing) and
cost probes (actuators, campaign, candidate_costs, exact_eval). Each has a one-line
docstring and ``--help``. The benchmark suite (``rigid-body-sim bench``,
:mod:`rigid_body_sim.bench`) runs live_simulator, recorder_load and viewer as subprocesses
for its live section; the rest run only by hand.
"""
import argparse
import subprocess
import sys


def argument_parser(spec, doc: str) -> argparse.ArgumentParser:
    """The tool's parser: ``prog`` the way it is run, the description its docstring's first
    line (``spec`` is the module's ``__spec__``; None when run as a file path)."""
    prog = f'python -m {spec.name}' if spec is not None else None
    return argparse.ArgumentParser(prog=prog, description=doc.splitlines()[0])


def stop(proc, timeout: float = 10.0) -> None:
    """Stop a node process as Ctrl-C would (SIGINT), killing it if it has not exited within
    ``timeout`` s."""
    proc.send_signal(2)
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()


def command_line(spec, argv=None) -> str:
    """How the tool was run, for its run file: ``python -m <module>`` and its arguments."""
    return ' '.join([f'python -m {spec.name}', *(sys.argv[1:] if argv is None else argv)])
