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

/* the DH transform of one joint at a (complex) angle */
static void dh(cplx theta, double d, double a, double ca, double sa, cplx m[4][4]) {
    cplx c = ccos(theta), s = csin(theta);
    m[0][0] = c, m[0][1] = -s * ca, m[0][2] = s * sa, m[0][3] = a * c;
    m[1][0] = s, m[1][1] = c * ca, m[1][2] = -c * sa, m[1][3] = a * s;
    m[2][0] = 0, m[2][1] = sa, m[2][2] = ca, m[2][3] = d;
    m[3][0] = 0, m[3][1] = 0, m[3][2] = 0, m[3][3] = 1;
}

/* out = x y (4 x 4) */
static void mul4(cplx x[4][4], cplx y[4][4], cplx out[4][4]) {
    for (int r = 0; r < 4; ++r)
        for (int k = 0; k < 4; ++k) {
            cplx v = 0;
            for (int j = 0; j < 4; ++j) v += x[r][j] * y[j][k];
            out[r][k] = v;
        }
}

/* prefix products pre[0..joints] of the DH transforms at theta */
static void chain(const double *d, const double *a, const double *ca, const double *sa, const cplx *theta,
                  int joints, cplx pre[7][4][4]) {
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) pre[0][r][c] = r == c;
    for (int i = 0; i < joints; ++i) {
        cplx m[4][4];
        dh(theta[i], d[i], a[i], ca[i], sa[i], m);
        mul4(pre[i], m, pre[i + 1]);
    }
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
        for (int r = c + 1; r < 6; ++r)
            if (cabs(j[r][c]) > cabs(j[p][c])) p = r;
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

/* `dh`: d (6), a (6), alpha (6) of the unit-scale arm; `theta`: k candidates x 6 complex angles
 * (interleaved real, imaginary), polished in place; `t`: their targets (k x 4 x 4); `size`: max
 * |r| of each at the end. Returns 0, or 1 when a Jacobian was exactly singular (the caller's
 * numpy path, which then takes least-squares steps, answers). */
int optik_g6r_polish(const double *dh, int k, int iterations, double *theta, const double *t, double *size) {
    const double *d = dh, *a = dh + 6;
    double ca[6], sa[6];
    for (int i = 0; i < 6; ++i) ca[i] = cos(dh[12 + i]), sa[i] = sin(dh[12 + i]);
    for (int n = 0; n < k; ++n) {
        cplx *th = (cplx *)theta + 6 * n, err[6], pre[7][4][4];
        const double *tn = t + 16 * n;
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
        size[n] = now;
    }
    return 0;
}

/* general_6r._angle: the angle whose cosine and sine are proportional to c, s, continued
 * analytically to complex values: -i log((c + i s) / sqrt(c^2 + s^2)) */
static cplx angle(cplx c, cplx s) { return -I * clog((c + I * s) / csqrt(c * c + s * s)); }

/* `arm`: d (6), a (6), alpha (6) of the unit-scale arm, the rotations delta_3..5 (3), A_6^-1 at
 * theta_6 = 0 (4 x 4); per candidate n < k: phi (3 complex, interleaved), the pseudo-inverse of
 * its target's Q (8 x 14), the constants r0 (14), the unit-scale target T' (4 x 4). `theta` gets
 * the six (complex) angles of each (non-finite ones 0). Returns 0. */
int optik_g6r_back(const double *arm, int k, const double *phi, const double *pinv, const double *r0,
                   const double *tp, double *theta) {
    const double *d = arm, *a = arm + 6, *rot = arm + 18, *inv6 = arm + 21;
    double ca[6], sa[6];
    for (int i = 0; i < 6; ++i) ca[i] = cos(arm[12 + i]), sa[i] = sin(arm[12 + i]);
    for (int n = 0; n < k; ++n) {
        const cplx *ph = (const cplx *)phi + 3 * n;
        const double *pn = pinv + 112 * n, *rn = r0 + 14 * n, *tn = tp + 16 * n;
        cplx *th = (cplx *)theta + 6 * n, t[4][4], m[4][4], u[4][4], lhs[14], x[8];
        dh(ph[0] + rot[0], d[2], a[2], ca[2], sa[2], t);
        dh(ph[1] + rot[1], d[3], a[3], ca[3], sa[3], m);
        mul4(t, m, u);
        dh(ph[2] + rot[2], d[4], a[4], ca[4], sa[4], m);
        mul4(u, m, t);
        cplx l[3] = {t[0][2], t[1][2], t[2][2]}, p[3] = {t[0][3], t[1][3], t[2][3]};
        cplx pp = p[0] * p[0] + p[1] * p[1] + p[2] * p[2], pl = p[0] * l[0] + p[1] * l[1] + p[2] * l[2];
        for (int i = 0; i < 3; ++i) lhs[i] = l[i], lhs[3 + i] = p[i], lhs[11 + i] = pp * l[i] - 2.0 * pl * p[i];
        lhs[6] = pp, lhs[7] = pl;
        lhs[8] = p[1] * l[2] - p[2] * l[1], lhs[9] = p[2] * l[0] - p[0] * l[2], lhs[10] = p[0] * l[1] - p[1] * l[0];
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
    return 0;
}
