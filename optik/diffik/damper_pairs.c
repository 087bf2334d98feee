/* optik's damper pairs: the exact distance and witness points of every pair whose screening bound is
 * below the influence distance, in one call (optik/diffik/damper_pairs.py describes the method).
 *
 * A shape is the convex hull of its vertices (in its own frame) grown by a radius: a box (its
 * corners, 0), a sphere (its centre, r), a capsule (its two end centres, r), a convex mesh (its
 * hull's vertices, 0). The distance of two shapes is the distance of the two hulls (GJK with an
 * exact sub-simplex search) minus both radii, exact whenever the hulls are apart; the call
 * returns -1 (the caller asks coal) when the hulls touch or overlap (coal's EPA), when a shape is
 * not of these kinds, or when GJK does not converge. Appended to CasADi's generated code. */

#include <math.h>
#include <string.h>

typedef struct {
    double w[3], a[3], b[3]; /* w = a - b: a point of the Minkowski difference and its two ends */
} dp_point;

static double dp_dot(const double *x, const double *y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; }

/* The vertex of the hull of the n vertices v, placed by the row-major rotation r and origin t
 * (r NULL: already placed), farthest along the base-frame direction d, into out (base frame). */
static void dp_support(const double *v, long long n, const double *r, const double *t, const double *d,
                       double *out) {
    double l[3];
    if (r) {
        for (int j = 0; j < 3; ++j) l[j] = r[j] * d[0] + r[3 + j] * d[1] + r[6 + j] * d[2];
    } else {
        l[0] = d[0], l[1] = d[1], l[2] = d[2];
    }
    long long best = 0;
    double top = dp_dot(v, l);
    for (long long k = 1; k < n; ++k) {
        double s = dp_dot(v + 3 * k, l);
        if (s > top) top = s, best = k;
    }
    const double *x = v + 3 * best;
    if (r) {
        for (int i = 0; i < 3; ++i) out[i] = r[3 * i] * x[0] + r[3 * i + 1] * x[1] + r[3 * i + 2] * x[2] + t[i];
    } else {
        out[0] = x[0], out[1] = x[1], out[2] = x[2];
    }
}

/* Barycentric weights lam of the point of the affine hull of the k points idx of s nearest the
 * origin; 0 when that hull is degenerate or the point is not inside the face (a weight <= 0). */
static int dp_face(const dp_point *s, const int *idx, int k, double *lam) {
    if (k == 1) {
        lam[0] = 1.0;
        return 1;
    }
    double e[3][3], m[3][3], rhs[3], mu[3] = {0.0, 0.0, 0.0};
    const double *w0 = s[idx[0]].w;
    int n = k - 1;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < 3; ++j) e[i][j] = s[idx[i + 1]].w[j] - w0[j];
    for (int i = 0; i < n; ++i) {
        rhs[i] = -dp_dot(e[i], w0);
        for (int j = 0; j < n; ++j) m[i][j] = dp_dot(e[i], e[j]);
    }
    if (n == 1) {
        if (!(m[0][0] > 0.0)) return 0;
        mu[0] = rhs[0] / m[0][0];
    } else if (n == 2) {
        double det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        if (!(det > 1e-12 * m[0][0] * m[1][1])) return 0;
        mu[0] = (rhs[0] * m[1][1] - m[0][1] * rhs[1]) / det;
        mu[1] = (m[0][0] * rhs[1] - m[1][0] * rhs[0]) / det;
    } else {
        double c0 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
        double c1 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
        double c2 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
        double det = m[0][0] * c0 + m[0][1] * c1 + m[0][2] * c2;
        if (!(det > 1e-12 * m[0][0] * m[1][1] * m[2][2])) return 0;
        for (int c = 0; c < 3; ++c) { /* Cramer's rule: column c replaced by rhs */
            double a[3][3];
            memcpy(a, m, sizeof a);
            for (int i = 0; i < 3; ++i) a[i][c] = rhs[i];
            mu[c] = (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                     a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])) /
                    det;
        }
    }
    double first = 1.0;
    for (int i = 0; i < n; ++i) {
        if (!(mu[i] > 0.0)) return 0;
        lam[i + 1] = mu[i];
        first -= mu[i];
    }
    if (!(first > 0.0)) return 0;
    lam[0] = first;
    return 1;
}

