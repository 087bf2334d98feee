/* optik: the projected Levenberg-Marquardt driver over a chunk of IK targets.
 *
 * Compiled together with the CasADi-generated functions OPTIK_STEP (one LM iteration) and
 * OPTIK_ERRORS (the success check's errors); optik/solvers/lm_kernel.py defines OPTIK_NQ,
 * OPTIK_NT (target parameters per target: 12 per frame target), OPTIK_STEP and OPTIK_ERRORS
 * before this file and documents the algorithm. Every target runs
 * its own multi-start loop: the start q0, then starts drawn uniformly within the limits from
 * a splitmix64 stream seeded with the target's seed; iterations until the errors are below the
 * stop thresholds, a block of iterations stalls, max_iter iterations, or the target's time
 * limit (checked after every iteration). Reentrant: work memory is allocated per call.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* conf: [block, max_iter, max_restarts (< 0: none), time_limit, mu0, stall,
 *        stop_position, stop_orientation, stop_closure, gain, w_p, w_o,
 *        lower[n], upper[n] (sampling bounds of the restarts), q_ref[n],
 *        limit_lo[n], limit_hi[n] (the limits the steps project onto; may be infinite),
 *        band_lo[n], band_hi[n] (the open intervals within which an answer is its own wrap;
 *        may be infinite: optik.solvers.base.wrap_bands)] */
#define OPTIK_CONF_SCALARS 12

