"""Compiled parameter homotopy for square systems of homogeneous quadrics, with a Cauchy endgame.

A family of systems ``F_j(z; s) = z^T M_j(s) z = 0`` (``j = 1..k``, ``z`` in ``P^k``) whose
matrices are quadratic in a complex parameter, ``M_j(s) = C0_j + s C1_j + s^2 C2_j``, is solved
at ``s = 0`` (the target) from the known isolated solutions at ``s = 1`` (a generic start
instance) along

``s(t) = gamma t / (1 + (gamma - 1) t)``,  ``t: 1 -> 0``,

a circular arc from 1 to 0 fixed by a random unit complex ``gamma`` (the gamma trick: with
probability one the arc misses the finitely many parameters where solutions merge, so every
path is nonsingular on ``(0, 1]``; by coefficient-parameter continuation, every isolated
solution of the target is the end point of a path from the start solutions of a generic
instance). Homogeneous coordinates are fixed on a random affine patch ``a^T z = 1``.

*Tracking* (generated C, compiled once per machine by `optik.native.source_library`; one path
at a time, no Python in the loop): third-order Runge-Kutta predictor (Ralston's: stages at
``0, h/2, 3h/4``, weights ``2/9, 1/3, 4/9``; the first stage is the last corrector update's
tangent, so a step solves for two new tangents, where the classical fourth-order rule took three)
on ``dz/dt = -J^{-1} dH/dt`` with ``J = [2 M(s) z; a^T]``, a corrector of at most 4 updates
``d_1, d_2, ...`` (two Newton updates, then chord updates with the second one's factorized
Jacobian), accepted when the last update is below ``tol (1 + |z|)`` (or, but in the end
steps below, after the first when the quadratic-convergence estimate of the next one,
``kappa d_1^2``, is; ``kappa`` is the largest ``d_2 / d_1^2`` the path has shown, at least 1)
and the corrected point stays within ``JUMP_GUARD (1 + |z|)`` of the prediction (a first update
beyond that rejects the step at once). The step aims
the predictor error (the corrector's displacement) at ``PREDICTOR_TARGET`` (third order: error
``O(h^4)``; growth at most 2x per step, none right after a rejection) and shrinks by the same
rule on rejection (0.1x to 0.5x; 0.5x when the corrector did not converge). Each path runs from
``t = 1`` to ``0`` in one go, with a step that ends exactly at ``t = ENDGAME_RADIUS``, where the
point is kept for the endgame; that step and the last one (to ``t = 0``) are corrected to
`ENDGAME_TOL`, so a singular end point (where Newton converges only linearly) stalls the path.
A path that stalls near ``t = 0`` (its step falls below ``stall t``: a singular end point, or a
path to a positive-dimensional set) goes to the endgame. A path that jumps to another one is not
detected here; the callers' count check (distinct nonsingular end points) does that.

*Cauchy endgame* (paths that stall near ``t = 0`` or arrive at a singular end point, where
Newton converges only linearly). Near ``t = 0`` a path is a convergent Puiseux series in
``t^(1/c)`` (``c`` its winding number). Tracking around the circle ``|t| = r``
(``r = ENDGAME_RADIUS``) returns to the start after ``c`` loops; the mean of the points at
``m`` equally spaced angles over the ``c`` loops is the trapezoidal rule for the Cauchy
integral ``(1 / 2 pi) int z dtheta``, the end point ``z(0)``, exact up to terms of order
``m c`` of the series. The points are averaged on the patch ``conj(z_r)^T z = 1`` of the
path's own point at ``t = r`` (the random tracking patch may have its pole inside the circle,
which would spoil the series).
"""

from __future__ import annotations

import ctypes
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from optik.errors import InvalidArgumentError, SolverUnavailableError
from optik.native import source_library

ENDGAME_RADIUS = 0.1
"""``|t|`` at which the endgame starts (paths are tracked from 1 to here, then to 0)."""

ENDGAME_SAMPLES = 16
"""Points per loop of the Cauchy endgame."""

MAX_WINDING = 8
"""Loops tried before the endgame gives up on a path."""

GAMMA_ANGLE = np.pi / 4
"""``gamma = exp(i theta)`` with ``theta`` uniform in ``[-GAMMA_ANGLE, GAMMA_ANGLE]``: any
``theta`` but a measure-zero set makes the arc generic, and a small one keeps it short
(``|s| <= 1 / cos(theta / 2)``; ``theta`` near ``pi`` sends ``s`` far away)."""

PREDICTOR_TARGET = 3e-3
"""Predictor error (corrector displacement relative to ``1 + |z|``) the step size aims at
(with `JUMP_GUARD` 10x it: on 3000 random 6-6 platforms 1e-3 and 1e-2 took 20 % more steps,
1329 against 1108 a platform, for the same real postures; a jump costs a retry, the count check
sees it)."""

SINGULAR_CONDITION = 1e8
"""End points whose Jacobian condition number (`condition_numbers`) exceeds this are singular:
they go to the endgame even when the corrector converged at ``t = 0``."""

JUMP_GUARD = 3e-2
"""Largest accepted corrector displacement relative to ``1 + |z|`` (guards against path jumping)."""

ENDGAME_FIRST_STEP = 0.05
"""First step (in the segment's ``tau``) of each of the `ENDGAME_SAMPLES` arcs of an endgame loop."""

ENDGAME_TOL = 1e-8
"""Corrector tolerance of the points at ``t = ENDGAME_RADIUS`` and ``t = 0`` and of the endgame
loops (which close when they return to the first within ``1e-8 (1 + |z|)``)."""

