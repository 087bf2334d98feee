/* Steps of optik.closed_form.general_6r in C (same arithmetic, one candidate after the other):
 *
 * - optik_g6r_back: the back-substitution of a candidate (phi_3, phi_4, phi_5): the fourteen
 *   left sides, x_R by the pseudo-inverse, theta_1, theta_2 from its cosines and sines, theta_6
 *   from A_6 = (A_1 ... A_5)^-1 T' (the inner function back_substitute of _solve);
 * - optik_g6r_polish: Newton's method on the pose of the arm in standard DH form, real or
 *   complex angles (_polish: same residual, Jacobian, bounded step and stopping rules).
 *
 * A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i), T = A_1 ... A_6 (unit scale); the residual of a
 * target T* is r = [p - p*; vee(R R*^T - R* R^T) / 2], the Jacobian the geometric one
 * [z_{i-1} x (p - o_{i-1}); z_{i-1}] of the prefix frames. A step is bounded to 0.5 per entry
 * (theta -= s / max(1, 2 |s|)); a candidate stops once max |r| < 1e-15, or once it no longer
 * halves below 1e-9 prod cosh(Im theta_i) (rounding).
 *
 * Reentrant: stack memory only.
 */
#include <complex.h>
#include <math.h>

typedef double complex cplx;

/* cos and sin of a (complex) angle theta = x + i y: cos theta = cos x cosh y - i sin x sinh y,
 * sin theta = sin x cosh y + i cos x sinh y, the products glibc's ccos and csin form (for |y| <
 * 709, where they need no scaling), with one sin, cos, cosh and sinh for both and none of the
 * latter two for a real angle (cosh 0 = 1, sinh(+-0) = +-0) */
static void cos_sin(cplx theta, cplx *c, cplx *s) {
    double x = creal(theta), y = cimag(theta), cx = cos(x), sx = sin(x);
    double ch = y == 0.0 ? 1.0 : cosh(y), sh = y == 0.0 ? y : sinh(y);
    *c = fabs(y) < 709.0 ? CMPLX(cx * ch, -(sx * sh)) : ccos(theta);
    *s = fabs(y) < 709.0 ? CMPLX(sx * ch, cx * sh) : csin(theta);
}

/* out = x A (rows 0-2; row 3 is 0, 0, 0, 1) of a homogeneous transform x and the DH transform of
 * one joint at theta, A = Rz(theta) Tz(d) Tx(a) Rx(alpha) =
 *     [c  -s ca   s sa  a c]
 *     [s   c ca  -c sa  a s]
 *     [0   sa     ca    d  ]
 *     [0   0      0     1  ]
 * column by column, the terms of A's zeros left out and its real entries (sa, ca, d) taken as
 * real factors: the sums of the full 4 x 4 product in its order, x_0 A_0k + x_1 A_1k + x_2 A_2k
 * (+ x_3 for the last column), with the same products */
static void times_dh(cplx x[4][4], cplx theta, double d, double a, double ca, double sa, cplx out[4][4]) {
    cplx c, s;
    cos_sin(theta, &c, &s);
    cplx m01 = -s * ca, m11 = c * ca, m02 = s * sa, m12 = -c * sa, m03 = a * c, m13 = a * s;
    for (int r = 0; r < 3; ++r) {
        cplx x0 = x[r][0], x1 = x[r][1], x2 = x[r][2];
        out[r][0] = x0 * c + x1 * s;
        out[r][1] = x0 * m01 + x1 * m11 + x2 * sa;
        out[r][2] = x0 * m02 + x1 * m12 + x2 * ca;
        out[r][3] = x0 * m03 + x1 * m13 + x2 * d + x[r][3];
    }
    for (int k = 0; k < 4; ++k) out[3][k] = k == 3;
}

/* out = A itself (times_dh of the identity, whose products by 1 and 0 give A's entries) */
static void dh(cplx theta, double d, double a, double ca, double sa, cplx out[4][4]) {
    cplx c, s;
    cos_sin(theta, &c, &s);
    out[0][0] = c, out[0][1] = -s * ca, out[0][2] = s * sa, out[0][3] = a * c;
    out[1][0] = s, out[1][1] = c * ca, out[1][2] = -c * sa, out[1][3] = a * s;
    out[2][0] = 0, out[2][1] = sa, out[2][2] = ca, out[2][3] = d;
    for (int k = 0; k < 4; ++k) out[3][k] = k == 3;
}

/* prefix products pre[0..joints] of the DH transforms at theta */
static void chain(const double *d, const double *a, const double *ca, const double *sa, const cplx *theta,
                  int joints, cplx pre[7][4][4]) {
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) pre[0][r][c] = r == c;
    dh(theta[0], d[0], a[0], ca[0], sa[0], pre[1]);
    for (int i = 1; i < joints; ++i) times_dh(pre[i], theta[i], d[i], a[i], ca[i], sa[i], pre[i + 1]);
}

