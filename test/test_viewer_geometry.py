"""The viewer's geometry (rigid_body_sim/viewer/geometry.py) against analytic values: the
inertia box, the energy ellipsoid, the invariable plane and Poinsot's rolling condition on
the exact torque-free motion."""
import numpy as np
import pytest

from rigid_body_sim.physics import rotation
from rigid_body_sim.physics.exact import TorqueFreeSolution
from rigid_body_sim.viewer import geometry

pytestmark = pytest.mark.fast  # make check


def test_box_edges_of_a_known_box():
    # a 1 × 2 × 3 m box of 12 kg: I = m(b² + c²)/12 ... = (13, 10, 5) kg·m²
    edges = geometry.box_edges((13.0, 10.0, 5.0), mass=12.0)
    np.testing.assert_allclose(edges, (1.0, 2.0, 3.0), rtol=1e-15)
    np.testing.assert_allclose(geometry.box_inertia(edges, 12.0), (13.0, 10.0, 5.0), rtol=1e-15)


def test_cube_and_thin_plate():
    # a cube of edge a: I = m a²/6 on every axis
    np.testing.assert_allclose(geometry.box_edges((1.0, 1.0, 1.0), 6.0), (1.0, 1.0, 1.0),
                               rtol=1e-15)
    # I₃ = I₁ + I₂ (the tennis racket's plate): no thickness along axis 3
    edges = geometry.box_edges((1.0, 2.0, 3.0), 1.0)
    assert edges[2] == 0.0
    np.testing.assert_allclose(edges[:2], (np.sqrt(24.0), np.sqrt(12.0)), rtol=1e-15)


def test_moments_violating_the_triangle_inequality_have_no_box():
    with pytest.raises(ValueError, match='triangle inequality'):
        geometry.box_edges((1.0, 1.0, 3.0))


@pytest.mark.parametrize('moments', [(0.04, 0.2, 0.2), (1.0, 2.0, 3.0), (8.0e37, 8.0e37, 8.03e37)])
def test_display_box_keeps_the_moments_up_to_mass(moments):
    edges, mass = geometry.display_box(moments, size=1.5)
    assert edges.max() == pytest.approx(1.5, rel=1e-15)
    np.testing.assert_allclose(geometry.box_inertia(edges, mass), moments, rtol=1e-12)


def test_invariable_plane_touches_the_energy_ellipsoid_at_omega():
    rng = np.random.default_rng(3)
    for _ in range(50):
        moments = np.sort(rng.uniform(0.5, 3.0, 3))
        if moments[0] + moments[1] < moments[2]:
            continue
        w = rng.normal(size=3)
        L = moments * w
        T = 0.5 * float(w @ L)
        semi = geometry.ellipsoid_semi_axes(moments, T)
        assert np.sum((w / semi) ** 2) == pytest.approx(1.0, rel=1e-13)   # ω on the ellipsoid
        normal, d = geometry.invariable_plane(L, T)
        assert float(w @ normal) == pytest.approx(d, rel=1e-13)           # ω on the plane
        # the ellipsoid's outward normal at ω, ∇(ω·Iω) = 2Iω, is the plane's: tangent
        grad = 2.0 * moments * w
        np.testing.assert_allclose(np.cross(grad, normal), 0.0, atol=1e-12 * np.linalg.norm(grad))


def test_at_rest_there_is_no_invariable_plane():
    with pytest.raises(ValueError, match='at rest'):
        geometry.invariable_plane((0.0, 0.0, 0.0), 0.0)


def test_herpolhode_stays_on_the_fixed_plane_in_the_exact_motion():
    moments = np.array([1.0, 2.0, 3.0])
    m0 = moments * np.array([0.05, 1.0, 0.2])             # near the intermediate axis
    sol = TorqueFreeSolution(moments, np.array([0.0, 0.0, 0.0, 1.0]), m0)
    t = np.linspace(0.0, 40.0, 801)                       # several flips
    q, m = sol.at(t)
    w = m / moments
    T = 0.5 * np.einsum('ni,ni->n', w, m)
    L_world = rotation.rotate(q, m)
    normal, d = geometry.invariable_plane(L_world[0], T[0])
    herpolhode = rotation.rotate(q, w)                    # the contact point, world frame
    np.testing.assert_allclose(herpolhode @ normal, d, rtol=1e-12)
    # and the polhode (body frame) stays on the energy ellipsoid
    semi = geometry.ellipsoid_semi_axes(moments, T[0])
    np.testing.assert_allclose(np.sum((geometry.polhode_point(w) / semi) ** 2, axis=1), 1.0,
                               rtol=1e-12)


@pytest.mark.parametrize('v', [(0, 0, 1), (0, 0, -1), (1, 2, 3), (-1, 1e-9, 0), (0, 1, 0)])
def test_plane_and_arrow_rotations(v):
    v = np.asarray(v, float)
    u = v / np.linalg.norm(v)
    np.testing.assert_allclose(rotation.rotate(geometry.plane_rotation(u), (0, 0, 1)), u,
                               atol=1e-15)
    np.testing.assert_allclose(rotation.rotate(geometry.arrow_rotation(3.0 * v), (1, 0, 0)), u,
                               atol=1e-15)
    np.testing.assert_allclose(rotation.rotate(geometry.arrow_rotation((-2.0, 0, 0)), (1, 0, 0)),
                               (-1, 0, 0), atol=1e-15)
    np.testing.assert_array_equal(geometry.arrow_rotation((0, 0, 0)), (0, 0, 0, 1))


