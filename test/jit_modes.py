"""Run a script compiled and as plain Python (NUMBA_DISABLE_JIT=1): the kernels' one source."""
import json
import os
import subprocess
import sys


def run_both(script, *args):
    """(compiled, plain): the JSON each run of ``script`` prints on its last line."""
    out = []
    for disable in ('0', '1'):
        proc = subprocess.run([sys.executable, '-c', script, *args], capture_output=True,
                              text=True, env=dict(os.environ, NUMBA_DISABLE_JIT=disable),
                              timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        out.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    return tuple(out)


def run_in_mode(script, disable_jit):
    """What ``script`` prints, compiled or as plain Python. Compiled, it runs in this
    interpreter (whose kernels are compiled and loaded already): a fresh one paid ~0.9 CPU-s
    of imports and kernel loading for the same result. Plain Python needs its own process
    (NUMBA_DISABLE_JIT is read at numba's import). Warnings are ignored in both."""
    if disable_jit:
        proc = subprocess.run([sys.executable, '-W', 'ignore', '-c', script],
                              capture_output=True, text=True, timeout=600,
                              env=dict(os.environ, NUMBA_DISABLE_JIT='1'))
        assert proc.returncode == 0, proc.stderr[-3000:]
        return proc.stdout
    import contextlib
    import io
    import warnings

    from rigid_body_sim.physics import jit
    assert jit.COMPILED, 'this interpreter runs the kernels as plain Python'
    out = io.StringIO()
    with contextlib.redirect_stdout(out), warnings.catch_warnings():
        warnings.simplefilter('ignore')
        exec(compile(script, '<script>', 'exec'), {'__name__': '__script__'})
    return out.getvalue()
