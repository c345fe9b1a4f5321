"""The C source of :mod:`.extended`'s run (kept as a string so that an installed package
carries it: setup.py installs Python modules). ``extended`` compiles it twice, REAL = long
double and REAL = double.
"""
SOURCE = r"""
/* The generalisation suite's extended-precision reference (bench/extended.py builds it):
 * Euler's equations and the quaternion kinematics under a zero-order-hold rate-damping law
 * and/or a dissipation model, advanced by Taylor series in REAL (long double: 64-bit
 * mantissa, or double to measure what float64's rounding does to the same run). The
 * equations are polynomial in the state (quadratic; the double bracket cubic, viscous
 * damping linear), so the series' coefficients follow from Cauchy products with exact
 * rational factors 1/(n+1): no tableau whose digits would cap the accuracy at float64's.
 * The series runs until two successive terms fall under tol (relative); a step whose
 * series has not converged by NMAX terms is halved.
 *
 * Dissipation (principal frame, as physics/dynamics_kernel.rates): model 1, the double
 * bracket dm/dt += coef * m x (m x w); model 2, viscous dm/dt -= coef * w; 0 none.
 *
 * Frames as engine/closed_loop.py: q principal -> inertial (x, y, z, w), m the principal
 * momentum; the law sees the body rate axes @ (m / I), its gains kw act on the
 * controller's principal rates law_axes^T w_b (detumble: tau = -kw * w), then the norm
 * limit, the clip, and tau_p = axes^T tau_body held until the next control instant. */
#include <math.h>

#ifndef REAL
#define REAL long double
#endif
#ifndef NAME
#define NAME taylor_run_ld
#endif
#define NMAX 60

static REAL absr(REAL x) { return x < 0 ? -x : x; }

/* One Taylor step of h (s) from (q, m); 0 if converged (then q, m advanced), else 1. */
static int step(REAL h, REAL *q, REAL *m, const REAL *I, const REAL *tau, int model,
                REAL coef, REAL tol, long long *terms)
{
    /* cc: the series of m x w, which the double bracket's m x (m x w) multiplies again */
    REAL qc[NMAX + 1][4], mc[NMAX + 1][3], wc[NMAX + 1][3], cc[NMAX + 1][3];
    REAL mscale = absr(m[0]) + absr(m[1]) + absr(m[2]) + h * (absr(tau[0]) + absr(tau[1])
                                                              + absr(tau[2]));
    REAL hp = 1, small = 0;
    int n, k, i, top = -1;
    for (i = 0; i < 4; i++) qc[0][i] = q[i];
    for (i = 0; i < 3; i++) { mc[0][i] = m[i]; wc[0][i] = m[i] / I[i]; }
    for (n = 0; n < NMAX; n++) {
        REAL c0 = 0, c1 = 0, c2 = 0, p0 = 0, p1 = 0, p2 = 0, p3 = 0;
        for (k = 0; k <= n; k++) {
            const REAL *a = mc[k], *w = wc[n - k], *b = qc[k];
            c0 += a[1] * w[2] - a[2] * w[1];   /* m x w */
            c1 += a[2] * w[0] - a[0] * w[2];
            c2 += a[0] * w[1] - a[1] * w[0];
            /* q (x) (w, 0), (x, y, z, w) order */
            p0 += b[3] * w[0] + b[1] * w[2] - b[2] * w[1];
            p1 += b[3] * w[1] + b[2] * w[0] - b[0] * w[2];
            p2 += b[3] * w[2] + b[0] * w[1] - b[1] * w[0];
            p3 -= b[0] * w[0] + b[1] * w[1] + b[2] * w[2];
        }
        cc[n][0] = c0; cc[n][1] = c1; cc[n][2] = c2;
        if (model == 1) {
            REAL d0 = 0, d1 = 0, d2 = 0;
            for (k = 0; k <= n; k++) {
                const REAL *a = mc[k], *c = cc[n - k];
                d0 += a[1] * c[2] - a[2] * c[1];
                d1 += a[2] * c[0] - a[0] * c[2];
                d2 += a[0] * c[1] - a[1] * c[0];
            }
            c0 += coef * d0; c1 += coef * d1; c2 += coef * d2;
        } else if (model == 2) {
            c0 -= coef * wc[n][0]; c1 -= coef * wc[n][1]; c2 -= coef * wc[n][2];
        }
        if (n == 0) { c0 += tau[0]; c1 += tau[1]; c2 += tau[2]; }
        REAL f = (REAL)1 / (REAL)(n + 1);
        mc[n + 1][0] = c0 * f; mc[n + 1][1] = c1 * f; mc[n + 1][2] = c2 * f;
        for (i = 0; i < 3; i++) wc[n + 1][i] = mc[n + 1][i] / I[i];
        f *= (REAL)0.5;
        qc[n + 1][0] = p0 * f; qc[n + 1][1] = p1 * f; qc[n + 1][2] = p2 * f;
        qc[n + 1][3] = p3 * f;
        hp *= h;
        REAL em = (absr(mc[n + 1][0]) + absr(mc[n + 1][1]) + absr(mc[n + 1][2])) * hp
            / (mscale > 0 ? mscale : 1);
        REAL eq = (absr(qc[n + 1][0]) + absr(qc[n + 1][1]) + absr(qc[n + 1][2])
                   + absr(qc[n + 1][3])) * hp;
        REAL e = em > eq ? em : eq;
        if (e < tol && small < tol && n >= 3) { top = n + 1; break; }
        small = e;
    }
    if (top < 0) return 1;
    *terms += top;
    for (i = 0; i < 4; i++) {
        REAL s = qc[top][i];
        for (k = top - 1; k >= 0; k--) s = s * h + qc[k][i];
        q[i] = s;
    }
    for (i = 0; i < 3; i++) {
        REAL s = mc[top][i];
        for (k = top - 1; k >= 0; k--) s = s * h + mc[k][i];
        m[i] = s;
    }
    return 0;
}

static void law(const REAL *m, const REAL *I, const double *axes, const double *law_axes,
                const double *kw, double torque_limit, double clip, REAL *tau_body,
                REAL *tau_p)
{
    REAL wb[3], wl[3], p[3];
    int i, j;
    for (i = 0; i < 3; i++) {
        wb[i] = 0;
        for (j = 0; j < 3; j++) wb[i] += (REAL)axes[3 * i + j] * (m[j] / I[j]);
    }
    for (j = 0; j < 3; j++) {
        wl[j] = 0;
        for (i = 0; i < 3; i++) wl[j] += wb[i] * (REAL)law_axes[3 * i + j];
        p[j] = -(REAL)kw[j] * wl[j];
    }
    REAL n2 = 0;
    for (i = 0; i < 3; i++) {
        tau_body[i] = 0;
        for (j = 0; j < 3; j++) tau_body[i] += p[j] * (REAL)law_axes[3 * i + j];
        n2 += tau_body[i] * tau_body[i];
    }
    if (n2 > (REAL)torque_limit * (REAL)torque_limit) {
        REAL s = (REAL)torque_limit / sqrtl((long double)n2);
        for (i = 0; i < 3; i++) tau_body[i] *= s;
    }
    for (i = 0; i < 3; i++) {
        if (tau_body[i] > (REAL)clip) tau_body[i] = clip;
        if (tau_body[i] < -(REAL)clip) tau_body[i] = -clip;
    }
    for (j = 0; j < 3; j++) {
        tau_p[j] = 0;
        for (i = 0; i < 3; i++) tau_p[j] += tau_body[i] * (REAL)axes[3 * i + j];
    }
}

/* From (q0, m0) at t0 (ns) with the held body torque tau0 through every sample instant
 * ts[0..n) (ns, increasing, >= t0): the law at control0 + k*period (ns) (none when
 * control0 lies past ts[n-1]); dissipation `model` of coefficient `coef`; steps of at
 * most turn/r s, r = |w|_1 + the dissipation's rate (its stiffness: viscous coef/I_min,
 * the double bracket coef |m|^2 (1/I_min - 1/I_max)). Writes q_out (n x 4) and m_out
 * (n x 3); counts[0] the steps, counts[1] the series' terms. Returns 0, or -1 where a
 * step could not converge (halved 40 times). */
int NAME(const double *q0, const double *m0, const double *tau0, const double *moments,
         const double *axes, const double *law_axes, const double *kw, double torque_limit,
         double clip, int model, double coef, long long t0, long long control0,
         long long period,
         const long long *ts, long long n, double turn, double tol, double *q_out,
         double *m_out, long long *counts)
{
    REAL q[4], m[3], I[3], tau_body[3], tau_p[3];
    long long t = t0, ctl = control0, si = 0;
    int i, j;
    for (i = 0; i < 4; i++) q[i] = q0[i];
    for (i = 0; i < 3; i++) { m[i] = m0[i]; I[i] = moments[i]; tau_body[i] = tau0[i]; }
    for (j = 0; j < 3; j++) {
        tau_p[j] = 0;
        for (i = 0; i < 3; i++) tau_p[j] += tau_body[i] * (REAL)axes[3 * i + j];
    }
    counts[0] = counts[1] = 0;
    while (si < n) {
        if (t == ctl) {
            law(m, I, axes, law_axes, kw, torque_limit, clip, tau_body, tau_p);
            ctl += period;
        }
        if (t == ts[si]) {
            for (i = 0; i < 4; i++) q_out[4 * si + i] = (double)q[i];
            for (i = 0; i < 3; i++) m_out[3 * si + i] = (double)m[i];
            si++;
            if (si == n) break;
        }
        long long next = ts[si] < ctl ? ts[si] : ctl;
        REAL span = (REAL)(next - t) * (REAL)1e-9;
        REAL w = 0;
        for (i = 0; i < 3; i++) w += absr(m[i] / I[i]);
        {
            REAL lo = I[0] < I[1] ? (I[0] < I[2] ? I[0] : I[2]) : (I[1] < I[2] ? I[1] : I[2]);
            REAL hi = I[0] > I[1] ? (I[0] > I[2] ? I[0] : I[2]) : (I[1] > I[2] ? I[1] : I[2]);
            REAL m2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
            if (model == 1)
                w += (REAL)coef * m2 * (1 / lo - 1 / hi);
            else if (model == 2)
                w += (REAL)coef / lo;
        }
        long long parts = (long long)ceill((long double)(span * w / (REAL)turn));
        if (parts < 1) parts = 1;
        REAL h = span / (REAL)parts;
        for (long long k = 0; k < parts; k++) {
            int halvings = 0, pieces = 1;
            REAL hs = h;
            while (step(hs, q, m, I, tau_p, model, (REAL)coef, (REAL)tol, &counts[1])) {
                if (++halvings > 40) return -1;
                hs *= (REAL)0.5;
                pieces *= 2;
            }
            counts[0]++;
            for (int r = 1; r < pieces; r++) {
                if (step(hs, q, m, I, tau_p, model, (REAL)coef, (REAL)tol, &counts[1])) return -1;
                counts[0]++;
            }
        }
        t = next;
    }
    return 0;
}
"""
