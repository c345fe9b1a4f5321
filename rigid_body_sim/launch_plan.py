"""What ``ros2 launch rigid_body_sim sim.launch.py`` starts, decided without ROS.

The launch file only turns this plan into launch actions, so the decisions — which scene
file, which nodes, with which parameters, and that the launch ends with the simulation —
are plain Python that the tests run here (the ``launch`` package is not on PyPI).
"""
import os
from dataclasses import dataclass, field
from typing import Dict, List, Tuple

from .scene import load, resolve

CONTROLLER_CHOICES = ('auto', 'true', 'false')


@dataclass(frozen=True)
class PlannedNode:
    """One node: executable of this package, node name, params files and values, and its
    namespace under the launch's (a formation's spacecraft name; '' = the launch's own)."""
    executable: str
    name: str
    params_files: Tuple[str, ...] = ()
    parameters: Dict[str, object] = field(default_factory=dict)
    namespace: str = ''

    def ros_arguments(self, namespace: str = '') -> List[str]:
        """The node's ``--ros-args …`` as ``ros2 run`` would pass them (name, namespace
        ``namespace`` + its own, params files, then parameters, which win)."""
        args = ['--ros-args', '-r', f'__node:={self.name}']
        ns = '/'.join(n.strip('/') for n in (namespace, self.namespace) if n.strip('/'))
        args += ['-r', f'__ns:=/{ns}'] if ns else []
        for path in self.params_files:
            args += ['--params-file', path]
        for key, value in self.parameters.items():
            args += ['-p', f'{key}:={value}']
        return args


def _flag(value: str, name: str, choices=('true', 'false')) -> str:
    v = str(value).strip().lower()
    if v not in choices:
        raise ValueError(f'launch argument {name}:={value}: choose one of {", ".join(choices)}')
    return v


def lockstep_parameters(loaded) -> Tuple[Dict[str, object], Dict[str, object]]:
    """(simulator's, controller's) extra parameters of a lockstep run of a loaded scene:
    the simulator holds the controller's control instants and stamps with sim time
    (docs/live-nodes.md, Lockstep). ValueError naming the reason if the scene cannot."""
    from .engine import lockstep, specs
    from .param_spec import coerce_all
    sim = {'lockstep': True, 'publish_clock': True,
           'control_rate': float(loaded.controller.get('control_rate', 50.0))}
    try:
        lockstep.period_ns(coerce_all(specs.SIMULATOR, {**loaded.simulator, **sim}))
    except ValueError as exc:
        raise ValueError(f'scene {loaded.name}: {exc}') from None
    return sim, {'lockstep': True}


def controllers(loaded, path: str, extra=None, lockstep=False) -> List[PlannedNode]:
    """The controllers of a loaded scene (in the params file ``path``), with the values
    ``extra``: one in the launch's namespace, or for a scene with several spacecraft one
    per spacecraft in its namespace (``<name>/attitude``, ``<name>/torque_command``), with
    that spacecraft's body frame and inertia over the scene's controller values. In
    ``lockstep`` a spacecraft out of the loop (``<name>.lockstep: false``) gets none: it
    runs free, and nothing answers it. A spacecraft spawned later gets no controller."""
    extra = dict(extra or {})
    if not loaded.spacecraft:
        return [PlannedNode('controller', 'attitude_controller', (path,), extra)]
    out = []
    for name, own in loaded.spacecraft.items():
        if lockstep and not own.get('lockstep', True):
            continue
        body = {'child_frame_id': f'{name}/{loaded.simulator["child_frame_id"]}',
                'inertia': list(own.get('inertia', loaded.simulator['inertia']))}
        out.append(PlannedNode('controller', 'attitude_controller', (path,),
                               {**body, **extra}, namespace=name))
    return out


def plan(scene: str = 'default', record: str = 'true', output: str = '',
         controller: str = 'auto', viewer: str = 'false',
         viewer_port: str = '8765', lockstep: str = 'false') -> Tuple[List[PlannedNode], str]:
    """(nodes, summary line). The scene is resolved and validated first, so an unknown
    name or a bad file fails at once (SceneError listing the built-in scenes) instead of
    starting nodes on defaults. ``controller``: auto = only for scenes that control the
    body (a free-tumble scene gets no controller, hence no torque); true/false force it.
    The simulator is the node whose exit ends the launch (the scene's ``duration``).
    ``viewer``: also start the Foxglove viewer (nodes/viewer.py) on 127.0.0.1:``viewer_port``
    (off by default: it opens a port). ``lockstep``: the simulator holds each control
    instant until the controller's command for it (:func:`lockstep_parameters`)."""
    path = os.path.abspath(resolve(scene))
    loaded = load(path)
    use_controller = _flag(controller, 'controller', CONTROLLER_CHOICES)
    with_controller = loaded.controlled if use_controller == 'auto' else use_controller == 'true'
    record = _flag(record, 'record') == 'true'
    sim_extra, ctl_extra = {}, {}
    if _flag(lockstep, 'lockstep') == 'true':
        if not with_controller:
            raise ValueError(f'launch argument lockstep:=true: scene {loaded.name} runs no '
                             'controller (controller:=true starts one)')
        sim_extra, ctl_extra = lockstep_parameters(loaded)
    # recording: the simulator holds its t = 0 until the recorder (which subscribes at its
    # start) is matched on every state topic, so the bag begins with the first sample
    # and with a controller, until it is matched too: its mission clock starts at t = 0
    nodes = [PlannedNode('simulator', 'attitude_simulator', (path,),
                         {**({'wait_for_subscribers': 1} if record else {}),
                          **({'wait_for_controller': True} if with_controller else {}),
                          **sim_extra})]
    if with_controller:
        nodes += controllers(loaded, path, ctl_extra, lockstep=bool(sim_extra))
    if _flag(viewer, 'viewer') == 'true':
        try:
            port = int(viewer_port)
        except ValueError:
            port = -1
        if not 0 <= port <= 65535:
            raise ValueError(f'launch argument viewer_port:={viewer_port}: a TCP port, '
                             '0 to 65535')
        nodes.append(PlannedNode('viewer', 'attitude_viewer', (), {'port': port}))
    if record:
        nodes.append(PlannedNode('recorder', 'mcap_recorder', (), {
            'output': output or f'rigid_body_sim_{loaded.name}', 'scene': loaded.name}))
    duration = loaded.simulator['duration']
    ends = f'ends after {duration:g} s of sim time' if duration > 0 else \
        'runs until stopped (duration 0)'
    summary = (f'scene {loaded.name}: ' + ', '.join(
        n.executable + (f' ({n.namespace})' if n.namespace else '') for n in nodes)
               + (' in lockstep' if sim_extra else '') + f'; {ends}, when the simulator exits')
    return nodes, summary
