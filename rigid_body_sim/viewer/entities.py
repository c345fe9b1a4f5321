"""The Foxglove scene entities of one update: each spacecraft's box, arrows and label, and
its orbit's drawing (``orbit_view.OrbitFrame``). Built from plain numbers; ``view.py`` logs
them. All arrows point along their pose's +x (Foxglove's convention)."""
import numpy as np
from foxglove.messages import (ArrowPrimitive, Color, CubePrimitive, LinePrimitive, Point3,
                               Pose, Quaternion, SceneEntity, SpherePrimitive, TextPrimitive,
                               Timestamp, Vector3)

from . import geometry

IDENTITY = (0.0, 0.0, 0.0, 1.0)
LVLH_COLORS = ((1.0, 0.2, 0.2), (0.2, 0.9, 0.2), (0.3, 0.4, 1.0))  # x, y, z: as axes are
SUN_COLOR = (1.0, 0.85, 0.1)
FIELD_COLOR = (0.8, 0.3, 1.0)
INSET_OFFSET = (0.0, -2.5, 0.0)   # body sizes from the first body to the orbit's inset


def stamp(stamp_ns: int):
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return Timestamp(sec=sec, nsec=nsec)


def quat(q):
    return Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def vec(v):
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def point(p):
    return Point3(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def color(r, g, b, a=1.0):
    return Color(r=r, g=g, b=b, a=a)


class Builder:
    """Primitives at one stamp, sized by the body size ``size`` (m)."""

    def __init__(self, stamp_ns: int, size: float):
        self.t = stamp(stamp_ns)
        self.size = size

    def entity(self, frame, eid, **prims):
        return SceneEntity(timestamp=self.t, frame_id=frame, id=eid, frame_locked=True, **prims)

    def arrow(self, direction, length, rgb, at=(0.0, 0.0, 0.0)):
        d = float(np.linalg.norm(direction))
        return ArrowPrimitive(pose=Pose(position=vec(at),
                                        orientation=quat(geometry.arrow_rotation(direction))),
                              shaft_length=length * 0.8 if d else 0.0,
                              shaft_diameter=0.03 * self.size, head_length=length * 0.2,
                              head_diameter=0.08 * self.size, color=color(*rgb))

    def line(self, points, rgba):
        return LinePrimitive(thickness=0.01 * self.size, scale_invariant=False,
                             points=list(points), color=color(*rgba))

    def sphere(self, centre, diameter, rgba, orientation=IDENTITY):
        d = np.broadcast_to(np.asarray(diameter, float), (3,))
        return SpherePrimitive(pose=Pose(position=vec(centre), orientation=quat(orientation)),
                               size=vec(d), color=color(*rgba))


def craft_entities(b: Builder, craft, world: str):
    """Spacecraft ``craft`` (``view.Craft``, body and state known): its inertia box and ω
    in its body frame, L (world) at its slot, its name above it, and with an orbit the
    LVLH axes, the Sun's and the field's directions at it (world)."""
    size, p = b.size, craft.prefix
    origin = (0.0, 0.0, 0.0)
    q, omega = craft.q, craft.omega
    L_world = geometry.rotate_vector(q, craft.body.inertia @ omega)
    w_dir = omega / (np.linalg.norm(omega) or 1.0)
    out = [
        b.entity(craft.frame, p + 'body', cubes=[CubePrimitive(
            pose=Pose(position=vec(origin), orientation=quat(craft.body.principal_to_body)),
            size=vec(craft.box_edges), color=color(0.7, 0.7, 0.75, 0.9))]),
        b.entity(craft.frame, p + 'omega', arrows=[b.arrow(w_dir, 1.2 * size,
                                                           (1.0, 0.3, 0.2))]),
        b.entity(world, p + 'angular_momentum', arrows=[b.arrow(
            L_world, 1.2 * size, (0.2, 0.5, 1.0), at=craft.offset)]),
    ]
    if craft.name:
        out.append(b.entity(world, p + 'label', texts=[TextPrimitive(
            pose=Pose(position=vec(craft.offset + (0.0, 0.0, 1.0 * size)),
                      orientation=quat(IDENTITY)),
            billboard=True, font_size=0.2 * size, scale_invariant=False,
            color=color(1.0, 1.0, 1.0), text=craft.name)]))
    orbit = craft.orbit
    if orbit is not None:
        b = Builder(orbit.stamp_ns, size)  # stamped with the orbit sample they show
        out.append(b.entity(world, p + 'lvlh', arrows=[
            b.arrow(orbit.lvlh[:, k], 1.0 * size, LVLH_COLORS[k], at=craft.offset)
            for k in range(3)]))
        if orbit.sun is not None:
            out.append(b.entity(world, p + 'sun', arrows=[b.arrow(
                orbit.sun, 1.5 * size, SUN_COLOR, at=craft.offset)]))
        if orbit.field is not None:
            out.append(b.entity(world, p + 'magnetic_field', arrows=[b.arrow(
                orbit.field, 1.5 * size, FIELD_COLOR, at=craft.offset)]))
    return out


def orbit_inset(b: Builder, craft, world: str):
    """The orbit of ``craft`` in an inset beside it (axes parallel to world, the Earth at
    its centre): the Earth, the path over one period, the spacecraft's position, and the
    Sun's direction from the Earth. Scaled so that the apoapsis is one body size out;
    stamped with the orbit sample they show."""
    orbit = craft.orbit
    b = Builder(orbit.stamp_ns, b.size)
    centre = craft.offset + np.asarray(INSET_OFFSET) * b.size
    s = orbit.scale
    out = [
        b.entity(world, 'earth', spheres=[b.sphere(centre, 2.0 * orbit.earth_radius,
                                                   (0.2, 0.4, 0.9, 0.8))]),
        b.entity(world, 'orbit_path', lines=[b.line(
            [point(centre + s * r) for r in orbit.path], (1.0, 1.0, 1.0, 0.8))]),
        b.entity(world, 'orbit_position', spheres=[b.sphere(
            centre + s * orbit.r, 0.06 * b.size, (1.0, 0.3, 0.2, 1.0))]),
    ]
    if orbit.sun is not None:
        out.append(b.entity(world, 'orbit_sun', arrows=[b.arrow(
            orbit.sun, 1.3 * b.size, SUN_COLOR, at=centre)]))
    return out
