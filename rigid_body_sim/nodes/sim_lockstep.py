"""Lockstep's exchange on the simulator's side, cut to what one exchange needs. A mixin
of the node (``simulator.py``); the hold and its checks are ``sim_holds.py``'s.

Per exchange the simulator takes one command and publishes one control instant's
state: everything it does in between is CPU of every exchange (the issue's target is
100 µs of it). So the command of the held instant for a simulation of one spacecraft
(the common case, and the benchmark's: ``tools.lockstep``) goes the short way: its CDR
bytes decoded into a tuple (no message objects), checked against the held stamp taken
apart once per instant, applied, and the instant released; every other command
(another stamp, frame or spacecraft, a NaN) goes the general way,
``vector3_stamped`` then ``_route``, which counts and rejects it as before. Both ways
accept exactly the same commands: a command stamped with the held instant's stamp is
one the general checks let through (neither ahead of the node's stamp nor older than
``command_timeout``; before t = 0 stamps are not judged at all), so only its value and
frame are left to check.
"""
import math

from .commands import vector3_stamped, vector3_stamped_fields

_AWAITING = {('', 'torque')}  # the unnamed spacecraft's torque command only (_awaiting)


class Exchange:
    """The node's torque_command callback (raw bytes) with lockstep's short way.
    ``_held_fields``: the held instant's stamp as a command carries it, (sec, nanosec),
    or None (``sim_holds``: set by ``_hold``, cleared by ``_release``)."""

    def _on_torque_bytes(self, data):
        fields = vector3_stamped_fields(data)
        if fields is not None and fields[:2] == self._held_fields and \
                self._take_held(fields):
            return
        m = vector3_stamped(data)
        self._route(m.header, m.vector, 'torque_command')

    def _take_held(self, fields) -> bool:
        """The held instant's command, stamped with its stamp, for the one unnamed
        spacecraft when the instant awaits only it: applied and the instant released
        (True). False to go the general way: several spacecraft, a frame other than the
        body's, a value that is not finite, a run stopped."""
        _, _, frame, x, y, z = fields
        craft = self._crafts.get('')
        if craft is None or len(self._crafts) != 1 or self._awaiting != _AWAITING or \
                self._fault or craft.engine.finished or \
                frame.lstrip('/') not in ('', craft.p['child_frame_id']) or \
                not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return False
        craft.engine.apply_command((x, y, z))
        self._awaiting.clear()
        self._release()
        return True
