"""The shell blocks of the docs and the README, and a runner for the runnable ones.

Convention (CONTRIBUTING.md): every ```sh fence is preceded by a marker line,
- ``<!-- runnable -->``: each command runs and must exit 0;
- ``<!-- runnable: ready="TEXT" -->``: each command runs until it prints TEXT (a node that
  runs until Ctrl-C), then gets SIGINT and must exit 0;
- ``<!-- runnable: append="--duration 2" -->``: appended to each ``rigid-body-sim run`` or
  ``demo`` command that does not give that option itself (short runs), before the line's
  comment (after it, bash never saw it: the blocks ran their full durations);
- ``<!-- not-runnable: REASON -->``: shown only (needs ros2cli, sudo, a cluster, minutes).
A node (``ros2 run rigid_body_sim simulator|controller|recorder|viewer|replay``) needs no
``ready``: it has started once it logs its first line (``READY``), then gets SIGINT; a node
that ends by itself before then must have logged that line and exited 0.
Commands run from a fresh directory holding links to the repository's ``.venv`` and
``config``; ``ros2 run rigid_body_sim EXE`` runs the venv's ``lib/rigid_body_sim/EXE``, the
executable colcon installs under that name.

A plain ``rigid-body-sim`` command (no pipe, redirection, variable or glob) runs in this
process (``cli.main`` with the command's words, from the same directory): its exit status
and output are the same, without a new interpreter importing numba, ROS and matplotlib for
each (issue 32: about 1 CPU-s a command). Anything else, and every node, runs in bash.
"""
import os
import re
import shlex
import signal
import subprocess
import time
from typing import List, NamedTuple

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MARKER = re.compile(r'^<!--\s*(runnable|not-runnable)\s*(?::\s*(.*?))?\s*-->\s*$')
FENCE = re.compile(r'^(\s*)```+\s*(sh|bash|shell|console)\s*$')


class Block(NamedTuple):
    path: str          # relative to the repository
    line: int          # of the fence, 1-based
    kind: str          # 'runnable' | 'not-runnable' | '' (no marker)
    options: dict
    commands: List[str]

    @property
    def id(self) -> str:
        return f'{self.path}:{self.line}'


def _options(text: str) -> dict:
    out = {}
    for item in shlex.split(text or ''):
        key, _, value = item.partition('=')
        out[key] = value
    return out


def _commands(lines: List[str]) -> List[str]:
    """Commands of a block: continuation lines joined, comment-only and blank lines out."""
    out, current = [], ''
    for line in lines:
        current += line.rstrip()
        if current.endswith('\\'):
            current = current[:-1] + ' '
            continue
        if current.strip() and not current.lstrip().startswith('#'):
            out.append(current.strip())
        current = ''
    return out


def blocks(path: str) -> List[Block]:
    """The shell blocks of one Markdown file."""
    with open(os.path.join(REPO, path), encoding='utf-8') as f:
        lines = f.read().splitlines()
    found, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        start, j = i, i + 1
        while j < len(lines) and not lines[j].strip().startswith('```'):
            j += 1
        prev = next((lines[k] for k in range(start - 1, -1, -1) if lines[k].strip()), '')
        marker = MARKER.match(prev.strip())
        kind = marker.group(1) if marker else ''
        options = _options(marker.group(2)) if marker and kind == 'runnable' else {}
        found.append(Block(path, start + 1, kind, options, _commands(lines[start + 1:j])))
        i = j + 1
    return found


def doc_files() -> List[str]:
    """README.md and the hand-written pages of docs/ (the generated reference aside)."""
    out = ['README.md', 'CONTRIBUTING.md']
    for root, dirs, files in os.walk(os.path.join(REPO, 'docs')):
        dirs[:] = [d for d in dirs if d not in ('_build', 'reference', 'bench', 'tour')]
        out += sorted(os.path.relpath(os.path.join(root, f), REPO)
                      for f in files if f.endswith('.md'))
    return [p for p in out if os.path.exists(os.path.join(REPO, p))]