/* The point v of the hull of the *n points of s nearest the origin, among the faces that hold the
 * newest point s[*n - 1] (GJK's new nearest point is on one of them, the old one being the nearest
 * of the other points; the caller keeps the old one when this is not nearer): the face it is
 * inside of is the one of smallest distance among the faces whose nearest affine point is inside
 * them (every such point is in the hull, and the nearest point is inside its own face). Keeps that
 * face's points in s and their weights in lam; returns 0 when it is the whole tetrahedron (the
 * origin is inside: the hulls overlap). */
static int dp_closest(dp_point *s, int *n, double *lam, double *v) {
    int best_mask = 0, best_k = 0, best_idx[4] = {0, 0, 0, 0};
    double best = INFINITY, best_lam[4] = {0.0, 0.0, 0.0, 0.0};
    int newest = 1 << (*n - 1);
    for (int mask = newest; mask < (1 << *n); ++mask) {
        if (!(mask & newest)) continue;
        int idx[4], k = 0;
        double l[4], p[3] = {0.0, 0.0, 0.0};
        for (int i = 0; i < *n; ++i)
            if (mask & (1 << i)) idx[k++] = i;
        if (!dp_face(s, idx, k, l)) continue;
        for (int i = 0; i < k; ++i)
            for (int j = 0; j < 3; ++j) p[j] += l[i] * s[idx[i]].w[j];
        double d2 = dp_dot(p, p);
        if (d2 < best) {
            best = d2, best_mask = mask, best_k = k;
            memcpy(best_idx, idx, sizeof idx);
            memcpy(best_lam, l, sizeof l);
        }
    }
    if (best_k == 4 || !best_mask) return 0;
    dp_point kept[4];
    for (int i = 0; i < best_k; ++i) kept[i] = s[best_idx[i]];
    memcpy(s, kept, sizeof(dp_point) * (size_t)best_k);
    *n = best_k;
    v[0] = v[1] = v[2] = 0.0;
    for (int i = 0; i < best_k; ++i) {
        lam[i] = best_lam[i];
        for (int j = 0; j < 3; ++j) v[j] += lam[i] * s[i].w[j];
    }
    return 1;
}

#define DP_ITERATIONS 128

/* GJK between the hulls of (va, na) placed by (ra, ta) and (vb, nb) placed by (rb, tb): 1 with
 * their nearest points pa, pb when they are apart, 0 otherwise (touching, overlap, no convergence). */
