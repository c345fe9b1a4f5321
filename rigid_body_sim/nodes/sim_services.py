"""simulation_interfaces services of the simulator: the ROS 2 standard for simulators.

ros_gz and other simulators implement the same services, so a tool written for them
drives this one. The services are private to the node (``/attitude_simulator/...``, as
Gazebo serves ``/gz_server/...``):

* ``get_simulator_features``: what is supported (below).
* ``get_simulation_state`` / ``set_simulation_state``: PLAYING, PAUSED, STOPPED (= reset
  to the initial state and paused) and QUITTING (the node exits).
* ``step_simulation``: while paused, advance N steps. A step is one sample period
  (1/``publish_rate``), and each step publishes its sample.
* ``reset_simulation``: the bodies back to their initial state. Sim time keeps running, so
  stamps and /clock stay monotonic, and SCOPE_TIME alone is refused as unsupported.
  SCOPE_SPAWNED (and ALL): the scene's spacecraft again, spawned ones removed, deleted
  ones of the scene back.
* ``simulate_steps`` (action ``SimulateSteps``, ``sim_steps``): as ``step_simulation``,
  with feedback after each step and cancellation.
* ``get_entities`` / ``get_entities_states`` / ``get_entity_info`` / ``get_entity_state``:
  the spacecraft (the unnamed one named after ``child_frame_id``, the others by name) and
  their wheels and CMGs (``sim_entities`` says what their states hold); filters by regular
  expression, category and tags.
* ``set_entity_state``: a spacecraft. Its pose is the attitude in ``frame_id``. Its
  twist is the angular velocity in ``frame_id``, or in its body frame when the request's
  header names that frame.
* ``spawn_entity`` / ``delete_entity``: spacecraft at run time (``sim_spawn``).
* ``get_available_worlds`` / ``load_world`` / ``get_current_world``: the scenes
  (``sim_worlds``), switched live when the node can.

Not served, and not listed as features: spawning several at once (SpawnEntities), named
poses, bounds, setting entity info, unloading a world.

They exist where the interface package is installed: a full Jazzy install
(``ros-jazzy-simulation-interfaces``), or the venv, which builds it at setup.
"""
import os

import numpy as np

from ..physics import rotation
from ..scene import SceneError, resolve as resolve_scene
from . import sim_entities as entities, sim_worlds as worlds

try:
    from simulation_interfaces.msg import (EntityInfo, EntityState, Result, SimulationState,
                                           SimulatorFeatures, TagsFilter, WorldResource)
    from simulation_interfaces.srv import (GetAvailableWorlds, GetCurrentWorld, GetEntities,
                                           GetEntitiesStates, GetEntityInfo, GetEntityState,
                                           GetSimulationState, GetSimulatorFeatures, LoadWorld,
                                           ResetSimulation, SetEntityState, SetSimulationState,
                                           StepSimulation, SpawnEntity, DeleteEntity)
    AVAILABLE = True
except ImportError:  # pragma: no cover - depends on the installation
    AVAILABLE = False

S = SimulationState if AVAILABLE else None


def _result(response, code, message=''):
    response.result.result = code
    response.result.error_message = message
    return response


