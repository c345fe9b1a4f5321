"""The documentation builds without a warning, its internal links resolve, and its
reference pages hold every parameter spec and interface of the nodes."""
import os
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def sphinx(src, out, *extra):
    """sphinx-build as `make docs` runs it (-W --keep-going -n); returns (code, stderr)."""
    proc = subprocess.run([sys.executable, '-m', 'sphinx', '-b', 'html', '-W', '--keep-going',
                           '-n', '-q', *extra, src, out], capture_output=True, text=True,
                          timeout=300)
    return proc.returncode, proc.stderr


def test_docs_build_without_warnings(tmp_path):
    code, err = sphinx(os.path.join(REPO, 'docs'), str(tmp_path / 'html'))
    assert code == 0, f'make docs warns:\n{err}'
    for page in ('index', 'reference/attitude_simulator', 'reference/mcap_recorder'):
        assert (tmp_path / 'html' / f'{page}.html').exists(), page


def test_a_broken_internal_link_fails_the_build(tmp_path):
    src = tmp_path / 'src'
    src.mkdir()
    (src / 'index.md').write_text('# Page\n\n```{toctree}\nreference/index\n```\n\n'
                                  'See [gone](gone.md) and [no anchor](#no-such-heading).\n')
    code, err = sphinx(str(src), str(tmp_path / 'html'), '-c', os.path.join(REPO, 'docs'))
    assert code != 0
    assert "'gone.md'" in err and 'no-such-heading' in err, err


def test_reference_pages_hold_every_spec_and_table_entry():
    sys.path.insert(0, os.path.join(REPO, 'docs', '_ext'))
    import node_reference
    from rigid_body_sim import node_interfaces as ni
    from rigid_body_sim.engine import specs
    from rigid_body_sim.viewer.specs import VIEWER
    pages = node_reference.pages()
    for node, params in ((ni.SIMULATOR, specs.SIMULATOR_DECLARED),
                         (ni.CONTROLLER, specs.CONTROLLER),
                         (ni.VIEWER, VIEWER), (ni.RECORDER, ni.RECORDER_PARAMETERS)):
        page = pages[f'{node.name}.md']
        for spec in params:
            assert f'| `{spec.name}` |' in page, (node.name, spec.name)
        for entry in node.topics + node.services:
            assert f'`{entry.name}` | `{entry.type}`' in page, (node.name, entry.name)
    assert '--start-offset' in pages['mcap_replay.md']
