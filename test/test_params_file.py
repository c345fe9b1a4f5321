"""Params files are read as rcl reads them: our ROS-free reader against rcl itself.

The oracle is the real parser: rclpy initialised with ``--params-file`` and a node that
declares every override, so rcl_yaml_param_parser types each value and rclpy matches the
node keys. Then the same files through the offline loader and through real simulator node
processes (``--params-file``), for every node-key form users write.
"""
import math
import os
import subprocess
import sys

import pytest

from cli_inprocess import run_cli
from ros_helpers import spin_until, venv_exe

from rigid_body_sim import params_file, scene

SPELLINGS = ['1e-06', '0x10', '010', '08', '-7', '+3', '1_000', '3.', '.5', '1E3', 'yes',
             'On', 'FALSE', 'n', 'true', '.inf', '-.Inf', '+.INF', '.nan', 'inf', 'nan',
             'infinity', '"1.0"', "'true'", '!!str 5', 'hello', '0x1p3', '9223372036854775808',
             '[1.0, 2.0]', '[1, 2]', '[true, false]', '[a, b]', '[1e-06, 2.5]']


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _rcl_parameters(path, node_name='probe', namespace='/'):
    """{name: value} as rcl parses the file for node ``namespace/node_name``."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    context = Context()
    rclpy.init(args=['--ros-args', '--params-file', path], context=context)
    try:
        node = Node(node_name, namespace=namespace, context=context,
                    automatically_declare_parameters_from_overrides=True)
        try:
            return {name: p.value for name, p in node._parameters.items()
                    if name not in ('use_sim_time', 'start_type_description_service')}
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def _same(a, b):
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a):
        return math.isnan(b)
    return type(a) is type(b) and a == b


def test_values_are_typed_as_rcl_types_them(tmp_path):
    """Every scalar spelling above, one parameter each: the same Python type and value as
    rcl gives (1e-06 is a double, 0x10 and 010 integers, 08 a double, yes/On bools,
    .inf/.nan doubles, quoted and !!str strings, int64 overflow a double)."""
    body = ''.join(f'    p{i}: {text}\n' for i, text in enumerate(SPELLINGS))
    path = _write(tmp_path, 'values.yaml', f'probe:\n  ros__parameters:\n{body}')
    rcl = _rcl_parameters(path)
    ours = {k: v.value for k, v in params_file.node_parameters(path, '/probe').items()}
    assert set(ours) == set(rcl) == {f'p{i}' for i in range(len(SPELLINGS))}
    for i, text in enumerate(SPELLINGS):
        a, b = ours[f'p{i}'], rcl[f'p{i}']
        if isinstance(a, list):
            assert len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b)), text
        else:
            assert _same(a, b), f'{text}: ours {a!r} ({type(a).__name__}), rcl {b!r}'
    assert ours['p0'] == 1e-06 and ours['p1'] == 16 and ours['p2'] == 8


NODE_KEYS = ['attitude_simulator', '/attitude_simulator', '/**/attitude_simulator', '/**',
             '/*/attitude_simulator', '/sat1/attitude_simulator', '/**/sat1/**']
NAMESPACES = ['/', '/sat1', '/fleet/sat1']


@pytest.mark.parametrize('key', NODE_KEYS)
def test_node_keys_match_as_rcl_matches_them(tmp_path, key):
    """Each key form against nodes in three namespaces: ours applies a section to exactly
    the nodes rcl applies it to, and nested namespace keys ({sat1: {attitude_simulator:
    ...}}) are the same section as the joined key."""
    path = _write(tmp_path, 'keys.yaml', f'{key}:\n  ros__parameters:\n    accuracy: 1e-06\n')
    for ns in NAMESPACES:
        rcl = _rcl_parameters(path, 'attitude_simulator', ns)
        ours = params_file.node_parameters(
            path, params_file.fully_qualified('attitude_simulator', ns))
        assert {k: v.value for k, v in ours.items()} == rcl, (key, ns)
    nested = _write(tmp_path, 'nested.yaml',
                    'sat1:\n  attitude_simulator:\n    ros__parameters:\n      step: 2\n')
    assert params_file.node_parameters(nested, '/sat1/attitude_simulator')['step'].value == 2
    assert _rcl_parameters(nested, 'attitude_simulator', '/sat1') == {'step': 2}


def test_later_sections_override_earlier_ones_as_in_rcl(tmp_path):
    path = _write(tmp_path, 'order.yaml', '/**:\n  ros__parameters:\n    step: 0.5\n'
                  '    accuracy: 0.1\nattitude_simulator:\n  ros__parameters:\n    step: 0.25\n')
    ours = {k: v.value for k, v in
            params_file.node_parameters(path, '/attitude_simulator').items()}
    assert ours == _rcl_parameters(path, 'attitude_simulator') == {'step': 0.25,
                                                                   'accuracy': 0.1}


def test_mixed_sequences_are_refused_as_rcl_refuses_them(tmp_path):
    path = _write(tmp_path, 'mixed.yaml',
                  'attitude_simulator:\n  ros__parameters:\n    inertia: [1.0, 2, 3.0]\n')
    with pytest.raises(params_file.ParamsFileError, match='inertia: a sequence must hold'):
        params_file.node_parameters(path, '/attitude_simulator')
    with pytest.raises(Exception):
        _rcl_parameters(path, 'attitude_simulator')


SCENE_BODY = ('    inertia: [1.0, 2.0, 3.0]\n    initial_angular_velocity: [0.1, 0.7, -0.2]\n'
              '    accuracy: 1e-06\n    step: 1\n    publish_rate: 20\n')


@pytest.mark.parametrize('key', ['attitude_simulator', '/attitude_simulator',
                                 '/**/attitude_simulator', '/**', '/NS/attitude_simulator'])
def test_a_file_runs_offline_and_starts_the_node(tmp_path, key, ros_process, namespace,
                                                 rclpy_node):
    """The same file through the offline loader and a real simulator process
    (--params-file): both take the file's values (the node's first angular_velocity
    message is the file's initial rate), and ``rigid-body-sim run`` runs it."""
    from geometry_msgs.msg import Vector3Stamped
    key = key.replace('/NS', namespace)  # a section for the node in our test namespace
    path = _write(tmp_path, 'scene.yaml', f'{key}:\n  ros__parameters:\n{SCENE_BODY}')
    named_ns = key.startswith(namespace)
    loaded = scene.load(path, namespace=namespace if named_ns else '/')
    assert loaded.simulator['accuracy'] == 1e-06 and loaded.simulator['step'] == 1.0
    assert loaded.simulator['initial_angular_velocity'] == [0.1, 0.7, -0.2]
    out = run_cli('run', path, '--duration', '1', '--json', '--no-bag', '--no-plots',
                  '--out', tmp_path / 'o', *(['--namespace', namespace] if named_ns else []))
    assert out.returncode == 0, out.stderr
    if key.startswith('/**') or named_ns:
        ns_args = ['-r', f'__ns:={namespace}']
    else:  # a key without wildcard names the node in the root namespace
        ns_args, namespace = [], ''
    got = []
    rclpy_node.create_subscription(Vector3Stamped, f'{namespace}/angular_velocity',
                                   got.append, 10)
    sim = ros_process(venv_exe('simulator'), '--ros-args', '--params-file', path, *ns_args,
                      '-p', 'publish_clock:=true')  # stamps = sim time
    assert spin_until(rclpy_node, lambda: got, 60.0), sim.output()[-2000:]
    # the node's state at that sim time is the offline engine's for the loaded file
    t_ns = got[0].header.stamp.sec * 1_000_000_000 + got[0].header.stamp.nanosec
    from rigid_body_sim.engine import Engine, EngineConfig, SampleBlock
    offline = SampleBlock.concatenate(
        Engine(EngineConfig.from_parameters(loaded.simulator)).run(t_ns))
    assert offline.t_ns[-1] == t_ns
    v = got[0].vector
    assert max(abs(a - b) for a, b in zip([v.x, v.y, v.z], offline.angular_velocity[-1])) \
        <= 1e-12


