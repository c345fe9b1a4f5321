"""``robot_joint_commands``: the wheels and gimbals driven through ros2_control's topic contract.

ros2_control's ``joint_state_topic_hardware_interface`` (``JointStateTopicSystem``, formerly
PickNik's ``topic_based_ros2_control``) writes a stock controller's commands as one
``sensor_msgs/JointState`` on its ``joint_commands_topic`` (default
``/robot_joint_commands``, reliable, depth 1). Its ``write()`` names every joint of the
``<ros2_control>`` tag in ``name`` and appends, joint by joint, one entry to ``position``,
``velocity`` or ``effort`` for each command interface that joint has: each array holds the
values of the joints that have that interface, in ``name`` order (so it is shorter than
``name`` when the joints' interfaces differ).

Here a wheel's command interface is ``effort`` (motor torque, N·m) and a gimbal's is
``velocity`` (gimbal rate, rad/s), the two values of the forward command
(``actuators.command: forward``; ``actuator_command`` takes the same as one array). So
``effort`` holds the named wheels' torques and ``velocity`` the named gimbals' rates, in
the order of ``name``; joints not named keep their last command. A message where every
array has one entry per name (the usual JointState form) is the same thing when it names
only wheels or only gimbals. Joint names are those of ``wheel_states`` / ``gimbal_states``
(``actuators.wheels.names`` / ``actuators.cmgs.names``). The stamp is not checked: the
interface stamps with the controller manager's clock and sends at every update.

Bad input (an unknown or repeated joint, an array of the wrong length, a position, a
wheel given a velocity or a gimbal an effort, a value not finite, a scene that allocates
body torque) is rejected whole, counted by reason in diagnostics
(``joint_commands_rejected.<reason>``) and warned about (throttled); the last valid
command stays.
"""
import math

from .commands import Rejections

TOPIC = 'robot_joint_commands'
REJECT_REASONS = ('unknown_joint', 'duplicate_joint', 'wrong_length', 'unsupported_interface',
                  'non_finite', 'refused')


class JointCommandError(ValueError):
    """A JointState command that cannot be applied: ``reason`` (REJECT_REASONS), text."""

    def __init__(self, reason: str, text: str):
        super().__init__(text)
        self.reason = reason


def forward_values(config, name, position, velocity, effort, wheel_cmd, rate_cmd) -> list:
    """The full forward command (N wheel torques, then K gimbal rates) that a JointState
    command (its ``name``, ``position``, ``velocity``, ``effort``) makes of the last one
    (``wheel_cmd``, ``rate_cmd``); JointCommandError if it is bad (module docstring)."""
    wheels = {n: i for i, n in enumerate(config.wheel_names)}
    gimbals = {n: i for i, n in enumerate(config.cmg_names)}
    names = list(name)
    if not names:
        raise JointCommandError('wrong_length', 'name lists no joint')
    seen = set()
    for n in names:
        if n not in wheels and n not in gimbals:
            raise JointCommandError('unknown_joint', f'joint {n!r} is neither a wheel '
                                    f'{list(wheels)} nor a gimbal {list(gimbals)}')
        if n in seen:
            raise JointCommandError('duplicate_joint', f'joint {n!r} is named twice')
        seen.add(n)
    if len(position):
        raise JointCommandError('unsupported_interface', 'position given: wheels take effort '
                                '(torque, N·m) and gimbals velocity (rate, rad/s)')
    named_w = [n for n in names if n in wheels]
    named_g = [n for n in names if n in gimbals]
    w_values = _entries('effort', effort, names, named_w, 'velocity', 'gimbal')
    g_values = _entries('velocity', velocity, names, named_g, 'effort', 'wheel')
    out_w, out_g = [float(v) for v in wheel_cmd], [float(v) for v in rate_cmd]
    for n, v in zip(named_w, w_values):
        out_w[wheels[n]] = v
    for n, v in zip(named_g, g_values):
        out_g[gimbals[n]] = v
    return out_w + out_g


def _entries(field, values, names, named, other_field, other_kind):
    """The entries of ``field`` for the ``named`` joints that take it."""
    values = [float(v) for v in values]
    if len(values) != len(named):
        if len(values) == len(names):  # one per name: some joint of the other kind got one
            joint = next(n for n in names if n not in named)
            raise JointCommandError('unsupported_interface', f'{field} given for {other_kind} '
                                    f'{joint!r}, which takes {other_field}')
        raise JointCommandError('wrong_length', f'{field} has {len(values)} entries for the '
                                f'{len(named)} joint(s) named that take it {named}')
    bad = [(n, v) for n, v in zip(named, values) if not math.isfinite(v)]
    if bad:
        raise JointCommandError('non_finite', f'{field} of {bad[0][0]!r} is {bad[0][1]}')
    return values


class JointCommands:
    """The simulator's ``robot_joint_commands`` subscription; ``engine``: the node's Engine
    (``apply_actuator_command``; its ``actuators`` hold the last command); ``ready()``
    before each command: False drops it (the run stopped), else what was due has run."""

    def __init__(self, node, engine, qos, ready=lambda: True, prefix=''):
        from sensor_msgs.msg import JointState
        self._engine, self._ready = engine, ready
        self.rejections = Rejections(node, REJECT_REASONS, 'joint_commands_rejected',
                                     'the last valid command is held')
        self.accepted = 0
        self.subscription = node.create_subscription(JointState, prefix + TOPIC,
                                                     self.on_command, qos)

    def counts(self) -> dict:
        return {'joint_commands_accepted': self.accepted, **self.rejections.counts()}

    def on_command(self, msg) -> bool:
        """Apply ``msg`` (sensor_msgs/JointState) or reject it; True if applied."""
        if not self._ready():
            return False
        act = self._engine.actuators
        try:
            if act is None:  # pragma: no cover - the node subscribes only with actuators
                raise JointCommandError('refused', 'the scene has no actuators')
            values = forward_values(act.config, msg.name, msg.position, msg.velocity,
                                    msg.effort, act.u_cmd, act.rate_cmd)
            try:
                self._engine.apply_actuator_command(values)
            except ValueError as exc:  # e.g. actuators.command: torque
                raise JointCommandError('refused', str(exc)) from None
        except JointCommandError as exc:
            return self.rejections.reject(exc.reason, TOPIC, str(exc))
        self.accepted += 1
        return True
