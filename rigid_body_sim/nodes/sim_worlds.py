"""Scenes as simulation_interfaces worlds: what a running simulator can switch to.

A world is a scene (``config/*.yaml``, ``rigid_body_sim.scene``): its URI is the scene's
name or the path of a params file. Loading one sets every simulator parameter to the
scene's value (a key the scene leaves out goes back to its default), as starting the node
with ``--params-file`` would, then resets the body to the scene's initial state. Sim time
keeps running, as on any reset.

What cannot change live is refused, and nothing changes: a scene whose start-up-only
(read-only) parameters differ from the running node's (actuators, sensors, QoS, lockstep,
...), since those decide the node's topics. The refusal names them and how to start the
node with that scene instead.
"""
from typing import Dict, List, NamedTuple, Tuple

from .. import scene as scenes
from ..engine import specs

READ_ONLY = {s.name for s in specs.SIMULATOR if s.read_only}


class World(NamedTuple):
    name: str
    uri: str           # the path of its params file
    description: str
    tags: Tuple[str, ...]


def tags_of(scene: scenes.SceneFile) -> Tuple[str, ...]:
    """What a scene holds: ``controlled`` (a controller section), ``wheels``, ``cmgs``,
    ``sensors``."""
    p = scene.simulator
    return tuple(t for t, on in (
        ('controlled', scene.controlled),
        ('wheels', bool(p.get('actuators.wheels.axes'))),
        ('cmgs', p.get('actuators.cmgs.cluster', 'none') != 'none'),
        ('sensors', p.get('sensors.gyro.enabled') or p.get('sensors.star_tracker.enabled')),
    ) if on)


def available(namespace: str = '/') -> List[World]:
    """The built-in scenes; one that fails to load is left out (``rigid-body-sim scenes``
    reports it)."""
    out = []
    for name, description, path in scenes.list_scenes():
        try:
            sc = scenes.load(path, namespace=namespace)
        except scenes.SceneError:
            continue
        out.append(World(name, path, description, tags_of(sc)))
    return out


def uri_path(uri: str) -> str:
    """A scene name or a path, with an optional ``file://`` prefix removed."""
    return uri[len('file://'):] if uri.startswith('file://') else uri


def plan(uri: str, current: Dict, namespace: str = '/'):
    """(scene, {name: value} to set) to load the world ``uri`` into a node whose
    parameters are ``current``. SceneError if it cannot be read; ValueError naming the
    start-up-only parameters that differ (nothing changed)."""
    sc = scenes.load(uri_path(uri), namespace=namespace)
    target = sc.simulator  # every parameter: the scene's value or the default
    fixed = sorted(k for k in READ_ONLY if k in target and target[k] != current.get(k))
    if fixed:
        raise ValueError(
            f'scene {sc.name!r} ({sc.path}) needs start-up-only parameters the running node '
            f'cannot change: {", ".join(fixed)}; start the simulator with it instead '
            f'(--ros-args --params-file {sc.path})')
    return sc, {k: v for k, v in target.items()
                if k not in READ_ONLY and current.get(k) != v}