/* the pose residual at pre[6] for the target t (4 x 4 row-major); returns max |r| */
static double residual(cplx pre[7][4][4], const double *t, cplx *err) {
    cplx rot[3][3];
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
            cplx v = 0;
            for (int j = 0; j < 3; ++j) v += pre[6][r][j] * t[4 * c + j];
            rot[r][c] = v;
        }
    for (int r = 0; r < 3; ++r) err[r] = pre[6][r][3] - t[4 * r + 3];
    err[3] = 0.5 * (rot[2][1] - rot[1][2]);
    err[4] = 0.5 * (rot[0][2] - rot[2][0]);
    err[5] = 0.5 * (rot[1][0] - rot[0][1]);
    double size = 0.0;
    for (int r = 0; r < 6; ++r) size = fmax(size, cabs(err[r]));
    return size;
}

/* x = J^-1 b by Gaussian elimination with partial pivoting; 0 when J is exactly singular */
static int solve6(cplx j[6][6], cplx *b, cplx *x) {
    for (int c = 0; c < 6; ++c) {
        int p = c;
        double top = cabs(j[c][c]);
        for (int r = c + 1; r < 6; ++r) {
            double size = cabs(j[r][c]);
            if (size > top) top = size, p = r;
        }
        if (j[p][c] == 0) return 0;
        if (p != c) {
            for (int k = 0; k < 6; ++k) {
                cplx v = j[c][k];
                j[c][k] = j[p][k], j[p][k] = v;
            }
            cplx v = b[c];
            b[c] = b[p], b[p] = v;
        }
        for (int r = c + 1; r < 6; ++r) {
            cplx f = j[r][c] / j[c][c];
            for (int k = c; k < 6; ++k) j[r][k] -= f * j[c][k];
            b[r] -= f * b[c];
        }
    }
    for (int r = 5; r >= 0; --r) {
        cplx v = b[r];
        for (int k = r + 1; k < 6; ++k) v -= j[r][k] * x[k];
        x[r] = v / j[r][r];
    }
    return 1;
}

/* Newton on one candidate th (6 complex angles, in place) towards the target tn (4 x 4); `size` gets
 * max |r| at the end. Returns 0, or 1 when a Jacobian was exactly singular. */
static int polish_one(const double *d, const double *a, const double *ca, const double *sa, int iterations, cplx *th,
                      const double *tn, double *size) {
    cplx err[6], pre[7][4][4];
    chain(d, a, ca, sa, th, 6, pre);
    double now = residual(pre, tn, err), before = now;
    for (int it = 0; it < iterations && now >= 1e-15; ++it) {
        cplx jac[6][6], step[6];
        for (int i = 0; i < 6; ++i) {
            cplx z[3] = {pre[i][0][2], pre[i][1][2], pre[i][2][2]};
            cplx v[3] = {pre[6][0][3] - pre[i][0][3], pre[6][1][3] - pre[i][1][3], pre[6][2][3] - pre[i][2][3]};
            jac[0][i] = z[1] * v[2] - z[2] * v[1];
            jac[1][i] = z[2] * v[0] - z[0] * v[2];
            jac[2][i] = z[0] * v[1] - z[1] * v[0];
            jac[3][i] = z[0], jac[4][i] = z[1], jac[5][i] = z[2];
        }
        if (!solve6(jac, err, step)) return 1;
        for (int i = 0; i < 6; ++i) th[i] -= step[i] / fmax(1.0, 2.0 * cabs(step[i]));
        chain(d, a, ca, sa, th, 6, pre);
        now = residual(pre, tn, err);
        double magnitude = 1.0;
        for (int i = 0; i < 6; ++i) magnitude *= cosh(cimag(th[i]));
        if (now > 0.5 * before && now < 1e-9 * magnitude) break; /* stalled at rounding */
        before = now;
    }
    *size = now;
    return 0;
}

/* `dh`: d (6), a (6), alpha (6) of the unit-scale arm; `theta`: k candidates x 6 complex angles
 * (interleaved real, imaginary), polished in place; `t`: their targets (k x 4 x 4); `size`: max
 * |r| of each at the end. Returns 0, or 1 when a Jacobian was exactly singular (the caller's
 * numpy path, which then takes least-squares steps, answers). */
int optik_g6r_polish(const double *dh, int k, int iterations, double *theta, const double *t, double *size) {
    const double *d = dh, *a = dh + 6;
    double ca[6], sa[6];
    for (int i = 0; i < 6; ++i) ca[i] = cos(dh[12 + i]), sa[i] = sin(dh[12 + i]);
    for (int n = 0; n < k; ++n)
        if (polish_one(d, a, ca, sa, iterations, (cplx *)theta + 6 * n, t + 16 * n, size + n)) return 1;
    return 0;
}

/* general_6r._wrap: q wrapped to (-pi, pi] with numpy's floating remainder ((q + pi) % 2 pi, the
 * sign of the divisor), then - pi: the same numbers as numpy's */
static double wrap(double q) {
    double two_pi = 2.0 * M_PI, mod = fmod(q + M_PI, two_pi);
    if (mod != 0.0) {
        if (mod < 0.0) mod += two_pi;
    } else
        mod = 0.0;
    double w = mod - M_PI;
    return w <= -M_PI ? w + two_pi : w;
}

