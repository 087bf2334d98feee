/* Every real assembly mode of a planar 3-RPR in C: optik.closed_form.parallel.planar_3rpr's
 * float path (coefficients, Cramer start, Newton polish, acceptance, de-duplication, full
 * coordinates), with the degree-6 polynomial's real roots isolated on the unit circle by
 * certified bounds instead of the eigenvalues of its companion matrix.
 *
 * F(phi) = sum_{k=-3..3} c_k e^{i k phi} is real: F = A_0 + sum_{k=1..3} A_k cos k phi + B_k sin k phi.
 * On an interval [m - h, m + h], with R_k = hypot(A_k, B_k), |F'''| <= M3 = sum k^3 R_k, so by
 * Taylor's theorem |F''| <= C = |F''(m)| + h M3 on it and
 *   |F(phi) - F(m)| <= h |F'(m)| + h^2 C / 2,   |F'(phi) - F'(m)| <= h |F''(m)| + h^2 M3 / 2.
 * An interval holds no root when |F(m)| exceeds the first bound (each value widened by the
 * rounding bound E0, E1, E2 of its evaluation), and at most one when F' keeps its sign:
 * then a sign change of F between the ends (or an end where |F| <= E0) gives the root, refined
 * by Newton's method kept inside the bracket. Other intervals are halved. An interval still
 * undecided at half-width H_AMBIGUOUS lies where F and F' are both nearly zero (two roots
 * closer than about 1e-3 rad, or a complex pair that close to the circle): the call answers
 * status 1 and the caller runs the general path (numpy.roots, cluster centroids), as it does
 * for the architecture singularities (F identically zero, W = 0 or singular at a root).
 *
 * Reentrant: stack memory only.
 */
#include <complex.h>
#include <math.h>

typedef double complex cplx;

#define H_AMBIGUOUS 1e-3
#define START_INTERVALS 24
#define MAX_CANDIDATES 32
#define MAX_MODES 12
#define POLISH_ITERS 8
#define QUADRATIC_STOP 1e-9 /* optik.closed_form.parallel.common.QUADRATIC_STOP */
#define EPS 2.220446049250313e-16

static const double PI = 3.141592653589793;
static const double TWO_PI = 6.283185307179586;

/* out[0 .. na + nb - 1) = a * b, Laurent coefficient lists centred alike */
static void mul(const cplx *a, int na, const cplx *b, int nb, cplx *out) {
    for (int i = 0; i < na + nb - 1; ++i) out[i] = 0;
    for (int i = 0; i < na; ++i)
        for (int j = 0; j < nb; ++j) out[i + j] += a[i] * b[j];
}

/* Coefficients c_{-3..3} of F (planar_3rpr._rpr_coefficients) and the magnitude of its terms. */
static double coefficients(const double *b, const double *p, const double *rho, cplx *coef) {
    double b0x = b[0], b0y = b[1], p0x = p[0], p0y = p[1], r0 = rho[0];
    cplx wx[2][3], wy[2][3], k[2][3];
    for (int i = 1; i <= 2; ++i) {
        double dx = p[2 * i] - p0x, dy = p[2 * i + 1] - p0y;
        double ex = b[2 * i] - b0x, ey = b[2 * i + 1] - b0y;
        cplx rdx0 = 0.5 * dx - 0.5 * I * dy, rdx2 = 0.5 * dx + 0.5 * I * dy;
        cplx rdy0 = 0.5 * dy + 0.5 * I * dx, rdy2 = 0.5 * dy - 0.5 * I * dx;
        cplx *x = wx[i - 1], *y = wy[i - 1], *kk = k[i - 1];
        x[0] = rdx0, x[1] = -ex, x[2] = rdx2;
        y[0] = rdy0, y[1] = -ey, y[2] = rdy2;
        cplx e_rd = 2 * (ex * rdx0 + ey * rdy0);
        double base = rho[i] * rho[i] - r0 * r0 - dx * dx - dy * dy - ex * ex - ey * ey;
        kk[0] = e_rd, kk[1] = base, kk[2] = conj(e_rd);
    }
    cplx t1[5], t2[5], det2[5], nx[5], ny[5], n2[9], d2[9], u[9];
    mul(wx[0], 3, wy[1], 3, t1);
    mul(wy[0], 3, wx[1], 3, t2);
    for (int i = 0; i < 5; ++i) det2[i] = 2 * (t1[i] - t2[i]);
    mul(wy[1], 3, k[0], 3, t1);
    mul(wy[0], 3, k[1], 3, t2);
    for (int i = 0; i < 5; ++i) nx[i] = t1[i] - t2[i];
    mul(wx[0], 3, k[1], 3, t1);
    mul(wx[1], 3, k[0], 3, t2);
    for (int i = 0; i < 5; ++i) ny[i] = t1[i] - t2[i];
    mul(nx, 5, nx, 5, n2);
    mul(ny, 5, ny, 5, u);
    for (int i = 0; i < 9; ++i) n2[i] += u[i];
    mul(det2, 5, det2, 5, d2);
    double sn = 0.0, sd = 0.0;
    for (int i = 0; i < 9; ++i) {
        d2[i] = r0 * r0 * d2[i];
        sn += cabs(n2[i]);
        sd += cabs(d2[i]);
    }
    for (int i = 0; i < 7; ++i) coef[i] = n2[i + 1] - d2[i + 1];
    return sn > sd ? sn : sd;
}

