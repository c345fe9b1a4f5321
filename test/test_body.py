"""Body validation, principal axes, and the user-frame propagator."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rigid_body_sim.physics import Dissipation, Propagator, RigidBody, poinsot, rotation

pytestmark = pytest.mark.fast  # make check


@pytest.mark.parametrize('inertia,message', [
    ([1.0, 2.0], 'needs 3 principal moments or 9'),
    ([1.0, float('nan'), 2.0], 'not finite'),
    ([[1, 0.5, 0], [0, 1, 0], [0, 0, 1]], 'not symmetric'),
    ([1.0, -2.0, 2.0], 'not positive definite'),
    ([1.0, 1.0, 3.0], 'triangle inequality'),
    ([0.0, 0.0, 0.0], 'not positive definite'),
])
def test_invalid_inertia_is_a_clear_error(inertia, message):
    with pytest.raises(ValueError, match=message):
        RigidBody.from_inertia(inertia)


def test_thin_plate_on_the_triangle_boundary_is_accepted():
    body = RigidBody.from_inertia([1.0, 2.0, 3.0])  # I1 + I2 = I3: a flat plate
    assert np.allclose(body.principal_moments, [1, 2, 3])


def test_full_tensor_is_diagonalised_into_a_proper_rotation():
    r = Rotation.from_euler('xyz', [0.3, -0.7, 1.1])
    tensor = r.as_matrix() @ np.diag([1.0, 2.0, 3.0]) @ r.as_matrix().T
    body = RigidBody.from_inertia(tensor.ravel())
    assert np.allclose(body.principal_moments, [1, 2, 3], atol=1e-12)
    assert np.linalg.det(body.principal_axes) == pytest.approx(1.0)
    axes = body.principal_axes
    assert np.allclose(axes @ np.diag(body.principal_moments) @ axes.T, tensor, atol=1e-12)


@pytest.mark.parametrize('integrator', ['splitting4', 'exact', 'rk4'])
def test_rotated_body_moves_like_its_principal_twin(integrator):
    """A body given by a non-diagonal tensor = its principal twin seen through the fixed
    rotation R."""
    r = Rotation.from_euler('zyx', [0.4, 0.2, -0.9])
    R = r.as_matrix()
    tensor = R @ np.diag([1.0, 2.0, 3.0]) @ R.T  # body frame b = R · principal frame
    w_principal = np.array([0.2, 1.0, 0.3])
    q_principal = Rotation.from_euler('x', 0.3).as_quat()
    twin = Propagator(RigidBody.from_inertia([1.0, 2.0, 3.0]), q_principal, w_principal,
                      integrator=integrator)
    rotated = Propagator(RigidBody.from_inertia(tensor),
                         (Rotation.from_quat(q_principal) * r.inv()).as_quat(),
                         R @ w_principal, integrator=integrator)
    twin.advance(5.0, 0.01)
    rotated.advance(5.0, 0.01)
    assert np.allclose(rotated.angular_velocity, R @ twin.angular_velocity, atol=1e-10)
    assert np.allclose(rotated.angular_momentum_inertial, twin.angular_momentum_inertial,
                       atol=1e-10)
    assert np.allclose(rotated.kinetic_energy, twin.kinetic_energy, rtol=1e-12)
    expected = Rotation.from_quat(twin.attitude) * r.inv()
    assert rotation.angle_between(rotated.attitude, expected.as_quat()) < 1e-9


def test_bad_state_and_dissipation_inputs_are_clear_errors():
    body = RigidBody.from_inertia([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match='zero norm'):
        Propagator(body, attitude=[0, 0, 0, 0])
    with pytest.raises(ValueError, match='attitude is not finite'):
        Propagator(body, attitude=[0, 0, float('nan'), 1])
    with pytest.raises(ValueError, match='angular velocity is not finite'):
        Propagator(body, angular_velocity=[0, float('inf'), 0])
    with pytest.raises(ValueError, match='must be >= 0'):
        Dissipation('double_bracket', -0.1)
    with pytest.raises(ValueError, match='unknown dissipation model'):
        Dissipation('friction', 0.1)
    with pytest.raises(ValueError, match='unknown integrator'):
        Propagator(body, integrator='verlet')


def test_poinsot_quantities():
    """L·ω = 2T; the invariable plane lies at 2T/|L|; the polhode point is on the energy
    ellipsoid."""
    moments = np.array([1.0, 2.0, 3.0])
    m = np.array([0.3, -1.2, 0.8])
    p = poinsot(moments, m)
    w = p['polhode_point']
    assert m @ w == pytest.approx(2 * p['kinetic_energy'])
    assert w @ p['invariable_plane_normal'] == pytest.approx(p['invariable_plane_distance'])
    assert np.sum(moments * w * w) == pytest.approx(2 * p['kinetic_energy'])


def test_switching_integrator_keeps_state_continuous():
    p = Propagator(RigidBody.from_inertia([1.0, 2.0, 3.0]), angular_velocity=[0.1, 1.0, 0.1])
    p.advance(1.0, 0.01)
    before = (p.attitude.copy(), p.angular_velocity.copy())
    p.set_integrator('rk4')
    assert np.array_equal(p.attitude, before[0]) and np.array_equal(p.angular_velocity, before[1])


def test_from_matrix_is_scipys_quaternion_to_the_bit():
    """rotation.from_matrix replaces scipy's Rotation at start-up; its quaternions must be
    scipy's, bit for bit (the principal frame feeds every run: test_free_body_unchanged),
    on random rotations, principal axes of random tensors, each branch of Shepperd's choice,
    and a matrix just off orthogonal (scipy's SVD projection)."""
    rng = np.random.default_rng(20261126)
    mats = [Rotation.random(random_state=i).as_matrix() for i in range(2000)]
    for _ in range(500):
        a = rng.normal(size=(3, 3))
        _, axes = np.linalg.eigh(a + a.T + 5 * np.eye(3))
        if np.linalg.det(axes) < 0:
            axes[:, 2] *= -1.0
        mats.append(axes)
    mats += [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]),
             np.diag([-1.0, -1.0, 1.0]), Rotation.random(random_state=7).as_matrix() * 1.001]
    for m in mats:
        assert np.array_equal(rotation.from_matrix(m), Rotation.from_matrix(m).as_quat()), m
    for bad in (np.diag([1.0, 1.0, -1.0]), np.zeros((3, 3)), np.full((3, 3), np.nan)):
        with pytest.raises(ValueError, match='not a rotation matrix'):
            rotation.from_matrix(bad)


@pytest.mark.slow
def test_a_node_starts_without_scipys_subpackages():
    """A node's or a run's process imports no scipy subpackage (spatial, integrate,
    special: 0.5 of its 1.1 CPU-s start-up); they load only where a path needs them."""
    import subprocess
    import sys
    code = ('import sys, rigid_body_sim.nodes.simulator, rigid_body_sim.nodes.controller, '
            'rigid_body_sim.offline; print(sorted(m for m in sys.modules '
            'if m.split(".")[:2] in (["scipy", "spatial"], ["scipy", "integrate"], '
            '["scipy", "special"])))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == '[]', out.stdout
