"""The simulator's entities for simulation_interfaces: its spacecraft and their actuators.

* Each spacecraft (category ROBOT, tag ``spacecraft``): named after ``child_frame_id``
  when it is the unnamed one of a scene without ``spacecraft``, else by its name. Its
  state: the attitude in ``frame_id`` and the angular velocity in ``frame_id`` (or in its
  body frame when the request names that frame); position stays zero.
* Each reaction wheel, ``<spacecraft>/<joint name>`` (the joint names of
  ``wheel_states``; category DYNAMIC_OBJECT, tags ``actuator``, ``reaction_wheel``). Its
  state is in the body frame: orientation identity (the wheel's spin angle is not
  simulated: it changes no torque) and angular velocity the wheel's speed relative to the
  body along its spin axis, in rad/s.
* Each CMG, ``<spacecraft>/<gimbal joint name>`` (tags ``actuator``, ``cmg``): in the
  body frame, the orientation is the rotation by the gimbal angle about the gimbal axis
  (identity at the scene's zero angle) and the angular velocity is the gimbal rate along
  that axis.

Pure functions of the spacecraft's engines (``nodes/spacecraft.py``: ``entity``,
``engine``): the services (``sim_services``) turn them into messages.
"""
import re
from typing import List, NamedTuple, Optional, Tuple

import numpy as np

from ..physics import rotation

ROBOT, DYNAMIC_OBJECT = 1, 4  # simulation_interfaces EntityCategory values
BODY, WHEEL, CMG = 'body', 'wheel', 'cmg'


class Entity(NamedTuple):
    name: str
    kind: str          # BODY | WHEEL | CMG
    index: int         # wheel or CMG index (0 for the body)
    category: int
    description: str
    tags: Tuple[str, ...]
    craft: object      # the spacecraft it belongs to (nodes/spacecraft.py)


def entities(crafts) -> List[Entity]:
    """The entities now: each spacecraft, then its wheels, then its CMGs."""
    out = []
    for craft in crafts:
        body = craft.entity
        out.append(Entity(body, BODY, 0, ROBOT, 'spacecraft (rigid body); pose: attitude',
                          ('spacecraft',), craft))
        a = craft.engine.config.actuators
        if a is None:
            continue
        out += [Entity(f'{body}/{n}', WHEEL, i, DYNAMIC_OBJECT,
                       'reaction wheel; twist: speed relative to the body about its spin '
                       'axis (body frame)', ('actuator', 'reaction_wheel'), craft)
                for i, n in enumerate(a.wheel_names)]
        out += [Entity(f'{body}/{n}', CMG, i, DYNAMIC_OBJECT,
                       'control moment gyro; pose: gimbal angle about the gimbal axis, '
                       'twist: gimbal rate (body frame)', ('actuator', 'cmg'), craft)
                for i, n in enumerate(a.cmg_names)]
    return out


def find(crafts, name: str) -> Optional[Entity]:
    """The entity called ``name`` (a leading ``/`` is ignored), or None."""
    name = name[1:] if name.startswith('/') else name
    return next((e for e in entities(crafts) if e.name == name), None)


def matching(crafts, pattern: str, categories, tags, all_tags: bool):
    """Entities whose name matches the regular expression ``pattern`` (searched, as POSIX
    regexec does; empty: all), whose category is one of ``categories`` (empty: any) and
    which carry any (``all_tags``: all) of ``tags`` (empty: no tag filter). ValueError
    naming the pattern if it is not a valid expression."""
    try:
        regex = re.compile(pattern) if pattern else None
    except re.error as exc:
        raise ValueError(f'filter {pattern!r} is not a valid regular expression: {exc}') \
            from None
    wanted = set(tags)
    out = []
    for e in entities(crafts):
        if regex is not None and not regex.search(e.name):
            continue
        if categories and e.category not in categories:
            continue
        if wanted and not (wanted <= set(e.tags) if all_tags else wanted & set(e.tags)):
            continue
        out.append(e)
    return out


def state(entity: Entity, body_frame_twist: bool = False):
    """(frame, attitude (x, y, z, w), angular velocity (3,)) of ``entity`` now: the body's
    in the inertial frame (``frame`` None), or with the twist in the body frame when
    ``body_frame_twist``; an actuator's in the body frame (``frame`` 'body')."""
    engine = entity.craft.engine
    if entity.kind == BODY:
        q, w = engine.attitude, engine.angular_velocity
        return ('body' if body_frame_twist else None), q, (w if body_frame_twist else
                                                           rotation.rotate(q, w))
    a = engine.config.actuators
    _, m = engine.principal_state
    row = engine.actuators.row(m, engine.body.principal_moments)
    n = a.wheels
    if entity.kind == WHEEL:
        return 'body', np.array([0.0, 0.0, 0.0, 1.0]), a.axes[entity.index] * row[entity.index]
    k = a.cmgs
    angle, rate = row[2 * n + entity.index], row[2 * n + k + entity.index]
    axis = a.gimbal[entity.index]
    q = np.concatenate((axis * np.sin(angle / 2), [np.cos(angle / 2)]))
    return 'body', q, axis * rate
