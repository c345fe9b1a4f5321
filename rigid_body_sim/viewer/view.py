"""The Foxglove side of the viewer: channels, messages and the SDK's WebSocket server (and
optional MCAP sink). Free of ROS: the node (``nodes/viewer.py``) and the benchmark feed it
plain numbers.

Channels (all stamped with the state's stamp, which is also the log time):
- ``/tf`` (foxglove.FrameTransform): ``world`` → ``base_link``, every sample;
- ``/tf_poinsot`` (foxglove.FrameTransforms): ``world`` → ``poinsot`` (a fixed offset beside
  the body) and ``poinsot`` → ``poinsot_body`` (the body's attitude), at ``scene_rate``;
- ``/scene`` (foxglove.SceneUpdate), at ``scene_rate``: the body as its inertia box, the ω
  (body) and L (world) arrows; Poinsot's construction: the energy ellipsoid with its polhode
  (``poinsot_body``), the invariable plane with the herpolhode and the contact point
  (``poinsot``);
- ``/state`` (JSON): ω, |ω|, T, |L|, their drift, the pointing error, for Plot panels;
- ``/diagnostics`` (diagnostic_msgs/msg/DiagnosticArray, ROS 2 CDR as received): the ROS
  graph's diagnostics, this viewer's own included, for Foxglove's Diagnostics panels.

Client messages the server refuses (not JSON, unknown opcodes, a subscribe to an unknown
channel) are answered by the SDK with a status message; :class:`Rejections` counts them from
the SDK's log records, which is the only place the SDK reports them.
"""
import logging
from collections import deque
import math
import threading

import foxglove
import numpy as np
from foxglove import Channel
from foxglove.channels import (FrameTransformChannel, FrameTransformsChannel,
                               SceneUpdateChannel)
from foxglove.messages import (ArrowPrimitive, Color, CubePrimitive, FrameTransform,
                               FrameTransforms, LinePrimitive, Point3, Pose, Quaternion,
                               SceneEntity, SceneUpdate, SpherePrimitive, Timestamp, Vector3)

from . import geometry

POINSOT_FRAME = 'poinsot'
POINSOT_BODY_FRAME = 'poinsot_body'

STATE_SCHEMA = {
    'type': 'object',
    'properties': {
        'timestamp': {'type': 'object', 'properties': {'sec': {'type': 'integer'},
                                                       'nsec': {'type': 'integer'}}},
        'omega': {'type': 'object', 'description': 'angular velocity, base_link, rad/s',
                  'properties': {k: {'type': 'number'} for k in 'xyz'}},
        'omega_norm': {'type': 'number', 'description': '|ω|, rad/s'},
        'kinetic_energy': {'type': 'number', 'description': 'T, J'},
        'angular_momentum_norm': {'type': 'number', 'description': '|L|, kg·m²/s'},
        'kinetic_energy_drift': {'type': 'number', 'description': '(T − T₀)/T₀'},
        'angular_momentum_drift': {'type': 'number', 'description': '(|L| − |L|₀)/|L|₀'},
        'pointing_error_deg': {'type': 'number', 'description': 'angle to the target, °'},
    },
}
DIAGNOSTICS_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'


class PortInUse(RuntimeError):
    """The server could not bind its port."""


class Rejections(logging.Handler):
    """Counts client messages the SDK's server refused, by reason, from its log records."""

    KINDS = (('attempted to subscribe to unknown channel', 'unknown_channel'),
             ('Invalid message', 'invalid_message'))

    def __init__(self, on_reject=None):
        super().__init__(logging.ERROR)
        self.counts = {kind: 0 for _, kind in self.KINDS}
        self.on_reject = on_reject
        self._lock = threading.Lock()  # records arrive on the SDK's threads

    def emit(self, record):
        text = record.getMessage()
        for needle, kind in self.KINDS:
            if needle in text:
                with self._lock:
                    self.counts[kind] += 1
                if self.on_reject is not None:
                    self.on_reject(kind, text)
                return

    def snapshot(self):
        with self._lock:
            return dict(self.counts)


def _time(stamp_ns: int):
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return Timestamp(sec=sec, nsec=nsec)


def _quat(q):
    return Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def _vec(v):
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _color(r, g, b, a=1.0):
    return Color(r=r, g=g, b=b, a=a)


def start_server(host: str, port: int, name: str = 'rigid_body_sim', on_reject=None,
                 listener=None):
    """The SDK's WebSocket server on ``host``:``port``, with refused client messages counted.
    Returns (server, Rejections). PortInUse naming the port and the ``port`` parameter when
    it cannot bind."""
    rejections = Rejections(on_reject)
    sdk_log = logging.getLogger('foxglove')
    sdk_log.addHandler(rejections)
    sdk_log.propagate = False  # the node reports rejections itself (counted, rate-limited)
    sdk_log.setLevel(logging.ERROR)
    foxglove.set_log_level('ERROR')
    try:
        server = foxglove.start_server(name=name, host=host, port=port,
                                        server_listener=listener)
    except RuntimeError as exc:
        raise PortInUse(f'cannot serve Foxglove on {host}:{port} (parameter port): '
                        f'{exc}; choose another with -p port:=N (0 = any free port)') from None
    return server, rejections


