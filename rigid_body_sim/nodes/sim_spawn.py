"""SpawnEntity and DeleteEntity (simulation_interfaces): spacecraft at run time.

A spawned spacecraft starts at the simulation's sim time, its samples on the same grid as
the others', its topics under ``<name>/`` and its body frame ``<name>/<child_frame_id>``:

* ``name``: the spacecraft's name (``engine/fleet.py``: letters, digits, single
  underscores); with ``allow_renaming`` an empty or taken name becomes a free one.
* ``uri`` (a scene's name or a params file's path) or ``resource_string`` (a params file's
  text): its body's values (inertia, angular velocity, dissipation, actuators, sensors) are
  the scene's simulator values, or those of the scene's spacecraft of the same name. Empty:
  the running scene's node-level values.
* ``initial_pose``: its orientation, in ``frame_id`` (header empty or ``frame_id``), is the
  initial attitude; the position must be finite (an attitude simulator ignores it).

A spawn that cannot be done is refused with the reason and the running spacecraft are
untouched: a name in use or invalid, an invalid pose, a resource that cannot be read or
whose values are invalid, or lockstep (it holds one spacecraft). Deleting takes a
spacecraft's topics off the graph; deleting the last leaves a running, empty simulation
that says so in diagnostics. Wheels and CMGs go with their spacecraft only.
"""
import math
import os
import tempfile

from ..engine import fleet
from ..physics import rotation
from ..scene import SceneError, load as load_scene, resolve as resolve_scene
from . import sim_worlds as worlds

from simulation_interfaces.msg import Result
from simulation_interfaces.srv import SpawnEntity


def _result(response, code, message=''):
    response.result.result = code
    response.result.error_message = message
    return response


def _free_name(name, taken):
    """``name`` (default ``spacecraft``) with the first free suffix _1, _2, ..."""
    stem, k = name or 'spacecraft', 1
    while f'{stem}_{k}' in taken:
        k += 1
    return f'{stem}_{k}'


def _resource_values(sim, request, name):
    """The body's values from the request's resource ({} for none); SceneError(code, why)."""
    if not request.uri and not request.resource_string:
        return {}
    if request.uri:
        try:
            resolve_scene(worlds.uri_path(request.uri))
        except SceneError as exc:
            raise _Refused(SpawnEntity.Response.NO_RESOURCE, str(exc)) from None
        return _scene_values(worlds.uri_path(request.uri), sim, name)
    with tempfile.TemporaryDirectory() as folder:  # a params file's text, read as one
        path = os.path.join(folder, 'resource_string.yaml')
        with open(path, 'w', encoding='utf-8') as f:
            f.write(request.resource_string)
        try:
            return _scene_values(path, sim, name)
        except _Refused as exc:
            raise _Refused(exc.code, exc.reason.replace(path, 'resource_string')) from None


def _scene_values(path, sim, name):
    try:
        sc = load_scene(path, namespace=sim.get_namespace())
    except SceneError as exc:
        raise _Refused(SpawnEntity.Response.RESOURCE_PARSE_ERROR, str(exc)) from None
    values = {k: sc.simulator[k] for k in fleet.BODY_KEYS}
    values.update(sc.spacecraft.get(name, {}))
    return values


class _Refused(Exception):
    def __init__(self, code, reason):
        super().__init__(reason)
        self.code, self.reason = code, reason


def _pose(sim, pose):
    """The initial attitude (x, y, z, w) from a PoseStamped; _Refused(INVALID_POSE)."""
    world = sim.frames[0]
    frame = pose.header.frame_id.lstrip('/')
    if frame not in ('', world):
        raise _Refused(SpawnEntity.Response.INVALID_POSE, f'initial_pose frame {frame!r}: '
                       f'give the pose in {world!r} (frame_id) or leave it empty')
    p, o = pose.pose.position, pose.pose.orientation
    if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
        raise _Refused(SpawnEntity.Response.INVALID_POSE,
                       f'initial_pose position ({p.x}, {p.y}, {p.z}) is not finite')
    try:
        return [float(v) for v in rotation.validated([o.x, o.y, o.z, o.w],
                                                     'initial_pose orientation')]
    except ValueError as exc:
        raise _Refused(SpawnEntity.Response.INVALID_POSE, str(exc)) from None


def spawn(sim, request, response):
    """The spawn_entity service on the simulator ``sim`` (module docstring)."""
    taken = {c.entity for c in sim.crafts} | {c.name for c in sim.crafts}
    name = request.name
    if request.allow_renaming and (not name or name in taken):
        name = _free_name(name, taken)
    if not name:
        return _result(response, SpawnEntity.Response.NAME_INVALID,
                       'give the spacecraft a name (or allow_renaming for one chosen here)')
    if name in taken:
        return _result(response, SpawnEntity.Response.NAME_NOT_UNIQUE,
                       f'a spacecraft named {name!r} is running; delete it first, choose '
                       'another name, or allow_renaming')
    problem = fleet.name_problem(name)
    if problem:
        return _result(response, SpawnEntity.Response.NAME_INVALID, problem)
    if request.entity_namespace.strip('/'):
        return _result(response, SpawnEntity.Response.NAMESPACE_INVALID,
                       f'entity_namespace {request.entity_namespace!r}: a spacecraft\'s topics '
                       f'are under its name in the simulator\'s namespace; leave it empty')
    if sim.lockstep:
        return _result(response, Result.RESULT_OPERATION_FAILED,
                       'lockstep holds the control instants of one spacecraft: no spawning')
    try:
        own = {k: sim.parameters[k] for k in fleet.BODY_KEYS}
        own.update(_resource_values(sim, request, name))
        own['initial_attitude'] = _pose(sim, request.initial_pose)
    except _Refused as exc:
        return _result(response, exc.code, exc.reason)
    try:
        sim.spawn(name, own)
    except ValueError as exc:  # its values (a resource's): the others are untouched
        return _result(response, SpawnEntity.Response.RESOURCE_PARSE_ERROR, str(exc))
    response.entity_name = name
    return _result(response, Result.RESULT_OK)


def delete(sim, request, response):
    """The delete_entity service: a spacecraft (with its wheels and CMGs)."""
    name = request.entity.lstrip('/')
    craft = next((c for c in sim.crafts if c.entity == name), None)
    if craft is None:
        names = ', '.join(c.entity for c in sim.crafts) or 'none'
        return _result(response, Result.RESULT_NOT_FOUND,
                       f'no spacecraft {request.entity!r} to delete (the spacecraft are '
                       f'{names}; wheels and CMGs go with their spacecraft)')
    sim.delete(craft)
    return _result(response, Result.RESULT_OK)
