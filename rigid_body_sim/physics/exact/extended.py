"""Extended precision (``np.longdouble``) for the secular phases of :mod:`.exact`'s numpy
path (``TorqueFreeSolution.at_numpy``); the compiled path does the same in double-double
(:mod:`.constants`, :mod:`.double_double`), which numba supports and every platform has.

Why: a phase such as λt or (G/I)t reaches ~1e7 rad at t = 1e6 s, so a float64 rate with a
relative error of a few eps moves it by ~eps·|ω|·t (2e-9 rad for 10 rad/s), and the
precession gains 2j·Π(n|m) per half period j, so Π's error is multiplied by j ~ 1e6 (scipy's
elliprj gave Π only to ~2e-15 with the unbalanced arguments near the separatrix). Rates and
complete integrals are therefore computed in long double, products with t and j are formed
there and reduced modulo their periods; only the reduced values (|x| ≤ K or ≤ 2π) go back
to float64 for the Jacobi functions and the trigonometry. long double is the x87 format on
x86-64 (eps 1.1e-19) and IEEE quad on aarch64 Linux; where it is plain double (MSVC) the
code is unchanged in form and keeps float64 accuracy.
"""
import numpy as np

LD = np.longdouble
PI = 4 * np.arctan(LD(1))                # atanl: π to long double precision
FOUR_PI = 4 * PI
# cel converges quadratically: once the AGM-like pair agrees to CA the result is good to
# ~CA² (Bulirsch); a tenth of √eps leaves a margin of one iteration.
_CA = 0.1 * np.sqrt(np.finfo(LD).eps)


def _cel1(kc, p):
    """cel for one element on long double scalars: the iteration as Bulirsch wrote it."""
    a, b, e, em = LD(1), 1 / p, kc, LD(1)
    for _ in range(100):                  # ~log2(log(1/kc)) + 6 steps; 100 is unreachable
        f = a
        a = a + b / p
        g = e / p
        b = 2 * (b + f * g)
        p = g + p
        g = em
        em = kc + em
        if abs(g - kc) <= g * _CA:
            break
        kc = 2 * np.sqrt(e)
        e = kc * em
    return (PI / 2) * (b + a * em) / (em * (em + p))


def cel(kc, p):
    """Bulirsch's complete integral cel(kc, p, 1, 1) = ∫₀^{π/2} dθ / ((cos²θ + p sin²θ)
    √(cos²θ + kc² sin²θ)) for p > 0, in long double, element-wise.

    K(m) = cel(k', 1) and Π(n|m) = cel(k', 1 − n), k' = √(1 − m): the complement k' enters
    directly, so k' down to 1e-200 (the near-separatrix case) costs no cancellation.
    (R. Bulirsch, Numer. Math. 13 (1969) 305; the iteration of Numerical Recipes' ``cel``.)
    """
    kc = np.abs(np.asarray(kc, LD))
    p = np.sqrt(np.asarray(p, LD))
    kc, p = (np.array(x) for x in np.broadcast_arrays(kc, p))
    if kc.size <= 8:                      # a few bodies: scalars beat masked array updates
        return np.array([_cel1(k, q) for k, q in zip(kc.ravel(), p.ravel())],
                        LD).reshape(kc.shape)
    a = np.ones_like(kc)
    b = 1 / p
    e = kc.copy()
    em = np.ones_like(kc)
    done = np.zeros(kc.shape, bool)
    for _ in range(100):                  # the same iteration, frozen where converged
        act = ~done
        if not act.any():
            break
        f = a
        g = e / p
        a = np.where(act, a + b / p, a)
        b = np.where(act, 2 * (b + f * g), b)
        p = np.where(act, g + p, p)
        g = em
        em = np.where(act, kc + em, em)
        conv = act & (np.abs(g - kc) <= g * _CA)
        done |= conv
        more = act & ~conv
        kc = np.where(more, 2 * np.sqrt(e), kc)
        e = np.where(more, kc * em, e)
    return (PI / 2) * (b + a * em) / (em * (em + p))


def reduce_4pi(x):
    """x − 4π·round(x/4π) as float64, x in long double. 4π, not 2π: these angles enter
    quaternions as half angles, so the result keeps the quaternion's sign (continuity)."""
    if isinstance(x, LD):                 # one value: scalar arithmetic, no array overhead
        return float(x - FOUR_PI * np.rint(x / FOUR_PI))
    x = np.asarray(x, LD)
    return (x - FOUR_PI * np.rint(x / FOUR_PI)).astype(float)