class SimulationServices:
    """Serves the standard on a :class:`~rigid_body_sim.nodes.simulator.Simulator`, which
    provides ``engine``, ``paused``, ``pause()``, ``play()``, ``step(n)``, ``reset()``,
    ``quit()``, ``frames``, ``set_state(q, w)``, ``parameters`` and ``load_values(values)``."""

    FEATURES = ('SIMULATION_RESET', 'SIMULATION_RESET_STATE', 'SIMULATION_STATE_GETTING',
                'SIMULATION_STATE_SETTING', 'SIMULATION_STATE_PAUSE', 'STEP_SIMULATION_SINGLE',
                'STEP_SIMULATION_MULTIPLE', 'STEP_SIMULATION_ACTION', 'ENTITY_STATE_GETTING',
                'ENTITY_STATE_SETTING', 'ENTITY_INFO_GETTING', 'ENTITY_CATEGORIES',
                'ENTITY_TAGS', 'AVAILABLE_WORLDS', 'WORLD_LOADING', 'WORLD_RESOURCE_STRING',
                'WORLD_INFO_GETTING', 'WORLD_TAGS', 'SPAWNING', 'SPAWNING_RESOURCE_STRING',
                'DELETING', 'SIMULATION_RESET_SPAWNED')

    def __init__(self, sim):
        from . import sim_spawn as spawn  # simulation_interfaces: only where installed
        self.sim = sim
        self.state = SimulationState.STATE_PLAYING
        self.world = None  # the World loaded by load_world
        for srv, name, handler in (
                (GetSimulatorFeatures, 'get_simulator_features', self._features),
                (GetSimulationState, 'get_simulation_state', self._get_state),
                (SetSimulationState, 'set_simulation_state', self._set_state),
                (StepSimulation, 'step_simulation', self._step),
                (ResetSimulation, 'reset_simulation', self._reset),
                (GetEntities, 'get_entities', self._get_entities),
                (GetEntitiesStates, 'get_entities_states', self._get_entities_states),
                (GetEntityInfo, 'get_entity_info', self._get_entity_info),
                (GetEntityState, 'get_entity_state', self._get_entity),
                (SetEntityState, 'set_entity_state', self._set_entity),
                (GetAvailableWorlds, 'get_available_worlds', self._available_worlds),
                (LoadWorld, 'load_world', self._load_world),
                (GetCurrentWorld, 'get_current_world', self._current_world),
                (SpawnEntity, 'spawn_entity', lambda req, res: spawn.spawn(sim, req, res)),
                (DeleteEntity, 'delete_entity', lambda req, res: spawn.delete(sim, req, res))):
            sim.create_service(srv, f'~/{name}', self._guarded(handler))
        from .sim_steps import StepsAction  # rclpy.action: only with the interfaces
        self.steps_action = StepsAction(self)

    def _guarded(self, handler):
        """A failing request answers RESULT_OPERATION_FAILED; it never stops the node."""
        def call(request, response):
            try:
                return handler(request, response)
            except Exception as exc:  # noqa: BLE001 - report to the caller, keep simulating
                self.sim.get_logger().error(f'{handler.__name__}: {type(exc).__name__}: {exc}')
                if hasattr(response, 'result'):
                    return _result(response, Result.RESULT_OPERATION_FAILED,
                                   f'{type(exc).__name__}: {exc}')
                return response
        return call

    # ------------------------------------------------------------------ simulation
    def _features(self, request, response):
        response.features.features = [getattr(SimulatorFeatures, f) for f in self.FEATURES]
        response.features.custom_info = (
            'spacecraft (the unnamed one named after child_frame_id, the others by name; '
            'spawned and deleted at run time, resource: a scene), their wheels and CMGs '
            '(<spacecraft>/<joint>); a step is one sample period (1/publish_rate); reset '
            'keeps sim time; worlds are scenes (config/*.yaml), loaded live when their '
            'start-up-only parameters match the running node\'s')
        return response

    def _get_state(self, request, response):
        response.state.state = self.state
        return _result(response, Result.RESULT_OK)

    def _set_state(self, request, response):
        target, sim = request.state.state, self.sim
        if target == self.state:
            return _result(response, SetSimulationState.Response.ALREADY_IN_TARGET_STATE,
                           'already in that state')
        if target == S.STATE_PLAYING:
            sim.play()
        elif target == S.STATE_PAUSED:
            sim.pause()
        elif target == S.STATE_STOPPED:
            sim.pause()
            sim.reset()
        elif target == S.STATE_QUITTING:
            sim.quit()
        else:
            return _result(response, SetSimulationState.Response.INCORRECT_TRANSITION,
                           f'state {target} cannot be set here (PLAYING, PAUSED, STOPPED, '
                           'QUITTING can)')
        self.state = target
        return _result(response, Result.RESULT_OK)

    def _step(self, request, response):
        if self.state not in (S.STATE_PAUSED, S.STATE_STOPPED):
            return _result(response, Result.RESULT_OPERATION_FAILED,
                           'the simulation is not paused: pause it first '
                           '(set_simulation_state PAUSED)')
        if request.steps < 1:
            return _result(response, Result.RESULT_OPERATION_FAILED, 'steps must be >= 1')
        problem = self.sim.step(int(request.steps))
        if problem:
            return _result(response, Result.RESULT_OPERATION_FAILED, problem)
        self.state = S.STATE_PAUSED
        return _result(response, Result.RESULT_OK)

    def _reset(self, request, response):
        scope = request.scope
        if scope == ResetSimulation.Request.SCOPE_TIME:
            return _result(response, Result.RESULT_FEATURE_UNSUPPORTED,
                           'sim time is not reset: stamps and /clock stay monotonic')
        every = scope == ResetSimulation.Request.SCOPE_DEFAULT  # = SCOPE_ALL
        done = []
        if every or scope & ResetSimulation.Request.SCOPE_SPAWNED:
            done.append(self.sim.restore_scene())  # spawned out, deleted ones back
        if every or scope & ResetSimulation.Request.SCOPE_STATE:
            self.sim.reset()
            done.append('state reset; sim time keeps running')
        return _result(response, Result.RESULT_OK, '; '.join(done))

    # ------------------------------------------------------------------ entities
    def _find(self, name):
        """(entity, None) or (None, the reason it is not there)."""
        entity = entities.find(self.sim.crafts, name)
        if entity is None:
            names = [e.name for e in entities.entities(self.sim.crafts)]
            return None, f'no entity {name!r}: the entities are {", ".join(names) or "none"}'
        return entity, None

    def _fill_state(self, msg, entity, body_twist=False):
        world, body = entity.craft.frames
        frame, q, w = entities.state(entity, body_twist)
        msg.header.frame_id = body if frame == 'body' else world
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(
            self.sim.stamp_ns(entity.craft.engine.t_ns), 1_000_000_000)
        o = msg.pose.orientation
        o.x, o.y, o.z, o.w = (float(v) for v in q)
        a = msg.twist.angular
        a.x, a.y, a.z = (float(v) for v in w)
        return msg

    def _filtered(self, filters):
        """Entities passing ``filters``, or (None, code, reason)."""
        if filters.bounds.type != 0:  # Bounds.TYPE_EMPTY
            return None, Result.RESULT_FEATURE_UNSUPPORTED, \
                'bounds filters are not supported (ENTITY_BOUNDS): entities have no extent'
        try:
            found = entities.matching(
                self.sim.crafts, filters.filter,
                [c.category for c in filters.categories], list(filters.tags.tags),
                filters.tags.filter_mode == TagsFilter.FILTER_MODE_ALL)
        except ValueError as exc:
            return None, Result.RESULT_OPERATION_FAILED, str(exc)
        return found, Result.RESULT_OK, ''

    def _get_entities(self, request, response):
        found, code, reason = self._filtered(request.filters)
        response.entities = [e.name for e in found or ()]
        return _result(response, code, reason)

    def _get_entities_states(self, request, response):
        found, code, reason = self._filtered(request.filters)
        response.entities = [e.name for e in found or ()]
        response.states = [self._fill_state(EntityState(), e) for e in found or ()]
        return _result(response, code, reason)

    def _get_entity_info(self, request, response):
        entity, problem = self._find(request.entity)
        if problem:
            return _result(response, Result.RESULT_NOT_FOUND, problem)
        response.info = EntityInfo(description=entity.description, tags=list(entity.tags))
        response.info.category.category = entity.category
        return _result(response, Result.RESULT_OK)

    def _get_entity(self, request, response):
        entity, problem = self._find(request.entity)
        if problem:
            return _result(response, Result.RESULT_NOT_FOUND, problem)
        self._fill_state(response.state, entity)
        return _result(response, Result.RESULT_OK)

    def _set_entity(self, request, response):
        entity = entities.find(self.sim.crafts, request.entity)
        if entity is None or entity.kind != entities.BODY:
            names = [c.entity for c in self.sim.crafts]
            return _result(response, Result.RESULT_NOT_FOUND,
                           f'no spacecraft {request.entity!r} to set: the spacecraft are '
                           f'{", ".join(names) or "none"}; wheel and CMG states follow from '
                           'their commands')
        craft = entity.craft
        world, body = craft.frames
        st = request.state
        frame = st.header.frame_id.lstrip('/')
        if frame not in ('', world, body):
            return _result(response, Result.RESULT_OPERATION_FAILED,
                           f'frame {frame!r}: give the state in {world!r} (or empty) or the '
                           f'twist in {body!r}')
        o, a = st.pose.orientation, st.twist.angular
        q = np.array([o.x, o.y, o.z, o.w])
        w = np.array([a.x, a.y, a.z])
        try:
            q = rotation.validated(list(q), 'pose.orientation')
            if frame != body:  # twist observed in the world frame: into the body frame
                w = rotation.rotate(rotation.conjugate(q), w)
            self.sim.set_state(q, w, craft)
        except ValueError as exc:
            return _result(response, SetEntityState.Response.INVALID_POSE, str(exc))
        return _result(response, Result.RESULT_OK)

    # ------------------------------------------------------------------ worlds
    def _world_msg(self, world):
        msg = WorldResource(name=world.name, description=world.description,
                            tags=list(world.tags))
        msg.world_resource.uri = world.uri
        return msg

    def _available_worlds(self, request, response):
        if request.additional_sources:
            return _result(response, Result.RESULT_FEATURE_UNSUPPORTED,
                           'additional sources are not searched: load_world takes the path '
                           'of any params file as its uri')
        wanted = set(request.filter.tags)
        every = request.filter.filter_mode == TagsFilter.FILTER_MODE_ALL
        response.worlds = [
            self._world_msg(w) for w in worlds.available(self.sim.get_namespace())
            if not wanted or (wanted <= set(w.tags) if every else wanted & set(w.tags))]
        return _result(response, Result.RESULT_OK)

    def _load_world(self, request, response):
        if not request.uri and request.resource_string:
            # a params file's text: read from a file as every scene is, named in messages
            import tempfile
            with tempfile.TemporaryDirectory() as folder:
                path = os.path.join(folder, 'resource_string.yaml')
                with open(path, 'w', encoding='utf-8') as f:
                    f.write(request.resource_string)
                self._load(path, response)
            response.result.error_message = response.result.error_message.replace(
                path, 'resource_string')
            if response.result.result == Result.RESULT_OK:
                response.world.world_resource.uri = ''
                response.world.world_resource.resource_string = request.resource_string
                self.world = self.world._replace(uri='')
            return response
        if not request.uri:
            return _result(response, LoadWorld.Response.NO_RESOURCE,
                           'give the uri (a scene name, see get_available_worlds, or the path '
                           'of a params file) or the resource_string (a params file\'s text)')
        return self._load(request.uri, response)

    def _load(self, uri, response):
        try:
            resolve_scene(worlds.uri_path(uri))
        except SceneError as exc:
            return _result(response, LoadWorld.Response.NO_RESOURCE, str(exc))
        try:
            scene, values = worlds.plan(uri, self.sim.parameters,
                                        self.sim.get_namespace())
        except SceneError as exc:
            return _result(response, LoadWorld.Response.RESOURCE_PARSE_ERROR, str(exc))
        except ValueError as exc:  # start-up-only parameters differ: nothing changed
            return _result(response, LoadWorld.Response.UNSUPPORTED_ELEMENTS, str(exc))
        problem = self.sim.load_values(values)
        if problem:
            return _result(response, Result.RESULT_OPERATION_FAILED, problem)
        self.world = worlds.World(scene.name, scene.path, scene.description,
                                  worlds.tags_of(scene))
        response.world = self._world_msg(self.world)
        return _result(response, Result.RESULT_OK)

    def _current_world(self, request, response):
        if self.world is None and self.sim.has_parameter('scene.name'):
            # the scene the node was started with, where the node declares its name
            name = str(self.sim.get_parameter('scene.name').value or '')
            found = [w for w in worlds.available(self.sim.get_namespace()) if w.name == name]
            self.world = found[0] if found else None
        if self.world is None:
            return _result(response, GetCurrentWorld.Response.NO_WORLD_LOADED,
                           'no world loaded through load_world: the node runs the parameters '
                           'it was started with')
        response.world = self._world_msg(self.world)
        return _result(response, Result.RESULT_OK)