class View:
    """Channels and the state they show. Call :meth:`set_body` once the inertia is known,
    then :meth:`transform` for each attitude and :meth:`sample` for each complete sample."""

    def __init__(self, frame_id='world', child_frame_id='base_link', body_size=1.0,
                 trace_length=600, scene_period_ns=100_000_000, diagnostics_definition=''):
        """``diagnostics_definition``: the ros2msg text of DiagnosticArray (from the ROS
        install; ``bag.schema.message_definition``), the schema of ``/diagnostics``."""
        self.frame_id, self.child_frame_id = frame_id, child_frame_id
        self.body_size = float(body_size)
        self.tf = FrameTransformChannel('/tf')
        self.tf_poinsot = FrameTransformsChannel('/tf_poinsot')
        self.scene = SceneUpdateChannel('/scene')
        self.state = Channel('/state', schema=STATE_SCHEMA)
        self.diagnostics = Channel('/diagnostics', message_encoding='cdr', schema=foxglove.Schema(
            name=DIAGNOSTICS_TYPE, encoding='ros2msg', data=diagnostics_definition.encode()))
        self.scene_period_ns = int(scene_period_ns)
        self.body = None
        self.polhode = geometry.Trace(trace_length, 0.0)
        self.herpolhode = geometry.Trace(trace_length, 0.0)
        # the traces as the SDK's points, built once per kept point: rebuilding 2 × 600 of
        # them at every scene update was the viewer's largest cost
        self._points = {'polhode': deque(maxlen=int(trace_length)),
                        'herpolhode': deque(maxlen=int(trace_length))}
        self.reset()

    def reset(self):
        """Forget the reference values (T₀, |L|₀, the Poinsot scale) and the traces: after
        the simulator's ~/reset."""
        self.T0 = self.L0 = None
        self.scale = None  # m per rad/s in the Poinsot view
        self.next_scene_ns = None
        self.polhode.clear()
        self.herpolhode.clear()
        for points in self._points.values():
            points.clear()

    def set_body(self, body):
        """``body``: physics.body.RigidBody (principal moments and axes)."""
        self.body = body
        self.box_edges, _ = geometry.display_box(body.principal_moments, self.body_size)
        # a thin plate has a zero edge: draw it 1 % thick so it stays visible
        self.box_edges = np.maximum(self.box_edges, 0.01 * self.body_size)

    # --- every sample ----------------------------------------------------------------------
    def transform(self, stamp_ns: int, q):
        """``world`` → ``base_link`` (q rotates base_link vectors into world)."""
        if not self.tf.has_sinks():
            return  # nobody subscribed and no MCAP: build nothing
        self.tf.log(FrameTransform(timestamp=_time(stamp_ns), parent_frame_id=self.frame_id,
                                   child_frame_id=self.child_frame_id, rotation=_quat(q)),
                    log_time=stamp_ns)

    def _poinsot_frames(self, stamp_ns, q):
        """``world`` → ``poinsot`` (fixed, beside the body) → ``poinsot_body`` (the attitude),
        at the scene's rate: the Poinsot view moves with its entities."""
        t = _time(stamp_ns)
        offset = (0.0, 2.5 * self.body_size, 0.0)
        self.tf_poinsot.log(FrameTransforms(transforms=[
            FrameTransform(timestamp=t, parent_frame_id=self.frame_id,
                           child_frame_id=POINSOT_FRAME, translation=_vec(offset),
                           rotation=_quat((0.0, 0.0, 0.0, 1.0))),
            FrameTransform(timestamp=t, parent_frame_id=POINSOT_FRAME,
                           child_frame_id=POINSOT_BODY_FRAME, rotation=_quat(q))]),
            log_time=stamp_ns)

    def sample(self, stamp_ns: int, q, omega, target=None):
        """One sample: q (base_link → world), ω (base_link, rad/s); plot channel now, scene at
        ``scene_rate``. From the body: L = R(q)·Iω (world, kg·m²/s) and T = ½ ω·Iω (J)."""
        if self.body is None:
            return
        q = np.asarray(q, float)
        omega = np.asarray(omega, float)
        L_body = self.body.inertia @ omega
        L_world = geometry.rotate_vector(q, L_body)
        T = 0.5 * float(omega @ L_body)
        L = float(np.linalg.norm(L_world))
        if self.T0 is None:
            self.T0, self.L0 = T, L
            semi = geometry.ellipsoid_semi_axes(self.body.principal_moments, T)
            self.scale = self.body_size / semi.max() if semi.max() > 0 else 1.0
            min_step = 0.002 * self.body_size
            self.polhode.min_step = self.herpolhode.min_step = min_step
        error = math.nan
        if target is not None:
            from ..physics import rotation
            error = math.degrees(float(rotation.angle_between(np.asarray(q, float),
                                                              np.asarray(target, float))))
        sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
        row = {
            'timestamp': {'sec': sec, 'nsec': nsec},
            'omega': {'x': omega[0], 'y': omega[1], 'z': omega[2]},
            'omega_norm': float(np.linalg.norm(omega)), 'kinetic_energy': T,
            'angular_momentum_norm': L,
            'kinetic_energy_drift': (T - self.T0) / self.T0 if self.T0 else 0.0,
            'angular_momentum_drift': (L - self.L0) / self.L0 if self.L0 else 0.0,
        }
        if not math.isnan(error):  # no target known: no point on the plot
            row['pointing_error_deg'] = error
        if self.state.has_sinks():
            self.state.log(row, log_time=stamp_ns)
        # traces every sample (cheap), drawn at scene rate
        for name, trace, p in (('polhode', self.polhode, omega * self.scale),
                               ('herpolhode', self.herpolhode,
                                geometry.rotate_vector(q, omega) * self.scale)):
            if trace.add(p):
                x, y, z = p.tolist()
                self._points[name].append(Point3(x=x, y=y, z=z))
        if self.next_scene_ns is None or stamp_ns >= self.next_scene_ns:
            self.next_scene_ns = stamp_ns + self.scene_period_ns
            if self.tf_poinsot.has_sinks():
                self._poinsot_frames(stamp_ns, q)
            if self.scene.has_sinks():
                self._scene(stamp_ns, q, omega, L_world, T)

    # --- the 3D scene ----------------------------------------------------------------------
    def _scene(self, stamp_ns, q, omega, L_world, T):
        t = _time(stamp_ns)
        size = self.body_size
        origin = _vec((0.0, 0.0, 0.0))
        p2b = _quat(self.body.principal_to_body)

        def entity(frame, eid, **prims):
            return SceneEntity(timestamp=t, frame_id=frame, id=eid, frame_locked=True, **prims)

        def arrow(vec, length, color):
            d = float(np.linalg.norm(vec))
            return ArrowPrimitive(pose=Pose(position=origin,
                                            orientation=_quat(geometry.arrow_rotation(vec))),
                                  shaft_length=length * 0.8 if d else 0.0,
                                  shaft_diameter=0.03 * size, head_length=length * 0.2,
                                  head_diameter=0.08 * size, color=color)

        def line(points, color):
            return LinePrimitive(thickness=0.01 * size, scale_invariant=False,
                                 points=list(points), color=color)

        w_dir = omega / (np.linalg.norm(omega) or 1.0)
        L_norm = float(np.linalg.norm(L_world))
        entities = [
            entity(self.child_frame_id, 'body', cubes=[CubePrimitive(
                pose=Pose(position=origin, orientation=p2b), size=_vec(self.box_edges),
                color=_color(0.7, 0.7, 0.75, 0.9))]),
            entity(self.child_frame_id, 'omega', arrows=[arrow(w_dir, 1.2 * size,
                                                               _color(1.0, 0.3, 0.2))]),
            entity(self.frame_id, 'angular_momentum', arrows=[arrow(
                L_world, 1.2 * size, _color(0.2, 0.5, 1.0))]),
        ]
        semi = geometry.ellipsoid_semi_axes(self.body.principal_moments, T) * self.scale
        entities.append(entity(POINSOT_BODY_FRAME, 'energy_ellipsoid', spheres=[SpherePrimitive(
            pose=Pose(position=origin, orientation=p2b), size=_vec(2.0 * semi),
            color=_color(0.9, 0.8, 0.3, 0.35))]))
        # the traces even when (just after a reset) too short to draw: an entity left out of
        # an update would keep its old points on the client
        entities.append(entity(POINSOT_BODY_FRAME, 'polhode', lines=[line(
            self._points['polhode'], _color(1.0, 0.3, 0.2))]))
        if L_norm > 0.0:
            normal, dist = geometry.invariable_plane(L_world, T)
            centre = normal * dist * self.scale
            plane = 3.0 * semi.max()
            entities.append(entity(POINSOT_FRAME, 'invariable_plane', cubes=[CubePrimitive(
                pose=Pose(position=_vec(centre),
                          orientation=_quat(geometry.plane_rotation(normal))),
                size=_vec((plane, plane, 0.002 * size)), color=_color(0.3, 0.6, 1.0, 0.25))]))
            entities.append(entity(POINSOT_FRAME, 'contact', spheres=[SpherePrimitive(
                pose=Pose(position=_vec(geometry.rotate_vector(q, omega) * self.scale),
                          orientation=_quat((0, 0, 0, 1))),
                size=_vec((0.05 * size,) * 3), color=_color(1.0, 0.3, 0.2))]))
            entities.append(entity(POINSOT_FRAME, 'herpolhode', lines=[line(
                self._points['herpolhode'], _color(0.2, 0.5, 1.0))]))
        self.scene.log(SceneUpdate(entities=entities), log_time=stamp_ns)

    def publish_diagnostics(self, stamp_ns: int, cdr: bytes):
        """A DiagnosticArray as ROS 2 serialized it (CDR), forwarded untouched."""
        if self.diagnostics.has_sinks():
            self.diagnostics.log(cdr, log_time=stamp_ns)