def test_trace_keeps_the_last_points_in_order_and_skips_small_steps():
    trace = geometry.Trace(capacity=4, min_step=0.5)
    for x in (0.0, 0.1, 1.0, 2.0, 3.0, 3.2, 4.0, 5.0):
        trace.add((x, 0.0, 0.0))
    # 0.1 and 3.2 are within 0.5 of their predecessors; of the rest the last 4 remain
    np.testing.assert_array_equal(trace.ordered()[:, 0], (2.0, 3.0, 4.0, 5.0))
    trace.clear()
    assert trace.ordered().shape == (0, 3)


def test_rotate_vector_is_the_physics_rotation():
    rng = np.random.default_rng(5)
    for _ in range(100):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        v = rng.normal(size=3)
        np.testing.assert_allclose(geometry.rotate_vector(q, v), rotation.rotate(q, v),
                                   rtol=0, atol=1e-15 * 4 * np.linalg.norm(v))


def test_shipped_foxglove_layout_is_the_built_one_and_names_our_channels():
    import json
    from rigid_body_sim.viewer import layout, view
    with open(layout.PATH) as f:
        shipped = f.read()
    assert shipped == layout.text(), 'run python -m rigid_body_sim.viewer.layout'
    found = []

    def walk(node):
        if isinstance(node, dict):
            if node.get('panelType') == 'Plot':
                found.extend(p['value'] for p in node['config']['paths'])
            for v in node.values():
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)
    walk(json.loads(shipped))
    fields = set(view.STATE_SCHEMA['properties'])
    assert found and all(v.startswith('/state.') for v in found)
    assert {v.split('.')[1] for v in found} <= fields
    assert {'omega', 'kinetic_energy', 'angular_momentum_norm', 'pointing_error_deg'} <= \
        {v.split('.')[1] for v in found}


# --- the orbit's drawing (viewer/orbit_view.py) --------------------------------------------
def test_orbit_path_is_the_conic_over_one_period():
    """An ellipse (a = 8,000 km, e = 0.1): the path closes on the state it starts from,
    its radii span the perigee a(1 − e) and the apogee a(1 + e), and the apoapsis is drawn
    one body size from the Earth's centre, the Earth at the same scale."""
    from rigid_body_sim.physics.orbit import KeplerOrbit
    from rigid_body_sim.viewer import orbit_view
    a, e = 8.0e6, 0.1
    r, v = KeplerOrbit(a, e, 0.5, 0.3, 0.7, 1.1).state(0.0)
    frame = orbit_view.OrbitFrame(r, v, size=2.0)
    radii = np.linalg.norm(frame.path, axis=1)
    np.testing.assert_allclose(frame.path[0], r, rtol=1e-12)
    np.testing.assert_allclose(frame.path[-1], r, rtol=1e-9)
    assert radii.min() == pytest.approx(a * (1 - e), rel=1e-3)   # 180 points: near perigee
    assert radii.max() == pytest.approx(a * (1 + e), rel=1e-3)
    assert frame.scale * radii.max() == pytest.approx(2.0, rel=1e-15)
    assert frame.earth_radius == pytest.approx(6378137.0 * frame.scale, rel=1e-15)
    h = np.cross(r, v)
    np.testing.assert_allclose(frame.path @ h, 0.0, atol=1e-6 * a * np.linalg.norm(h))
    with pytest.raises(ValueError, match='closed orbit'):
        orbit_view.OrbitFrame(r, 3.0 * np.asarray(v))   # escape speed


def test_sim_time_of_a_stamp():
    """Stamps are the run's start plus sim time / real_time_factor, or sim time itself with
    publish_clock (nodes/simulator.py); one (stamp, sim time) pair and the slope date any."""
    from rigid_body_sim.viewer.orbit_view import SimTime
    t = SimTime()
    assert t(5) is None
    t.set(1_000_000_000_000, 20.0, 1000.0, publish_clock=False)
    assert t(1_000_000_000_000 + 10_000_000) == pytest.approx(30.0, rel=1e-15)
    t.set(20_000_000_000, 20.0, 1000.0, publish_clock=True)
    assert t(30_000_000_000) == pytest.approx(30.0, rel=1e-15)
    t.set(1_000_000_000_000, 20.0, 0.0, publish_clock=False)   # as fast as possible: 1
    assert t(1_001_000_000_000) == pytest.approx(21.0, rel=1e-15)


def test_environment_refuses_an_unknown_model_and_an_epoch_outside_the_field_model():
    from rigid_body_sim.viewer.orbit_view import Environment
    with pytest.raises(ValueError, match="'wmm' is not one of"):
        Environment(None, 'wmm')
    from datetime import datetime, timezone
    with pytest.raises(ValueError, match='outside the IGRF-14'):
        Environment(datetime(1850, 1, 1, tzinfo=timezone.utc))
    assert Environment().epoch.year == 2000   # no epoch: J2000


def test_dipole_field_drawn_is_the_physics_field():
    """The viewer's dipole (its moment kept for an hour of sim time) against
    physics.environment.magnetic_field over a 20,000 s run: within 1e-6 relative."""
    from rigid_body_sim.engine.environment_specs import parse_epoch
    from rigid_body_sim.physics.environment import magnetic_field
    from rigid_body_sim.physics.orbit import KeplerOrbit
    from rigid_body_sim.viewer.orbit_view import Environment
    orbit, epoch = KeplerOrbit(7.0e6, 0.01, 0.9, 0.2, 0.0, 0.0), '2026-03-20T12:00:00Z'
    env = Environment(parse_epoch(epoch), 'dipole')
    for t in np.linspace(0.0, 20000.0, 41):
        r, _ = orbit.state(t)
        want = magnetic_field.field('dipole', r, epoch, t)
        np.testing.assert_allclose(env.field(r, t), want, rtol=0,
                                   atol=1e-6 * np.linalg.norm(want))
