"""Dispersions are data: which scene parameters vary, how, and one draw per run.

A dispersion is ``KEY=DIST:SPREAD`` (the ``--disperse`` option, or ``KEY: DIST:SPREAD`` in
a YAML file's ``dispersions:`` mapping):

* ``normal:SIGMA`` — value + N(0, SIGMA²) per component;
* ``uniform:HALFWIDTH`` — value + U(−HALFWIDTH, HALFWIDTH) per component;
* a trailing ``%`` makes the spread relative to the scene's value, component by component
  (``inertia=uniform:5%`` moves each principal moment by up to 5 % of itself).

KEY is a parameter name of the scene's nodes, as ``--set`` takes it; it is dispersed in
every node that declares it, as ``--set`` applies it (``inertia`` moves the simulated body
and the controller's model of it together). A 9-value inertia tensor is dispersed on its
six independent components and kept symmetric.

A draw that the scene would refuse — an inertia that is not positive definite or violates
the triangle inequality, a gain out of its range — is never clipped: with ``redraw`` the
whole draw is repeated (up to :data:`MAX_DRAWS` times, the count kept in the run's row),
with ``reject`` the run is a failed row naming the reason.
"""
import math
from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple

import numpy as np

from ..scene import SceneError, SceneFile

DISTRIBUTIONS = ('normal', 'uniform')
POLICIES = ('redraw', 'reject')
MAX_DRAWS = 1000


class DrawRejected(ValueError):
    """No acceptable draw: ``attempts`` draws were refused, the last for ``reason``."""

    def __init__(self, attempts: int, reason: str):
        super().__init__(f'{attempts} draw(s) refused; last: {reason}')
        self.attempts, self.reason = attempts, reason


@dataclass(frozen=True)
class Dispersion:
    """One dispersed parameter: ``distribution`` around the scene's value with ``spread``
    (σ for normal, half-width for uniform), relative to the value when ``relative``."""
    key: str
    distribution: str
    spread: float
    relative: bool = False

    @property
    def text(self) -> str:
        spread = f'{self.spread * 100:g}%' if self.relative else f'{self.spread:g}'
        return f'{self.key}={self.distribution}:{spread}'


def parse(text: str) -> Dispersion:
    """``KEY=normal:SIGMA`` / ``KEY=uniform:HALFWIDTH[%]`` → Dispersion; ValueError naming
    the text and what is wrong."""
    key, sep, rule = text.partition('=')
    key = key.strip()
    if not sep or not key:
        raise ValueError(f'--disperse {text}: expected KEY=DIST:SPREAD, e.g. '
                         'inertia=uniform:5% or initial_angular_velocity=normal:0.2')
    return parse_rule(key, rule, f'--disperse {text}')


def parse_rule(key: str, rule, where: str) -> Dispersion:
    dist, sep, spread = str(rule).strip().partition(':')
    dist = dist.strip().lower()
    if not sep or dist not in DISTRIBUTIONS:
        raise ValueError(f'{where}: distribution must be one of {", ".join(DISTRIBUTIONS)} '
                         f'followed by :SPREAD, got {rule!r}')
    spread = spread.strip()
    relative = spread.endswith('%')
    try:
        value = float(spread[:-1] if relative else spread)
    except ValueError:
        raise ValueError(f'{where}: spread must be a number (optionally with %), '
                         f'got {spread!r}') from None
    if not math.isfinite(value) or value < 0:
        raise ValueError(f'{where}: spread must be finite and >= 0, got {spread!r}')
    return Dispersion(key, dist, value / 100 if relative else value, relative)


def load_file(path: str) -> Tuple[List[Dispersion], dict]:
    """A YAML file: ``dispersions: {KEY: DIST:SPREAD, ...}`` and optionally ``runs``,
    ``seed``. Returns (dispersions, {'runs': .., 'seed': ..} given in the file)."""
    import yaml
    try:
        with open(path, encoding='utf-8') as f:
            doc = yaml.safe_load(f)
    except OSError as exc:
        raise ValueError(f'{path}: cannot read: {exc.strerror}') from None
    except yaml.YAMLError as exc:
        raise ValueError(f'{path}: not valid YAML: {exc}') from None
    if not isinstance(doc, dict) or not isinstance(doc.get('dispersions'), dict):
        raise ValueError(f'{path}: expected a mapping with a "dispersions:" mapping of '
                         'KEY: DIST:SPREAD (e.g. inertia: uniform:5%)')
    unknown = set(doc) - {'dispersions', 'runs', 'seed'}
    if unknown:
        raise ValueError(f'{path}: unknown top-level key(s) {sorted(unknown)}; '
                         'allowed: dispersions, runs, seed')
    out = [parse_rule(str(k), v, f'{path}: dispersions: {k}')
           for k, v in doc['dispersions'].items()]
    extra = {}
    for name in ('runs', 'seed'):
        if name in doc:
            low, high = (1, 10 ** 9) if name == 'runs' else (0, 2 ** 63 - 1)
            v = doc[name]
            if not isinstance(v, int) or isinstance(v, bool) or not low <= v <= high:
                raise ValueError(f'{path}: {name} must be an integer in [{low}, {high}], '
                                 f'got {v!r}')
            extra[name] = doc[name]
    return out, extra