def test_unknown_and_unmatched_keys_are_refused_offline(tmp_path):
    typo = _write(tmp_path, 'typo.yaml',
                  'attitude_simulator:\n  ros__parameters:\n    intertia: [1.0, 2.0, 3.0]\n')
    with pytest.raises(scene.SceneError, match=r'typo\.yaml: /attitude_simulator: intertia: '
                                               r'unknown parameter .*did you mean inertia'):
        scene.load(typo)
    other = _write(tmp_path, 'other.yaml',
                   'attitude_simulatr:\n  ros__parameters:\n    step: 0.1\n')
    with pytest.raises(scene.SceneError, match='applies to neither'):
        scene.load(other)


def test_the_offline_loader_needs_no_ros(tmp_path):
    path = _write(tmp_path, 's.yaml', f'attitude_simulator:\n  ros__parameters:\n{SCENE_BODY}')
    code = ('import sys; sys.modules["rclpy"] = None\n'
            'from rigid_body_sim import scene\n'
            f'print(scene.load({path!r}).simulator["accuracy"])\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, env=dict(os.environ))
    assert out.returncode == 0 and out.stdout.strip() == '1e-06', out.stderr


@pytest.mark.parametrize('exe', ['simulator', 'controller'])
def test_live_nodes_refuse_unknown_keys_and_name_the_file(tmp_path, exe):
    """A typo in a params file, a typo given with -p, and a bad value from a file: the
    node exits with code 2 before publishing, and its FATAL line names the file, the
    section, the key and the closest valid key (rclpy alone would start on defaults)."""
    node = 'attitude_simulator' if exe == 'simulator' else 'attitude_controller'
    typo = _write(tmp_path, 'typo.yaml', f'{node}:\n  ros__parameters:\n'
                  '    intertia_typo: [1.0, 2.0, 3.0]\n')
    bad = _write(tmp_path, 'bad.yaml', f'/**/{node}:\n  ros__parameters:\n    inertia: [-1.0]\n')
    env = dict(os.environ, ROS_DOMAIN_ID=os.environ['ROS_DOMAIN_ID'])
    cases = [(['--params-file', typo], [typo, f'/{node}', 'intertia_typo',
                                        'did you mean inertia?']),
             (['-p', 'intertia:=[1.0, 2.0, 3.0]'], ['-p intertia', 'did you mean inertia?']),
             (['--params-file', bad], [bad, f'/**/{node}', 'inertia'])]
    for args, expected in cases:
        out = subprocess.run([venv_exe(exe), '--ros-args', *args], capture_output=True,
                             text=True, timeout=60, env=env)
        text = out.stdout + out.stderr
        assert out.returncode == 2, text
        fatal = [line for line in text.splitlines() if '[FATAL]' in line]
        assert fatal and all(e in fatal[0] for e in expected), (expected, text)


def test_setting_an_undeclared_parameter_is_refused(ros_process, namespace, rclpy_node):
    """`ros2 param set` of a name the simulator does not declare fails with a reason."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}')
    client = rclpy_node.create_client(SetParameters,
                                      f'{namespace}/attitude_simulator/set_parameters')
    assert spin_until(rclpy_node, client.service_is_ready, 60.0), sim.output()[-2000:]
    future = client.call_async(SetParameters.Request(parameters=[
        Parameter('intertia', value=[1.0, 2.0, 3.0]).to_parameter_msg()]))
    assert spin_until(rclpy_node, future.done, 30.0)
    result = future.result().results[0]
    assert not result.successful and 'intertia' in result.reason


def test_set_overrides_apply_after_the_file(tmp_path):
    """--set KEY=VALUE wins over the file, typed as a params file types it, goes to each
    node of the scene that declares KEY, and refuses keys no node of the scene has; the
    demo's second params file carries the result to the live nodes (rcl: later wins)."""
    from rigid_body_sim.demo import _overrides_file
    s = scene.load('slew', ['accuracy=1e-9', 'inertia=[1.0, 2.0, 2.25]', 'mode=detumble',
                            'publish_clock=on'])
    assert s.simulator['accuracy'] == 1e-9 and s.simulator['publish_clock'] is True
    assert s.simulator['inertia'] == s.controller['inertia'] == [1.0, 2.0, 2.25]
    assert s.controller['mode'] == 'detumble'
    sets = ['accuracy=1e-9', 'inertia=[1, 2, 3]', 'mode=off', 'publish_clock=on',
            'natural_frequency=[2]', 'max_rate=1']
    path = _overrides_file(scene.load('slew', sets), sets, str(tmp_path))
    import yaml
    written = yaml.safe_load(open(path))  # only the keys set, in the scene's sections
    assert {k: set(v['ros__parameters']) for k, v in written.items()} == {
        '/**': {'inertia'}, '/**/attitude_simulator': {'accuracy', 'publish_clock'},
        '/**/attitude_controller': {'mode', 'natural_frequency', 'max_rate'}}
    # the live nodes get each value, typed as the scene types it (rclpy is the oracle):
    # [2] over the scene's scalar 1.0 would have been dropped by rcl without a word
    both = ['--params-file', scene.resolve('slew'), '--params-file', path]
    sim = _rcl_overrides(both)
    ctl = _rcl_overrides(both, 'attitude_controller')
    assert sim['accuracy'] == 1e-9 and sim['publish_clock'] is True
    assert sim['inertia'] == ctl['inertia'] == [1.0, 2.0, 3.0]  # ints written as doubles
    assert ctl['natural_frequency'] == 2.0 and type(ctl['natural_frequency']) is float
    assert ctl['mode'] == 'off' and ctl['max_rate'] == 1.0
    with pytest.raises(scene.SceneError, match='the scene gives natural_frequency as double'):
        _overrides_file(scene.load('slew', ['natural_frequency=[1,2,3]']),
                        ['natural_frequency=[1,2,3]'], str(tmp_path))
    with pytest.raises(scene.SceneError, match='did you mean accuracy'):
        scene.load('slew', ['acuracy=1e-9'])
    with pytest.raises(scene.SceneError, match='mode: not a parameter'):
        scene.load('tennis_racket', ['mode=slew'])  # no controller in that scene
    with pytest.raises(scene.SceneError, match='--set: accuracy'):
        scene.load('slew', ['accuracy=-1'])
    with pytest.raises(scene.SceneError, match='expected KEY=VALUE'):
        scene.load('slew', ['accuracy'])


def _rcl_overrides(args, node_name='attitude_simulator'):
    """{name: value} rclpy hands the node from these --ros-args (the oracle)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    context = Context()
    rclpy.init(args=['--ros-args', *args], context=context)
    try:
        node = Node(node_name, context=context)
        try:
            return {name: p.value for name, p in node._parameter_overrides.items()}
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_several_files_and_p_merge_as_rcl_merges_them(tmp_path):
    """Which value a node gets when several files and -p give a key: rcl's table of node
    keys in first-appearance order, one slot per type in an entry, rclpy's type order.
    Each case against rclpy itself."""
    scene_file = _write(tmp_path, 'scene.yaml', '/**:\n  ros__parameters:\n    a: 1.0\n'
                        '/**/attitude_simulator:\n  ros__parameters:\n    duration: 10.0\n'
                        '    gain: 0.8\n    rate: [1.0]\n')
    second = _write(tmp_path, 'second.yaml', '/**/attitude_simulator:\n  ros__parameters:\n'
                    '    gain: [2.0]\n    rate: 3.0\n    duration: 7\n')
    cases = [['--params-file', scene_file, '-p', 'duration:=6.0'],  # the section wins
             ['-p', 'duration:=6.0', '--params-file', scene_file],
             ['--params-file', scene_file, '--params-file', second],  # types differ
             ['--params-file', scene_file, '-p', 'a:=2', '-p', 'a:=3.5']]
    for args in cases:
        sources = [('file' if flag == '--params-file' else 'param', arg)
                   for flag, arg in zip(args[::2], args[1::2])]
        _, kept = params_file.given_values(sources, '/attitude_simulator')
        rcl = _rcl_overrides(args)
        assert {k: v.value for k, v in kept.items()} == rcl, args
        assert all(type(kept[k].value) is type(v) for k, v in rcl.items()), args
    # the cases the issue names: the file's 10.0 over -p 6.0; [2.0] lost beside 0.8; the
    # int 7 kept over 10.0 (rclpy prefers the integer slot)
    assert _rcl_overrides(cases[0])['duration'] == 10.0
    assert _rcl_overrides(cases[2]) == {'a': 1.0, 'duration': 7, 'gain': 0.8, 'rate': 3.0}


def test_the_node_warns_when_the_last_value_given_is_not_in_effect(tmp_path):
    """overridden_warnings (what the nodes log at start): the key, the value in effect and
    where it came from, for -p under a scene's node section and for a second file's value
    of another type; nothing when the last value given wins."""
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    from rigid_body_sim.nodes.common import overridden_warnings
    scene_file = _write(tmp_path, 'scene.yaml', '/**:\n  ros__parameters:\n'
                        '    use_sim_time: false\n/**/attitude_simulator:\n  ros__parameters:\n'
                        '    duration: 10.0\n    accuracy: 1.0e-6\n')
    second = _write(tmp_path, 'second.yaml', '/**/attitude_simulator:\n  ros__parameters:\n'
                    '    accuracy: [1.0e-3]\n    duration: 12.0\n')

    def lines(args):
        context = Context()
        argv = ['node', '--ros-args', *args]
        rclpy.init(args=argv, context=context)
        try:
            node = Node('attitude_simulator', context=context)
            try:
                return overridden_warnings(node, argv)
            finally:
                node.destroy_node()
        finally:
            rclpy.shutdown(context=context)

    (line,) = lines(['--params-file', scene_file, '-p', 'duration:=6.0'])
    assert line.startswith('parameter duration: 6.0 from -p duration:=6.0 is overridden: '
                           f'10.0 from {scene_file}: /**/attitude_simulator is in effect'), line
    (line,) = lines(['--params-file', scene_file, '--params-file', second])
    assert line.startswith(f'parameter accuracy: [0.001] from {second}: /**/attitude_simulator'
                           f' is overridden: 1e-06 from {scene_file}: /**/attitude_simulator'
                           ' is in effect (its type (double_array) differs'), line
    # the last value given wins: no warning (a second file of the same types; -p where the
    # file has no '/**' section before its node section, so '/**' comes last)
    assert lines(['--params-file', scene_file, '--params-file', _write(
        tmp_path, 'same.yaml', '/**/attitude_simulator:\n  ros__parameters:\n'
        '    duration: 12.0\n')]) == []
    assert lines(['--params-file', second, '-p', 'duration:=6.0']) == []


def test_a_file_is_parsed_once_while_its_text_is_the_same(tmp_path, monkeypatch):
    """A scene's loading reads its file ~6 times and a demo ~30 (issue 32): the YAML is
    parsed once per text. Each reader gets its own copy; an edited file is parsed again;
    a file that is not UTF-8 is refused by name."""
    import yaml
    parses = []
    real = yaml.parse
    monkeypatch.setattr(yaml, 'parse', lambda text: parses.append(text) or real(text))
    path = _write(tmp_path, 'p.yaml', '/**:\n  ros__parameters:\n    a: 1.0\n')
    first = params_file._tree(path)
    first['/**']['ros__parameters']['a'] = 5.0  # one reader's change is its own
    assert params_file._tree(path) == {'/**': {'ros__parameters': {'a': 1.0}}}
    assert len(parses) == 1
    _write(tmp_path, 'p.yaml', '/**:\n  ros__parameters:\n    a: 2.0\n')
    assert params_file._tree(path) == {'/**': {'ros__parameters': {'a': 2.0}}}
    assert len(parses) == 2
    bad = tmp_path / 'bad.yaml'
    bad.write_bytes(b'a: \xff\n')
    with pytest.raises(params_file.ParamsFileError, match='bad.yaml: not UTF-8 text'):
        params_file._tree(str(bad))