static double optik_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static unsigned long long optik_splitmix64(unsigned long long *state) {
  unsigned long long z = (*state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

static int optik_work(int (*work)(casadi_int *, casadi_int *, casadi_int *, casadi_int *),
                      casadi_int *sz) {
  return work(&sz[0], &sz[1], &sz[2], &sz[3]);
}

/* Status codes: 0 converged (stop thresholds met), 1 time limit, 2 max_restarts, -1 error. */
CASADI_SYMBOL_EXPORT int optik_lm_chunk(casadi_int n_targets, const double *targets, const double *q0,
                                        const unsigned long long *seeds, const double *conf,
                                        double *q_out, double *err_out, casadi_int *iter_out,
                                        casadi_int *restart_out, casadi_int *status_out,
                                        double *time_out) {
  enum { N = OPTIK_NQ };
  casadi_int ss[4], se[4];
  optik_work(OPTIK_STEP_WORK, ss);
  optik_work(OPTIK_ERRORS_WORK, se);
  casadi_int n_iw = ss[2] > se[2] ? ss[2] : se[2];
  casadi_int n_w = ss[3] > se[3] ? ss[3] : se[3];
  casadi_int *iw = (casadi_int *)malloc(sizeof(casadi_int) * (size_t)(n_iw + 1));
  double *w = (double *)malloc(sizeof(double) * (size_t)(n_w + 1));
  if (!iw || !w) {
    free(iw);
    free(w);
    return -1;
  }
  const casadi_int block = (casadi_int)conf[0], max_iter = (casadi_int)conf[1];
  const casadi_int max_restarts = (casadi_int)conf[2];
  const double time_limit = conf[3], mu0 = conf[4], stall = conf[5];
  const double stop_p = conf[6], stop_o = conf[7], stop_c = conf[8];
  const double gain = conf[9];
  const double weights[2] = {conf[10], conf[11]};
  const double *lower = conf + OPTIK_CONF_SCALARS, *upper = lower + N;
  const double *q_ref = upper + N, *limit_lo = q_ref + N, *limit_hi = limit_lo + N;
  int rc = 0;
  for (casadi_int t = 0; t < n_targets; ++t) {
    const double t0 = optik_now(), deadline = t0 + time_limit;
    const double *target = targets + OPTIK_NT * t;
    unsigned long long rng = seeds[t];
    double q[N], q_new[N], best[N], mu, mu_new, cost, pos, ori, clo, accept;
    double best_cost = INFINITY, e3[3];
    casadi_int iterations = 0, restarts = -1, status = 0;
    const double *answer = q;
    memcpy(best, q0 + N * t, sizeof(best));
    /* step: (q, mu, target, weights, q_ref, gain, lo, hi) -> (q+, mu+, cost+, accept, pos+, ori+, clo+) */
    /* OPTIK_SZ_ARG / OPTIK_SZ_RES: the functions' sz_arg / sz_res (a function that calls others
       uses the entries past its own inputs and outputs as scratch) */
    const double *s_arg[OPTIK_SZ_ARG] = {q, &mu, target, weights, q_ref, &gain, limit_lo, limit_hi};
    double *s_res[OPTIK_SZ_RES] = {q_new, &mu_new, &cost, &accept, &e3[0], &e3[1], &e3[2]};
    const double *e_arg[OPTIK_SZ_ARG] = {q, target};
    double *e_res[OPTIK_SZ_RES] = {&pos, &ori, &clo};
    for (;;) {
      ++restarts;
      if (restarts == 0) {
        memcpy(q, q0 + N * t, sizeof(q));
      } else {
        for (int j = 0; j < N; ++j) {
          double u = (double)(optik_splitmix64(&rng) >> 11) * 0x1.0p-53;
          q[j] = lower[j] + (upper[j] - lower[j]) * u;
        }
      }
      if (OPTIK_ERRORS(e_arg, e_res, iw, w, 0)) { rc = -1; status = -1; break; }
      if (pos <= stop_p && ori <= stop_o && clo <= stop_c) { answer = q; status = 0; break; }
      mu = mu0;
      double previous = INFINITY;
      int out_of_time = 0;
      for (casadi_int k = 1; k <= max_iter; ++k) {
        if (OPTIK_STEP(s_arg, s_res, iw, w, 0)) { rc = -1; status = -1; break; }
        ++iterations;
        memcpy(q, q_new, sizeof(q));
        mu = mu_new;
        if (accept != 0.0) { pos = e3[0]; ori = e3[1]; clo = e3[2]; }
        if (cost < best_cost) { best_cost = cost; memcpy(best, q, sizeof(best)); }
        if (pos <= stop_p && ori <= stop_o && clo <= stop_c) { status = 0; goto done; }
        if (optik_now() >= deadline) { out_of_time = 1; break; }
        if (k % block == 0) {
          if (cost > stall * previous) break;
          previous = cost;
        }
      }
      if (status == -1) break;
      if (out_of_time || optik_now() >= deadline) { status = 1; answer = best; break; }
      if (max_restarts >= 0 && restarts >= max_restarts) { status = 2; answer = best; break; }
    }
  done:
    memcpy(q_out + N * t, answer, sizeof(q));
    if (status != -1) { /* the errors of the answer (the best start's may be older) */
      const double *a_arg[OPTIK_SZ_ARG] = {q_out + N * t, target};
      if (OPTIK_ERRORS(a_arg, e_res, iw, w, 0)) { rc = -1; status = -1; }
    }
    err_out[3 * t] = pos;
    err_out[3 * t + 1] = ori;
    err_out[3 * t + 2] = clo;
    iter_out[t] = iterations;
    restart_out[t] = restarts;
    status_out[t] = status;
    time_out[t] = optik_now() - t0;
  }
  free(iw);
  free(w);
  return rc;
}

/* optik_lm_chunk with its arguments packed in one array: args[0] the target count (as an
 * integer), args[1..10] the pointers in optik_lm_chunk's order. One ctypes argument instead of
 * eleven: a single solve's call costs about a microsecond instead of ten. */
CASADI_SYMBOL_EXPORT int optik_lm_packed(void *const *args) {
  return optik_lm_chunk((casadi_int)(size_t)args[0], (const double *)args[1], (const double *)args[2],
                        (const unsigned long long *)args[3], (const double *)args[4], (double *)args[5],
                        (double *)args[6], (casadi_int *)args[7], (casadi_int *)args[8],
                        (casadi_int *)args[9], (double *)args[10]);
}

/* The whole per-call work of one solve_ik call, for optik.solvers.lm.LMCall.
 * args: [transform (4x4, row-major), q0[n], seed, conf, q_out[n], err_out[3], counts[4], time_out]
 * with counts = (iterations, restarts, status, canonical) as 64-bit integers. The transform is
 * checked first, as optik.checks.as_transform checks it (the same expressions in the same order,
 * the tolerances OPTIK_ORTHO_DIAG / OPTIK_ORTHO_OFF defined from it), then q0 for finiteness;
 * they become the 12 target parameters [vec(R) column-major; p] and the solve runs as
 * optik_lm_chunk's for one target. canonical = 1 when every coordinate of the answer, one by
 * one, lies within [limit_lo, limit_hi] and within (band_lo, band_hi) (conf: the open interval
 * within which a value is its own wrap, optik.solvers.base.wrap_bands); without spherical or free joints that
 * is the answer make_result keeps as it is, with them it is not enough: the norms of their
 * rotation vectors are checked in Python (optik.solvers.base.rotation_vectors_canonical, in
 * LMCall) before the answer is kept.
 * Returns 0, 2 (the transform fails the check: Python raises the named error), 3 (q0 is not
 * finite) or -1 (evaluation error). */
CASADI_SYMBOL_EXPORT int optik_lm_call(void *const *args) {
  enum { N = OPTIK_NQ };
  const double *t = (const double *)args[0], *q0 = (const double *)args[1];
  const double *conf = (const double *)args[3];
  double *q_out = (double *)args[4];
  casadi_int *counts = (casadi_int *)args[6];
  for (int i = 0; i < 16; ++i)
    if (!isfinite(t[i])) return 2;
  if (!(fabs(t[12]) <= 1e-9 && fabs(t[13]) <= 1e-9 && fabs(t[14]) <= 1e-9 &&
        fabs(t[15] - 1.0) <= 1e-9 + 1e-5))
    return 2;
  const double r00 = t[0], r01 = t[1], r02 = t[2], r10 = t[4], r11 = t[5], r12 = t[6];
  const double r20 = t[8], r21 = t[9], r22 = t[10];
  if (!(fabs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0) <= OPTIK_ORTHO_DIAG &&
        fabs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0) <= OPTIK_ORTHO_DIAG &&
        fabs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0) <= OPTIK_ORTHO_DIAG &&
        fabs(r00 * r01 + r10 * r11 + r20 * r21) <= OPTIK_ORTHO_OFF &&
        fabs(r00 * r02 + r10 * r12 + r20 * r22) <= OPTIK_ORTHO_OFF &&
        fabs(r01 * r02 + r11 * r12 + r21 * r22) <= OPTIK_ORTHO_OFF &&
        r00 * (r11 * r22 - r21 * r12) - r10 * (r01 * r22 - r21 * r02) + r20 * (r01 * r12 - r11 * r02) >=
            0.0))
    return 2;
  for (int j = 0; j < N; ++j)
    if (!isfinite(q0[j])) return 3;
  const double params[12] = {r00, r10, r20, r01, r11, r21, r02, r12, r22, t[3], t[7], t[11]};
  int rc = optik_lm_chunk(1, params, q0, (const unsigned long long *)args[2], conf, q_out,
                          (double *)args[5], &counts[0], &counts[1], &counts[2], (double *)args[7]);
  const double *limit_lo = conf + OPTIK_CONF_SCALARS + 3 * N, *limit_hi = limit_lo + N;
  const double *band_lo = limit_hi + N, *band_hi = band_lo + N;
  casadi_int canonical = 1;
  for (int j = 0; j < N; ++j)
    if (!(limit_lo[j] <= q_out[j] && q_out[j] <= limit_hi[j] && band_lo[j] < q_out[j] && q_out[j] < band_hi[j]))
      canonical = 0;
  counts[3] = canonical;
  return rc;
}

