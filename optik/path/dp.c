/* The least-motion dynamic program of optik.path.graph, in C (same recursion, same answer).
 *
 * Layer k holds offset[k+1] - offset[k] nodes, rows of `nodes` (n doubles each). Each layer is
 * sorted by one coordinate, the key (`first`: the one that tells the nodes apart most). For
 * each node b of layer k+1, in key order, the predecessors a are visited outwards from b in the
 * key; the visit stops as soon as the least predecessor cost plus the key distance alone
 * reaches the best cost found for b (no later a can beat it), an a whose own cost plus that
 * distance reaches it is skipped, and the squared edge length is summed joint by joint,
 * stopping when it exceeds (best - C_k(a))^2. This branch and bound is exact: it skips only
 * edges that cannot improve on the best. On equal totals the first edge found is kept.
 *
 * A joint with period[j] > 0 measures its difference modulo the period, in [-period/2,
 * period/2] (the relaxed graph of optik.path.plan, one node per solution and no turns); a
 * periodic key is ordered by its value modulo the period, whatever turn the node is on.
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

/* d modulo p in [-p/2, p/2] (p > 0; d itself when p is 0): d - p round(d / p), one step for
 * any number of periods, as optik.path.graph.differences */
static double wrapped(double d, double p) {
    return p > 0.0 ? d - p * nearbyint(d / p) : d;
}

/* Sorts the nodes [p0, p0 + k) into out[0..k) by key, warm-started from `prev`, the sorted
 * order of the previous layer (its `kprev` nodes start at `pprev`): consecutive layers hold the
 * solutions of nearby poses in the same order, so that order is nearly sorted and an insertion
 * sort finishes in about k steps. Past a budget of shifts it falls back to the merge sort. */
static void sort_layer(int *out, int *tmp, const int *prev, int kprev, int pprev, int p0, int k,
                       const double *key) {
    int m = 0;
    for (int i = 0; i < kprev; ++i)
        if (prev[i] - pprev < k) out[m++] = p0 + prev[i] - pprev;
    for (int i = kprev; i < k; ++i) out[m++] = p0 + i; /* the local indices past the previous layer */
    long budget = 16L * k;
    for (int i = 1; i < k; ++i) {
        int v = out[i];
        int j = i - 1;
        while (j >= 0 && key[out[j]] > key[v]) {
            out[j + 1] = out[j];
            --j;
            if (--budget < 0) {
                out[j + 1] = v;
                sort_by(out, tmp, k, key);
                return;
            }
        }
        out[j + 1] = v;
    }
}

/* whether the predecessor `a` is among the `count` removed predecessors `list` of a node */
static int banned(const int *list, int count, int a) {
    for (int i = 0; i < count; ++i)
        if (list[i] == a) return 1;
    return 0;
}

/* Returns -1 with index[] and *total set, or the first layer no node of which is reachable.
 * key[] (one per node) receives the nodes' coordinate `first` (the one the scan orders by); order[] and here[] (each of the
 * largest layer's size) hold the sorted orders of the previous and the current layer. When
 * fstart is not NULL, the edges from fpred[fstart[b] .. fstart[b + 1]) to node b are removed
 * (edges in collision: optik.path.plan). */
int optik_path_dp(int n_layers, const int *offset, const double *nodes, int n, int first, const double *w,
                  const double *period, const double *bounds, double *cost, int *back, int *order,
                  int *tmp, int *index, double *total, double *key, int *here, const int *fstart,
                  const int *fpred) {
    const double w0 = fabs(w[first]), p0d = period[first];
    /* a periodic key is taken into [0, p0d), so that the key order is the order around the
     * circle: the unvisited predecessors are then one arc, nearest at one of its two ends */
    for (int a = 0; a < offset[n_layers]; ++a) {
        double v = nodes[(long)a * n + first];
        if (p0d > 0.0) {
            v -= p0d * floor(v / p0d);
            if (v >= p0d) v -= p0d; /* a rounding of a tiny negative v */
        }
        key[a] = v;
    }
    for (int a = offset[0]; a < offset[1]; ++a) cost[a] = 0.0;
    for (int i = 0; i < offset[1] - offset[0]; ++i) order[i] = offset[0] + i;
    sort_by(order, tmp, offset[1] - offset[0], key);
    for (int k = 1; k < n_layers; ++k) {
        int p0 = offset[k - 1], kp = offset[k] - p0, kb = offset[k + 1] - offset[k];
        sort_layer(here, tmp, order, kp, p0, offset[k], kb, key);
        double cmin = INFINITY;
        for (int i = 0; i < kp; ++i)
            if (cost[p0 + i] < cmin) cmin = cost[p0 + i];
        const double *bd = bounds ? bounds + (long)(k - 1) * n : 0;
        int reached = 0, lo = 0;
        for (int ib = 0; ib < kb; ++ib) { /* the nodes in increasing key: lo only moves up */
            int b = here[ib];
            const double *qb = nodes + (long)b * n;
            double b0 = key[b], best = INFINITY;
            int arg = -1;
            while (lo < kp && key[order[lo]] < b0) ++lo; /* first predecessor with key >= b0 */
            int r = lo, l = lo - 1;
            for (int seen = 0; seen < kp; ++seen) {
                /* the nearer unvisited predecessor in the key coordinate, on either side */
                int ir = p0d > 0.0 && r >= kp ? r - kp : r, il = p0d > 0.0 && l < 0 ? l + kp : l; /* r < 2 kp, l >= -kp */
                double dr = (p0d > 0.0 || r < kp) ? fabs(wrapped(key[order[ir]] - b0, p0d)) : INFINITY;
                double dl = (p0d > 0.0 || l >= 0) ? fabs(wrapped(key[order[il]] - b0, p0d)) : INFINITY;
                int take;
                double d0;
                if (dr <= dl) {
                    take = order[ir], d0 = dr, ++r;
                } else {
                    take = order[il], d0 = dl, --l;
                }
                /* every unvisited predecessor is at least d0 away in the key coordinate */
                if (!(cmin + w0 * d0 < best) || (bd && d0 > bd[first])) break;
                double ca = cost[take];
                if (!(ca + w0 * d0 < best)) continue;
                double room = best - ca, room2 = room * room, s = 0.0;
                const double *qa = nodes + (long)take * n;
                int ok = 1;
                for (int j = 0; j < n; ++j) {
                    double d = wrapped(qb[j] - qa[j], period[j]);
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
                if (c < best && !(fstart && banned(fpred + fstart[b], fstart[b + 1] - fstart[b], take))) {
                    best = c;
                    arg = take;
                }
            }
            cost[b] = best;
            back[b] = arg;
            reached |= arg >= 0;
        }
        if (!reached) return k;
        int *swap = order; /* the current order is the next layer's previous one */
        order = here, here = swap;
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
