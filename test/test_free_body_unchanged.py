"""A scene without an orbit is today's free body, bit for bit: the environment's code in
the loops (an element array whose ON flag is 0) changes no sample of an offline run.

The reference (test/data/free_body_reference.npz) was written by this file's ``main``
run on the code before the orbit existed (commit 8bf9116, extracted with ``git archive``
and put first on PYTHONPATH):
``PYTHONPATH=<extracted> .venv/bin/python test/test_free_body_unchanged.py``.
Except ``explorer1-exact``: rewritten when exact's split steps were compiled
(integrators/exact_flow_kernel.py; its damping sub-flow is the splittings' compiled one,
which rounds otherwise than the Python flow it took: 5e-16 apart), on that code, which
has no environment term in exact's steps (it integrates none). ``slew-splitting4`` was
``slew-auto``: auto's choice on the slew was splitting4 at 0.01 s then, and it reproduces
those samples bit for bit; auto now takes rk4 there (its control-law constants).
"""
import os
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.fast  # make check

REFERENCE = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'data',
                         'free_body_reference.npz')
FIXED = ('splitting2', 'splitting4', 'splitting6', 'rk4', 'euler', 'dop853',
         'implicit_midpoint', 'splitting2_lstable', 'exact')
# (key, scene, overrides, --set): every method on a dissipative scene (Explorer 1), the
# closed form (torque-free), a law in the compiled closed loop (splitting4 and rk4), the
# gyrostat (wheels, CMGs)
CASES = ([(f'explorer1-{m}', 'explorer1', {'duration': 1.0, 'integrator': m, 'step': 1e-3},
           ['publish_rate=20.0']) for m in FIXED]
         + [('tennis_racket-auto', 'tennis_racket', {'duration': 5.0}, ['publish_rate=10.0']),
            # auto's choice on the slew when the reference was written (it now takes rk4)
            ('slew-splitting4', 'slew', {'duration': 3.0, 'integrator': 'splitting4',
                                         'step': 0.01}, ['publish_rate=20.0']),
            ('detumble-rk4', 'detumble', {'duration': 3.0, 'integrator': 'rk4', 'step': 2e-3},
             ['publish_rate=20.0']),
            ('wheel_slew-gyrostat', 'wheel_slew', {'duration': 3.0}, ['publish_rate=20.0']),
            ('cmg_slew-gyrostat', 'cmg_slew', {'duration': 3.0}, ['publish_rate=20.0'])])


def samples(scene, overrides, sets):
    from rigid_body_sim.engine import SampleBlock
    from rigid_body_sim.offline import engine_for
    from rigid_body_sim.scene import load
    engine = engine_for(load(scene, sets), **overrides)
    block = SampleBlock.concatenate(list(engine.run()))
    return {'t_ns': block.t_ns, 'q': block.q, 'm': block.m, 'torque': block.torque}


@pytest.mark.parametrize('key,scene,overrides,sets', CASES, ids=[c[0] for c in CASES])
def test_a_scene_without_an_orbit_runs_as_before_bit_for_bit(key, scene, overrides, sets):
    reference = np.load(REFERENCE)
    now = samples(scene, overrides, sets)
    assert len(now['t_ns']) > 10
    for field, values in now.items():
        np.testing.assert_array_equal(values, reference[f'{key}/{field}'],
                                      err_msg=f'{key}: {field}')


def main():
    out = {}
    for key, scene, overrides, sets in CASES:
        for field, values in samples(scene, overrides, sets).items():
            out[f'{key}/{field}'] = values
    np.savez_compressed(REFERENCE, **out)
    print(f'wrote {REFERENCE}: {len(CASES)} runs', file=sys.stderr)


if __name__ == '__main__':
    main()