/* general_6r._last_polish of one real candidate th (DH angles): the joint angles q = wrap(th - offset)
 * polished on the DH model from q + offset, then wrap(theta - offset) again, into q. Returns
 * polish_one's code. */
static int last_polish(const double *d, const double *a, const double *ca, const double *sa, const double *offset,
                       const double *th, const double *tn, double *q) {
    cplx x[6];
    double ignored;
    for (int i = 0; i < 6; ++i) x[i] = wrap(th[i] - offset[i]) + offset[i];
    if (polish_one(d, a, ca, sa, 12, x, tn, &ignored)) return 1;
    for (int i = 0; i < 6; ++i) q[i] = wrap(creal(x[i]) - offset[i]);
    return 0;
}

/* general_6r._angle: the angle whose cosine and sine are proportional to c, s, continued
 * analytically to complex values: -i log((c + i s) / sqrt(c^2 + s^2)) */
static cplx angle(cplx c, cplx s) { return -I * clog((c + I * s) / csqrt(c * c + s * s)); }

/* the 14 Raghavan-Roth quantities (l, p, p.p, p.l, p x l, (p.p) l - 2 (p.l) p) of general_6r._fourteen */
static void fourteen(const cplx *l, const cplx *p, cplx *e) {
    cplx pp = p[0] * p[0] + p[1] * p[1] + p[2] * p[2], pl = p[0] * l[0] + p[1] * l[1] + p[2] * l[2];
    for (int i = 0; i < 3; ++i) e[i] = l[i], e[3 + i] = p[i], e[11 + i] = pp * l[i] - 2.0 * pl * p[i];
    e[6] = pp, e[7] = pl;
    e[8] = p[1] * l[2] - p[2] * l[1], e[9] = p[2] * l[0] - p[0] * l[2], e[10] = p[0] * l[1] - p[1] * l[0];
}

/* the back-substitution of one candidate ph (phi_3..5) with the pseudo-inverse pn (8 x 14), the
 * constants rn (14) and the unit-scale target tn of its target: th (6 angles, non-finite ones 0) */
static void back_one(const double *arm, const double *ca, const double *sa, const cplx *ph, const double *pn,
                     const double *rn, const double *tn, cplx *th) {
    const double *d = arm, *a = arm + 6, *rot = arm + 18, *inv6 = arm + 21;
    cplx t[4][4], u[4][4], lhs[14], x[8];
    dh(ph[0] + rot[0], d[2], a[2], ca[2], sa[2], u); /* A_3 A_4 A_5 */
    times_dh(u, ph[1] + rot[1], d[3], a[3], ca[3], sa[3], t);
    times_dh(t, ph[2] + rot[2], d[4], a[4], ca[4], sa[4], u);
    cplx l[3] = {u[0][2], u[1][2], u[2][2]}, p[3] = {u[0][3], u[1][3], u[2][3]};
    fourteen(l, p, lhs);
    for (int i = 0; i < 8; ++i) {
        cplx v = 0;
        for (int j = 0; j < 14; ++j) v += pn[14 * i + j] * (lhs[j] - rn[j]);
        x[i] = v;
    }
    th[0] = angle(x[2], x[5]);
    th[1] = angle(x[0], x[1]);
    for (int i = 0; i < 3; ++i) th[2 + i] = ph[i] + rot[i];
    cplx pre[7][4][4], inv[4][4], w[4][4];
    chain(d, a, ca, sa, th, 5, pre);
    for (int r = 0; r < 3; ++r) { /* (A_1 ... A_5)^-1: transposed rotation, -R^T p */
        for (int c = 0; c < 3; ++c) inv[r][c] = pre[5][c][r];
        inv[r][3] = -(pre[5][0][r] * pre[5][0][3] + pre[5][1][r] * pre[5][1][3] + pre[5][2][r] * pre[5][2][3]);
        inv[3][r] = 0;
    }
    inv[3][3] = 1;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) {
            cplx v = 0;
            for (int j = 0; j < 4; ++j) v += inv[r][j] * tn[4 * j + c];
            w[r][c] = v;
        }
    cplx a60 = 0, a61 = 0; /* column 0 of w A_6^-1, rows 0 and 1 */
    for (int j = 0; j < 4; ++j) a60 += w[0][j] * inv6[4 * j], a61 += w[1][j] * inv6[4 * j];
    th[5] = angle(a60, a61);
    for (int i = 0; i < 6; ++i)
        if (!isfinite(creal(th[i])) || !isfinite(cimag(th[i]))) th[i] = 0;
}

/* `arm`: d (6), a (6), alpha (6) of the unit-scale arm, the rotations delta_3..5 (3), A_6^-1 at
 * theta_6 = 0 (4 x 4); per candidate n < k: phi (3 complex, interleaved), the pseudo-inverse of
 * its target's Q (8 x 14), the constants r0 (14), the unit-scale target T' (4 x 4). `theta` gets
 * the six (complex) angles of each (non-finite ones 0). Returns 0. */