/* A check of an answer that optik_lm_call_checked runs in the same call: check(block + 1, q),
 * block[0] the function itself and the entries after it its arguments; nonzero: it failed. */
typedef int (*optik_check_fn)(void *const *args, const double *q);

/* optik_lm_call, then, when the answer is one LMCall keeps as it is (canonical and within the
 * tolerances: the errors at most tol[0..2], NaN failing), the check of that answer: one C call
 * for the solve and its test (optik.solvers.collision_free.CollisionCall: the screening bounds of
 * the exact collision check, optik.collision.screen). args: optik_lm_call's 8, then the
 * tolerances (3 doubles) and the check's block (see optik_check_fn). The check writes its own
 * verdict; it is not run for any other answer. Returns optik_lm_call's code, or -1 when the
 * check failed. */
CASADI_SYMBOL_EXPORT int optik_lm_call_checked(void *const *args) {
  int rc = optik_lm_call(args);
  if (rc != 0) return rc;
  const double *err = (const double *)args[5], *tol = (const double *)args[8];
  const casadi_int *counts = (const casadi_int *)args[6];
  if (counts[3] && err[0] <= tol[0] && err[1] <= tol[1] && err[2] <= tol[2]) {
    void *const *block = (void *const *)args[9];
    if (((optik_check_fn)block[0])(block + 1, (const double *)args[4])) return -1;
  }
  return rc;
}
