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