int optik_g6r_back(const double *arm, int k, const double *phi, const double *pinv, const double *r0,
                   const double *tp, double *theta) {
    double ca[6], sa[6];
    for (int i = 0; i < 6; ++i) ca[i] = cos(arm[12 + i]), sa[i] = sin(arm[12 + i]);
    for (int n = 0; n < k; ++n)
        back_one(arm, ca, sa, (const cplx *)phi + 3 * n, pinv + 112 * n, r0 + 14 * n, tp + 16 * n, (cplx *)theta + 6 * n);
    return 0;
}

/* ---------------------------------------------------------------- the whole solve of one target
 * optik_g6r_solve runs steps 1-3 of general_6r (the 14 x 8 matrix Q of the right sides, its SVD,
 * the 12 x 12 coefficients of M(x_3), the singular-pencil probes, the 24 x 24 companion matrix and
 * its eigenvalues), the choice of candidates (finite, not spurious, not far) and, per candidate,
 * the null vector w of M(x_3) (the eigenvector's upper half), the back-substitution, the complex
 * polish and the real retry: what general_6r._candidates does in numpy (which takes w from the
 * companion matrix's eigenvectors instead). The linear algebra is LAPACK's (scipy's, through the
 * function pointers `lapack`: dgesdd, dgebal, dgehd2, dlahqr, dgetrf, dgetrs, dlasq1; one OpenBLAS
 * thread during the call; the 12 x 12 singular values of the probes and of A by our own
 * bidiagonalization and dlasq1): the eigenvalues alone, by balancing, Hessenberg reduction and the double-shift
 * QR (what dgeev runs without eigenvectors, minus its workspace and block-size queries), because
 * the eigenvectors of all 24 cost more than the null vectors of the 16 candidates' 12 x 12 M(x_3). The right sides are trigonometric of degree one in theta_1 and
 * theta_2, so three samples per angle (0, 2 pi / 3, 4 pi / 3) give their coefficients exactly. */
typedef void (*dgesdd_t)(char *, int *, int *, double *, int *, double *, double *, int *, double *, int *, double *,
                         int *, int *, int *);
typedef void (*dgebal_t)(char *, int *, double *, int *, int *, int *, double *, int *);
typedef void (*dgehd2_t)(int *, int *, int *, double *, int *, double *, double *, int *);
typedef void (*dlahqr_t)(int *, int *, int *, int *, int *, double *, int *, double *, double *, int *, int *, double *,
                         int *, int *);
typedef void (*dlasq1_t)(int *, double *, double *, double *, int *);
typedef void (*dgetrf_t)(int *, int *, double *, int *, int *, int *);
typedef void (*dgetrs_t)(char *, int *, int *, double *, int *, int *, double *, int *, int *);

enum { WORK = 4096, MAX_CANDIDATES = 24 };
typedef int (*threads_t)(int);

/* the Householder reflector H = I - tau v v^T with H x = (beta, 0, ..., 0) of x (n entries,
 * stride inc; x_0 = alpha): beta = -sign(alpha) |x|, tau = (beta - alpha) / beta, v = (1,
 * x_1.. / (alpha - beta)), v's tail written over x's (LAPACK's dlarfg, without its rescaling of
 * tiny norms: the entries here are of order one); returns beta */
static double reflector(int n, double *x, int inc, double *tau) {
    double alpha = x[0], tail = 0.0;
    for (int i = 1; i < n; ++i) tail += x[i * inc] * x[i * inc];
    if (tail == 0.0) {
        *tau = 0.0;
        return alpha;
    }
    double beta = -copysign(hypot(alpha, sqrt(tail)), alpha), scale = 1.0 / (alpha - beta);
    *tau = (beta - alpha) / beta;
    for (int i = 1; i < n; ++i) x[i * inc] *= scale;
    return beta;
}

/* singular values of the 12 x 12 column-major matrix a (destroyed), largest first; 0 on
 * success: the Householder bidiagonalization (LAPACK's dgebd2: a reflector from the left on each
 * column, from the right on each row), then dlasq1 (dqds) on the bidiagonal: what dgesdd without
 * vectors does for a matrix this small, without the overhead of its ~50 BLAS calls */
static int singular_values(dlasq1_t lasq1, double *a, double *s) {
    enum { N = 12 };
    double e[N], work[4 * N], tau;
    for (int k = 0; k < N; ++k) {
        double *col = a + k + N * k; /* a[k.., k] */
        s[k] = reflector(N - k, col, 1, &tau);
        for (int j = k + 1; j < N && tau != 0.0; ++j) { /* H a[k.., j] */
            double *c = a + k + N * j, w = c[0];
            for (int i = 1; i < N - k; ++i) w += col[i] * c[i];
            w *= tau, c[0] -= w;
            for (int i = 1; i < N - k; ++i) c[i] -= w * col[i];
        }
        if (k == N - 1) break;
        double *row = a + k + N * (k + 1); /* a[k, k + 1..] */
        e[k] = reflector(N - k - 1, row, N, &tau);
        for (int i = k + 1; i < N && tau != 0.0; ++i) { /* a[i, k + 1..] H */
            double *r = a + i + N * (k + 1), w = r[0];
            for (int j = 1; j < N - k - 1; ++j) w += row[N * j] * r[N * j];
            w *= tau, r[0] -= w;
            for (int j = 1; j < N - k - 1; ++j) r[N * j] -= w * row[N * j];
        }
    }
    int n = N, info = 0;
    lasq1(&n, s, e, work, &info);
    return info;
}

