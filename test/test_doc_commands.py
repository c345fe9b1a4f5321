"""Every command the docs show is run (a renamed flag breaks this test, not a user), and
every shell block says whether it is runnable (doc_blocks.py: the convention)."""
import pytest

from doc_blocks import blocks, doc_files, make_workdir, run

ALL = [b for path in doc_files() for b in blocks(path)]
RUNNABLE = [b for b in ALL if b.kind == 'runnable']


def test_every_shell_block_is_marked():
    unmarked = [b.id for b in ALL if not b.kind]
    assert not unmarked, ('shell blocks without <!-- runnable --> or <!-- not-runnable: why -->'
                          f' (see CONTRIBUTING.md): {unmarked}')


def test_the_docs_have_runnable_blocks():
    assert len(RUNNABLE) >= 5, [b.id for b in RUNNABLE]


@pytest.mark.parametrize('block', RUNNABLE, ids=[b.id for b in RUNNABLE])
def test_runnable_block(block, tmp_path):
    cwd = make_workdir(str(tmp_path))
    for command in block.commands:
        ok, what = run(command, block.options, cwd)
        assert ok, f'{block.id}: {what}'


def test_the_runner_fails_on_a_renamed_flag(tmp_path):
    ok, what = run('.venv/bin/rigid-body-sim run tennis_racket --duraton 1', {},
                   make_workdir(str(tmp_path)))
    assert not ok and 'exit 2' in what, what


def test_a_node_that_never_gets_ready_fails(tmp_path):
    ok, what = run('sleep 30', {'ready': 'never printed'}, make_workdir(str(tmp_path)),
                   timeout=1.0)
    assert not ok and 'never printed' in what, what


def test_markers_and_options_are_parsed(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text('<!-- runnable: append="--duration 2" ready="x y" -->\n```sh\n'
                    'a --b \\\n  --c  # note\n# only a comment\n\nd\n```\n\n```sh\ne\n```\n'
                    '<!-- not-runnable: needs ros2cli -->\n```bash\nf\n```\n')
    import doc_blocks
    found = doc_blocks.blocks(str(page))
    assert [(b.kind, b.options, b.commands) for b in found] == [
        ('runnable', {'append': '--duration 2', 'ready': 'x y'}, ['a --b    --c  # note', 'd']),
        ('', {}, ['e']), ('not-runnable', {}, ['f'])]
    assert doc_blocks.shell_command('ros2 run rigid_body_sim simulator --ros-args', {}) == \
        '.venv/lib/rigid_body_sim/simulator --ros-args'
    short = {'append': '--duration 2'}
    assert doc_blocks.shell_command('x/rigid-body-sim run a', short) == \
        'x/rigid-body-sim run a --duration 2'
    assert doc_blocks.shell_command('x/rigid-body-sim run a --duration 5', short) == \
        'x/rigid-body-sim run a --duration 5'
    assert doc_blocks.shell_command('ros2 run rigid_body_sim simulator', short) == \
        '.venv/lib/rigid_body_sim/simulator'
    # before the comment (after it bash never saw it), and only where the option exists
    assert doc_blocks.shell_command("x/rigid-body-sim run a --set 'b=#1'  # c --d", short) == \
        "x/rigid-body-sim run a --set 'b=#1' --duration 2  # c --d"
    assert doc_blocks.shell_command('x/rigid-body-sim scenes  # one line each', short) == \
        'x/rigid-body-sim scenes  # one line each'


def test_a_plain_cli_command_runs_in_process_and_shell_syntax_in_bash(tmp_path, monkeypatch):
    """A `rigid-body-sim` command runs in this process (no interpreter start-up per
    command, issue 32), with its exit status and output; a pipe or variable goes to bash."""
    import subprocess

    import doc_blocks
    cwd = make_workdir(str(tmp_path))
    assert doc_blocks.cli_words('.venv/bin/rigid-body-sim run a --set "w=[1, 2]"  # x', cwd) \
        == ['.venv/bin/rigid-body-sim', 'run', 'a', '--set', 'w=[1, 2]']
    for shell in ('.venv/bin/rigid-body-sim scenes | head -1', 'x=1 .venv/bin/rigid-body-sim',
                  '.venv/bin/rigid-body-sim run $SCENE', '.venv/bin/rigid-body-sim > f',
                  '.venv/lib/rigid_body_sim/simulator', 'missing/rigid-body-sim scenes'):
        assert doc_blocks.cli_words(shell, cwd) is None, shell

    def no_process(*args, **kwargs):
        raise AssertionError(f'a process was started: {args}')
    monkeypatch.setattr(subprocess, 'Popen', no_process)
    ok, what = run('.venv/bin/rigid-body-sim scenes', {}, cwd)
    assert ok and 'tennis_racket' in what and 'exit 0' in what, what
    ok, what = run('.venv/bin/rigid-body-sim run no_such_scene --duration 1', {}, cwd)
    assert not ok and 'no_such_scene' in what and 'Traceback' not in what, what
