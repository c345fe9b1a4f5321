"""The figures of ``auto``'s reason: :func:`answers.g_text` writes what ``'%.*g'`` writes."""
import math
import random

import pytest

from rigid_body_sim.physics.auto.answers import g_text

pytestmark = pytest.mark.fast


def _values():
    """Below %g's fixed form (< 1e-4, the exponent g_text writes itself) down to the
    subnormals, random mantissas and the cases where rounding or log10 could move the
    exponent: powers of ten and their neighbours, ties at the last kept digit; then the
    values it hands to %g (fixed form, 0, inf, nan, negative)."""
    rng = random.Random(20261127)
    for k in range(-323, -3):
        b = 10.0 ** k
        yield from (b, math.nextafter(b, 0.0), math.nextafter(b, 1.0), 1.5 * b, 2.5 * b,
                    9.5 * b, 9.95 * b, 9.995 * b, 9.9999995 * b)
        yield from (rng.uniform(1.0, 10.0) * b for _ in range(20))
    yield from (5e-324, 9.999999999999999e-05, 1e-4, 4.7e-05, -3.3e-07, 0.0, -0.0, 0.25,
                123456.0, 1.5e300, math.inf, -math.inf, math.nan)


@pytest.mark.parametrize('precision', range(1, 8))
def test_g_text_writes_what_percent_g_writes(precision):
    wrong = [(x, g_text(x, precision), '%.*g' % (precision, x)) for x in _values()
             if g_text(x, precision) != '%.*g' % (precision, x)]
    assert not wrong, wrong[:5]


def test_explorer1_s_split_figure_keeps_its_exponent():
    """The row it was written for (Explorer 1 over 1 s: 2·Δβ = 4.7e-05 in the reason)."""
    assert g_text(4.7e-05, 2) == '4.7e-05' and g_text(9.96e-06, 2) == '1e-05'