/* the least-squares ratio of general_6r._half_angle: 2 atan(x) from the blocks lo, hi (count
 * entries each, hi = x lo for an exact eigenvector); with `real` from the ratios' real parts */
static cplx half_angle(const cplx *lo, const cplx *hi, int count, int real) {
    cplx fwd = 0, rev = 0;
    double nlo = 0, nhi = 0;
    for (int i = 0; i < count; ++i) {
        fwd += conj(lo[i]) * hi[i], rev += conj(hi[i]) * lo[i];
        nlo += creal(lo[i]) * creal(lo[i]) + cimag(lo[i]) * cimag(lo[i]);
        nhi += creal(hi[i]) * creal(hi[i]) + cimag(hi[i]) * cimag(hi[i]);
    }
    fwd /= fmax(nlo, 1e-300), rev /= fmax(nhi, 1e-300);
    if (real) fwd = creal(fwd), rev = creal(rev);
    return cabs(fwd) <= 1.0 ? 2.0 * catan(fwd) : M_PI - 2.0 * catan(rev);
}

/* (phi_4, phi_5) of the normalized eigenvector part w = (x_4^i x_5^j), i <= 3, j <= 2 */
static void wrist_angles(const cplx *w, int real, cplx *phi) {
    cplx lo[12], hi[12];
    for (int i = 0; i < 9; ++i) lo[i] = w[i], hi[i] = w[i + 3]; /* rows 0..2 against 1..3 */
    phi[0] = half_angle(lo, hi, 9, real);
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 2; ++j) lo[2 * i + j] = w[3 * i + j], hi[2 * i + j] = w[3 * i + j + 1];
    phi[1] = half_angle(lo, hi, 8, real);
}

/* w with M(x) w = 0 for the 12 x 12 column-major coefficients mats (C, B, A) of M(x) = C + B x + A x^2
 * at an eigenvalue x: Gaussian elimination with complete pivoting (the near-zero pivot comes
 * last), then w from the back-substitution with its last entry 1, permuted back, scaled to
 * largest entry 1 */
static void null_vector(const double mats[3][144], cplx x, cplx *w) {
    cplx m[12][12], y[12], x2 = x * x;
    int col[12];
    for (int r = 0; r < 12; ++r)
        for (int c = 0; c < 12; ++c) m[r][c] = mats[0][r + 12 * c] + x * mats[1][r + 12 * c] + x2 * mats[2][r + 12 * c];
    for (int c = 0; c < 12; ++c) col[c] = c;
    for (int k = 0; k < 11; ++k) {
        int pr = k, pc = k;
        double top = -1.0;
        for (int r = k; r < 12; ++r)
            for (int c = k; c < 12; ++c) {
                double size = fabs(creal(m[r][c])) + fabs(cimag(m[r][c]));
                if (size > top) top = size, pr = r, pc = c;
            }
        if (pr != k)
            for (int c = 0; c < 12; ++c) {
                cplx v = m[k][c];
                m[k][c] = m[pr][c], m[pr][c] = v;
            }
        if (pc != k) {
            for (int r = 0; r < 12; ++r) {
                cplx v = m[r][k];
                m[r][k] = m[r][pc], m[r][pc] = v;
            }
            int v = col[k];
            col[k] = col[pc], col[pc] = v;
        }
        if (top == 0.0) continue; /* a null column: its entry of y is taken free below */
        cplx inv = 1.0 / m[k][k];
        for (int r = k + 1; r < 12; ++r) {
            cplx f = m[r][k] * inv;
            for (int c = k + 1; c < 12; ++c) m[r][c] -= f * m[k][c];
        }
    }
    y[11] = 1.0;
    for (int r = 10; r >= 0; --r) {
        cplx v = 0;
        for (int c = r + 1; c < 12; ++c) v -= m[r][c] * y[c];
        y[r] = m[r][r] != 0 ? v / m[r][r] : 0.0;
    }
    int top = 0;
    for (int r = 1; r < 12; ++r)
        if (cabs(y[r]) > cabs(y[top])) top = r;
    cplx scale = y[top];
    for (int r = 0; r < 12; ++r) w[col[r]] = y[r] / scale;
}