def _code_and_comment(command: str):
    """``command`` split before its shell comment (a ``#`` starting a word, outside quotes):
    (code, comment), the comment '' or starting with its whitespace."""
    for m in re.finditer(r'\s#', command):
        head = command[:m.start()]
        try:
            shlex.split(head)
        except ValueError:  # inside quotes
            continue
        return head.rstrip(), command[len(head.rstrip()):]
    return command, ''


def shell_command(command: str, options: dict) -> str:
    """The command as the runner runs it (see the module docstring)."""
    command = re.sub(r'\bros2 run rigid_body_sim (\S+)', r'.venv/lib/rigid_body_sim/\1', command)
    extra = options.get('append', '')
    code, comment = _code_and_comment(command)
    if extra and re.search(r'rigid-body-sim (run|demo) ', code + ' ') and \
            extra.split()[0] not in code.split():
        command = f'{code} {extra}{comment}'
    return command


def cli_words(cmd: str, cwd: str):
    """The words of ``cmd`` if it is a plain ``rigid-body-sim`` command that the runner
    runs in this process (see the module docstring), else None."""
    code, _ = _code_and_comment(cmd)
    if re.search(r'[|&;<>$`*?(){}\\]', code):  # shell syntax: bash runs it
        return None
    try:
        words = shlex.split(code)
    except ValueError:
        return None
    if not words or os.path.basename(words[0]) != 'rigid-body-sim' or \
            not os.access(os.path.join(cwd, words[0]), os.X_OK):
        return None
    return words


def _run_cli(cmd: str, words, cwd: str):
    """``cli.main`` on ``words`` from ``cwd``: (ok, what), as ``run`` says them."""
    from cli_inprocess import run_cli
    done = run_cli(*words[1:], cwd=cwd)
    return done.returncode == 0, \
        f'{cmd}: exit {done.returncode} (in process)\n{done.stdout}{done.stderr}'


# what each long-running node logs once it has started
# (a namespace prefixes the logger's name: [sat1.attitude_simulator]); replay ends by itself
# unless it loops
READY = {'simulator': 'attitude_simulator]', 'controller': 'attitude_controller]',
         'recorder': 'recording to', 'viewer': 'attitude_viewer]', 'replay': 'playing'}


def make_workdir(tmp: str) -> str:
    for name in ('.venv', 'config'):
        os.symlink(os.path.join(REPO, name), os.path.join(tmp, name))
    return tmp


def run(command: str, options: dict, cwd: str, timeout: float = 90.0):
    """Run one command; returns (ok, what happened with its output)."""
    cmd = shell_command(command, options)
    words = cli_words(cmd, cwd)
    if words is not None:
        return _run_cli(cmd, words, cwd)
    proc = subprocess.Popen(['bash', '-c', cmd], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, start_new_session=True)
    node = re.match(r'ros2 run rigid_body_sim (\S+)', command)
    ready = options.get('ready') or (READY.get(node.group(1)) if node else None)
    if not ready:
        try:
            out, _ = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, _ = proc.communicate()
            text = out.decode(errors='replace')
            return False, f'{cmd}: still running after {timeout:g} s\n{text}'
        text = out.decode(errors='replace')
        return proc.returncode == 0, f'{cmd}: exit {proc.returncode}\n{text}'
    os.set_blocking(proc.stdout.fileno(), False)
    text, deadline = '', time.monotonic() + timeout
    while ready not in text and proc.poll() is None and time.monotonic() < deadline:
        chunk = proc.stdout.read()
        text += chunk.decode(errors='replace') if chunk else ''
        if not chunk:
            time.sleep(0.1)
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    rest = proc.stdout.read()
    text += rest.decode(errors='replace') if rest else ''
    started = ready in text
    ok = started and proc.returncode == 0
    why = f'printed {ready!r}' if started else f'never printed {ready!r}'
    return ok, f'{cmd}: {why}, exit {proc.returncode} after SIGINT\n{text}'