typedef struct {
    double a[4], b[4]; /* F = a0 + sum a_k cos k phi + b_k sin k phi */
    double m3, e0, e1, e2; /* bound of |F'''|, rounding bounds of F, F' and F'' */
} Trig;

/* F, F' and F'' at phi (the multiple angles by the addition formulas) */
static void evaluate(const Trig *t, double phi, double *f, double *f1, double *f2) {
    double c1 = cos(phi), s1 = sin(phi);
    double c2 = c1 * c1 - s1 * s1, s2 = 2 * s1 * c1;
    double c3 = c2 * c1 - s2 * s1, s3 = s2 * c1 + c2 * s1;
    double g1 = t->a[1] * c1 + t->b[1] * s1, g2 = t->a[2] * c2 + t->b[2] * s2, g3 = t->a[3] * c3 + t->b[3] * s3;
    *f = t->a[0] + g1 + g2 + g3;
    *f1 = t->b[1] * c1 - t->a[1] * s1 + 2 * (t->b[2] * c2 - t->a[2] * s2) + 3 * (t->b[3] * c3 - t->a[3] * s3);
    *f2 = -(g1 + 4 * g2 + 9 * g3);
}

/* the root of F in [lo, hi], where F is monotone and changes sign: Newton kept in the bracket */
static double refine(const Trig *t, double lo, double hi, double flo) {
    double x = 0.5 * (lo + hi);
    for (int it = 0; it < 100 && hi - lo > 4 * EPS * (1 + fabs(x)); ++it) {
        double f, f1, f2;
        evaluate(t, x, &f, &f1, &f2);
        if (f == 0.0) return x;
        if ((f < 0) == (flo < 0)) lo = x;
        else hi = x;
        double next = f1 != 0.0 ? x - f / f1 : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (fabs(next - x) <= 2 * EPS * (1 + fabs(x))) return next;
        x = next;
    }
    return x;
}

/* Candidate headings (real roots of F on [-pi, pi]); -1: an undecided interval, -2: too many. */
static int roots(const Trig *t, double *out) {
    double stack[64][2];
    int top = 0, n = 0;
    double width = TWO_PI / START_INTERVALS;
    for (int i = START_INTERVALS - 1; i >= 0; --i) {
        stack[top][0] = -PI + width * i;
        stack[top][1] = i == START_INTERVALS - 1 ? PI : -PI + width * (i + 1);
        ++top;
    }
    while (top > 0) {
        --top;
        double lo = stack[top][0], hi = stack[top][1];
        double mid = 0.5 * (lo + hi), h = 0.5 * (hi - lo), f, f1, f2;
        evaluate(t, mid, &f, &f1, &f2);
        double curve = fabs(f2) + t->e2 + h * t->m3; /* bounds |F''| on the interval */
        if (fabs(f) - t->e0 > h * (fabs(f1) + t->e1) + 0.5 * h * h * curve) continue; /* no root */
        if (fabs(f1) - t->e1 > h * (fabs(f2) + t->e2) + 0.5 * h * h * t->m3) { /* F' != 0: one root at most */
            double flo, fhi, g, g2;
            evaluate(t, lo, &flo, &g, &g2);
            evaluate(t, hi, &fhi, &g, &g2);
            if (n >= MAX_CANDIDATES) return -2;
            if (fabs(flo) <= t->e0) out[n++] = lo;
            else if (fabs(fhi) <= t->e0) out[n++] = hi;
            else if ((flo < 0) != (fhi < 0)) out[n++] = refine(t, lo, hi, flo);
            continue;
        }
        if (h < H_AMBIGUOUS || top + 2 > 64) return -1;
        stack[top][0] = mid, stack[top][1] = hi;
        stack[top + 1][0] = lo, stack[top + 1][1] = mid;
        top += 2;
    }
    return n;
}

