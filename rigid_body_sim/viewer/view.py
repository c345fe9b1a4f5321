"""The Foxglove side of the viewer: channels, messages and the SDK's WebSocket server (and
optional MCAP sink). Free of ROS: the node (``nodes/viewer.py``) and the benchmark feed it
plain numbers.

Channels (all stamped with the state's stamp, which is also the log time):
- ``/tf`` (foxglove.FrameTransform): ``world`` → ``base_link``, every sample; for a
  formation, ``world`` → ``<name>/base_link`` for each spacecraft, translated to its display
  slot (the simulator has attitudes, not positions: the slots keep the bodies apart);
- ``/tf_poinsot`` (foxglove.FrameTransforms): ``world`` → ``poinsot`` (a fixed offset beside
  the body) and ``poinsot`` → ``poinsot_body`` (the body's attitude), at ``scene_rate``;
- ``/scene`` (foxglove.SceneUpdate), at ``scene_rate``: each body as its inertia box, the ω
  (body) and L (world) arrows (a formation's prefixed ``<name>/``, with a label; a deleted
  spacecraft's deleted); Poinsot's construction of the first body: the energy ellipsoid
  with its polhode (``poinsot_body``), the invariable plane with the herpolhode and the
  contact point (``poinsot``); with an orbit, the Earth, the orbit and the LVLH frame, the
  Sun and the field (``orbit_view.py``);
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
from foxglove.messages import (CubePrimitive, FrameTransform, FrameTransforms, Point3, Pose,
                               SceneEntityDeletion, SceneEntityDeletionType, SceneUpdate)

from . import entities as ent, geometry
from .entities import quat as _quat, stamp as _time, vec as _vec

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
SLOT_SPACING = 2.5   # body sizes between the display slots of a formation's bodies
CRAFT_ENTITIES = ('body', 'omega', 'angular_momentum', 'label', 'lvlh', 'sun',
                  'magnetic_field')


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


class Craft:
    """One spacecraft as drawn: its body frame, its display slot (an offset in ``world``),
    its body (None until known) and its latest state."""

    def __init__(self, name: str, frame: str, offset):
        self.name, self.frame = name, frame
        self.prefix = f'{name}/' if name else ''
        self.offset = np.asarray(offset, float)
        self.body = self.box_edges = None
        self.q = self.omega = None
        self.orbit = None   # orbit_view.OrbitFrame of its latest orbit sample

    def ids(self):
        return [self.prefix + e for e in CRAFT_ENTITIES]


class View:
    """Channels and the state they show. Call :meth:`set_body` once the inertia is known,
    then :meth:`transform` for each attitude and :meth:`sample` for each complete sample.
    A formation's spacecraft are added by name (:meth:`add_craft`) and taken out with
    :meth:`remove_craft`; the unnamed one ('') is the single body of other scenes."""

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
        self.crafts = {'': Craft('', child_frame_id, (0.0, 0.0, 0.0))}
        self._primary = ''
        self.polhode = geometry.Trace(trace_length, 0.0)
        self.herpolhode = geometry.Trace(trace_length, 0.0)
        # the traces as the SDK's points, built once per kept point: rebuilding 2 × 600 of
        # them at every scene update was the viewer's largest cost
        self._points = {'polhode': deque(maxlen=int(trace_length)),
                        'herpolhode': deque(maxlen=int(trace_length))}
        self.reset()

    @property
    def body(self):
        """The body of the Poinsot construction and ``/state`` (the first drawn)."""
        return self.crafts[self._primary].body if self._primary in self.crafts else None

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

    # --- the spacecraft --------------------------------------------------------------------
    def add_craft(self, name: str):
        """Spacecraft ``name`` (body frame ``<name>/<child_frame_id>``) in the first free
        display slot along x; returns it (the existing one if known)."""
        if name in self.crafts:
            return self.crafts[name]
        taken = {round(float(c.offset[0]) / (SLOT_SPACING * self.body_size))
                 for n, c in self.crafts.items() if n}
        slot = next(i for i in range(len(taken) + 1) if i not in taken)
        craft = Craft(name, f'{name}/{self.child_frame_id}',
                      (slot * SLOT_SPACING * self.body_size, 0.0, 0.0))
        self.crafts[name] = craft
        return craft

    def remove_craft(self, name: str, stamp_ns: int):
        """Take spacecraft ``name`` out: its entities are deleted from the scene."""
        craft = self.crafts.pop(name, None)
        if craft is None:
            return
        if self.scene.has_sinks():
            t = _time(stamp_ns)
            self.scene.log(SceneUpdate(deletions=[
                SceneEntityDeletion(timestamp=t, type=SceneEntityDeletionType.MatchingId, id=i)
                for i in craft.ids()]), log_time=stamp_ns)
        if name == self._primary:  # the Poinsot construction moves to the next one
            self._primary = next((n for n, c in self.crafts.items() if c.q is not None), '')
            self.reset()

    def drawn(self):
        """Names of the spacecraft drawn now (body and a state known)."""
        return [n for n, c in self.crafts.items() if c.body is not None and c.q is not None]

    def set_body(self, body, name: str = ''):
        """``body``: physics.body.RigidBody (principal moments and axes)."""
        craft = self.crafts.get(name) or self.add_craft(name)
        craft.body = body
        craft.box_edges, _ = geometry.display_box(body.principal_moments, self.body_size)
        # a thin plate has a zero edge: draw it 1 % thick so it stays visible
        craft.box_edges = np.maximum(craft.box_edges, 0.01 * self.body_size)

    def set_orbit(self, frame, name: str = ''):
        """The orbit's drawing (``orbit_view.OrbitFrame``) at spacecraft ``name``'s latest
        sample: drawn at the next scene update."""
        if name in self.crafts:
            self.crafts[name].orbit = frame

    # --- every sample ----------------------------------------------------------------------
    def transform(self, stamp_ns: int, q, name: str = ''):
        """``world`` → the body frame (q rotates body vectors into world), at its slot."""
        if not self.tf.has_sinks() or name not in self.crafts:
            return  # nobody subscribed and no MCAP: build nothing
        craft = self.crafts[name]
        self.tf.log(FrameTransform(timestamp=_time(stamp_ns), parent_frame_id=self.frame_id,
                                   child_frame_id=craft.frame,
                                   translation=_vec(craft.offset), rotation=_quat(q)),
                    log_time=stamp_ns)

    def _poinsot_frames(self, stamp_ns, q):
        """``world`` → ``poinsot`` (fixed, beside the body) → ``poinsot_body`` (the attitude),
        at the scene's rate: the Poinsot view moves with its entities."""
        t = _time(stamp_ns)
        offset = self.crafts[self._primary].offset + (0.0, 2.5 * self.body_size, 0.0)
        self.tf_poinsot.log(FrameTransforms(transforms=[
            FrameTransform(timestamp=t, parent_frame_id=self.frame_id,
                           child_frame_id=POINSOT_FRAME, translation=_vec(offset),
                           rotation=_quat((0.0, 0.0, 0.0, 1.0))),
            FrameTransform(timestamp=t, parent_frame_id=POINSOT_FRAME,
                           child_frame_id=POINSOT_BODY_FRAME, rotation=_quat(q))]),
            log_time=stamp_ns)

    def sample(self, stamp_ns: int, q, omega, target=None, name: str = ''):
        """One sample of spacecraft ``name``: q (body → world), ω (body, rad/s). The first
        drawn spacecraft's go to the plot channel now; the scene, of all, at ``scene_rate``.
        From the body: L = R(q)·Iω (world, kg·m²/s) and T = ½ ω·Iω (J)."""
        craft = self.crafts.get(name)
        if craft is None or craft.body is None:
            return
        q = np.asarray(q, float)
        omega = np.asarray(omega, float)
        craft.q, craft.omega = q, omega
        if self.crafts.get(self._primary) is None or self.crafts[self._primary].q is None:
            self._primary = name
            self.reset()
        if name == self._primary:
            self._primary_sample(stamp_ns, q, omega, target)
        if self.T0 is None:
            return  # the first body not sampled since a reset: no Poinsot scale yet
        if self.next_scene_ns is None or stamp_ns >= self.next_scene_ns:
            self.next_scene_ns = stamp_ns + self.scene_period_ns
            primary = self.crafts[self._primary]
            if self.tf_poinsot.has_sinks():
                self._poinsot_frames(stamp_ns, primary.q)
            if self.scene.has_sinks():
                self._scene(stamp_ns, primary)

    def _primary_sample(self, stamp_ns, q, omega, target):
        """The plot row and the Poinsot traces of the first drawn body."""
        body = self.body
        L_body = body.inertia @ omega
        L_world = geometry.rotate_vector(q, L_body)
        T = 0.5 * float(omega @ L_body)
        L = float(np.linalg.norm(L_world))
        if self.T0 is None:
            self.T0, self.L0 = T, L
            semi = geometry.ellipsoid_semi_axes(body.principal_moments, T)
            self.scale = self.body_size / semi.max() if semi.max() > 0 else 1.0
            min_step = 0.002 * self.body_size
            self.polhode.min_step = self.herpolhode.min_step = min_step
        self._T = T
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

    # --- the 3D scene ----------------------------------------------------------------------
    def _scene(self, stamp_ns, primary):
        """Every drawn spacecraft, the orbit's inset, and the first body's Poinsot
        construction (``poinsot_body``: the energy ellipsoid and the polhode; ``poinsot``:
        the invariable plane, the contact point and the herpolhode)."""
        b = ent.Builder(stamp_ns, self.body_size)
        size = self.body_size
        entities = []
        for craft in self.crafts.values():
            if craft.body is not None and craft.q is not None:
                entities += ent.craft_entities(b, craft, self.frame_id)
        if primary.orbit is not None:
            entities += ent.orbit_inset(b, primary, self.frame_id)
        q, omega, T = primary.q, primary.omega, self._T
        L_world = geometry.rotate_vector(q, primary.body.inertia @ omega)
        L_norm = float(np.linalg.norm(L_world))
        p2b = primary.body.principal_to_body
        semi = geometry.ellipsoid_semi_axes(primary.body.principal_moments, T) * self.scale
        entities.append(b.entity(POINSOT_BODY_FRAME, 'energy_ellipsoid', spheres=[b.sphere(
            (0.0, 0.0, 0.0), 2.0 * semi, (0.9, 0.8, 0.3, 0.35), orientation=p2b)]))
        # the traces even when (just after a reset) too short to draw: an entity left out of
        # an update would keep its old points on the client
        entities.append(b.entity(POINSOT_BODY_FRAME, 'polhode', lines=[b.line(
            self._points['polhode'], (1.0, 0.3, 0.2, 1.0))]))
        if L_norm > 0.0:
            normal, dist = geometry.invariable_plane(L_world, T)
            centre = normal * dist * self.scale
            plane = 3.0 * semi.max()
            entities.append(b.entity(POINSOT_FRAME, 'invariable_plane', cubes=[CubePrimitive(
                pose=Pose(position=_vec(centre),
                          orientation=_quat(geometry.plane_rotation(normal))),
                size=_vec((plane, plane, 0.002 * size)),
                color=ent.color(0.3, 0.6, 1.0, 0.25))]))
            entities.append(b.entity(POINSOT_FRAME, 'contact', spheres=[b.sphere(
                geometry.rotate_vector(q, omega) * self.scale, 0.05 * size,
                (1.0, 0.3, 0.2, 1.0))]))
            entities.append(b.entity(POINSOT_FRAME, 'herpolhode', lines=[b.line(
                self._points['herpolhode'], (0.2, 0.5, 1.0, 1.0))]))
        self.scene.log(SceneUpdate(entities=entities), log_time=stamp_ns)

    def publish_diagnostics(self, stamp_ns: int, cdr: bytes):
        """A DiagnosticArray as ROS 2 serialized it (CDR), forwarded untouched."""
        if self.diagnostics.has_sinks():
            self.diagnostics.log(cdr, log_time=stamp_ns)