def nominal(scene: SceneFile, key: str):
    """The scene's value of ``key`` (the simulator's if both nodes declare it)."""
    if key in scene.simulator:
        return scene.simulator[key]
    return scene.controller[key]


def check_keys(scene: SceneFile, dispersions: Sequence[Dispersion], namespace='/') -> None:
    """SceneError for a key the scene's nodes do not have (naming the closest, as ``--set``
    does: the check is scene.load's) or a value that is not numeric."""
    from ..scene import load
    seen = set()
    for d in dispersions:
        if d.key in seen:
            raise SceneError(f'--disperse {d.key}: given twice')
        seen.add(d.key)
        probe = f'{d.key}={_text(nominal(scene, d.key))}' if d.key in scene.simulator \
            or d.key in scene.controller else f'{d.key}=0'
        try:
            load(scene.path, [probe], namespace)  # the key check of --set, closest name
        except SceneError as exc:
            raise SceneError(str(exc).replace(f'--set {probe}', f'--disperse {d.text}', 1)) \
                from None
        value = nominal(scene, d.key)
        if isinstance(value, bool) or not isinstance(value, (int, float, list, tuple)):
            raise SceneError(f'--disperse {d.text}: {d.key} is not numeric '
                             f'(scene value {value!r})')


def _text(value) -> str:
    return '[' + ','.join(repr(float(v)) for v in value) + ']' if isinstance(
        value, (list, tuple)) else repr(value)


def columns(scene: SceneFile, dispersions: Sequence[Dispersion]) -> List[str]:
    """Column names of the dispersed values: ``key`` for a scalar, ``key[i]`` per component."""
    out = []
    for d in dispersions:
        value = nominal(scene, d.key)
        out += [d.key] if not isinstance(value, (list, tuple)) else \
            [f'{d.key}[{i}]' for i in range(len(value))]
    return out


def _draw_one(d: Dispersion, value, rng: np.random.Generator):
    base = np.atleast_1d(np.asarray(value, float))
    tensor = d.key == 'inertia' and base.size == 9
    # a tensor moves on its 6 independent components and stays symmetric
    free = base.reshape(3, 3)[np.triu_indices(3)] if tensor else base
    scale = d.spread * np.abs(free) if d.relative else np.full(free.shape, d.spread)
    if d.distribution == 'normal':
        moved = free + scale * rng.standard_normal(free.size)
    else:
        moved = free + scale * rng.uniform(-1.0, 1.0, free.size)
    if tensor:
        m = np.zeros((3, 3))
        m[np.triu_indices(3)] = moved
        moved = (m + np.triu(m, 1).T).ravel()
    return moved.tolist() if isinstance(value, (list, tuple)) else float(moved[0])


def apply(scene: SceneFile, values: Dict[str, object]) -> SceneFile:
    """``scene`` with ``values`` replacing its parameters in every node that declares them,
    validated as scene.load validates (the nodes' specs, then the engine's config).
    ValueError naming the parameter and the reason."""
    from ..engine import EngineConfig, specs
    from ..param_spec import coerce_all
    sim, ctl = dict(scene.simulator), dict(scene.controller)
    for key, value in values.items():
        for node in (sim, ctl):
            if key in node:
                node[key] = value
    sim = coerce_all(specs.SIMULATOR, sim)
    ctl = coerce_all(specs.CONTROLLER, ctl) if scene.controlled else {}
    EngineConfig.from_parameters(sim, ctl or None)
    return SceneFile(scene.name, scene.description, scene.path, sim, ctl)


def draw(scene: SceneFile, dispersions: Sequence[Dispersion], rng: np.random.Generator,
         policy: str = 'redraw') -> Tuple[Dict[str, object], SceneFile, int]:
    """One run's values: (values by key, the scene with them, refused draws before it).
    DrawRejected when the policy is ``reject`` and the first draw is refused, or after
    MAX_DRAWS refused draws."""
    for attempt in range(MAX_DRAWS):
        values = {d.key: _draw_one(d, nominal(scene, d.key), rng) for d in dispersions}
        try:
            return values, apply(scene, values), attempt
        except ValueError as exc:
            reason = str(exc)
            if policy == 'reject':
                raise DrawRejected(attempt + 1, reason) from None
    raise DrawRejected(MAX_DRAWS, reason)


def flatten(scene: SceneFile, dispersions: Sequence[Dispersion], values) -> Dict[str, float]:
    """Values by column name (see :func:`columns`); NaN where a run has no draw."""
    out = {}
    for d in dispersions:
        v = values.get(d.key) if values else None
        if isinstance(nominal(scene, d.key), (list, tuple)):
            n = len(nominal(scene, d.key))
            comps = v if v is not None else [math.nan] * n
            out.update({f'{d.key}[{i}]': float(c) for i, c in enumerate(comps)})
        else:
            out[d.key] = float(v) if v is not None else math.nan
    return out
