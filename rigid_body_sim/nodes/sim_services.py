"""simulation_interfaces services of the simulator: the ROS 2 standard for simulators.

ros_gz and other simulators implement the same services, so a tool written for them
drives this one. The services are private to the node (``/attitude_simulator/...``, as
Gazebo serves ``/gz_server/...``):

* ``get_simulator_features``: what is supported (below).
* ``get_simulation_state`` / ``set_simulation_state``: PLAYING, PAUSED, STOPPED (= reset
  to the initial state and paused) and QUITTING (the node exits).
* ``step_simulation``: while paused, advance N steps. A step is one sample period
  (1/``publish_rate``), and each step publishes its sample.
* ``reset_simulation``: the body back to its initial state. Sim time keeps running, so
  stamps and /clock stay monotonic, and SCOPE_TIME alone is refused as unsupported.
* ``get_entity_state`` / ``set_entity_state``: the one entity, named after
  ``child_frame_id``. Its pose is the attitude in ``frame_id``. Its twist is the angular
  velocity in ``frame_id``, or in the body frame when the request's header names
  ``child_frame_id``.

They exist where the interface package is installed: a full Jazzy install
(``ros-jazzy-simulation-interfaces``), or the venv, which builds it at setup.
"""
import numpy as np

from ..physics import rotation

try:
    from simulation_interfaces.msg import Result, SimulationState, SimulatorFeatures
    from simulation_interfaces.srv import (GetEntityState, GetSimulationState,
                                           GetSimulatorFeatures, ResetSimulation,
                                           SetEntityState, SetSimulationState, StepSimulation)
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
    ``quit()``, ``frames`` and ``set_state(q, w)``."""

    FEATURES = ('SIMULATION_RESET', 'SIMULATION_RESET_STATE', 'SIMULATION_STATE_GETTING',
                'SIMULATION_STATE_SETTING', 'SIMULATION_STATE_PAUSE', 'STEP_SIMULATION_SINGLE',
                'STEP_SIMULATION_MULTIPLE', 'ENTITY_STATE_GETTING', 'ENTITY_STATE_SETTING')

    def __init__(self, sim):
        self.sim = sim
        self.state = SimulationState.STATE_PLAYING
        for srv, name, handler in (
                (GetSimulatorFeatures, 'get_simulator_features', self._features),
                (GetSimulationState, 'get_simulation_state', self._get_state),
                (SetSimulationState, 'set_simulation_state', self._set_state),
                (StepSimulation, 'step_simulation', self._step),
                (ResetSimulation, 'reset_simulation', self._reset),
                (GetEntityState, 'get_entity_state', self._get_entity),
                (SetEntityState, 'set_entity_state', self._set_entity)):
            sim.create_service(srv, f'~/{name}', self._guarded(handler))

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
            'one rigid body (entity named after child_frame_id); a step is one sample period '
            '(1/publish_rate); reset keeps sim time')
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
        if scope & ResetSimulation.Request.SCOPE_STATE or scope in (
                ResetSimulation.Request.SCOPE_DEFAULT, ResetSimulation.Request.SCOPE_ALL):
            self.sim.reset()
        return _result(response, Result.RESULT_OK,
                       'state reset; sim time keeps running' if scope != 4 else
                       'nothing spawned to remove')

    # ------------------------------------------------------------------ the body
    def _entity_problem(self, name):
        body = self.sim.frames[1]
        if name not in (body, '/' + body):
            return f'no entity {name!r}: the one entity is {body!r} (child_frame_id)'
        return None

    def _get_entity(self, request, response):
        problem = self._entity_problem(request.entity)
        if problem:
            return _result(response, Result.RESULT_NOT_FOUND, problem)
        e, (world, _) = self.sim.engine, self.sim.frames
        q = e.attitude
        w_world = rotation.rotate(q, e.angular_velocity)
        st = response.state
        st.header.frame_id = world
        st.header.stamp.sec, st.header.stamp.nanosec = divmod(self.sim.stamp_ns(e.t_ns),
                                                              1_000_000_000)
        o = st.pose.orientation
        o.x, o.y, o.z, o.w = (float(v) for v in q)
        a = st.twist.angular
        a.x, a.y, a.z = (float(v) for v in w_world)
        return _result(response, Result.RESULT_OK)

    def _set_entity(self, request, response):
        problem = self._entity_problem(request.entity)
        if problem:
            return _result(response, Result.RESULT_NOT_FOUND, problem)
        world, body = self.sim.frames
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
            self.sim.set_state(q, w)
        except ValueError as exc:
            return _result(response, SetEntityState.Response.INVALID_POSE, str(exc))
        return _result(response, Result.RESULT_OK)