/* `model`: the arm as optik_g6r_back takes it (37 numbers), then the 14 x 3 x 3 x 3 coefficients of
 * the left sides (_Left.coef) and A_2^-1 A_1^-1 at the 3 x 3 sample angles (3 x 3 x 4 x 4);
 * `lapack`: dgesdd, dgebal, dgehd2, dlahqr, dgetrf, dgetrs, dlasq1 and OpenBLAS's openblas_set_num_threads_local (or NULL:
 * the threaded BLAS of OpenBLAS costs milliseconds on matrices this small); `tp`: n unit-scale targets T' (4 x 4). Per target t:
 * `info` (8): status (0 done, 1 A too badly conditioned for the companion matrix: QZ needed,
 * 2 a LAPACK failure or an exactly singular Jacobian: the numpy path answers), Q of full rank,
 * pencil regular, pencil well posed, finite non-spurious eigenvalues, those far from the real
 * axis, candidates k. The candidates of the done targets, target after target (a target handed
 * back leaves none; room for 24 per target): `theta` (6 complex each) the polished candidates,
 * `size` their residuals, `retry` whether each was polished from its real part too, `again` (6)
 * the result of that, `owner` the target of each. With `offset` (the arm's 6 joint offsets, or
 * NULL: not done) the last polish of general_6r._last_polish runs here too: `real` (6) gets it
 * for each candidate real to 1e-8 (IMAG_TOL; NaN for the others) and `again` is replaced by it.
 * Returns the number of candidates. */
