"""The ``SimulateSteps`` action of simulation_interfaces: steps while paused, with
feedback after each and cancellation between any two.

A step is one sample period, as ``step_simulation``'s, and publishes its sample. With
``lockstep: true`` a step that reaches a control instant publishes its state and the next
step waits, polling every ``LOCKSTEP_POLL_S``, for the controller's command for that
instant (the stepping never passes it without one, as when playing); a cancel request is
served meanwhile, and ``step_simulation`` (a plain service, which cannot wait) stops there
and says how many steps it made. The
execute callback is a coroutine that hands the executor back after every step, so the
node keeps serving (a cancel request, other services, commands) while a long goal runs;
rclpy's events executor, the simulator's, resumes it at its next turn.

One goal runs at a time. A goal that cannot run (the simulation is not paused, zero
steps, another goal running) is accepted and aborted at once with a result code and the
reason, which a rejection could not carry.
"""
from rclpy.action import ActionServer, CancelResponse
from rclpy.qos import QoSProfile

from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Result, SimulationState


FEEDBACK_DEPTH = 100
LOCKSTEP_POLL_S = 0.005  # a held lockstep instant is checked this often while a goal waits


class _Turn:
    """Awaitable that yields to the executor once."""

    def __await__(self):
        yield


class StepsAction:
    """``~/simulate_steps`` on the node of ``services`` (a ``SimulationServices``)."""

    def __init__(self, services):
        self.services = services
        self.running = None  # the goal handle being stepped
        # feedback: a deeper history than rclpy's 10, as steps come faster than a reader
        # may acknowledge them
        self.server = ActionServer(services.sim, SimulateSteps, '~/simulate_steps',
                                   execute_callback=self._execute,
                                   cancel_callback=lambda _: CancelResponse.ACCEPT,
                                   feedback_pub_qos_profile=QoSProfile(depth=FEEDBACK_DEPTH))

    def _paused(self) -> bool:
        return self.services.state in (SimulationState.STATE_PAUSED,
                                       SimulationState.STATE_STOPPED)

    def _refusal(self, steps: int):
        if self.running is not None:
            return 'another simulate_steps goal is running: cancel it or wait for it'
        if not self._paused():
            return 'the simulation is not paused: pause it first (set_simulation_state PAUSED)'
        if steps < 1:
            return 'steps must be >= 1'
        return None

    async def _execute(self, goal):
        n = int(goal.request.steps)
        problem = self._refusal(n)
        if problem:
            goal.abort()
            return self._result(Result.RESULT_INCORRECT_STATE if 'paused' in problem
                                else Result.RESULT_OPERATION_FAILED, problem)
        self.running = goal
        try:
            for done in range(n):
                if goal.is_cancel_requested:
                    goal.canceled()
                    return self._result(Result.RESULT_OK, f'canceled after {done} of {n} steps')
                if not self._paused():
                    goal.abort()
                    return self._result(Result.RESULT_INCORRECT_STATE,
                                        f'the simulation left PAUSED after {done} of {n} steps')
                while self.services.sim.lockstep_held and not goal.is_cancel_requested:
                    await self._sleep(LOCKSTEP_POLL_S)  # the controller's command for it
                if goal.is_cancel_requested:
                    goal.canceled()
                    return self._result(Result.RESULT_OK, f'canceled after {done} of {n} steps')
                problem = self.services.sim.step(1)
                if problem:
                    goal.abort()
                    return self._result(Result.RESULT_OPERATION_FAILED,
                                        f'after {done} of {n} steps: {problem}')
                self.services.state = SimulationState.STATE_PAUSED
                goal.publish_feedback(SimulateSteps.Feedback(completed_steps=done + 1,
                                                             remaining_steps=n - done - 1))
                await _Turn()
            goal.succeed()
            return self._result(Result.RESULT_OK)
        except Exception as exc:  # noqa: BLE001 - report to the caller, keep simulating
            self.services.sim.get_logger().error(f'simulate_steps: {type(exc).__name__}: {exc}')
            if goal.is_active:
                goal.abort()
            return self._result(Result.RESULT_OPERATION_FAILED, f'{type(exc).__name__}: {exc}')
        finally:
            self.running = None

    def _sleep(self, seconds):
        """A future done ``seconds`` from now (wall clock), for the coroutine to await."""
        from rclpy.clock import Clock, ClockType
        from rclpy.task import Future
        node, done = self.services.sim, Future()

        def fire():
            node.destroy_timer(timer)
            done.set_result(True)
        timer = node.create_timer(seconds, fire, clock=Clock(clock_type=ClockType.STEADY_TIME))
        return done

    @staticmethod
    def _result(code, message=''):
        out = SimulateSteps.Result()
        out.result.result, out.result.error_message = code, message
        return out