_C_SOURCE = r"""
#include <complex.h>
#include <math.h>
#include <time.h>

typedef double complex cplx;
#define NMAX 16
#define INLINE static inline __attribute__((always_inline))

typedef struct { const long *ptr; const int *col; const cplx *val; } csr_t; /* rows j * n + r */

/* LANES complex numbers, real and imaginary parts apart, lane l of each vector belonging to one
   of a group of legs: the leg quadrics are evaluated LANES legs at a time in SIMD registers (four
   with AVX, compiled in where the processor has it (AVX_FLAGS): two groups for the six legs,
   the last two lanes idle (zero); else two, SSE2 on x86-64: three groups; the compiler lowers
   the vector types to scalars where there is none). Every lane does the same IEEE operations in
   the same order whatever LANES is, so the answers do not depend on it. */
#ifdef __AVX__
#define LANES 4
#else
#define LANES 2
#endif
#define GROUPS ((6 + LANES - 1) / LANES)
typedef double v2 __attribute__((vector_size(16)));
typedef double vl __attribute__((vector_size(8 * LANES)));
typedef struct { vl re, im; } c2;

INLINE c2 c2_add(c2 a, c2 b) { c2 r = {a.re + b.re, a.im + b.im}; return r; }
INLINE c2 c2_sub(c2 a, c2 b) { c2 r = {a.re - b.re, a.im - b.im}; return r; }
INLINE c2 c2_mul(c2 a, c2 b) {
    c2 r = {a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re};
    return r;
}
INLINE c2 c2_scale(double f, c2 a) { c2 r = {f * a.re, f * a.im}; return r; }
INLINE c2 c2_splat(cplx x) {
    c2 r;
    for (int l = 0; l < LANES; l++) {
        r.re[l] = creal(x);
        r.im[l] = cimag(x);
    }
    return r;
}
/* A complex number as one vector (re, im); stored through its two doubles (C11 lays a complex
   out as double[2]) */
INLINE v2 load2(const cplx *x) { return (v2){creal(*x), cimag(*x)}; }
INLINE void store2(cplx *out, v2 x) {
    double *d = (double *)out;
    d[0] = x[0];
    d[1] = x[1];
}
#ifdef __AVX__
/* Two consecutive complex numbers as one vector (re, im, re, im) */
typedef double v4 __attribute__((vector_size(32)));
INLINE v4 load4(const cplx *x) { return (v4){creal(x[0]), cimag(x[0]), creal(x[1]), cimag(x[1])}; }
INLINE void store4(cplx *out, v4 x) {
    double *d = (double *)out;
    for (int i = 0; i < 4; i++) d[i] = x[i];
}
#endif
/* lane l of x into out */
INLINE void c2_store(c2 x, int l, cplx *out) { store2(out, (v2){x.re[l], x.im[l]}); }

typedef struct {
    int k, n;
    csr_t c[3]; /* C0, C1, C2: (k, n, n), symmetric, compressed sparse rows */
    cplx gamma, ta, tb;       /* arc parameter and segment t(tau) = ta + tau (tb - ta) */
    const cplx *patch;
    const cplx *legs; /* NULL, or the Stewart-Gough leg line (b, db, p, dp, c, dc), see evaluate_legs */
    c2 groups[GROUPS][14]; /* legs LANES k + l of the line: b[3], db[3], p[3], dp[3], c, dc (make_sys;
                              idle lanes zero) */
} sys_t;

typedef struct {
    double max_step, min_step, tol, guard, stall, deadline, h0, target, mark, end_tol;
    long max_steps;
} opts_t;

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double norm(int n, const cplx *z) {
    double s = 0.0;
    for (int i = 0; i < n; i++) s += creal(z[i]) * creal(z[i]) + cimag(z[i]) * cimag(z[i]);
    return sqrt(s);
}

/* x o v for a quaternion x and a pure quaternion v = (0, v): (-x_v . v, x0 v + x_v cross v) */
INLINE void times_pure(const c2 *x, const c2 *v, c2 *out) {
    out[0] = c2_scale(-1.0, c2_add(c2_add(c2_mul(x[1], v[0]), c2_mul(x[2], v[1])), c2_mul(x[3], v[2])));
    out[1] = c2_sub(c2_add(c2_mul(x[0], v[0]), c2_mul(x[2], v[2])), c2_mul(x[3], v[1]));
    out[2] = c2_sub(c2_add(c2_mul(x[0], v[1]), c2_mul(x[3], v[0])), c2_mul(x[1], v[2]));
    out[3] = c2_sub(c2_add(c2_mul(x[0], v[2]), c2_mul(x[1], v[1])), c2_mul(x[2], v[0]));
}

/* v o x for a pure quaternion v and a quaternion x: (-v . x_v, x0 v + v cross x_v) */
INLINE void pure_times(const c2 *v, const c2 *x, c2 *out) {
    out[0] = c2_scale(-1.0, c2_add(c2_add(c2_mul(v[0], x[1]), c2_mul(v[1], x[2])), c2_mul(v[2], x[3])));
    out[1] = c2_sub(c2_add(c2_mul(x[0], v[0]), c2_mul(v[1], x[3])), c2_mul(v[2], x[2]));
    out[2] = c2_sub(c2_add(c2_mul(x[0], v[1]), c2_mul(v[2], x[1])), c2_mul(v[0], x[3]));
    out[3] = c2_sub(c2_add(c2_mul(x[0], v[2]), c2_mul(v[0], x[2])), c2_mul(v[1], x[1]));
}

INLINE c2 dot4(const c2 *a, const c2 *b) {
    const c2 ab = c2_add(c2_mul(a[0], b[0]), c2_mul(a[1], b[1]));
    return c2_add(c2_add(ab, c2_mul(a[2], b[2])), c2_mul(a[3], b[3]));
}

/* The same J, value and dH/dtau as evaluate, for the Study quadric and the six leg quadrics of a
   Stewart-Gough platform whose base points, platform points and leg constants move on a line:
   b_i(s) = b_i + s db_i, p_i(s) = p_i + s dp_i, c_i(s) = c_i + s dc_i (legs = [b, db, p, dp
   (6 x 3 each), c, dc (6 each)]). With z = (e, g), u = e o p, w = b o e (b, p pure quaternions):
   F_0 = e . g and F_i = c e.e - 2 w.u + 4 (u - w).g + 4 g.g, so
   dF_i/de = 2 c e + 2 b o (u + 2 g) + 2 (w - 2 g) o p (L(b)^T = -L(b), R(p)^T = -R(p) for pure
   quaternions), dF_i/dg = 4 (u - w) + 8 g and
   dF_i/ds = dc e.e - 2 ((db o e).u + w.(e o dp)) + 4 (e o dp - db o e).g. LANES legs at a
   time (sys_t.groups, the lanes of c2). No J when jac is NULL (inlined: a constant NULL drops its
   operations). */
INLINE void evaluate_legs(const sys_t *q, const cplx *z, cplx s, cplx ds, cplx *jac, cplx *val, cplx *ht) {
    c2 e[4], g[4];
    for (int a = 0; a < 4; a++) {
        e[a] = c2_splat(z[a]);
        g[a] = c2_splat(z[4 + a]);
    }
    const c2 ee = dot4(e, e), gg4 = c2_scale(4.0, dot4(g, g)), sv = c2_splat(s), dsv = c2_splat(ds);
    if (jac)
        for (int c = 0; c < 4; c++) {
            jac[c] = z[4 + c];
            jac[4 + c] = z[c];
        }
    c2_store(dot4(e, g), 0, val);
    ht[0] = 0.0;
    for (int k = 0; k < GROUPS; k++) {
        const c2 *l = q->groups[k];
        c2 b[3], p[3], u[4], w[4], du[4], dw[4];
        for (int a = 0; a < 3; a++) {
            b[a] = c2_add(l[a], c2_mul(sv, l[3 + a]));
            p[a] = c2_add(l[6 + a], c2_mul(sv, l[9 + a]));
        }
        const c2 c = c2_add(l[12], c2_mul(sv, l[13]));
        times_pure(e, p, u);
        pure_times(b, e, w);
        c2 uw_g = c2_mul(c2_sub(u[0], w[0]), g[0]);
        for (int a = 1; a < 4; a++) uw_g = c2_add(uw_g, c2_mul(c2_sub(u[a], w[a]), g[a]));
        const c2 cw = c2_sub(c2_mul(c, ee), c2_scale(2.0, dot4(w, u)));
        const c2 v = c2_add(c2_add(cw, c2_scale(4.0, uw_g)), gg4);
        c2 row[8];
        if (jac) {
            c2 x[4], y[4];
            for (int a = 0; a < 4; a++) {
                x[a] = c2_add(u[a], c2_scale(2.0, g[a]));
                y[a] = c2_sub(w[a], c2_scale(2.0, g[a]));
            }
            pure_times(b, x, row);
            times_pure(y, p, row + 4); /* scratch: the e part is 2 c e + 2 row[0..3] + 2 row[4..7] */
            for (int a = 0; a < 4; a++) {
                row[a] = c2_scale(2.0, c2_add(c2_add(c2_mul(c, e[a]), row[a]), row[4 + a]));
                row[4 + a] = c2_add(c2_scale(4.0, c2_sub(u[a], w[a])), c2_scale(8.0, g[a]));
            }
        }
        times_pure(e, l + 9, du);
        pure_times(l + 3, e, dw);
        c2 d = c2_sub(c2_mul(l[13], ee), c2_scale(2.0, c2_add(dot4(dw, u), dot4(w, du))));
        for (int a = 0; a < 4; a++) d = c2_add(d, c2_mul(c2_scale(4.0, c2_sub(du[a], dw[a])), g[a]));
        d = c2_mul(d, dsv);
        for (int lane = 0; lane < LANES && LANES * k + lane < 6; lane++) {
            const int i = 1 + LANES * k + lane;
            c2_store(v, lane, val + i);
            c2_store(d, lane, ht + i);
            if (jac)
                for (int c = 0; c < 8; c++) c2_store(row[c], lane, jac + 8 * i + c);
        }
    }
}

/* J = [2 M(s) z; a^T] (row-major; not formed when jac is NULL), value [z^T M(s) z; a^T z - 1], dH/dtau */
static void evaluate(const sys_t *q, const cplx *z, double tau, cplx *jac, cplx *val, cplx *ht) {
    const int n = q->n, k = q->k;
    const cplx t = q->ta + tau * (q->tb - q->ta);
    const cplx den = 1.0 + (q->gamma - 1.0) * t;
    const cplx s = q->gamma * t / den, s2 = s * s;
    const cplx ds = q->gamma / (den * den) * (q->tb - q->ta);
    if (q->legs && jac) {
        evaluate_legs(q, z, s, ds, jac, val, ht);
    } else if (q->legs) {
        evaluate_legs(q, z, s, ds, NULL, val, ht);
    } else {
    for (int j = 0; j < k; j++) {
        cplx v = 0.0, w = 0.0;
        for (int r = 0; r < n; r++) {
            const long row = (long)j * n + r;
            cplx y[3];
            for (int m = 0; m < 3; m++) {
                const csr_t *a = &q->c[m];
                cplx acc = 0.0;
                for (long e = a->ptr[row]; e < a->ptr[row + 1]; e++) acc += a->val[e] * z[a->col[e]];
                y[m] = acc;
            }
            const cplx y0 = y[0], y1 = y[1], y2 = y[2];
            const cplx my = y0 + s * y1 + s2 * y2;
            if (jac) jac[j * n + r] = 2.0 * my;
            v += z[r] * my;
            w += z[r] * (y1 + 2.0 * s * y2);
        }
        val[j] = v;
        ht[j] = w * ds;
    }
    }
    cplx pz = 0.0;
    for (int c = 0; c < n; c++) {
        if (jac) jac[k * n + c] = q->patch[c];
        pz += q->patch[c] * z[c];
    }
    val[k] = pz - 1.0;
    ht[k] = 0.0;
}

/* Partial pivoting at column col of the n x n row-major a: the row r >= col of the largest
   |Re| + |Im| in that column is swapped with row col (whole rows); returns r, or -1 when the
   column is zero from col down. */
INLINE int pivot(int n, cplx *a, int col) {
    int piv = col;
    double best = fabs(creal(a[col * n + col])) + fabs(cimag(a[col * n + col]));
    for (int r = col + 1; r < n; r++) {
        double m = fabs(creal(a[r * n + col])) + fabs(cimag(a[r * n + col]));
        if (m > best) { best = m; piv = r; }
    }
    if (!(best > 0.0)) return -1;
    if (piv != col)
        for (int j = 0; j < n; j++) {
            cplx x = a[col * n + j];
            a[col * n + j] = a[piv * n + j];
            a[piv * n + j] = x;
        }
    return piv;
}

/* P A = L U of the n x n row-major a in place (partial pivoting: at column col, row col and
   row piv[col] >= col are swapped whole, multipliers included), L's multipliers below the
   diagonal, inv[col] = 1 / U[col][col]; 0 on success, 1 when a column is zero. */
INLINE int lu_factor(int n, cplx *a, int *piv, cplx *inv) {
    for (int col = 0; col < n; col++) {
        const int r0 = pivot(n, a, col);
        if (r0 < 0) return 1;
        piv[col] = r0;
        inv[col] = 1.0 / a[col * n + col];
        for (int r = col + 1; r < n; r++) {
            const cplx f = a[r * n + col] * inv[col];
            a[r * n + col] = f;
            /* a_rj -= f a_cj with a complex as one SIMD register (re, im): f a_cj = re(f) a_cj
               + (-im(f), im(f)) (im(a_cj), re(a_cj)) */
            const v2 fr = {creal(f), creal(f)}, fi = {-cimag(f), cimag(f)};
            int j = col + 1;
#ifdef __AVX__
            /* two complex entries a register, the same operations on each */
            const v4 fr4 = {fr[0], fr[1], fr[0], fr[1]}, fi4 = {fi[0], fi[1], fi[0], fi[1]};
            for (; j + 1 < n; j += 2) {
                const v4 x = load4(a + col * n + j);
                store4(a + r * n + j, load4(a + r * n + j) - (fr4 * x + fi4 * (v4){x[1], x[0], x[3], x[2]}));
            }
#endif
            for (; j < n; j++) {
                const v2 x = load2(a + col * n + j);
                store2(a + r * n + j, load2(a + r * n + j) - (fr * x + fi * (v2){x[1], x[0]}));
            }
        }
    }
    return 0;
}

/* A x = b and A y = c in place (b, c become x, y; c may be NULL) from lu_factor's factors of A:
   the swaps in order, then L and U; 0 when the solution is finite. */
INLINE int lu_solve(int n, const cplx *a, const int *piv, const cplx *inv,
                                                          cplx *b, cplx *c) {
    for (int col = 0; col < n; col++) {
        const int r = piv[col];
        if (r != col) {
            cplx x = b[col]; b[col] = b[r]; b[r] = x;
            if (c) { x = c[col]; c[col] = c[r]; c[r] = x; }
        }
    }
    for (int r = 1; r < n; r++) {
        cplx x = b[r], y = c ? c[r] : 0.0;
        for (int j = 0; j < r; j++) {
            x -= a[r * n + j] * b[j];
            if (c) y -= a[r * n + j] * c[j];
        }
        b[r] = x;
        if (c) c[r] = y;
    }
    for (int r = n - 1; r >= 0; r--) {
        cplx x = b[r], y = c ? c[r] : 0.0;
        for (int j = r + 1; j < n; j++) {
            x -= a[r * n + j] * b[j];
            if (c) y -= a[r * n + j] * c[j];
        }
        b[r] = x * inv[r];
        if (!isfinite(creal(b[r])) || !isfinite(cimag(b[r]))) return 1;
        if (c) {
            c[r] = y * inv[r];
            if (!isfinite(creal(c[r])) || !isfinite(cimag(c[r]))) return 1;
        }
    }
    return 0;
}

/* lu_factor and lu_solve with the dimension a constant where it is the Stewart-Gough one (8):
   unrolled loops */
static int factor2(int n, cplx *a, int *piv, cplx *inv) {
    return n == 8 ? lu_factor(8, a, piv, inv) : lu_factor(n, a, piv, inv);
}

static int back2(int n, const cplx *a, const int *piv, const cplx *inv, cplx *b, cplx *c) {
    return n == 8 ? lu_solve(8, a, piv, inv, b, c) : lu_solve(n, a, piv, inv, b, c);
}

/* a x = b and a y = c in place (a overwritten by its factors; c may be NULL); 0 on success */
static int solve2(int n, cplx *a, cplx *b, cplx *c) {
    int piv[NMAX];
    cplx inv[NMAX];
    return factor2(n, a, piv, inv) || back2(n, a, piv, inv, b, c);
}

static int tangent(const sys_t *q, const cplx *z, double tau, cplx *out) {
    cplx jac[NMAX * NMAX], val[NMAX];
    evaluate(q, z, tau, jac, val, out);
    for (int i = 0; i < q->n; i++) out[i] = -out[i];
    return solve2(q->n, jac, out, NULL);
}

/* status: 0 reached tau = 1, 1 step too small (stalled), 2 step or time budget exhausted */
static int track_one(const sys_t *q, const opts_t *o, cplx *z, cplx *zmark, double *tau_out,
                     long *steps_out) {
    const int n = q->n;
    cplx k1[NMAX], k2[NMAX], k3[NMAX], zt[NMAX], zp[NMAX], zc[NMAX];
    cplx jac[NMAX * NMAX], val[NMAX], ht[NMAX], inv[NMAX];
    int piv[NMAX];
    const double seglen = cabs(q->tb - q->ta);
    double tau = 0.0, h = o->h0;
    int status = 0, have_k1 = 0, retried = 0;
    double kappa = 1.0;
    long steps = 0;
    while (tau < 1.0) {
        if (steps >= o->max_steps || ((steps & 7) == 0 && now() > o->deadline)) { status = 2; break; }
        steps++;
        /* a step never crosses the mark: it ends there and the point is kept in zmark; the
           steps that end at the mark or at tb are corrected to end_tol (a singular end point,
           where Newton converges only linearly, then stalls the path) */
        const int to_mark = tau < o->mark && tau + h >= o->mark;
        const double st = to_mark ? o->mark - tau : fmin(h, 1.0 - tau);
        const int end = to_mark || tau + st >= 1.0;
        const double tol = end ? o->end_tol : o->tol;
        /* k1 is kept across a rejection (same point) and after an acceptance comes from the last
           corrector iteration (at the point before its final update, within the corrector's
           displacement: the predictor's first stage) */
        const int bad_k1 = have_k1 ? 0 : tangent(q, z, tau, k1);
        int bad = bad_k1;
        have_k1 = 0;
        for (int i = 0; i < n; i++) zt[i] = z[i] + 0.5 * st * k1[i];
        bad = bad || tangent(q, zt, tau + 0.5 * st, k2);
        for (int i = 0; i < n; i++) zt[i] = z[i] + 0.75 * st * k2[i];
        bad = bad || tangent(q, zt, tau + 0.75 * st, k3);
        int ok = !bad;
        double last = INFINITY, moved = INFINITY;
        if (ok) {
            for (int i = 0; i < n; i++)
                zc[i] = zp[i] = z[i] + st / 9.0 * (2.0 * k1[i] + 3.0 * k2[i] + 4.0 * k3[i]);
            double first = 0.0;
            for (int it = 0; it < 4 && ok; it++) {
                /* two Newton updates, then chord updates with the second one's factors (no new
                   J: only the value and dH/dtau), which contract about as fast from there,
                   d_(m+1) ~ kappa d_2 d_m; the next k1 (the last update's dH/dtau solve) then
                   has the Jacobian of a point within about d_3 */
                const int newton = it < 2;
                evaluate(q, zc, tau + st, newton ? jac : NULL, val, ht);
                for (int i = 0; i < n; i++) ht[i] = -ht[i];
                if ((newton && factor2(n, jac, piv, inv)) || back2(n, jac, piv, inv, val, ht)) {
                    ok = 0;
                    break;
                }
                for (int i = 0; i < n; i++) zc[i] -= val[i];
                last = norm(n, val);
                const double scale = 1.0 + norm(n, zc), lim = tol * scale;
                if (last <= lim) break;
                /* a first update beyond the guard fails the step whatever follows (the corrected
                   point would end about that far from the prediction): no more updates, and
                   the step shrinks by it as the predictor error */
                if (it == 0 && last > o->guard * scale) { ok = 0; moved = last / scale; break; }
                /* Newton converges quadratically (near a nonsingular point): the update after a
                   first one of size d is about kappa d^2, kappa the largest ratio d2 / d1^2 this
                   path has shown; the end steps measure it */
                if (it == 0 && !end && kappa * last * last <= lim) { last = kappa * last * last; break; }
                if (it == 0) first = last;
                else if (it == 1 && first > 0.0) kappa = fmax(kappa, last / (first * first));
            }
        }
        if (ok) {
            const double scale = 1.0 + norm(n, zc);
            for (int i = 0; i < n; i++) zt[i] = zc[i] - zp[i];
            moved = norm(n, zt) / scale;
            ok = last <= tol * scale && moved <= o->guard;
        }
        if (ok) {
            tau = to_mark ? o->mark : tau + st;
            if (to_mark)
                for (int i = 0; i < n; i++) zmark[i] = zc[i];
            for (int i = 0; i < n; i++) {
                z[i] = zc[i];
                k1[i] = ht[i];
            }
            have_k1 = 1;
            /* the predictor error of the third-order rule is O(h^4): aim the next one at o->target */
            const double grow = moved > 0.0 ? 0.9 * pow(o->target / moved, 0.25) : 2.0;
            /* no growth right after a rejection: the step that failed would be tried again */
            if (st >= h) h = fmin(h * fmin(fmax(grow, 0.5), retried ? 1.0 : 2.0), o->max_step);
            retried = 0;
        } else {
            have_k1 = !bad_k1;
            /* shrink by the predictor error where it is known (at most halve: st < h at the end
               of the run or before the mark) */
            h = st * (isfinite(moved) ? fmin(fmax(0.9 * pow(o->target / moved, 0.25), 0.1), 0.5) : 0.5);
            retried = 1;
            const double t_abs = cabs(q->ta + tau * (q->tb - q->ta));
            const double floor = t_abs < 1e-2 ? fmax(o->min_step, o->stall * t_abs / seglen) : o->min_step;
            if (h < floor) { status = 1; break; }
        }
    }
    *tau_out = tau;
    *steps_out = steps;
    return status;
}

/* |x| without hypot's overflow guard (the values are scaled) */
static inline double modulus(cplx x) { return sqrt(creal(x) * creal(x) + cimag(x) * cimag(x)); }

/* |A^-1|_1 (the largest column sum of moduli) of the n x n row-major matrix a, which it overwrites
   with its factors (lu_factor); column c of A^-1 solves A x = e_c. INFINITY when a pivot is zero
   or a column is not finite. */
static double inverse_norm1(int n, cplx *a) {
    int piv[NMAX];
    cplx inv[NMAX];
    if (factor2(n, a, piv, inv)) return INFINITY;
    double worst = 0.0;
    for (int c = 0; c < n; c++) {
        cplx x[NMAX];
        for (int i = 0; i < n; i++) x[i] = i == c ? 1.0 : 0.0;
        if (back2(n, a, piv, inv, x, NULL)) return INFINITY;
        double sum = 0.0;
        for (int i = 0; i < n; i++) sum += modulus(x[i]);
        if (!isfinite(sum)) return INFINITY;
        worst = fmax(worst, sum);
    }
    return worst;
}

/* The end points z (rows, in place) at t = tb: `iters` Newton steps with the point's own patch
   conj(z)^T dz = 0 (a failed solve leaves the point), then cond[p], the 1-norm condition number
   |A|_1 |A^-1|_1 of A = [J(u); conj(u)^T] with J(u) = 2 M(s) u the Jacobian rows at the unit
   point u = z / |z| (INFINITY where A is singular), and resid[p] = max_j |z^T M_j(s) z| / |z|^2. */
static void finish_one(const sys_t *q, cplx *z, int iters, double *cond, double *resid) {
    const int n = q->n, k = q->k;
    cplx jac[NMAX * NMAX], val[NMAX], ht[NMAX];
    for (int it = 0; it < iters; it++) {
        evaluate(q, z, 1.0, jac, val, ht);
        for (int c = 0; c < n; c++) jac[k * n + c] = conj(z[c]);
        val[k] = 0.0;
        if (solve2(n, jac, val, NULL)) break;
        for (int i = 0; i < n; i++) z[i] -= val[i];
    }
    const double len = norm(n, z);
    if (!isfinite(len) || !(len > 0.0)) { *cond = *resid = INFINITY; return; }
    cplx u[NMAX];
    for (int i = 0; i < n; i++) u[i] = z[i] / len;
    evaluate(q, u, 1.0, jac, val, ht);
    double worst = 0.0, a_norm = 0.0;
    for (int j = 0; j < k; j++) worst = fmax(worst, modulus(val[j]));
    *resid = worst; /* homogeneous of degree 2: |F(u)| = |F(z)| / |z|^2 */
    for (int c = 0; c < n; c++) jac[k * n + c] = conj(u[c]);
    for (int c = 0; c < n; c++) {
        double col = 0.0;
        for (int r = 0; r < n; r++) col += modulus(jac[r * n + c]);
        a_norm = fmax(a_norm, col);
    }
    *cond = a_norm * inverse_norm1(n, jac);
}

static int make_sys(sys_t *q, int k, int n, const long *ptr0, const int *col0, const cplx *val0,
                    const long *ptr1, const int *col1, const cplx *val1,
                    const long *ptr2, const int *col2, const cplx *val2,
                    double g_re, double g_im, const cplx *patch, double ta_re, double ta_im,
                    double tb_re, double tb_im, const cplx *legs) {
    if (n > NMAX || k != n - 1 || (legs && n != 8)) return -1;
    sys_t s = {k, n, {{ptr0, col0, val0}, {ptr1, col1, val1}, {ptr2, col2, val2}},
               g_re + I * g_im, ta_re + I * ta_im, tb_re + I * tb_im, patch, legs};
    *q = s;
    if (legs)
        for (int i = 0; i < 6; i++) {
            c2 *pair = q->groups[i / LANES];
            const int lane = i % LANES;
            for (int m = 0; m < 14; m++) {
                /* component m % 3 of b, db, p, dp (m / 3 = 0 .. 3), then c, dc (m = 12, 13) */
                const cplx x = m < 12 ? legs[18 * (m / 3) + 3 * i + m % 3] : legs[72 + 6 * (m - 12) + i];
                pair[m].re[lane] = creal(x);
                pair[m].im[lane] = cimag(x);
            }
        }
    return 0;
}

/* finish_one on every row of z at t = tb (the system as for optik_track_paths). */
int optik_finish_paths(int paths, int k, int n, const long *ptr0, const int *col0, const cplx *val0,
                       const long *ptr1, const int *col1, const cplx *val1,
                       const long *ptr2, const int *col2, const cplx *val2,
                       double g_re, double g_im, const cplx *patch, double ta_re, double ta_im,
                       double tb_re, double tb_im, const cplx *legs, int iters, cplx *z,
                       double *cond, double *resid) {
    sys_t q;
    if (make_sys(&q, k, n, ptr0, col0, val0, ptr1, col1, val1, ptr2, col2, val2, g_re, g_im, patch,
                 ta_re, ta_im, tb_re, tb_im, legs)) return -1;
    for (int p = 0; p < paths; p++) finish_one(&q, z + (long)p * n, iters, cond + p, resid + p);
    return 0;
}

/* Track every path (rows of z, updated in place) along t: ta -> tb. opts: max_step, min_step,
   tol, guard, stall, seconds, h0, max_steps, predictor target, mark (tau, a step ends there and
   zmark keeps the point), end_tol (tol of the steps ending at the mark or at tb). Returns the
   number of paths not at tb. */
int optik_track_paths(int paths, int k, int n, const long *ptr0, const int *col0, const cplx *val0,
                      const long *ptr1, const int *col1, const cplx *val1,
                      const long *ptr2, const int *col2, const cplx *val2,
                      double g_re, double g_im, const cplx *patch, double ta_re, double ta_im,
                      double tb_re, double tb_im, const double *opts, cplx *z, int *status,
                      double *tau, long *steps, cplx *zmark, const cplx *legs) {
    sys_t q;
    if (make_sys(&q, k, n, ptr0, col0, val0, ptr1, col1, val1, ptr2, col2, val2, g_re, g_im, patch,
                 ta_re, ta_im, tb_re, tb_im, legs)) return -1;
    opts_t o = {opts[0], opts[1], opts[2], opts[3], opts[4],
                now() + opts[5], opts[6], opts[8], opts[9], opts[10], (long)opts[7]};
    int left = 0;
    for (int p = 0; p < paths; p++) {
        status[p] = track_one(&q, &o, z + (long)p * n, zmark + (long)p * n, tau + p, steps + p);
        left += status[p] != 0;
    }
    return left;
}
"""

