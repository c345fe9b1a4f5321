"""The viewer's View (rigid_body_sim/viewer/view.py) without ROS: a formation's bodies
added, sampled and removed, written to an MCAP sink (so that every channel is built) and
read back with the mcap library."""
import numpy as np
import pytest

from rigid_body_sim.physics.body import RigidBody

pytestmark = pytest.mark.fast  # make check

NS = 1_000_000_000


def test_removing_the_first_body_hands_the_scene_to_the_next(tmp_path):
    """The first body drawn carries Poinsot's construction. Deleted, the next one takes it
    over from its own next sample; a sample of another body in between used to build the
    scene with no Poinsot scale (TypeError in the node's callback)."""
    import foxglove
    from mcap.reader import make_reader
    from rigid_body_sim.viewer.view import View
    path = tmp_path / 'view.mcap'
    sink = foxglove.open_mcap(str(path))
    try:
        view = View(scene_period_ns=NS // 10)
        for name, moments in (('leader', (10.0, 12.0, 14.0)), ('wingman', (1.0, 2.0, 3.0)),
                              ('tumbler', (1.0, 2.0, 2.5))):
            view.add_craft(name)
            view.set_body(RigidBody.from_inertia(list(moments)), name)
        q, w = (0.0, 0.0, 0.0, 1.0), (0.05, 1.0, 0.0)
        stamp = 0
        for _ in range(3):
            stamp += NS // 10
            for name in ('leader', 'wingman', 'tumbler'):
                view.sample(stamp, q, w, name=name)
        assert view.drawn() == ['leader', 'wingman', 'tumbler']
        view.remove_craft('leader', stamp)
        stamp += NS // 10
        view.sample(stamp, q, w, name='tumbler')   # before the new first one's sample
        view.sample(stamp, q, w, name='wingman')
        stamp += NS // 10
        for name in ('wingman', 'tumbler'):
            view.sample(stamp, q, w, name=name)
        assert view.drawn() == ['wingman', 'tumbler']
        assert view.body.principal_moments.tolist() == [1.0, 2.0, 3.0]   # wingman's
    finally:
        sink.close()
    with open(path, 'rb') as f:
        scenes = [(m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(
            topics=['/scene'])]
    # protobuf keeps the ids as bytes: the deletion names the leader's entities, and no
    # update after it draws the leader
    deleted = [i for i, (_, data) in enumerate(scenes) if b'leader/body' in data
               and b'energy_ellipsoid' not in data]   # a deletion only, no entity
    assert len(deleted) == 1, [len(d) for _, d in scenes]
    after = scenes[deleted[0] + 1:]
    assert after and all(b'leader/' not in d and b'tumbler/body' in d for _, d in after)
    assert all(b'energy_ellipsoid' in d for _, d in after)
    assert np.all(np.diff([t for t, _ in scenes]) >= 0)
