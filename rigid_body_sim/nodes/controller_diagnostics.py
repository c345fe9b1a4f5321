"""The ``attitude_controller``'s ``/diagnostics``: one status a second (wall clock) with
the law's state, what was rejected and what was published since the last one. A mixin of
the node (``controller.py``), which owns the counters it reads and clears."""
import math

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray

from .. import control
from .common import diagnostic_status


class Diagnostics:
    """``_publish_diagnostics``, the node's diagnostics timer's callback."""

    def _publish_diagnostics(self):
        out = self._last
        if self._q is not None:
            angle = float(control.error_angle(self._q, self._ctl.target))
        else:
            angle = math.nan
        rate = float(np.linalg.norm(self._w)) if self._w is not None else math.nan
        c = self._ctl.config
        values = {
            'mode': self._ctl.mode,
            # waiting: no state yet, so the schedule (free phase first) has not started
            'mission_phase': 'waiting' if self._q is None else
            'free' if self._law.free else self._ctl.mode,
            'attitude_error_angle': angle,
            'attitude_error_angle_deg': math.degrees(angle),
            'rate_norm': rate,
            # over the ticks since the last diagnostics message (short saturations count too)
            'saturation_active': self._saturated_ticks > 0,
            'saturated_fraction': self._saturated_ticks / max(self._ticks, 1),
            'rate_limit_active': self._rate_limited_ticks > 0,
            'rate_limited_fraction': self._rate_limited_ticks / max(self._ticks, 1),
            'state_age': self._age,
            'state_timeout': self._p['state_timeout'],
            'torque_norm': float(np.linalg.norm(out.torque)) if out is not None else 0.0,
            'target': ' '.join(f'{x:.9g}' for x in self._ctl.target),
            'targets_rejected': self._rejected_targets,
            'last_target_rejection': self._last_reject,
            'states_rejected': self._rejected_states,
            'commands_published': self._published,
            'max_torque': c.torque_limit if math.isfinite(c.torque_limit) else 0.0,
            'feedback': self._p['feedback'],
        }
        if self._estimator is not None:
            values.update(gyro_readings=self._estimator.readings,
                          star_tracker_fixes=self._estimator.fixes,
                          gyro_bias_estimate=' '.join(f'{x:.6g}' for x in self._estimator.bias))
        if self._bdot is not None:
            values.update(self._bdot.values())
        if self._stale_reason:
            level = 'OK' if self._ctl.mode in ('off', 'bdot') else 'WARN'
            message = f'{self._ctl.mode}: zero torque, {self._stale_reason}'
        elif self._ctl.mode == 'off':
            level, message = 'OK', 'off: zero torque'
        elif self._ctl.mode == 'detumble':
            level, message = 'OK', f'detumble: |w| = {rate:.3g} rad/s'
        else:
            level, message = 'OK', (f'slew: error {math.degrees(angle):.3g} deg, '
                                    f'|w| = {rate:.3g} rad/s')
        if self._saturated_ticks:
            message += ' (torque saturated)'
        elif self._rate_limited_ticks:
            message += ' (slew rate limited)'
        self._ticks = self._saturated_ticks = self._rate_limited_ticks = 0
        status = diagnostic_status(f'{self.get_name()}: control', self.get_fully_qualified_name(),
                                   level, message, values)
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)

