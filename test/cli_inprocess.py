"""``rigid-body-sim`` run in the test's own process, for the tests that are about what a
command does, not about its process (issue 32).

A new interpreter imports numba, ROS's message packages and matplotlib again for each
command (~1 CPU-s); in the test's process they are imported once. The result is a
``subprocess.CompletedProcess`` as ``subprocess.run(..., capture_output=True, text=True)``
gives it: the exit status (argparse's 2, a traceback's 1), stdout and stderr. Tests about
the process itself (signals, pipes, what a fresh process loads, exit codes of the installed
script) start the real one.
"""
import contextlib
import io
import os
import subprocess
import traceback


def run_cli(*argv, cwd=None) -> subprocess.CompletedProcess:
    """``rigid-body-sim ARGV`` through ``cli.main``, from ``cwd`` (default: here)."""
    from rigid_body_sim import cli
    out, err, here = io.StringIO(), io.StringIO(), os.getcwd()
    if cwd is not None:
        os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = cli.main([str(a) for a in argv])
            except SystemExit as exc:  # argparse's errors and --help
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None
                                                                   else 1)
            except Exception:  # noqa: BLE001 - as the process: its traceback, exit 1
                traceback.print_exc()
                code = 1
    finally:
        os.chdir(here)
    return subprocess.CompletedProcess(['rigid-body-sim', *map(str, argv)], code,
                                       out.getvalue(), err.getvalue())
