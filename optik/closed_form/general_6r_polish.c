/* Newton's method on the pose of a 6R arm in standard DH form, real or complex angles, in C:
 * optik.closed_form.general_6r._polish (same residual, Jacobian, bounded step and stopping
 * rules), one candidate after the other.
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

/* prefix products pre[0..6] of the DH transforms at theta */
static void chain(const double *d, const double *a, const double *ca, const double *sa, const cplx *theta,
                  cplx pre[7][4][4]) {
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) pre[0][r][c] = r == c;
    for (int i = 0; i < 6; ++i) {
        cplx c = ccos(theta[i]), s = csin(theta[i]), m[4][4] = {
            {c, -s * ca[i], s * sa[i], a[i] * c},
            {s, c * ca[i], -c * sa[i], a[i] * s},
            {0, sa[i], ca[i], d[i]},
            {0, 0, 0, 1},
        };
        for (int r = 0; r < 4; ++r)
            for (int k = 0; k < 4; ++k) {
                cplx v = 0;
                for (int j = 0; j < 4; ++j) v += pre[i][r][j] * m[j][k];
                pre[i + 1][r][k] = v;
            }
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
        chain(d, a, ca, sa, th, pre);
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
            chain(d, a, ca, sa, th, pre);
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
