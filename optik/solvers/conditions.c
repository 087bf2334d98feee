/* Condition numbers sigma_max / sigma_min of small dense matrices, by one-sided Jacobi
 * (Hestenes): plane rotations of pairs of the k = min(rows, cols) vectors (the columns, or the
 * rows of a wide matrix) until every pair is orthogonal to rounding; the singular values are
 * then the vectors' norms, each to high relative accuracy (Demmel and Veselic, 1992).
 * Reentrant: stack memory only.
 */
#include <math.h>

#define MAX_K 16
#define MAX_L 64
#define MAX_SWEEPS 60
#define EPS 2.220446049250313e-16

/* `count` matrices `rows` x `cols`, row-major one after the other in `a`: out[i] = the
 * condition number of matrix i (INFINITY when its smallest singular value is 0). Returns 0, or 1
 * for a shape beyond MAX_K x MAX_L or a non-finite entry (the caller decides). */
int optik_conditions(const double *a, int count, int rows, int cols, double *out) {
    int wide = rows < cols, k = wide ? rows : cols, len = wide ? cols : rows;
    if (k < 1 || k > MAX_K || len > MAX_L) return 1;
    for (int m = 0; m < count; ++m) {
        const double *x = a + (long)m * rows * cols;
        double u[MAX_K][MAX_L];
        for (int i = 0; i < k; ++i)
            for (int r = 0; r < len; ++r) {
                double v = wide ? x[i * cols + r] : x[r * cols + i];
                if (!isfinite(v)) return 1;
                u[i][r] = v;
            }
        for (int sweep = 0, rotated = 1; rotated && sweep < MAX_SWEEPS; ++sweep) {
            rotated = 0;
            for (int i = 0; i < k - 1; ++i)
                for (int j = i + 1; j < k; ++j) {
                    double alpha = 0.0, beta = 0.0, gamma = 0.0;
                    for (int r = 0; r < len; ++r) {
                        alpha += u[i][r] * u[i][r];
                        beta += u[j][r] * u[j][r];
                        gamma += u[i][r] * u[j][r];
                    }
                    if (!(fabs(gamma) > EPS * sqrt(alpha * beta))) continue;
                    rotated = 1;
                    double zeta = (beta - alpha) / (2.0 * gamma);
                    double t = (zeta >= 0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
                    double c = 1.0 / sqrt(1.0 + t * t), s = c * t;
                    for (int r = 0; r < len; ++r) {
                        double ui = u[i][r], uj = u[j][r];
                        u[i][r] = c * ui - s * uj;
                        u[j][r] = s * ui + c * uj;
                    }
                }
        }
        double hi = 0.0, lo = INFINITY;
        for (int i = 0; i < k; ++i) {
            double n2 = 0.0;
            for (int r = 0; r < len; ++r) n2 += u[i][r] * u[i][r];
            double n = sqrt(n2);
            hi = n > hi ? n : hi;
            lo = n < lo ? n : lo;
        }
        out[m] = lo > 0 ? hi / lo : INFINITY;
    }
    return 0;
}
