"""Run a script compiled and as plain Python (NUMBA_DISABLE_JIT=1): the kernels' one source."""
import json
import os
import subprocess
import sys


def run_both(script, *args):
    """(compiled, plain): the JSON each run of ``script`` (given ``args`` in sys.argv[1:])
    prints on its last line; the compiled run in this interpreter (run_in_mode)."""
    return tuple(json.loads(run_in_mode(script, disable, *args).strip().splitlines()[-1])
                 for disable in (False, True))


def run_in_mode(script, disable_jit, *args):
    """What ``script`` prints, compiled or as plain Python, given ``args`` in sys.argv[1:] as
    ``python -c script ARGS`` gives them. Compiled, it runs in this interpreter (whose
    kernels are compiled and loaded already): a fresh one paid ~0.9 CPU-s of imports and
    kernel loading for the same result (issue 32). Plain Python needs its own process
    (NUMBA_DISABLE_JIT is read at numba's import). Warnings are ignored in both."""
    if disable_jit:
        proc = subprocess.run([sys.executable, '-W', 'ignore', '-c', script, *args],
                              capture_output=True, text=True, timeout=600,
                              env=dict(os.environ, NUMBA_DISABLE_JIT='1'))
        assert proc.returncode == 0, proc.stderr[-3000:]
        return proc.stdout
    import contextlib
    import io
    import warnings

    from rigid_body_sim.physics import jit
    assert jit.COMPILED, 'this interpreter runs the kernels as plain Python'
    out, argv = io.StringIO(), sys.argv
    sys.argv = ['-c', *args]
    try:
        with contextlib.redirect_stdout(out), warnings.catch_warnings():
            warnings.simplefilter('ignore')
            exec(compile(script, '<script>', 'exec'), {'__name__': '__script__'})
    finally:
        sys.argv = argv
    return out.getvalue()
