/* The least-motion dynamic program of optik.path.graph, in C (same recursion, same answer).
 *
 * Layer k holds offset[k+1] - offset[k] nodes, rows of `nodes` (n doubles each). For each node
 * b of layer k+1, the predecessors a are visited in increasing order of their cost C_k(a); the
 * visit stops as soon as C_k(a) >= the best cost found for b (no later a can beat it), and the
 * squared edge length is summed joint by joint, stopping when it exceeds (best - C_k(a))^2.
 * This branch-and-bound is exact: it skips only edges that cannot improve on the best. Ties go
 * to the predecessor listed first (the sort is stable on equal costs, an equal total does not
 * replace the best).
 *
 * A joint with period[j] > 0 measures its difference modulo the period, in [-period/2,
 * period/2] (the relaxed graph of optik.path.plan, one node per solution and no turns).
 *
 * Reentrant: every buffer belongs to the caller.
 */
#include <math.h>

/* stable sort of idx[0..k) by key[idx] (insertion sort for short runs, merge sort above) */
static void sort_by(int *idx, int *tmp, int k, const double *key) {
    if (k < 24) {
        for (int i = 1; i < k; ++i) {
            int v = idx[i];
            int j = i - 1;
            while (j >= 0 && key[idx[j]] > key[v]) {
                idx[j + 1] = idx[j];
                --j;
            }
            idx[j + 1] = v;
        }
        return;
    }
    int h = k / 2;
    sort_by(idx, tmp, h, key);
    sort_by(idx + h, tmp, k - h, key);
    int i = 0, j = h, o = 0;
    while (i < h && j < k) tmp[o++] = key[idx[j]] < key[idx[i]] ? idx[j++] : idx[i++];
    while (i < h) tmp[o++] = idx[i++];
    while (j < k) tmp[o++] = idx[j++];
    for (int q = 0; q < k; ++q) idx[q] = tmp[q];
}

/* Returns -1 with index[] and *total set, or the first layer no node of which is reachable. */
int optik_path_dp(int n_layers, const int *offset, const double *nodes, int n, const double *w,
                  const double *period, const double *bounds, double *cost, int *back, int *order, int *tmp, int *index,
                  double *total) {
    for (int a = offset[0]; a < offset[1]; ++a) cost[a] = 0.0;
    for (int k = 1; k < n_layers; ++k) {
        int p0 = offset[k - 1], kp = offset[k] - p0;
        for (int i = 0; i < kp; ++i) order[i] = p0 + i;
        sort_by(order, tmp, kp, cost);
        const double *bd = bounds ? bounds + (long)(k - 1) * n : 0;
        int reached = 0;
        for (int b = offset[k]; b < offset[k + 1]; ++b) {
            const double *qb = nodes + (long)b * n;
            double best = INFINITY;
            int arg = -1;
            for (int i = 0; i < kp; ++i) {
                int a = order[i];
                double ca = cost[a];
                if (!(ca < best)) break; /* sorted: no later predecessor can do better */
                double room = best - ca, room2 = room * room, s = 0.0;
                const double *qa = nodes + (long)a * n;
                int ok = 1;
                for (int j = 0; j < n; ++j) {
                    double d = qb[j] - qa[j];
                    if (period[j] > 0.0) { /* |d| is a few periods at most: subtract whole ones */
                        double p = period[j], half = 0.5 * p;
                        while (d > half) d -= p;
                        while (d < -half) d += p;
                    }
                    if (bd && fabs(d) > bd[j]) {
                        ok = 0;
                        break;
                    }
                    double e = w[j] * d;
                    s += e * e;
                    if (s >= room2) {
                        ok = 0;
                        break;
                    }
                }
                if (!ok) continue;
                double c = ca + sqrt(s);
                if (c < best) {
                    best = c;
                    arg = a;
                }
            }
            cost[b] = best;
            back[b] = arg;
            reached |= arg >= 0;
        }
        if (!reached) return k;
    }
    int l0 = offset[n_layers - 1], best_b = l0;
    for (int b = l0 + 1; b < offset[n_layers]; ++b)
        if (cost[b] < cost[best_b]) best_b = b;
    *total = cost[best_b];
    index[n_layers - 1] = best_b;
    for (int k = n_layers - 1; k > 0; --k) index[k - 1] = back[index[k]];
    for (int k = 0; k < n_layers; ++k) index[k] -= offset[k];
    return -1;
}