/* planar_3rpr._cramer_one: P_1 for a heading; 0 when W vanishes or is (nearly) singular */
static int cramer(const double *b, const double *p, const double *rho, double phi, double *ux, double *uy) {
    double c = cos(phi), s = sin(phi);
    double w[2][2], k[2];
    for (int i = 1; i <= 2; ++i) {
        double dx = p[2 * i] - p[0], dy = p[2 * i + 1] - p[1];
        double wx = c * dx - s * dy - (b[2 * i] - b[0]), wy = s * dx + c * dy - (b[2 * i + 1] - b[1]);
        w[i - 1][0] = wx, w[i - 1][1] = wy;
        k[i - 1] = rho[i] * rho[i] - rho[0] * rho[0] - wx * wx - wy * wy;
    }
    double det = w[0][0] * w[1][1] - w[0][1] * w[1][0];
    double w2 = w[0][0] * w[0][0] + w[0][1] * w[0][1] + w[1][0] * w[1][0] + w[1][1] * w[1][1];
    double e_max = 0.0;
    for (int i = 2; i < 6; ++i) {
        double e = fabs(b[i] - b[i % 2]);
        if (e > e_max) e_max = e;
    }
    double floor = 1e-12 * (1 + e_max);
    if (w2 <= floor * floor || !(fabs(det) > 1e-9 * w2)) return 0;
    *ux = b[0] + (w[1][1] * k[0] - w[0][1] * k[1]) / (2 * det);
    *uy = b[1] + (w[0][0] * k[1] - w[1][0] * k[0]) / (2 * det);
    return 1;
}

/* planar_3rpr._polish_one: Newton on |t + R p_i - b_i|^2 = rho_i^2; returns the leg-length error */
static double polish(const double *b, const double *p, const double *rho, double *x) {
    double tx = x[0], ty = x[1], phi = x[2];
    double rmax = fmax(rho[0], fmax(rho[1], rho[2]));
    double stop = 1e-15 * (1 + rmax * rmax);
    for (int it = 0; it < POLISH_ITERS; ++it) {
        double c = cos(phi), s = sin(phi), r[3][3], f[3], fmax_ = 0.0;
        for (int i = 0; i < 3; ++i) {
            double px = p[2 * i], py = p[2 * i + 1];
            double rx = c * px - s * py, ry = s * px + c * py;
            double vx = tx + rx - b[2 * i], vy = ty + ry - b[2 * i + 1];
            f[i] = vx * vx + vy * vy - rho[i] * rho[i];
            r[i][0] = 2 * vx, r[i][1] = 2 * vy, r[i][2] = 2 * (vy * rx - vx * ry);
            if (fabs(f[i]) > fmax_) fmax_ = fabs(f[i]);
        }
        if (fmax_ <= stop) break;
        double a1 = r[0][0], a2 = r[0][1], a3 = r[0][2], b1 = r[1][0], b2 = r[1][1], b3 = r[1][2];
        double c1 = r[2][0], c2 = r[2][1], c3 = r[2][2], f1 = f[0], f2 = f[1], f3 = f[2];
        double det = a1 * (b2 * c3 - b3 * c2) - a2 * (b1 * c3 - b3 * c1) + a3 * (b1 * c2 - b2 * c1);
        if (det == 0.0 || !isfinite(det)) break;
        double dx = (f1 * (b2 * c3 - b3 * c2) - a2 * (f2 * c3 - b3 * f3) + a3 * (f2 * c2 - b2 * f3)) / det;
        double dy = (a1 * (f2 * c3 - b3 * f3) - f1 * (b1 * c3 - b3 * c1) + a3 * (b1 * f3 - f2 * c1)) / det;
        double dp = (a1 * (b2 * f3 - f2 * c2) - a2 * (b1 * f3 - f2 * c1) + f1 * (b1 * c2 - b2 * c1)) / det;
        tx -= dx, ty -= dy, phi -= dp;
        double big = fmax(fabs(tx), fmax(fabs(ty), fabs(phi)));
        if (fmax(fabs(dx), fmax(fabs(dy), fabs(dp))) < QUADRATIC_STOP * (1 + big)) break;
    }
    double c = cos(phi), s = sin(phi), err = 0.0;
    for (int i = 0; i < 3; ++i) {
        double px = p[2 * i], py = p[2 * i + 1];
        double e = fabs(hypot(tx + c * px - s * py - b[2 * i], ty + s * px + c * py - b[2 * i + 1]) - rho[i]);
        if (e > err || isnan(e)) err = e;
    }
    x[0] = tx, x[1] = ty, x[2] = phi;
    return err;
}

/* optik.spatial.wrap_angle on a float: (a + pi) mod 2 pi - pi in (-pi, pi], Python's float modulo */
static double wrap(double a) {
    double v = a + PI, r = fmod(v, TWO_PI);
    if (r != 0.0) {
        if (r < 0) r += TWO_PI;
    } else {
        r = 0.0;
    }
    double w = r - PI;
    return w <= -PI ? w + TWO_PI : w;
}