static int dp_gjk(const double *va, long long na, const double *ra, const double *ta, const double *vb,
                  long long nb, const double *rb, const double *tb, double *pa, double *pb) {
    dp_point s[4];
    double lam[4] = {1.0, 0.0, 0.0, 0.0}, v[3], d[3];
    int n = 1;
    double ca[3], cb[3], x[3] = {1.0, 0.0, 0.0};
    dp_support(va, na, ra, ta, x, ca); /* any first direction: a support point of each */
    x[0] = -1.0;
    dp_support(vb, nb, rb, tb, x, cb);
    for (int j = 0; j < 3; ++j) d[j] = cb[j] - ca[j];
    dp_support(va, na, ra, ta, d, s[0].a);
    for (int j = 0; j < 3; ++j) d[j] = -d[j];
    dp_support(vb, nb, rb, tb, d, s[0].b);
    for (int j = 0; j < 3; ++j) v[j] = s[0].w[j] = s[0].a[j] - s[0].b[j];
    int converged = 0;
    for (int it = 0; it < DP_ITERATIONS; ++it) {
        double vv = dp_dot(v, v);
        if (!(vv > 1e-24)) return 0;
        dp_point p;
        for (int j = 0; j < 3; ++j) d[j] = -v[j];
        dp_support(va, na, ra, ta, d, p.a);
        dp_support(vb, nb, rb, tb, v, p.b);
        for (int j = 0; j < 3; ++j) p.w[j] = p.a[j] - p.b[j];
        if (vv - dp_dot(v, p.w) <= 1e-13 * vv) { /* duality gap: |v| - distance <= 1e-13 |v| / 2 */
            converged = 1;
            break;
        }
        int seen = 0;
        for (int i = 0; i < n; ++i)
            seen |= !memcmp(s[i].a, p.a, sizeof p.a) && !memcmp(s[i].b, p.b, sizeof p.b);
        if (seen) { /* no new support point: v is the nearest point */
            converged = 1;
            break;
        }
        dp_point old[4];
        double old_lam[4], old_v[3] = {v[0], v[1], v[2]};
        int old_n = n;
        memcpy(old, s, sizeof old);
        memcpy(old_lam, lam, sizeof old_lam);
        s[n++] = p;
        if (!dp_closest(s, &n, lam, v)) return 0;
        if (!(dp_dot(v, v) < vv)) { /* no progress (rounding): the old v is as near as it gets */
            memcpy(s, old, sizeof old);
            memcpy(lam, old_lam, sizeof old_lam);
            v[0] = old_v[0], v[1] = old_v[1], v[2] = old_v[2];
            n = old_n;
            converged = 1;
            break;
        }
    }
    if (!converged) return 0;
    for (int j = 0; j < 3; ++j) {
        pa[j] = pb[j] = 0.0;
        for (int i = 0; i < n; ++i) pa[j] += lam[i] * s[i].a[j], pb[j] += lam[i] * s[i].b[j];
    }
    return 1;
}

/* The pair slot k: witness points, sign and distance of robot part a (at pose ra, ta) and the other
 * shape (vb, nb, rad_b) at (rb, tb); 0 when it needs coal. */
static int dp_pair(const double *va, long long na, double rad_a, const double *ra, const double *ta,
                   const double *vb, long long nb, double rad_b, const double *rb, const double *tb, double *out) {
    double pa[3], pb[3], n[3];
    if (!dp_gjk(va, na, ra, ta, vb, nb, rb, tb, pa, pb)) return 0;
    for (int j = 0; j < 3; ++j) n[j] = pa[j] - pb[j];
    double core = sqrt(dp_dot(n, n));
    if (!(core > 0.0)) return 0;
    double dist = core - rad_a - rad_b;
    for (int j = 0; j < 3; ++j) {
        n[j] /= core;
        out[j] = pa[j] - rad_a * n[j];
        out[3 + j] = pb[j] + rad_b * n[j];
    }
    out[6] = dist >= 0.0 ? 1.0 : -1.0;
    out[7] = dist;
    return 1;
}

/* The damper rows of the pairs within the influence, closest first (damper_pairs.py): returns their
 * count (rows[j * (n_q + 1) ...]: G's row j, then h_j), or -1 when a pair needs coal; *d_min is the
 * smallest distance of the pairs queried (those whose bound is below the influence). */
