"""Run a script compiled and as plain Python (NUMBA_DISABLE_JIT=1): the kernels' one source."""
import atexit
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
    kernel loading for the same result (issue 32). Plain Python needs its own interpreter
    (NUMBA_DISABLE_JIT is read at numba's import): one per test process, kept for the
    scripts after its first (_PlainInterpreter). Warnings are ignored in both."""
    if disable_jit:
        return _PlainInterpreter.get().run(script, args)
    return _exec(script, args)


def _exec(script, args):
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


# The plain interpreter's loop: a request (the script and its arguments) a line on stdin,
# its answer (what the script printed, or its traceback) a line on the protocol's own fd;
# fd 1 goes to stderr so output from C cannot garble the protocol.
_SERVE = r'''
import contextlib, io, json, os, sys, traceback, warnings
warnings.simplefilter('ignore')
from rigid_body_sim.physics import jit
assert not jit.COMPILED, 'NUMBA_DISABLE_JIT=1 and still compiled'
answers = os.fdopen(os.dup(1), 'w')
os.dup2(2, 1)
for line in sys.stdin:
    request = json.loads(line)
    out, failure = io.StringIO(), None
    sys.argv = ['-c', *request['args']]
    try:
        with contextlib.redirect_stdout(out):
            exec(compile(request['script'], '<script>', 'exec'), {'__name__': '__script__'})
    except BaseException:
        failure = traceback.format_exc()
    answers.write(json.dumps({'stdout': out.getvalue(), 'failure': failure}) + '\n')
    answers.flush()
'''


class _PlainInterpreter:
    """One ``python`` with NUMBA_DISABLE_JIT=1 for this test process: a fresh one a script
    paid ~0.6 CPU-s of imports (numpy, numba, the package) before the script's own work,
    ~15 times in ``make test`` (issue 32). Its scripts share it as the compiled runs share
    the test process (the same modules, each script in its own globals)."""
    _one = None

    @classmethod
    def get(cls):
        if cls._one is None or cls._one.proc.poll() is not None:
            cls._one = cls()
        return cls._one

    def __init__(self):
        import tempfile
        self.stderr = tempfile.TemporaryFile('w+')  # a pipe nobody reads could fill
        self.proc = subprocess.Popen(
            [sys.executable, '-W', 'ignore', '-c', _SERVE], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=self.stderr, text=True,
            env=dict(os.environ, NUMBA_DISABLE_JIT='1'))
        atexit.register(self.close)

    def run(self, script, args):
        self.proc.stdin.write(json.dumps({'script': script, 'args': list(args)}) + '\n')
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:  # it died: say how, with what it wrote
            code = self.proc.wait()
            self.stderr.seek(0)
            raise AssertionError(f'the plain-Python interpreter exited ({code}): '
                                 f'{self.stderr.read()[-3000:]}')
        answer = json.loads(line)
        assert answer['failure'] is None, answer['failure'][-3000:]
        return answer['stdout']

    def close(self):
        if self.proc.poll() is None:
            self.proc.stdin.close()
            self.proc.wait(timeout=60)
        self.stderr.close()