int optik_g6r_solve(const double *model, void *const *lapack, int n, const double *tp, double *info, double *theta,
                    double *size, int *retry, double *again, const double *offset, double *real, long long *owner) {
    static const double probes[2][3] = {{1.0, 0.5773502692, 0.3333333333}, {1.0, -1.7320508076, 3.0}};
    dgesdd_t gesdd = (dgesdd_t)lapack[0];
    dgebal_t gebal = (dgebal_t)lapack[1];
    dgehd2_t gehd2 = (dgehd2_t)lapack[2];
    dlahqr_t lahqr = (dlahqr_t)lapack[3];
    dgetrf_t getrf = (dgetrf_t)lapack[4];
    dgetrs_t getrs = (dgetrs_t)lapack[5];
    dlasq1_t lasq1 = (dlasq1_t)lapack[6];
    const double *arm = model, *coef = model + 37, *grid = model + 37 + 378, *inv6 = arm + 21;
    const double *d = arm, *a = arm + 6;
    double ca[6], sa[6], wt[3][3];
    for (int i = 0; i < 6; ++i) ca[i] = cos(arm[12 + i]), sa[i] = sin(arm[12 + i]);
    for (int k = 0; k < 3; ++k) { /* f = sum_k wt[basis][k] f(2 pi k / 3) in the basis (1, cos, sin) */
        double g = 2.0 * M_PI * k / 3.0;
        wt[0][k] = 1.0 / 3.0, wt[1][k] = 2.0 / 3.0 * cos(g), wt[2][k] = 2.0 / 3.0 * sin(g);
    }
    threads_t threads = (threads_t)lapack[7]; /* this thread's OpenBLAS threads: 1 for these sizes */
    int total = 0;
    int threads_before = threads ? threads(1) : 0;
    for (int t = 0; t < n; ++t) {
        const double *tn = tp + 16 * t;
        double *out = info + 8 * t;
        for (int i = 0; i < 8; ++i) out[i] = 0.0;
        out[0] = 2.0;
        /* step 1: the fourteen right sides at the 3 x 3 samples, then their coefficients */
        double lv[4], pv[4], f[3][3][14], rhs[14][9];
        for (int r = 0; r < 4; ++r) {
            lv[r] = pv[r] = 0.0;
            for (int j = 0; j < 4; ++j) lv[r] += tn[4 * r + j] * inv6[4 * j + 2], pv[r] += tn[4 * r + j] * inv6[4 * j + 3];
        }
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const double *g = grid + 16 * (3 * i + j);
                cplx l[3] = {0}, p[3] = {0}, e[14];
                for (int r = 0; r < 3; ++r)
                    for (int c = 0; c < 4; ++c) l[r] += g[4 * r + c] * lv[c], p[r] += g[4 * r + c] * pv[c];
                fourteen(l, p, e);
                for (int r = 0; r < 14; ++r) f[i][j][r] = creal(e[r]);
            }
        for (int e = 0; e < 14; ++e)
            for (int u = 0; u < 3; ++u)
                for (int v = 0; v < 3; ++v) {
                    double s = 0.0;
                    for (int i = 0; i < 3; ++i)
                        for (int j = 0; j < 3; ++j) s += wt[u][i] * wt[v][j] * f[i][j][e];
                    rhs[e][3 * u + v] = s;
                }
        /* step 2: SVD of Q (column-major 14 x 8), the pseudo-inverse and the six left null vectors */
        double q[14 * 8], sv[8], uu[14 * 14], vt[8 * 8], r0[14], pinv[8 * 14], work[WORK];
        int iwork[64], m14 = 14, n8 = 8, lwork = WORK, res = 0;
        char jobz = 'A';
        for (int e = 0; e < 14; ++e) {
            r0[e] = rhs[e][0];
            for (int c = 0; c < 8; ++c) q[e + 14 * c] = rhs[e][c + 1];
        }
        gesdd(&jobz, &m14, &n8, q, &m14, sv, uu, &m14, vt, &n8, work, &lwork, iwork, &res);
        if (res) continue;
        out[1] = sv[7] > 1e-11 * sv[0];
        for (int i = 0; i < 8; ++i)
            for (int j = 0; j < 14; ++j) {
                double s = 0.0;
                for (int k = 0; k < 8; ++k) s += vt[k + 8 * i] * uu[j + 14 * k] / sv[k];
                pinv[14 * i + j] = s;
            }
        /* step 3: M(x_3) = C + B x + A x^2, column-major 12 x 12 each (mats[0] = C) */
        double mats[3][144] = {{0}};
        for (int p3 = 0; p3 < 3; ++p3)
            for (int e = 0; e < 6; ++e)
                for (int c = 0; c < 9; ++c) {
                    int b4 = c / 3, b5 = c % 3;
                    double one = (p3 != 1) * (b4 != 1) * (b5 != 1), s = 0.0;
                    for (int k = 0; k < 14; ++k)
                        s += uu[k + 14 * (8 + e)] * (coef[27 * k + 9 * p3 + c] - r0[k] * one);
                    mats[p3][e + 12 * c] = s, mats[p3][(e + 6) + 12 * (c + 3)] = s;
                }
        double ratio = 0.0, s12[12], tmp[144];
        int failed = 0;
        for (int p = 0; p < 2 && !failed; ++p) {
            for (int i = 0; i < 144; ++i)
                tmp[i] = probes[p][0] * mats[0][i] + probes[p][1] * mats[1][i] + probes[p][2] * mats[2][i];
            failed = singular_values(lasq1, tmp, s12);
            ratio = fmax(ratio, s12[11] / s12[0]);
        }
        if (failed) continue;
        out[2] = ratio > 1e-10, out[3] = ratio > 1e-7;
        for (int i = 0; i < 144; ++i) tmp[i] = mats[2][i];
        if (singular_values(lasq1, tmp, s12)) continue;
        if (!(s12[0] / s12[11] < 1e10)) { /* QZ (the numpy path) */
            out[0] = 1.0;
            continue;
        }
        /* the companion matrix [0 I; -A^-1 C  -A^-1 B] (column-major 24 x 24) and its eigenvalues */
        double lu[144], x[12 * 24], comp[24 * 24], wr[24], wi[24], scale[24], tau[24], unused = 0.0;
        int piv[12], n12 = 12, n24 = 24, one = 1, lo = 1, hi = 24, no_schur = 0;
        char trans = 'N', both = 'B';
        for (int i = 0; i < 144; ++i) lu[i] = mats[2][i], x[i] = mats[0][i], x[144 + i] = mats[1][i];
        getrf(&n12, &n12, lu, &n12, piv, &res);
        if (res) continue;
        getrs(&trans, &n12, &n24, lu, &n12, piv, x, &n12, &res);
        if (res) continue;
        for (int c = 0; c < 24; ++c)
            for (int r = 0; r < 24; ++r) comp[r + 24 * c] = r < 12 ? (double)(r == c - 12) : -x[(r - 12) + 12 * c];
        gebal(&both, &n24, comp, &n24, &lo, &hi, scale, &res);
        if (res) continue;
        gehd2(&n24, &lo, &hi, comp, &n24, tau, work, &res);
        if (res) continue;
        lahqr(&no_schur, &no_schur, &n24, &lo, &hi, comp, &n24, wr, wi, &one, &n24, &unused, &one, &res);
        if (res) continue;
        for (int i = 0; i < 24; ++i) /* the eigenvalues that balancing isolated (rows outside lo..hi) */
            if (i < lo - 1 || i >= hi) wr[i] = comp[i + 24 * i], wi[i] = 0.0;
        /* finite, not one of the 4 + 4 nearest +-i (the spurious factor), not far */
        cplx vals[24], vecs[24][12];
        int good[24], spurious[24] = {0}, have[24] = {0};
        for (int j = 0; j < 24; ++j) {
            vals[j] = wr[j] + I * wi[j];
            good[j] = isfinite(wr[j]) && isfinite(wi[j]) && cabs(vals[j]) < 1e12;
        }
        for (int sign = 1; sign >= -1; sign -= 2) {
            double dist[24];
            for (int j = 0; j < 24; ++j) dist[j] = cabs(vals[j] - sign * I);
            for (int rep = 0; rep < 4; ++rep) {
                int best = -1;
                double nearest = INFINITY;
                for (int j = 0; j < 24; ++j)
                    if (good[j] && !spurious[j] && dist[j] < nearest) nearest = dist[j], best = j;
                if (best >= 0) spurious[best] = 1;
            }
        }
        int count = 0, far = 0, k = 0;
        double *th_out = theta + 2 * 6 * total, *size_out = size + total;
        double *again_out = again + 6 * total, *real_out = real + 6 * total;
        int *retry_out = retry + total;
        for (int j = 0; j < 24 && !failed; ++j) {
            if (!good[j] || spurious[j]) continue;
            ++count;
            cplx phi3 = 2.0 * catan(vals[j]);
            if (fabs(cimag(phi3)) > 1.0 && out[3]) {
                ++far;
                continue;
            }
            cplx *v = vecs[j]; /* a pair's second (conjugate) eigenvalue: the conjugate of the first's */
            if (j > 0 && wi[j] < 0.0 && have[j - 1] && wi[j - 1] == -wi[j] && wr[j - 1] == wr[j])
                for (int r = 0; r < 12; ++r) v[r] = conj(vecs[j - 1][r]);
            else
                null_vector(mats, vals[j], v);
            have[j] = 1;
            cplx phi[3], *th = (cplx *)th_out + 6 * k;
            phi[0] = phi3;
            wrist_angles(v, 0, phi + 1);
            back_one(arm, ca, sa, phi, pinv, r0, tn, th);
            failed |= polish_one(d, a, ca, sa, 12, th, tn, size_out + k);
            double imag = 0.0;
            for (int i = 0; i < 6; ++i) imag = fmax(imag, fabs(cimag(th[i])));
            retry_out[k] = imag > 1e-8 && fabs(cimag(phi3)) <= 1e-3;
            if (retry_out[k]) { /* from the real parts */
                cplx flat[3], re[6];
                double ignored;
                flat[0] = creal(phi3);
                wrist_angles(v, 1, flat + 1);
                back_one(arm, ca, sa, flat, pinv, r0, tn, re);
                for (int i = 0; i < 6; ++i) re[i] = creal(re[i]);
                failed |= polish_one(d, a, ca, sa, 12, re, tn, &ignored);
                for (int i = 0; i < 6; ++i) again_out[6 * k + i] = creal(re[i]);
                if (offset) failed |= last_polish(d, a, ca, sa, offset, again_out + 6 * k, tn, again_out + 6 * k);
            }
            if (offset && imag <= 1e-8) {
                double re[6];
                for (int i = 0; i < 6; ++i) re[i] = creal(th[i]);
                failed |= last_polish(d, a, ca, sa, offset, re, tn, real_out + 6 * k);
            } else if (offset)
                for (int i = 0; i < 6; ++i) real_out[6 * k + i] = NAN;
            ++k;
        }
        if (failed) continue;
        out[0] = 0.0, out[4] = count, out[5] = far, out[6] = k;
        for (int i = 0; i < k; ++i) owner[total + i] = t;
        total += k;
    }
    if (threads) threads(threads_before);
    return total;
}

