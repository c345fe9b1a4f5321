"""The simulator node's control surface: pause, play, step, reset, set a state, load values,
quit (what ``sim_services`` calls), and the parameter changes. A mixin of the node
(``simulator.py``), which owns the state."""
import time

from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Trigger

from ..engine import NS
from .common import changed_values, qos_profile
from .sim_status import summary

QUIT_GRACE_S = 0.5           # a quit request's reply goes out before the node goes away
# parameters after whose change the engine configures its method again
NUMERICS = {'integrator', 'step', 'accuracy', 'publish_rate', 'duration', 'dissipation.model',
            'dissipation.coefficient'}


class Control:
    """Simulation control for :class:`~rigid_body_sim.nodes.simulator.Simulator`."""

    @property
    def engine(self):
        """The first spacecraft's engine (the only one's, without a fleet); None if empty."""
        return next(iter(self._crafts.values())).engine if self._crafts else None

    @property
    def frames(self):
        """(frame_id, child_frame_id): the inertial and the unnamed spacecraft's body frame."""
        return self._p['frame_id'], self._p['child_frame_id']

    def pause(self):
        """Stop advancing sim time (what was due runs first)."""
        if not self.paused:
            self._catch_up()
            self.paused = True

    def play(self):
        """Advance again, paced from now."""
        self.paused = False
        self._anchor()

    def step(self, n: int):
        """While paused: advance ``n`` sample periods, publishing each sample; a problem
        text, or None."""
        if self._fault or self.finished:
            return f'cannot step: {self._fault or "the run reached its duration"}'
        p = self._period_ns
        start, target = self.t_ns, (self.t_ns // p + n) * p
        self._advance(target, float('inf'), late=False)
        if self._fault or self.t_ns >= target:
            return self._fault
        # lockstep: a step never passes a control instant before its command (the action
        # waits for it: lockstep_held)
        return (f'stepped {(self.t_ns - start) // p} of {n}: {self.lockstep_held}; step again '
                'once the controller has answered')

    def reset(self):
        self._on_reset(None, Trigger.Response())

    def set_state(self, attitude, angular_velocity, craft=None):
        """A spacecraft (default: the first) in a new state now (attitude body → frame_id,
        ω body frame)."""
        craft = craft or self.crafts[0]
        self._catch_up()
        craft.engine.set_state(attitude, angular_velocity)
        craft.fault = None
        self._clear_fault()
        self._log.info(f'{craft.prefix}state set at t = {craft.engine.t:.6g} s')
        self._new_run()

    @property
    def parameters(self) -> dict:
        """The parameters' values now (a copy)."""
        return dict(self._p)

    def load_values(self, values: dict):
        """Set ``values`` ({name: value}) at once, as a params file would at start-up, then
        reset to the initial state they give (load_world); a problem text, or None (then
        nothing changed)."""
        if values:
            result = self.set_parameters_atomically([
                Parameter(k, self.get_parameter(k).type_, v) for k, v in values.items()])
            if not result.successful:
                return result.reason
        self.reset()
        return None

    def quit(self):
        """End the run loop shortly: the reply to the request still reaches the caller."""
        self._log.info('quitting on request (set_simulation_state QUITTING)')
        self._quit_at = time.monotonic() + QUIT_GRACE_S

    def _on_reset(self, request, response):
        for craft in self._crafts.values():
            craft.engine.reset()
            craft.fault = None
        self._clear_fault()
        response.success = True
        e = self.engine
        response.message = (f'reset to the initial state at t = {e.t:.6g} s; integrator '
                            f'{e.method} ({e.reason})') if len(self._crafts) == 1 else (
            f'reset {len(self._crafts)} spacecraft to their initial states at t = '
            f'{self.t_ns / NS:.6g} s')
        self._log.info(response.message)
        self._new_run()
        return response

    def _new_run(self):
        """A reset or a set state: counted in diagnostics (``resets``), published now, before
        the new state's first sample, so that subscribers (the viewer) see the count change
        before that sample."""
        self._resets += 1
        self._publish_diagnostics()

    def _apply_parameters(self, params):
        changed = changed_values(self._specs, self._p, params)
        if not changed:
            return
        self._catch_up()  # what was due runs under the old values
        stamp_now = self.stamp_ns(self.t_ns)
        self._p.update(changed)
        for name, craft in self._crafts.items():
            craft.set_values(self._values(name))
        self._commands.params = self._p
        self._period_ns = self._sample_period()
        if 'real_time_factor' in changed or 'publish_clock' in changed:
            self._base_stamp(stamp_now)  # stamps stay continuous across the change
        if any(k.split('.')[-1] in ('inertia', 'initial_attitude', 'initial_angular_velocity')
               for k in changed):
            self._log.info('inertia and initial state take effect on ~/reset')
        if self._p['publish_clock'] and self._clock_pub is None:
            self._clock_pub = self.create_publisher(Clock, '/clock', qos_profile('reliable'))
        self._anchor()
        self._refresh_subscribers()
        self._next_diag_wall = time.monotonic()
        self._log.info('parameters changed: ' + ', '.join(f'{k}={v}' for k, v in changed.items())
                       + f' -> {summary(self)}')
        if any(k.split('.', 1)[-1] in NUMERICS or k in NUMERICS for k in changed):
            self._warn_method()  # the engine checked the method again