int optik_damper_pairs(void **p, const long long *dims, const double *par, double *d_min) {
    const double *poses = p[0], *world_bounds = p[1], *own_bounds = p[2];
    const long long *sphere_start = p[3], *moving = p[4], *body = p[5], *self_pairs = p[6];
    const long long *rv_start = p[7], *r_exact = p[10], *wv_start = p[11], *w_exact = p[14];
    const double *rv = p[8], *r_rad = p[9], *wv = p[12], *w_rad = p[13];
    double *pairs = p[15], *sigma = p[16], *dist = p[17], *rows = p[19];
    const double *blocks = p[18];
    long long n_parts = dims[0], n_obj = dims[1], n_self = dims[2], n_b = dims[3], n_s = dims[4], n_q = dims[5];
    double influence = par[0], gain = par[1], margin = par[2], least = INFINITY;
    long long k = 0;
    for (long long a = 0; a < n_parts; ++a) {
        if (!moving[a]) continue;
        const double *ra = poses + 12 * a;
        for (long long o = 0; o < n_obj; ++o) {
            double bound = INFINITY;
            for (long long s = sphere_start[a]; s < sphere_start[a + 1]; ++s)
                if (world_bounds[o * n_s + s] < bound) bound = world_bounds[o * n_s + s];
            if (!(bound < influence)) continue;
            if (!r_exact[a] || !w_exact[o]) return -1;
            double *out = pairs + 8 * k;
            if (!dp_pair(rv + 3 * rv_start[a], rv_start[a + 1] - rv_start[a], r_rad[a], ra, ra + 9,
                         wv + 3 * wv_start[o], wv_start[o + 1] - wv_start[o], w_rad[o], NULL, NULL, out))
                return -1;
            if (out[7] < least) least = out[7];
            if (!(out[7] < influence)) continue;
            double *sig = sigma + n_b * k;
            memset(sig, 0, sizeof(double) * (size_t)n_b);
            sig[body[a]] -= 1.0;
            dist[k++] = out[7];
        }
    }
    for (long long i = 0; i < n_self; ++i) {
        if (!(own_bounds[i] < influence)) continue;
        long long a = self_pairs[2 * i], b = self_pairs[2 * i + 1];
        if (!r_exact[a] || !r_exact[b]) return -1;
        const double *ra = poses + 12 * a, *rb = poses + 12 * b;
        double *out = pairs + 8 * k;
        if (!dp_pair(rv + 3 * rv_start[a], rv_start[a + 1] - rv_start[a], r_rad[a], ra, ra + 9,
                     rv + 3 * rv_start[b], rv_start[b + 1] - rv_start[b], r_rad[b], rb, rb + 9, out))
            return -1;
        if (out[7] < least) least = out[7];
        if (!(out[7] < influence)) continue;
        double *sig = sigma + n_b * k;
        memset(sig, 0, sizeof(double) * (size_t)n_b);
        if (moving[a]) sig[body[a]] -= 1.0;
        if (moving[b]) sig[body[b]] += 1.0;
        dist[k++] = out[7];
    }
    for (long long i = 1; i < k; ++i) { /* stable insertion sort by distance (k is small) */
        for (long long j = i; j > 0 && dist[j] < dist[j - 1]; --j) {
            double t = dist[j];
            dist[j] = dist[j - 1], dist[j - 1] = t;
            for (int c = 0; c < 8; ++c) t = pairs[8 * j + c], pairs[8 * j + c] = pairs[8 * (j - 1) + c], pairs[8 * (j - 1) + c] = t;
            for (long long c = 0; c < n_b; ++c)
                t = sigma[n_b * j + c], sigma[n_b * j + c] = sigma[n_b * (j - 1) + c], sigma[n_b * (j - 1) + c] = t;
        }
    }
    *d_min = least;
    long long written = 0;
    for (long long j = 0; j < k; ++j) { /* G = [n; p_a x n]^T (sum_b sigma_b [J^0; J_w]_b), h = gain (d - margin) */
        const double *u = pairs + 8 * j;
        double delta[3] = {u[0] - u[3], u[1] - u[4], u[2] - u[5]};
        double length = sqrt(dp_dot(delta, delta));
        if (!(length >= 1e-12)) continue; /* touching at a point: no direction, no row */
        double w[6];
        for (int c = 0; c < 3; ++c) w[c] = delta[c] * u[6] / length;
        w[3] = u[1] * w[2] - u[2] * w[1];
        w[4] = u[2] * w[0] - u[0] * w[2];
        w[5] = u[0] * w[1] - u[1] * w[0];
        double *row = rows + (n_q + 1) * written;
        for (long long c = 0; c < n_q; ++c) row[c] = 0.0;
        for (long long b = 0; b < n_b; ++b) {
            double sb = sigma[n_b * j + b];
            if (sb == 0.0) continue;
            const double *blk = blocks + 6 * n_q * b; /* column-major 6 x n_q */
            for (long long c = 0; c < n_q; ++c) {
                const double *col = blk + 6 * c;
                row[c] += sb * (w[0] * col[0] + w[1] * col[1] + w[2] * col[2] + w[3] * col[3] + w[4] * col[4] + w[5] * col[5]);
            }
        }
        row[n_q] = gain * (u[7] - margin);
        ++written;
    }
    return (int)written;
}
