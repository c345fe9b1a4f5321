"""Sphinx extension: the reference pages (docs/reference/*.md), generated at build time.

Every node's parameters come from the specs the nodes declare (``engine/specs.py``,
``viewer/specs.py``, ``node_interfaces.RECORDER_PARAMETERS``); topics and services from
``node_interfaces``, which ``test/test_node_interfaces.py`` checks against the real nodes'
graph. The pages are written before Sphinx reads the sources, and only when their text
changes; they are not committed (``docs/reference/.gitignore``).

``python docs/_ext/node_reference.py`` writes them without Sphinx.
"""
import contextlib
import io
import json
import os

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(os.path.dirname(HERE), 'reference')

ROS_TYPES = {'float': 'double', 'int': 'integer', 'bool': 'bool', 'string': 'string',
             'float_array': 'double[]', 'string_array': 'string[]'}


def _cell(text) -> str:
    """Table-cell text: pipes and asterisks escaped, no line breaks."""
    return str(text).replace('|', '\\|').replace('*', '\\*').replace('\n', ' ')


def _code(value) -> str:
    text = json.dumps(value) if not isinstance(value, str) else value
    return f'`{text}`' if text else '(empty)'


def _range(spec) -> str:
    parts = []
    if spec.kind in ('float', 'int', 'float_array'):
        lo = None if spec.low is None else ('> ' if spec.low_open else '≥ ') + f'{spec.low:g}'
        hi = None if spec.high is None else ('< ' if spec.high_open else '≤ ') + f'{spec.high:g}'
        parts += [p for p in (lo, hi) if p]
    if spec.sizes:
        parts.append(' or '.join(map(str, spec.sizes)) + ' values')
    if spec.choices:
        parts.append(', '.join(f'`{c}`' for c in spec.choices))
    return '; '.join(_cell(p) if not p.startswith('`') else p for p in parts) or '—'


def parameters_table(specs) -> list:
    rows = ['| name | type | unit | range | default | description |',
            '|---|---|---|---|---|---|']
    for s in specs:
        kind = ROS_TYPES[s.kind] + (', read-only' if s.read_only else '')
        text = s.description + (f' ({s.note})' if s.note else '')
        rows.append(f'| `{s.name}` | {kind} | {_cell(s.unit) or "—"} | {_range(s)} | '
                    f'{_code(s.default)} | {_cell(text)} |')
    return rows


def topics_table(topics) -> list:
    rows = ['| direction | topic | type | when | description |', '|---|---|---|---|---|']
    word = {'pub': 'publishes', 'sub': 'subscribes'}
    for t in topics:
        when = _cell(t.when) or 'always'
        rows.append(f'| {word[t.direction]} | `{t.name}` | `{t.type}` | {when} '
                    f'| {_cell(t.description)} |')
    return rows


def services_table(services) -> list:
    rows = ['| service or action | type | when | description |', '|---|---|---|---|']
    for s in services:
        rows.append(f'| `{s.name}` | `{s.type}` | {_cell(s.when) or "always"} | '
                    f'{_cell(s.description)} |')
    return rows


def _replay_help() -> str:
    from rigid_body_sim.nodes import replay
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
        replay.parse_args(['--help'])
    return out.getvalue().rstrip()


def pages() -> dict:
    """{file name: Markdown text} of the reference."""
    from rigid_body_sim import node_interfaces as ni
    from rigid_body_sim.engine import specs
    from rigid_body_sim.viewer.specs import VIEWER
    params = {ni.SIMULATOR.name: specs.SIMULATOR_DECLARED, ni.CONTROLLER.name: specs.CONTROLLER,
              ni.VIEWER.name: VIEWER, ni.RECORDER.name: ni.RECORDER_PARAMETERS}
    out = {}
    index = ['# Reference', '',
             'Generated from the code at each build: the parameter specs the nodes declare '
             'and the table of their topics and services (`rigid_body_sim/node_interfaces.py`, '
             'checked against the running nodes by `test/test_node_interfaces.py`). '
             'Names without a leading `/` resolve in the node\'s namespace; `~/` is the '
             'node\'s own. Units are SI.', '', '```{toctree}', ':maxdepth: 1', '']
    for node in ni.NODES:
        lines = [f'# {node.name}', '', node.summary, '',
                 f'Run it with `ros2 run rigid_body_sim {node.executable}` '
                 f'(in the venv: `.venv/lib/rigid_body_sim/{node.executable}`).', '',
                 '## Parameters', ''] + parameters_table(params[node.name]) + \
                ['', '## Topics', ''] + topics_table(node.topics)
        if node.services:
            lines += ['', '## Services and actions', ''] + services_table(node.services)
        out[f'{node.name}.md'] = '\n'.join(lines) + '\n'
        index.append(node.name)
    out['mcap_replay.md'] = '\n'.join([
        '# mcap_replay', '',
        'Publishes a recorded bag again, each topic with its recorded type and QoS. It takes '
        'command-line options, not parameters:', '',
        '```text', _replay_help(), '```', '']) + '\n'
    index += ['mcap_replay', '```', '']
    out['index.md'] = '\n'.join(index)
    return out


def write(out_dir: str = OUT) -> list:
    """Write the pages whose text changed; returns their names."""
    os.makedirs(out_dir, exist_ok=True)
    changed = []
    for name, text in pages().items():
        path = os.path.join(out_dir, name)
        if os.path.exists(path):
            with open(path, encoding='utf-8') as f:
                if f.read() == text:
                    continue
        with open(path, 'w', encoding='utf-8') as f:
            f.write(text)
        changed.append(name)
    return changed


def _on_builder_inited(app):
    write(os.path.join(app.srcdir, 'reference'))


def setup(app):
    app.connect('builder-inited', _on_builder_inited)
    return {'version': '1', 'parallel_read_safe': True, 'parallel_write_safe': True}


if __name__ == '__main__':
    print('\n'.join(write()) or 'reference up to date')