/* ---------------------------------------------------------------- the deduplication of the answers
 * general_6r._distinct: `rows` (k x 6 complex, interleaved) of the targets `owner` (k, each in
 * 0 .. n-1); `order` (k) is scratch. Per target, in the rows' order, a row is kept unless it is
 * within 1e-6 (general_6r._SAME) of a row kept before it, by general_6r._gap: the largest
 * |wrap(Re d)| + |Im d| over the joints of the difference d (the same floating operations as
 * numpy's, so the same decisions). `idx` gets the kept rows' indices target by target, `bounds`
 * (n + 1) where each target's start in `idx`. Returns 0. */
int optik_g6r_distinct(const double *rows, const long long *owner, int k, int n, long long *order, long long *idx,
                       long long *bounds) {
    for (int t = 0; t <= n; ++t) bounds[t] = 0;
    for (int i = 0; i < k; ++i) ++bounds[owner[i] + 1];
    for (int t = 0; t < n; ++t) bounds[t + 1] += bounds[t];
    for (int i = 0; i < k; ++i) order[bounds[owner[i]]++] = i; /* stable; bounds[t] is now the end of t */
    long long start = 0, out = 0;
    for (int t = 0; t < n; ++t) {
        long long end = bounds[t], first = out;
        for (long long g = start; g < end; ++g) {
            const double *r = rows + 12 * order[g];
            int close = 0;
            for (long long h = first; h < out && !close; ++h) {
                const double *s = rows + 12 * idx[h];
                double gap = 0.0;
                for (int j = 0; j < 6; ++j) gap = fmax(gap, fabs(wrap(r[2 * j] - s[2 * j])) + fabs(r[2 * j + 1] - s[2 * j + 1]));
                close = gap < 1e-6;
            }
            if (!close) idx[out++] = order[g];
        }
        bounds[t] = first, start = end;
    }
    bounds[n] = out;
    return 0;
}

/* general_6r._pose_errors of k poses t against k targets (4 x 4 each, row-major): per pair the
 * position error |p - p*| and the geodesic angle atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2) of
 * R = R*^T R(q), with the sums in _pose_errors's order; out (k x 2). Returns 0. */
int optik_g6r_pose_errors(const double *t, const double *target, int k, double *out) {
    for (int n = 0; n < k; ++n) {
        const double *a = t + 16 * n, *b = target + 16 * n;
        double d[3], r[3][3];
        for (int i = 0; i < 3; ++i) d[i] = a[4 * i + 3] - b[4 * i + 3];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) r[i][j] = b[i] * a[j] + b[4 + i] * a[4 + j] + b[8 + i] * a[8 + j];
        double x = r[2][1] - r[1][2], y = r[0][2] - r[2][0], z = r[1][0] - r[0][1];
        double cosine = fmin(fmax((r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0, -1.0), 1.0);
        out[2 * n] = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        out[2 * n + 1] = atan2(0.5 * sqrt(x * x + y * y + z * z), cosine);
    }
    return 0;
}