_FLAGS = ("-fcx-limited-range",)
"""Plain complex arithmetic (no C99 Annex G inf/nan recovery in products and quotients): the
values tracked are finite and scaled, and the checks reject any non-finite step."""

AVX_FLAGS = ("-mavx",)
"""Added to `_FLAGS` where `has_avx`: 256-bit registers (four legs a lane group, ``LANES`` in the
C source) and three-operand instructions. No fused multiply-adds (``-mavx`` does not enable
them, and `optik.native` turns contraction off), so the same answers bit for bit as the SSE2
build (1000 random 6-6 platforms: postures, poses, residuals, fallbacks equal) in 10 % less
time (4.58 ms against 5.12 ms a platform, median of 60, same process, interleaved)."""

_LIB: list[ctypes.CDLL | None] = []


def has_avx() -> bool:
    """True where the processor and the operating system run AVX code: an x86-64 Linux machine
    with ``avx`` among the flags of ``/proc/cpuinfo`` (the kernel lists it only when it saves the
    AVX registers). False elsewhere: the tracker is built for the baseline instruction set."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return False
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as info:
            for line in info:
                if line.startswith("flags"):
                    return "avx" in line.split()
    except OSError:
        pass
    return False


def compiled() -> ctypes.CDLL | None:
    """The compiled tracker (built on first use, cached on disk), or None without a C compiler.

    Built with `AVX_FLAGS` too where `has_avx` (the flags are part of the cache key, so a cache
    shared by machines with and without AVX holds both builds), and without them if that build
    fails (a compiler that does not know them)."""
    if not _LIB:
        lib = None
        if has_avx():
            lib = source_library(_C_SOURCE, "optik_quadric_tracker", "auto", (*_FLAGS, *AVX_FLAGS))
        if lib is None:
            lib = source_library(_C_SOURCE, "optik_quadric_tracker", "auto", _FLAGS)
        if lib is not None:
            fn = lib.optik_track_paths
            ptr, dbl, i32 = ctypes.c_void_p, ctypes.c_double, ctypes.c_int
            fn.argtypes = [i32, i32, i32, *([ptr] * 9), dbl, dbl, ptr, dbl, dbl, dbl, dbl, *([ptr] * 7)]
            fn.restype = i32
            fin = lib.optik_finish_paths
            fin.argtypes = [i32, i32, i32, *([ptr] * 9), dbl, dbl, ptr, dbl, dbl, dbl, dbl, ptr, i32]
            fin.argtypes += [ptr] * 3
            fin.restype = i32
        _LIB.append(lib)
    return _LIB[0]


def available() -> bool:
    """True when the compiled tracker can be used (a working C compiler)."""
    return compiled() is not None


@dataclass(frozen=True)
class ParameterTracking:
    """End points of the paths of a parameter homotopy.

    Attributes:
        z: end points ``(paths, n)`` (``nan`` rows for unresolved paths): on the tracking patch,
            or on their own after ``refine`` Newton steps (`track`).
        status: per path ``"regular"`` (reached ``t = 0`` with a converged corrector),
            ``"endgame"`` (stalled near 0, end point from the Cauchy endgame), ``"abandoned"``
            (stalled near 0 where the caller's ``abandon`` test flagged it: ``z`` holds the
            point where it stopped), ``"failed"`` (stalled before the endgame zone, endgame
            not closing within `MAX_WINDING` loops, or the time limit; ``z`` is ``nan``).
        winding: winding number found by the endgame (1 for regular paths, 0 otherwise).
        condition: condition number of the Jacobian at the end point (`condition_numbers`;
            ``inf`` for abandoned and failed paths).
        residual: relative residual ``max_j |z^T M_j(0) z| / |z|^2`` of the end point (``inf``
            for abandoned and failed paths).
        steps: predictor-corrector steps, all paths and the endgame together.
        solve_time: wall time (s).
    """

    z: np.ndarray
    status: np.ndarray
    winding: np.ndarray
    condition: np.ndarray
    residual: np.ndarray
    steps: int
    solve_time: float


def _csr(c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Compressed sparse rows ``(row pointers, columns, values)`` of ``c`` as ``(k n, n)``;
    entries below ``1e-14`` of the largest are rounding noise of structural zeros and dropped."""
    rows = np.asarray(c, dtype=complex).reshape(-1, c.shape[-1])
    keep = np.abs(rows) > 1e-14 * max(float(np.max(np.abs(rows), initial=0.0)), 1e-300)
    ptr = np.concatenate([[0], np.cumsum(keep.sum(axis=1))]).astype(np.int64)
    cols = np.nonzero(keep)[1].astype(np.int32)
    return ptr, np.ascontiguousarray(cols), np.ascontiguousarray(rows[keep])


