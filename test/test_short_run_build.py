"""The fixed costs of a short offline run (issue 29: a run of ~400 samples cost ~1 ms, of
which the physics ~0.25 ms): building its config and body and converting its end rows
take the cheap path where the result cannot differ, and the same values come out."""
import struct

import numpy as np
import pytest

from rigid_body_sim import param_spec
from rigid_body_sim.engine import specs
from rigid_body_sim.engine.samples import SampleBlock
from rigid_body_sim.param_spec import ParamSpec, coerce_all
from rigid_body_sim.physics import RigidBody, rotation

pytestmark = pytest.mark.fast  # make check


def _bits(value):
    return [struct.pack('<d', float(x)) for x in np.ravel(value)]


def test_a_scene_dicts_defaults_are_not_coerced_again(monkeypatch):
    """A dict coerce_all made holds the spec's default object for every key not given;
    coercing it again (building a run from a scene) skips those (70 of 90 keys) and gives
    the same dict; a given value is still coerced and checked."""
    scene = coerce_all(specs.SIMULATOR, {'inertia': [1, 2, 2.5], 'duration': 3,
                                         'initial_angular_velocity': [0.1, 0.0, 2.0]})
    calls = []
    coerce = ParamSpec.coerce

    def counted(self, v):
        calls.append(self.name)
        return coerce(self, v)
    monkeypatch.setattr(ParamSpec, 'coerce', counted)
    again = coerce_all(specs.SIMULATOR, scene)
    assert sorted(calls) == ['duration', 'inertia', 'initial_angular_velocity']
    assert again == scene
    assert type(again['duration']) is float and again['inertia'] == [1.0, 2.0, 2.5]
    # a value equal to the default but not the default object is checked as given
    calls.clear()
    assert coerce_all(specs.SIMULATOR, {'step': 0.001})['step'] == 0.001
    assert calls == ['step']
    with pytest.raises(ValueError, match='step'):
        coerce_all(specs.SIMULATOR, {**scene, 'step': -1.0})


def test_a_scalar_default_that_coerces_to_a_list_is_still_coerced():
    """A scalar_ok spec's default is a number that coerce makes a list: given as the
    default object, it comes out as coerce makes it, as before."""
    spec = next(s for s in specs.CONTROLLER if s.scalar_ok)
    out = coerce_all(specs.CONTROLLER, {spec.name: spec.default})
    assert out[spec.name] == spec.coerce(spec.default)
    assert isinstance(out[spec.name], list)


def test_plain_numbers_skip_the_abc_check(monkeypatch):
    """float and int (a params file's numbers) are numbers without isinstance against the
    Real ABC (~1 µs each, ~90 a run); numpy's and bool keep their answers."""
    asked = []

    class Counting(type):
        def __instancecheck__(cls, v):
            asked.append(v)
            return isinstance(v, (int, float, np.floating, np.integer))

    monkeypatch.setattr(param_spec, 'Real', Counting('Real', (), {}))
    assert param_spec._is_number(1.5) and param_spec._is_number(3)
    assert asked == []
    assert param_spec._is_number(np.float32(2.0)) and asked
    assert not param_spec._is_number(True)


def test_a_diagonal_body_takes_the_identity_without_from_matrix(monkeypatch):
    """Moments given as a diagonal: principal frame = body frame, quaternion (0, 0, 0, 1)
    to the bit of from_matrix's (which costs a determinant, an allclose and Shepperd's
    choice); a rotated tensor still goes through it."""
    identity = rotation.from_matrix(np.eye(3))
    calls = []
    from_matrix = rotation.from_matrix

    def counted(m):
        calls.append(m)
        return from_matrix(m)
    monkeypatch.setattr(rotation, 'from_matrix', counted)
    for inertia in ([2.46, 1.07, 2.40], [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]):
        body = RigidBody.from_inertia(inertia)
        assert _bits(body.principal_to_body) == _bits(identity)
        assert not body.principal_to_body.flags.writeable
        np.testing.assert_array_equal(body.principal_axes, np.eye(3))
    assert calls == []
    m = np.array([[0.6, -0.8, 0.0], [0.8, 0.6, 0.0], [0.0, 0.0, 1.0]])
    body = RigidBody.from_inertia(m @ np.diag([1.0, 2.0, 2.5]) @ m.T)
    assert len(calls) == 1
    assert _bits(body.principal_to_body) == _bits(from_matrix(body.principal_axes))


