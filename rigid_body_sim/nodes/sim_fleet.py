"""The simulator node's spacecraft: which it runs, their values, adding and removing them,
and commands on the node's own topics routed to them. A mixin of the node
(``simulator.py``); ``engine/fleet.py`` says how a scene declares them, ``spacecraft.py``
what one is."""
from ..engine import NS, fleet, lockstep
from ..engine.config import seconds_to_ns
from ..scene import SceneError
from .spacecraft import Spacecraft, check_parameters as check_craft
from .usage import ros_arguments


def check_parameters(p, names=None):
    """Validate a full set of coerced node values (frames, inertia, ...) and those of each
    spacecraft of ``names`` (default: the scene's); ValueError(reason, naming the
    spacecraft)."""
    names = [n for n in p.get('spacecraft', []) if n] if names is None else names
    config = check_craft(fleet.node_values(p))
    for name in names:
        try:
            check_craft(fleet.craft_values(p, name))
        except ValueError as exc:
            raise ValueError(f'spacecraft {name}: {exc}') from None
    return config


class Fleet:
    """Spacecraft management for :class:`~rigid_body_sim.nodes.simulator.Simulator`."""

    def _declared_names(self):
        """The scene's spacecraft (``spacecraft``), read before anything is declared: their
        keys are declared with the node's. ValueError naming a bad one."""
        given = getattr(self, '_parameter_overrides', {}).get('spacecraft')
        names = [] if given is None else given.value
        if isinstance(names, str) or not all(isinstance(n, str) for n in names or []):
            raise SceneError(f'parameter spacecraft: a list of names, got {names!r}')
        return fleet.check_names([n for n in names or [] if n])

    def _check(self, p):
        """The on-set check: the node's values and every running spacecraft's."""
        check_parameters(p, [])
        for name in self._crafts:
            try:
                check_craft(self._values(name, p))
            except ValueError as exc:
                raise ValueError(f'spacecraft {name}: {exc}' if name else str(exc)) from None

    def _values(self, name, p=None):
        """Spacecraft ``name``'s simulator values: the scene's, or those it was spawned with."""
        values = fleet.craft_values(self._p if p is None else p, name)
        values.update(self._spawned.get(name, {}))
        return values

    def _sample_period(self) -> int:
        return seconds_to_ns(1.0 / self._p['publish_rate'], 'sample period')

    def _add(self, name, start_ns, own=None):
        """Build spacecraft ``name`` at sim time ``start_ns`` (``own``: its values when
        spawned); ValueError (nothing added) if its values are bad."""
        if own is not None:
            self._spawned[name] = own
        try:
            values = self._values(name)
            # lockstep: its controller's values from the params files, in its namespace
            controller = None if not values['lockstep'] else self._controller_values \
                if not name else lockstep.controller_values(
                    ros_arguments()[0], f'{self.get_namespace().rstrip("/")}/{name}')
            craft = Spacecraft(self, name, values, start_ns, tf=self._tf_pub,
                               qos=self._qos, state_qos=self._state_qos,
                               on_command=self._on_command, on_actuator=self._on_actuator,
                               controller=controller, ready=self._actuators_ready)
            craft.awaited = lockstep.awaited(values, craft.dipoles is not None, controller)
        except ValueError as exc:
            self._spawned.pop(name, None)
            raise ValueError(f'spacecraft {name}: {exc}' if name else str(exc)) from None
        for note in craft.notes:
            self._log.info(f'{craft.prefix}{note}')
        self._crafts[name] = craft
        craft.refresh()
        return craft

    def _remove(self, name):
        """Take spacecraft ``name`` out; the simulation runs on, empty if it was the last."""
        if len(self._crafts) == 1:
            self._idle_ns = self.t_ns
        craft = self._crafts.pop(name)
        self._spawned.pop(name, None)
        craft.destroy(self)
        self._forget_lockstep(name)

    @property
    def crafts(self):
        """The spacecraft now, in the order they came (a list)."""
        return list(self._crafts.values())

    @property
    def lockstep(self) -> bool:
        return bool(self._lockstep)

    def spawn(self, name, own):
        """A new spacecraft ``name`` with its values ``own`` (BODY_KEYS), from now;
        ValueError naming the problem (nothing changed)."""
        self._catch_up()  # what was due runs first: the new one starts at the present
        craft = self._add(name, self.t_ns, own)
        self._log.info(f'spacecraft {name} spawned at t = {craft.engine.t:.6g} s '
                       f'({len(self._crafts)} running)')
        self._publish_diagnostics()
        return craft

    def delete(self, craft):
        """Take ``craft`` out of the simulation (its topics leave the graph)."""
        self._catch_up()
        self._remove(craft.name)
        self._clear_fault()  # the one that failed deleted: the others run on
        self._log.info(f'spacecraft {craft.entity} deleted at t = {self.t_ns / NS:.6g} s ('
                       f'{len(self._crafts) or "none"} left'
                       + (': the simulation runs on, empty)' if not self._crafts else ')'))
        self._publish_diagnostics()

    def _route(self, header, vector, source):
        """A command on the node's own topic: for the spacecraft whose body frame its
        frame_id names, else for the unnamed one (which checks the frame as always); with
        neither, counted and rejected (``unknown_spacecraft``)."""
        frame = header.frame_id.lstrip('/')
        craft = next((c for c in self._crafts.values() if c.name and frame == c.frames[1]),
                     self._crafts.get(''))
        if craft is not None:
            return self._on_command(craft, header, vector, source)
        names = ', '.join(c.frames[1] for c in self._crafts.values()) or 'none: all deleted'
        self._commands.reject('unknown_spacecraft', source, f'frame_id {header.frame_id!r} '
                              f'is no spacecraft\'s body frame (they are: {names})')

    def restore_scene(self):
        """The scene's spacecraft again: the spawned ones removed, deleted ones of the scene
        back in their initial state (from now); a text saying what changed."""
        self._catch_up()
        removed = [c.entity for c in self.crafts if c.name in self._spawned]
        for craft in self.crafts:
            if craft.name in self._spawned:
                self._remove(craft.name)
        back = [n for n in self._scene_names if n not in self._crafts]
        for name in back:
            self._add(name, self.t_ns)
        self._crafts = {n: self._crafts[n] for n in self._scene_names}
        text = (f'removed {", ".join(removed) or "nothing spawned"}'
                + (f'; back: {", ".join(back)}' if back else ''))
        self._log.info(f'the scene\'s spacecraft again: {text}')
        return text