@dataclass(frozen=True)
class LegLine:
    """A Stewart-Gough family on a line of (complex) geometries, for the compiled tracker's
    structured evaluation of its 7 quadrics (`optik.closed_form.parallel.study.study_matrices`:
    the Study quadric and the six legs): base points ``base + s d_base``, platform points
    ``platform + s d_platform`` (``(6, 3)`` each) and leg constants ``constants + s d_constants``
    (``(6,)`` each). Quaternion products of the points with ``e`` and ``g`` take about 60 % of the
    operations of the three sparse matrices ``C0, C1, C2`` of the same family."""

    base: np.ndarray
    d_base: np.ndarray
    platform: np.ndarray
    d_platform: np.ndarray
    constants: np.ndarray
    d_constants: np.ndarray

    def packed(self) -> np.ndarray:
        """``[b, db, p, dp, c, dc]`` flattened, complex (the C layout)."""
        parts = (self.base, self.d_base, self.platform, self.d_platform, self.constants, self.d_constants)
        return np.ascontiguousarray(np.concatenate([np.ravel(a) for a in parts]), dtype=complex)


class _Tracker:
    """One call of the compiled tracker on a fixed system, gamma and patch."""

    def __init__(
        self, system: tuple[np.ndarray, np.ndarray, np.ndarray] | LegLine, gamma: complex, patch: np.ndarray
    ):
        if isinstance(system, LegLine):
            self.k, self.n, self.legs = 7, 8, system.packed()
            rows = self.k * self.n + 1
            empty = (np.zeros(rows, dtype=np.int64), np.zeros(1, dtype=np.int32), np.zeros(1, dtype=complex))
            self.c = [empty] * 3
        else:
            self.k, self.n, self.legs = system[0].shape[0], system[0].shape[1], None
            self.c = [_csr(c) for c in system]
        self.gamma = complex(gamma)
        self.patch = np.ascontiguousarray(patch, dtype=complex)
        self.steps = 0
        # addresses of the arrays every call passes, read once (ndarray.ctypes.data costs about a
        # microsecond; the arrays live as long as the tracker)
        self._arrays = tuple(a.ctypes.data for c in self.c for a in c)
        self._patch = self.patch.ctypes.data
        self._legs = None if self.legs is None else self.legs.ctypes.data

    def segment(
        self,
        z: np.ndarray,
        ta: complex,
        tb: complex,
        deadline: float,
        tol: float,
        max_step: float,
        first_step: float,
        mark: float = 2.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Track the rows of ``z`` from ``t = ta`` to ``tb`` (steps in ``tau``, ``t = ta + tau (tb - ta)``,
        the first one ``first_step``, none longer than ``max_step``).

        Returns ``(end points, status per path, points at the mark, tau reached)``: a step ends
        exactly at ``t(mark) = ta + mark (tb - ta)`` (``mark`` in ``(0, 1)``; none by default)
        and the point there is kept (rows of paths with ``tau < mark`` are undefined). The steps
        ending at the mark and at ``tb`` are corrected to `ENDGAME_TOL`.
        """
        z = np.ascontiguousarray(z, dtype=complex).copy()
        z_mark = np.empty_like(z)
        p = len(z)
        status = np.zeros(p, dtype=np.int32)
        tau = np.zeros(p)
        steps = np.zeros(p, dtype=np.int64)
        seconds = max(deadline - time.monotonic(), 0.0)
        opts = np.array(
            [
                max_step,
                1e-14,
                tol,
                JUMP_GUARD,
                1e-3,
                seconds,
                first_step,
                1e6,
                PREDICTOR_TARGET,
                mark,
                ENDGAME_TOL,
            ],
        )
        compiled().optik_track_paths(
            p, self.k, self.n, *self._arrays, self.gamma.real, self.gamma.imag, self._patch,
            complex(ta).real, complex(ta).imag, complex(tb).real, complex(tb).imag,
            opts.ctypes.data, z.ctypes.data, status.ctypes.data, tau.ctypes.data, steps.ctypes.data,
            z_mark.ctypes.data, self._legs,
        )  # fmt: skip
        self.steps += int(steps.sum())
        return z, status, z_mark, tau

    def finish(self, z: np.ndarray, iters: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points ``z`` at the target ``s = 0``: ``iters`` Newton steps with each point's own
        patch ``conj(z)^T dz = 0`` (as `optik.closed_form.homotopy.refine`), then `condition_numbers`
        and the relative residuals ``max_j |z^T M_j(0) z| / |z|^2``, all in C.

        Returns ``(points, condition numbers, residuals)``.
        """
        z = np.ascontiguousarray(z, dtype=complex).copy()
        cond, resid = np.empty(len(z)), np.empty(len(z))
        compiled().optik_finish_paths(
            len(z), self.k, self.n, *self._arrays, 1.0, 0.0,
            self._patch, 0.0, 0.0, 0.0, 0.0, self._legs,
            iters, z.ctypes.data, cond.ctypes.data, resid.ctypes.data,
        )  # fmt: skip
        return z, cond, resid


def track(
    system: tuple[np.ndarray, np.ndarray, np.ndarray] | LegLine,
    starts: np.ndarray,
    rng: np.random.Generator,
    *,
    time_limit: float = 1.0,
    tol: float = 1e-6,
    max_step: float = 0.25,
    abandon: Callable[[np.ndarray], np.ndarray] | None = None,
    refine: int = 0,
) -> ParameterTracking:
    """Track the start solutions ``starts`` (rows, solutions of ``M(1) = C0 + C1 + C2``) to ``s = 0``.

    Args:
        system: ``(C0, C1, C2)``, each ``(k, k + 1, k + 1)``, symmetric in the last two axes; or a
            Stewart-Gough `LegLine` (``k = 7``), which the tracker evaluates from the points
            instead of the matrices (fewer operations, the same values).
        starts: ``(paths, k + 1)`` complex start solutions (any scaling: projective points).
        rng: generator of ``gamma`` and the patch.
        time_limit: wall-time budget (s); paths unfinished then are ``"failed"``.
        tol: relative size of the last Newton update (measured or, after one update, estimated)
            for a corrector to be accepted while tracking; the points at ``t = ENDGAME_RADIUS``
            and ``t = 0`` and the endgame use `ENDGAME_TOL`.
        max_step: largest step in ``t`` (and the first step of every path).
        abandon: optional test ``z -> bool mask`` on the points where paths stalled near
            ``t = 0``; flagged paths skip the endgame (e.g. paths that clearly entered a known
            positive-dimensional set of no interest).
        refine: Newton steps on the target applied to the regular and endgame end points, each
            on its own patch ``conj(z)^T dz = 0`` (as `optik.closed_form.homotopy.refine`),
            before their condition numbers and residuals are taken.

    Raises:
        InvalidArgumentError: ``system`` not three ``(k, k + 1, k + 1)`` arrays with
            ``k + 1 <= 16`` nor a `LegLine` of points ``(6, 3)`` and constants ``(6,)``, or
            starts not ``(paths, k + 1)``.
        SolverUnavailableError: no working C compiler (check `available` first).
    """
    start = time.perf_counter()
    deadline = time.monotonic() + time_limit
    if isinstance(system, LegLine):
        shapes = [np.shape(a) for a in (system.base, system.d_base, system.platform, system.d_platform)]
        shapes += [np.shape(system.constants), np.shape(system.d_constants)]
        if shapes != [(6, 3)] * 4 + [(6,)] * 2:
            raise InvalidArgumentError("system", f"need leg points (6, 3) and constants (6,); got {shapes}")
        k = 7
    else:
        shapes = {np.shape(c) for c in system}
        k = system[0].shape[0] if len(system) == 3 and len(shapes) == 1 else -1
        if k < 1 or shapes != {(k, k + 1, k + 1)} or k + 1 > 16:
            raise InvalidArgumentError(
                "system", f"need three (k, k + 1, k + 1) arrays, k + 1 <= 16; got {shapes}"
            )
    if np.ndim(starts) != 2 or np.shape(starts)[1] != k + 1:
        raise InvalidArgumentError("starts", f"need shape (paths, {k + 1}), got {np.shape(starts)}")
    if compiled() is None:
        raise SolverUnavailableError("the compiled path tracker needs a working C compiler")
    n = k + 1
    gamma = np.exp(1j * GAMMA_ANGLE * rng.uniform(-1, 1))
    patch = rng.normal(size=n) + 1j * rng.normal(size=n)
    tracker = _Tracker(system, gamma, patch)
    z0 = np.asarray(starts, dtype=complex)
    z0 = z0 / (z0 @ patch)[:, None]
    r = ENDGAME_RADIUS
    # one run from t = 1 to 0 with a step ending at t = r (the endgame's start: mark 1 - r)
    z_end, st_end, z_r, tau = tracker.segment(z0, 1.0, 0.0, deadline, tol, max_step, max_step, mark=1.0 - r)
    st_r = np.where(tau >= 1.0 - r, 0, st_end)  # nonzero: the path failed before t = r
    status = np.where(st_end == 0, "regular", "failed").astype(object)
    status[st_r != 0] = "failed"
    winding = np.where(status == "regular", 1, 0)
    z_out = np.where((status == "regular")[:, None], z_end, np.nan)
    condition, residual = np.full(len(z0), np.inf), np.full(len(z0), np.inf)
    arrived = np.flatnonzero(st_end == 0)
    z_end[arrived], condition[arrived], residual[arrived] = tracker.finish(z_end[arrived], refine)
    z_out[arrived] = z_end[arrived]
    # stalled near 0, or arrived at a singular end point (where Newton converges only linearly)
    todo = np.flatnonzero((st_r == 0) & ((st_end == 1) | (condition > SINGULAR_CONDITION)))
    if abandon is not None and len(todo):
        gone = todo[abandon(z_end[todo])]
        status[gone] = "abandoned"
        z_out[gone] = z_end[gone]
        condition[gone], residual[gone] = np.inf, np.inf
        todo = np.setdiff1d(todo, gone)
    if len(todo):
        points, loops = _cauchy(tracker, z_r[todo], r, deadline, ENDGAME_TOL)
        ok = loops > 0
        status[todo[ok]] = "endgame"
        status[todo[~ok]] = "failed"
        winding[todo[ok]] = loops[ok]
        condition[todo], residual[todo] = np.inf, np.inf
        done = todo[ok]
        z_out[done], condition[done], residual[done] = tracker.finish(points[ok], refine)
    z_out[status == "failed"] = np.nan
    return ParameterTracking(
        z_out, status.astype(str), winding, condition, residual, tracker.steps, time.perf_counter() - start
    )


def _cauchy(tracker: _Tracker, z_r: np.ndarray, r: float, deadline: float, tol: float):
    """Cauchy endgame from the points ``z_r`` at ``t = r``: ``(end points, winding numbers)``
    (winding 0 where the loops did not close within `MAX_WINDING` or a segment failed)."""
    m = ENDGAME_SAMPLES
    ts = r * np.exp(2j * np.pi * np.arange(m + 1) / m)
    active = np.arange(len(z_r))
    z = z_r.copy()
    sums = np.zeros_like(z_r)
    points = np.full_like(z_r, np.nan)
    loops = np.zeros(len(z_r), dtype=int)
    for loop in range(1, MAX_WINDING + 1):
        for j in range(m):
            # averaged on the patch conj(z_r)^T z = 1 of the path's own start point: the tracking
            # patch may have its pole (a^T z = 0) within the circle, this one stays far from it
            za = z[active]
            sums[active] += za / np.sum(np.conj(z_r[active]) * za, axis=1, keepdims=True)
            z[active], st, _, _ = tracker.segment(
                z[active], ts[j], ts[j + 1], deadline, tol, 1.0, ENDGAME_FIRST_STEP
            )
            active = active[st == 0]
            if len(active) == 0:
                return points, loops
        scale = 1 + np.linalg.norm(z_r[active], axis=1)
        back = np.linalg.norm(z[active] - z_r[active], axis=1) <= 1e-8 * scale
        closed = active[back]
        points[closed] = sums[closed] / (m * loop)
        points[closed] /= (points[closed] @ tracker.patch)[:, None]  # back on the tracking patch
        loops[closed] = loop
        active = active[~back]
        if len(active) == 0:
            break
    return points, loops


def condition_numbers(c0: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Condition numbers (1-norm) of ``[2 M(0) z / |z|; conj(z)^T / |z|]``, the Jacobian on the
    patch normal to ``z`` (``inf`` where it is singular)."""
    u = z / np.linalg.norm(z, axis=1, keepdims=True)
    mz = np.einsum("kij,pj->pki", c0, u)
    jac = np.concatenate([2 * mz, np.conj(u)[:, None, :]], axis=1)
    with np.errstate(all="ignore"):
        return np.nan_to_num(np.linalg.cond(jac, 1), nan=np.inf)