/* The assembly modes of a 3-RPR. `in`: base points b (3 x 2, row-major), platform points p
 * (3 x 2), leg lengths rho (3), then planar_3rpr_poses' leg-length tolerance. `out`: the number
 * of modes k, then k rows (theta1, rho1, pin1, theta2, rho2, theta3, rho3) (planar_3rpr._pose_row,
 * pin1 not wrapped), at most MAX_MODES. Returns 0, or why the general path must answer: 1 an
 * undecided interval, 2 F identically zero, 3 W singular at a root, 4 more modes than MAX_MODES. */
int optik_rpr_fk(const double *in, double *out) {
    const double *b = in, *p = in + 6, *rho = in + 12, tol = in[15];
    cplx coef[7];
    out[0] = 0.0;
    double magnitude = coefficients(b, p, rho, coef), scale = 0.0;
    for (int i = 0; i < 7; ++i) scale = fmax(scale, cabs(coef[i]));
    if (!(scale > 1e-12 * magnitude)) return 2; /* F identically zero (or not finite) */
    Trig t;
    t.a[0] = creal(coef[3]), t.b[0] = 0.0;
    double sum0 = fabs(t.a[0]), sum1 = 0.0, sum2 = 0.0;
    t.m3 = 0.0;
    for (int k = 1; k <= 3; ++k) {
        t.a[k] = creal(coef[3 + k]) + creal(coef[3 - k]);
        t.b[k] = cimag(coef[3 - k]) - cimag(coef[3 + k]);
        double r = hypot(t.a[k], t.b[k]);
        sum0 += fabs(t.a[k]) + fabs(t.b[k]);
        sum1 += k * (fabs(t.a[k]) + fabs(t.b[k]));
        sum2 += k * k * (fabs(t.a[k]) + fabs(t.b[k]));
        t.m3 += k * k * k * r;
    }
    t.e0 = 64 * EPS * sum0, t.e1 = 64 * EPS * sum1, t.e2 = 64 * EPS * sum2;
    double phis[MAX_CANDIDATES];
    int n = roots(&t, phis);
    if (n < 0) return -n;
    double bmax = 0.0, pmax = 0.0, rmax = fmax(rho[0], fmax(rho[1], rho[2]));
    for (int i = 0; i < 6; ++i) bmax = fmax(bmax, fabs(b[i])), pmax = fmax(pmax, fabs(p[i]));
    double size = bmax + pmax + rmax, accept = tol * fmax(size, 1.0);
    double poses[MAX_MODES][3];
    int k = 0;
    for (int j = 0; j < n; ++j) {
        double phi = phis[j], ux, uy;
        if (!cramer(b, p, rho, phi, &ux, &uy)) return 3;
        double c = cos(phi), s = sin(phi);
        double x[3] = {ux - (c * p[0] - s * p[1]), uy - (s * p[0] + c * p[1]), phi};
        double err = polish(b, p, rho, x);
        if (!(err <= accept)) continue;
        x[2] = wrap(x[2]);
        int fresh = 1;
        for (int i = 0; i < k && fresh; ++i)
            if (hypot(x[0] - poses[i][0], x[1] - poses[i][1]) <= 1e-7 * size && fabs(wrap(x[2] - poses[i][2])) <= 1e-7)
                fresh = 0;
        if (!fresh) continue;
        if (k == MAX_MODES) return 4;
        poses[k][0] = x[0], poses[k][1] = x[1], poses[k][2] = x[2];
        ++k;
    }
    for (int i = 1; i < k; ++i) /* in increasing heading, as planar_3rpr_poses */
        for (int j = i; j > 0 && poses[j][2] < poses[j - 1][2]; --j)
            for (int c = 0; c < 3; ++c) {
                double v = poses[j][c];
                poses[j][c] = poses[j - 1][c], poses[j - 1][c] = v;
            }
    for (int i = 0; i < k; ++i) {
        double tx = poses[i][0], ty = poses[i][1], phi = poses[i][2];
        double c = cos(phi), s = sin(phi), *row = out + 1 + 7 * i;
        static const int at[3][2] = {{0, 1}, {3, 4}, {5, 6}}; /* theta_i, rho_i in the row */
        for (int j = 0; j < 3; ++j) {
            double px = p[2 * j], py = p[2 * j + 1];
            double lx = tx + (px * c - py * s) - b[2 * j], ly = ty + (px * s + py * c) - b[2 * j + 1];
            row[at[j][0]] = atan2(ly, lx);
            row[at[j][1]] = sqrt(lx * lx + ly * ly);
        }
        row[2] = phi - row[0];
    }
    out[0] = k;
    return 0;
}