def test_a_nearly_symmetric_tensor_is_still_accepted_and_an_asymmetric_refused():
    """The exact-symmetry shortcut leaves the tolerance to allclose."""
    t = np.array([[2.0, 0.1, 0.0], [0.1 + 1e-12, 2.0, 0.0], [0.0, 0.0, 3.0]])
    assert RigidBody.from_inertia(t).principal_moments.min() > 0
    with pytest.raises(ValueError, match='not symmetric'):
        RigidBody.from_inertia([[2.0, 0.5, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]])


def test_absent_actuators_are_not_converted(monkeypatch):
    """No wheels, no CMGs (most scenes): their one-value parameters need no numpy
    conversion; a wrong count of values is still refused, naming the parameter."""
    from rigid_body_sim.engine import actuator_specs
    converted = []
    asarray = np.asarray

    def counted(*a, **kw):
        converted.append(a[0])
        return asarray(*a, **kw)
    monkeypatch.setattr(actuator_specs.np, 'asarray', counted)
    p = coerce_all(specs.SIMULATOR, {})
    assert actuator_specs.ActuatorConfig.from_parameters(p) is None
    assert converted == []
    assert actuator_specs._per([0.5], 0, 'x').shape == (0,)
    with pytest.raises(ValueError, match='actuators.wheels.inertia needs 1 or 0'):
        actuator_specs.ActuatorConfig.from_parameters(
            {**p, 'actuators.wheels.inertia': [0.01, 0.02]})


@pytest.mark.parametrize('scene', ['tennis_racket', 'slew', 'explorer1'])
def test_a_run_in_one_block_converts_its_two_end_rows_in_one_pass(scene, monkeypatch):
    """A run that keeps every sample (one block) converts its first and last rows to the
    user's frames in one pass over both (each pass ~60 µs of numpy calls, a tenth of a
    short run), to the very bits of each row converted alone (the old path)."""
    from rigid_body_sim.offline import simulate
    from rigid_body_sim.scene import load
    sizes = []
    to_body = RigidBody.attitude_to_body

    def counted(self, q):
        sizes.append(len(q))
        return to_body(self, q)
    monkeypatch.setattr(RigidBody, 'attitude_to_body', counted)
    result = simulate(load(scene, ['publish_rate=20.0']), duration=2.37)
    assert sizes[-1:] == [2] and sizes.count(1) == 0
    monkeypatch.undo()
    b = result.samples
    for i, got in ((0, result.initial), (len(b) - 1, result.final)):
        alone = SampleBlock(b.t_ns, b.q, b.m, b.torque, b.body).take(slice(i, i + 1)).row(0)
        for key, value in alone.items():
            assert _bits(got[key]) == _bits(value), (scene, i, key)
    assert result.final['t_ns'] == int(round(2.37e9))


def test_a_free_exact_stretch_takes_its_instants_in_one_compiled_pass(monkeypatch):
    """A torque-free exact stretch's sample instants and their times from its anchor
    come from one compiled pass (sample_kernel.grid_instants), where numpy's arange,
    multiply, add, subtract and divide over the stretch cost ~3 ns a sample of a ~40 ns
    one; the numbers are numpy's to the bit, far from t = 0 too."""
    from rigid_body_sim.engine import sample_kernel, stepping
    from rigid_body_sim.offline import simulate
    from rigid_body_sim.scene import load

    class NoArange:
        def __getattr__(self, name):
            if name == 'arange':
                raise AssertionError('numpy arange over the stretch')
            return getattr(np, name)
    monkeypatch.setattr(stepping, 'np', NoArange())
    result = simulate(load('tennis_racket', ['publish_rate=100.0']), duration=3.37,
                      integrator='exact')
    assert result.integrator == 'exact' and result.sample_count == 338
    np.testing.assert_array_equal(np.diff(result.samples.t_ns[:-1]), 10_000_000)
    assert result.samples.t_ns[-1] == 3_370_000_000
    for first, period, anchor in ((10_000_000, 10_000_000, 3_000_000),
                                  (86_400_000_000_123, 1_000_003, 86_000_000_000_007)):
        t_ns, ts = np.empty(3000, np.int64), np.empty(3000)
        sample_kernel.grid_instants(first, period, anchor, t_ns, ts)
        times = first + period * np.arange(3000, dtype=np.int64)
        np.testing.assert_array_equal(t_ns, times)
        assert _bits(ts) == _bits((times - anchor) / 1_000_000_000)
