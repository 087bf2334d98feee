/* optik: every solution of one IK target of a derived closed form, in one call.
 *
 * Compiled together with CasADi-generated functions: the OPTIK_G functions of optik_group_fn
 * (the 16 entries of a row-major 4x4 target -> a group of the OPTIK_B candidate branches, 6
 * angles each: group 0 the regular candidates, the others runs of stand-ins for a singularity)
 * and OPTIK_CHECK (the cosines and then the sines of one candidate's 6 angles, and the target
 * -> its position and orientation errors on the product-of-exponentials model).
 * optik/closed_form/ik_all.py defines OPTIK_B, OPTIK_G, OPTIK_CHECK, the work sizes OPTIK_IW,
 * OPTIK_W and the tables optik_group_fn, optik_group_at (a group's first row in raw),
 * optik_group, optik_row (each candidate's group and row) and optik_stand_in before this file,
 * and documents the algorithm. Reentrant: all memory is on the stack.
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

/* in: [t (16, row-major), q0 (6), lower (6), upper (6), conf (OPTIK_NCONF)] */
enum { OPTIK_T = 0, OPTIK_Q0 = 16, OPTIK_LO = 22, OPTIK_HI = 28, OPTIK_CONF = 34 };
/* conf: [check position, check orientation, polish position, polish orientation, same,
 *        ortho diagonal, ortho off-diagonal, sort: 0 candidate order, 1 by the distance to q0,
 *        2 by the distance to the middle of the limits (Mechanism.mid_q: an infinite side is
 *        replaced so that the interval spans 2 pi)] */
/* out: [status, n within, n outside, q within (6 n within), q outside (6 n outside),
 *       errors within (2 n within)], packed
 * status: 0 answered; 1 the target is not a valid transform; 2 a candidate to polish, two
 * candidates closer than `same`, or one outside the limits by at most OPTIK_LIMIT_TOL (the
 * caller's numpy path decides). */

static const double OPTIK_PI = 3.14159265358979323846;
static const double OPTIK_TWO_PI = 6.28318530717958647692;

/* fmod(x, 2 pi), skipped where it is the identity (fmod is exact: the same number either way) */
static double optik_mod_two_pi(double x) {
  return x >= 0.0 && x < OPTIK_TWO_PI ? x : fmod(x, OPTIK_TWO_PI);
}

/* a to (-pi, pi] with the arithmetic of numpy's remainder (and the symbolic kernel's):
 * r = fmod(a + pi, 2 pi), + 2 pi when negative, - pi, then + 2 pi when at -pi */
static double optik_wrap(double a) {
  double r = optik_mod_two_pi(a + OPTIK_PI);
  double w = (r < 0.0 ? r + OPTIK_TWO_PI : r) - OPTIK_PI;
  return w <= -OPTIK_PI ? w + OPTIK_TWO_PI : w;
}

/* |a - b| modulo 2 pi (in [0, pi]) as the symbolic kernel: min(d, 2 pi - d), d = |a - b| */
static double optik_gap(double a, double b) {
  double d = fabs(a - b), e = OPTIK_TWO_PI - d; /* finite: a comparison, not the call of fmin */
  return e < d ? e : d;
}

/* |d| with d wrapped as Python's (d + pi) % (2 pi) - pi (the distance to q0 of the solvers) */
static double optik_turn_gap(double d) {
  double m = optik_mod_two_pi(d + OPTIK_PI);
  if (m < 0.0) m += OPTIK_TWO_PI;
  return fabs(m - OPTIK_PI);
}

/* cos and sin of x, for the FK check. For |x| < 64: x = k pi/2 + r, |r| <= pi/4 (k rounded by
 * the 1.5 2^52 shift), with pi/2 in three parts of 47, 47 and 53 bits (k P1 and k P2 exact, and
 * x - k P1 exact by Sterbenz's lemma), then the Taylor polynomials of sin r to r^17 and cos r to
 * r^16 (remainders below 1e-17 on |r| <= pi/4; Estrin's scheme: a short chain of dependent
 * operations) and the quadrant k mod 4: within about an ulp of
 * the exact values, as libm's, at a third of the time of libm's sincos (which took a quarter of
 * the driver's); libm beyond. */
static void optik_sincos(double x, double *c, double *s) {
  if (!(fabs(x) < 64.0)) {
    *c = cos(x);
    *s = sin(x);
    return;
  }
  const double shift = 0x1.8p52;
  const double k = (x * 0x1.45f306dc9c883p-1 + shift) - shift; /* round(x 2 / pi) */
  const double r = ((x - k * 0x1.921fb54442d00p+0) - k * 0x1.8469898cc5140p-48) - k * 0x1.80dc1cd129025p-95;
  const double z = r * r, z2 = z * z, z4 = z2 * z2; /* the polynomials in z by Estrin's scheme */
  const double sp = (-1.0 / 6.0 + z * (1.0 / 120.0)) + z2 * (-1.0 / 5040.0 + z * (1.0 / 362880.0)) +
                    z4 * ((-1.0 / 39916800.0 + z * (1.0 / 6227020800.0)) +
                          z2 * (-1.0 / 1307674368000.0 + z * (1.0 / 355687428096000.0)));
  const double cp = (1.0 / 24.0 + z * (-1.0 / 720.0)) + z2 * (1.0 / 40320.0 + z * (-1.0 / 3628800.0)) +
                    z4 * ((1.0 / 479001600.0 + z * (-1.0 / 87178291200.0)) + z2 * (1.0 / 20922789888000.0));
  const double sr = r + r * z * sp, cr = 1.0 - 0.5 * z + z2 * cp;
  switch ((int)k & 3) { /* k mod 4 (two's complement) */
    case 0: *c = cr, *s = sr; break;
    case 1: *c = -sr, *s = cr; break;
    case 2: *c = -cr, *s = -sr; break;
    default: *c = sr, *s = -cr;
  }
}

/* the checks of optik.checks.as_transform: finite, last row [0, 0, 0, 1], proper rotation */
static int optik_valid_transform(const double *t, double diag, double off) {
  for (int k = 0; k < 16; ++k)
    if (!isfinite(t[k])) return 0;
  if (!(fabs(t[12]) <= 1e-9 && fabs(t[13]) <= 1e-9 && fabs(t[14]) <= 1e-9 &&
        fabs(t[15] - 1.0) <= 1e-9 + 1e-5))
    return 0;
  const double r00 = t[0], r01 = t[1], r02 = t[2], r10 = t[4], r11 = t[5], r12 = t[6];
  const double r20 = t[8], r21 = t[9], r22 = t[10];
  return fabs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0) <= diag &&
         fabs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0) <= diag &&
         fabs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0) <= diag &&
         fabs(r00 * r01 + r10 * r11 + r20 * r21) <= off &&
         fabs(r00 * r02 + r10 * r12 + r20 * r22) <= off &&
         fabs(r01 * r02 + r11 * r12 + r21 * r22) <= off &&
         r00 * (r11 * r22 - r21 * r12) - r10 * (r01 * r22 - r21 * r02) +
                 r20 * (r01 * r12 - r11 * r02) >=
             0.0;
}

/* optik.spatial.wrap_into (the rules of wrap_to_limits), rule 3, for a wrapped angle c outside [lo, hi], by the same
   arithmetic: of c + 2 pi k for k = base - 1 .. base + 2 (base: whole turns from c to the nearest
   point of the interval), the one of least gap to the interval; of gap 0, the one of least |k|
   (no NaN here: the max and min are comparisons, not calls of fmax and fmin) */
static double optik_nearest_turn(double c, double lo, double hi) {
  const double nearest = c < lo ? lo : (c > hi ? hi : c);
  double base = floor((nearest - c) / OPTIK_TWO_PI), best = c, best_key = INFINITY;
  for (int step = -1; step <= 2; ++step) {
    double k = base + (double)step, x = c + OPTIK_TWO_PI * k;
    double below = lo - x, above = x - hi, gap = below > above ? below : above;
    gap = gap > 0.0 ? gap : 0.0;
    double key = gap > 0.0 ? gap : -1.0 / (1.0 + fabs(k));
    if (key < best_key) {
      best_key = key;
      best = x;
    }
  }
  return best;
}

/* whether the max-norm distance of two wrapped angle rows modulo 2 pi is below `same` (the
 * first angle at least `same` apart decides) */
static int optik_close(const double *a, const double *b, double same) {
  for (int k = 0; k < 6; ++k)
    if (!(optik_gap(a[k], b[k]) < same)) return 0;
  return 1;
}

/* max-norm distance of a row to q0, angles modulo 2 pi */
static double optik_distance_q0(const double *q, const double *q0) {
  double worst = 0.0;
  for (int k = 0; k < 6; ++k) {
    double d = optik_turn_gap(q[k] - q0[k]);
    if (d > worst) worst = d;
  }
  return worst;
}

CASADI_SYMBOL_EXPORT int optik_ik_all(const double *in, double *out) {
  enum { B = OPTIK_B };
  const double *t = in + OPTIK_T, *q0 = in + OPTIK_Q0, *lo = in + OPTIK_LO, *hi = in + OPTIK_HI;
  const double *conf = in + OPTIK_CONF;
  double mid[6];
  if (conf[7] == 2.0) {
    for (int k = 0; k < 6; ++k) {
      double a = lo[k], b = hi[k];
      if (!isfinite(a) && !isfinite(b)) {
        a = -OPTIK_PI;
        b = OPTIK_PI;
      } else if (!isfinite(a)) {
        a = b - OPTIK_TWO_PI;
      } else if (!isfinite(b)) {
        b = a + OPTIK_TWO_PI;
      }
      mid[k] = 0.5 * (a + b);
    }
    q0 = mid;
  }
  double q_out[6 * B];
  out[0] = out[1] = out[2] = 0.0;
  for (int k = 0; k < 6; ++k)
    if (!isfinite(q0[k])) {
      out[0] = 1.0;
      return 0;
    }
  if (!optik_valid_transform(t, conf[5], conf[6])) {
    out[0] = 1.0;
    return 0;
  }
  casadi_int iw[OPTIK_IW + 1];
  double w[OPTIK_W + 1], raw[6 * B], kept[6 * B], err[2 * B], e[2];
  const double *arg[2] = {t, 0};
  int n = 0, passed[B], evaluated[OPTIK_G] = {0}, n_seen[6] = {0};
  /* per joint, the distinct angles of the checked candidates (their bits) and their cosines
   * and sines */
  uint64_t seen[6][B];
  double seen_cos[6][B], seen_sin[6][B], c[12];
  for (int b = 0; b < B; ++b) {
    passed[b] = 0;
    if (optik_stand_in[b] >= 0 && passed[optik_stand_in[b]]) continue;
    const int g = optik_group[b];
    if (!evaluated[g]) { /* the group's candidates, when the first of them is needed */
      double *res[1] = {raw + 6 * optik_group_at[g]};
      if (optik_group_fn[g](arg, res, iw, w, 0)) return -1;
      evaluated[g] = 1;
    }
    const double *q = raw + 6 * optik_row[b];
    int finite = 1;
    for (int k = 0; k < 6; ++k) finite &= isfinite(q[k]);
    if (!finite) continue;
    /* candidates share angles (an elbow flip keeps the shoulder angle): the cosine and sine of
     * an angle equal to one already evaluated (the same bits) are copied, the others evaluated */
    for (int k = 0; k < 6; ++k) {
      uint64_t bits;
      memcpy(&bits, q + k, sizeof bits);
      int j = 0;
      while (j < n_seen[k] && seen[k][j] != bits) ++j;
      if (j == n_seen[k]) {
        seen[k][j] = bits;
        optik_sincos(q[k], &seen_cos[k][j], &seen_sin[k][j]);
        ++n_seen[k];
      }
      c[k] = seen_cos[k][j];
      c[6 + k] = seen_sin[k][j];
    }
    const double *carg[2] = {c, t};
    double *cres[1] = {e};
    if (OPTIK_CHECK(carg, cres, iw, w, 0)) return -1;
    if (e[0] <= conf[0] && e[1] <= conf[1]) {
      passed[b] = 1;
      for (int k = 0; k < 6; ++k) kept[6 * n + k] = optik_wrap(q[k]);
      err[2 * n] = e[0];
      err[2 * n + 1] = e[1];
      ++n;
    } else if (e[0] <= conf[2] && e[1] <= conf[3]) {
      out[0] = 2.0; /* inexact: the numpy path polishes it */
      return 0;
    }
  }
  for (int j = 1; j < n; ++j)
    for (int i = 0; i < j; ++i)
      if (optik_close(kept + 6 * i, kept + 6 * j, conf[4])) {
        out[0] = 2.0; /* two close solutions: the numpy path merges them by their accuracy */
        return 0;
      }
  /* the 2 pi shift into the limits (optik.spatial.wrap_to_limits), then the limit split */
  int order[B], n_in = 0, n_out = 0;
  double dist[B];
  for (int s = 0; s < n; ++s) {
    double *q = kept + 6 * s;
    int inside = 1;
    for (int k = 0; k < 6; ++k) {
      if (!(lo[k] <= q[k] && q[k] <= hi[k])) q[k] = optik_nearest_turn(q[k], lo[k], hi[k]);
      inside &= lo[k] <= q[k] && q[k] <= hi[k];
    }
    if (!inside) {
      int near = 1; /* within OPTIK_LIMIT_TOL of the limits: the numpy path clips and checks it */
      for (int k = 0; k < 6; ++k) near &= lo[k] - OPTIK_LIMIT_TOL <= q[k] && q[k] <= hi[k] + OPTIK_LIMIT_TOL;
      if (near) {
        out[0] = 2.0;
        return 0;
      }
      for (int k = 0; k < 6; ++k) q_out[6 * n_out + k] = q[k];
      ++n_out;
      continue;
    }
    /* nearest q0 first: insertion into the order, stable (ties keep the candidate order) */
    double d = conf[7] != 0.0 ? optik_distance_q0(q, q0) : 0.0; /* 0: candidate order */
    int at = n_in;
    while (at > 0 && dist[at - 1] > d) {
      order[at] = order[at - 1];
      dist[at] = dist[at - 1];
      --at;
    }
    order[at] = s;
    dist[at] = d;
    ++n_in;
  }
  double *q_in = out + 3, *q_outside = q_in + 6 * n_in, *e_in = q_outside + 6 * n_out;
  for (int r = 0; r < n_in; ++r) {
    const int s = order[r];
    for (int k = 0; k < 6; ++k) q_in[6 * r + k] = kept[6 * s + k];
    e_in[2 * r] = err[2 * s];
    e_in[2 * r + 1] = err[2 * s + 1];
  }
  for (int k = 0; k < 6 * n_out; ++k) q_outside[k] = q_out[k];
  out[1] = (double)n_in;
  out[2] = (double)n_out;
  return 0;
}

#ifdef OPTIK_PYTHON
/* The Python binding: optik_ik_all_function() (called once, through ctypes.PyDLL) returns three
 * builtin functions, ik_all(t, q0, lower, upper, sort) -> (q within, errors, q outside), False
 * or None, taking float64 arrays (any strides): t (4, 4), q0 (6,) or None, lower and upper
 * (6,); with sort true the solutions are ordered by their distance to q0, or to the middle of
 * the limits when q0 is None (sort 2 of conf). False: status 1 or 2 (the caller's general path
 * decides). None: an argument of another type, shape or layout (which the ctypes path, with its
 * conversions, takes). And ik_all_many, the same over many targets, and ik_all_q, the
 * solutions within the limits alone (below). */
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

/* copy a float64 array of shape (4, 4) (ndim 2) or (6,) (ndim 1), any strides, into dst */
static int optik_py_copy(PyObject *obj, int ndim, double *dst) {
  if (!PyArray_Check(obj)) return 0;
  PyArrayObject *a = (PyArrayObject *)obj;
  if (PyArray_TYPE(a) != NPY_DOUBLE || PyArray_NDIM(a) != ndim || !PyArray_ISALIGNED(a) ||
      !PyArray_ISNOTSWAPPED(a))
    return 0;
  const char *base = (const char *)PyArray_DATA(a);
  const npy_intp *st = PyArray_STRIDES(a);
  if (ndim == 1) {
    if (PyArray_DIM(a, 0) != 6) return 0;
    for (int k = 0; k < 6; ++k) dst[k] = *(const double *)(base + k * st[0]);
    return 1;
  }
  if (PyArray_DIM(a, 0) != 4 || PyArray_DIM(a, 1) != 4) return 0;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) dst[4 * i + j] = *(const double *)(base + i * st[0] + j * st[1]);
  return 1;
}

static PyObject *optik_py_rows(const double *data, npy_intp rows, npy_intp cols) {
  npy_intp dims[2] = {rows, cols};
  PyObject *a = PyArray_SimpleNew(2, dims, NPY_DOUBLE);
  if (a && rows) memcpy(PyArray_DATA((PyArrayObject *)a), data, sizeof(double) * (size_t)(rows * cols));
  return a;
}

/* the driver on the arguments (t, q0, lower, upper) and sort: 0 answered (out filled), 1 an
 * argument of another type, shape or layout, 2 status 1 or 2 of the driver, -1 an error raised */
static int optik_py_solve(PyObject *const *args, int sort, double *out) {
  double in[OPTIK_CONF + 8];
  int q0_given = args[1] != Py_None;
  if (!optik_py_copy(args[0], 2, in + OPTIK_T) || !optik_py_copy(args[2], 1, in + OPTIK_LO) ||
      !optik_py_copy(args[3], 1, in + OPTIK_HI) || (q0_given && !optik_py_copy(args[1], 1, in + OPTIK_Q0)))
    return 1;
  if (!q0_given) memset(in + OPTIK_Q0, 0, sizeof(double) * 6);
  memcpy(in + OPTIK_CONF, optik_conf, sizeof(double) * 7);
  in[OPTIK_CONF + 7] = sort ? (q0_given ? 1.0 : 2.0) : 0.0;
  if (optik_ik_all(in, out) != 0) {
    PyErr_SetString(PyExc_RuntimeError, "optik_ik_all: evaluation of the generated code failed");
    return -1;
  }
  return out[0] != 0.0 ? 2 : 0;
}

static PyObject *optik_py_ik_all(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
  (void)self;
  if (nargs != 5) {
    PyErr_SetString(PyExc_TypeError, "ik_all(t, q0, lower, upper, sort)");
    return NULL;
  }
  double out[3 + 14 * OPTIK_B];
  int sort = PyObject_IsTrue(args[4]);
  if (sort < 0) {
    PyErr_Clear();
    Py_RETURN_NONE;
  }
  switch (optik_py_solve(args, sort, out)) {
    case -1: return NULL;
    case 1: Py_RETURN_NONE;
    case 2: Py_RETURN_FALSE; /* status 1 or 2: the caller's general path decides */
  }
  const npy_intp n_in = (npy_intp)out[1], n_out = (npy_intp)out[2];
  PyObject *q_in = optik_py_rows(out + 3, n_in, 6);
  PyObject *q_out = optik_py_rows(out + 3 + 6 * n_in, n_out, 6);
  PyObject *err = optik_py_rows(out + 3 + 6 * (n_in + n_out), n_in, 2);
  if (!q_in || !q_out || !err) {
    Py_XDECREF(q_in);
    Py_XDECREF(q_out);
    Py_XDECREF(err);
    return NULL;
  }
  PyObject *res = PyTuple_Pack(3, q_in, err, q_out);
  Py_DECREF(q_in);
  Py_DECREF(q_out);
  Py_DECREF(err);
  return res;
}

/* ik_all_q(t, q0, lower, upper, outside): the solutions within the limits only, sorted as
 * ik_all's, one (K, 6) array; with outside true the tuple (q within, q outside); False and None
 * as ik_all's (no Python object besides the answer's arrays) */
static PyObject *optik_py_ik_all_q(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
  (void)self;
  if (nargs != 5) {
    PyErr_SetString(PyExc_TypeError, "ik_all_q(t, q0, lower, upper, outside)");
    return NULL;
  }
  double out[3 + 14 * OPTIK_B];
  const int outside = PyObject_IsTrue(args[4]);
  if (outside < 0) return NULL;
  switch (optik_py_solve(args, 1, out)) {
    case -1: return NULL;
    case 1: Py_RETURN_NONE;
    case 2: Py_RETURN_FALSE;
  }
  const npy_intp n_in = (npy_intp)out[1], n_out = (npy_intp)out[2];
  PyObject *q_in = optik_py_rows(out + 3, n_in, 6);
  if (!q_in || !outside) return q_in;
  PyObject *q_out = optik_py_rows(out + 3 + 6 * n_in, n_out, 6);
  PyObject *res = q_out ? PyTuple_Pack(2, q_in, q_out) : NULL;
  Py_DECREF(q_in);
  Py_XDECREF(q_out);
  return res;
}

/* a growing buffer of doubles (PyMem_Raw*: usable without the GIL) */
typedef struct {
  double *data;
  size_t size, capacity;
} optik_rows;

static int optik_rows_add(optik_rows *r, const double *src, size_t count) {
  if (r->size + count > r->capacity) {
    size_t cap = r->capacity ? 2 * r->capacity : 1024;
    while (cap < r->size + count) cap *= 2;
    double *grown = (double *)PyMem_RawRealloc(r->data, cap * sizeof(double));
    if (!grown) return 0;
    r->data = grown;
    r->capacity = cap;
  }
  if (count) memcpy(r->data + r->size, src, count * sizeof(double));
  r->size += count;
  return 1;
}

static PyObject *optik_py_ints(npy_intp n) {
  npy_intp dims[1] = {n};
  return PyArray_SimpleNew(1, dims, NPY_INT64);
}

/* ik_all_many(t (M, 4, 4) C-contiguous float64, q0 None or (6,) or C-contiguous (M, 6), lower,
 * upper (6,), sort) -> (q within (K, 6), errors (K, 2), counts within (M,), q outside (L, 6),
 * counts outside (M,), status (M,)): optik_ik_all target by target with the GIL released; the
 * rows of the targets whose status is not 0 are absent (their counts are 0); None for arrays of
 * another type, shape or layout. */
static PyObject *optik_py_ik_all_many(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
  (void)self;
  if (nargs != 5) {
    PyErr_SetString(PyExc_TypeError, "ik_all_many(t, q0, lower, upper, sort)");
    return NULL;
  }
  double in[OPTIK_CONF + 8], out[3 + 14 * OPTIK_B];
  int sort = PyObject_IsTrue(args[4]);
  if (!PyArray_Check(args[0]) || !optik_py_copy(args[2], 1, in + OPTIK_LO) ||
      !optik_py_copy(args[3], 1, in + OPTIK_HI) || sort < 0) {
    PyErr_Clear();
    Py_RETURN_NONE;
  }
  PyArrayObject *ta = (PyArrayObject *)args[0];
  if (PyArray_TYPE(ta) != NPY_DOUBLE || PyArray_NDIM(ta) != 3 || PyArray_DIM(ta, 1) != 4 ||
      PyArray_DIM(ta, 2) != 4 || !PyArray_IS_C_CONTIGUOUS(ta) || !PyArray_ISNOTSWAPPED(ta))
    Py_RETURN_NONE;
  const npy_intp m = PyArray_DIM(ta, 0);
  const double *t = (const double *)PyArray_DATA(ta), *q0s = NULL;
  npy_intp q0_step = 0;
  if (args[1] != Py_None) {
    if (!PyArray_Check(args[1])) Py_RETURN_NONE;
    PyArrayObject *qa = (PyArrayObject *)args[1];
    int nd = PyArray_NDIM(qa);
    if (PyArray_TYPE(qa) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(qa) || !PyArray_ISNOTSWAPPED(qa) ||
        !((nd == 1 && PyArray_DIM(qa, 0) == 6) || (nd == 2 && PyArray_DIM(qa, 0) == m && PyArray_DIM(qa, 1) == 6)))
      Py_RETURN_NONE;
    q0s = (const double *)PyArray_DATA(qa);
    q0_step = nd == 2 ? 6 : 0;
  }
  PyObject *counts = optik_py_ints(m), *counts_out = optik_py_ints(m), *status = optik_py_ints(m);
  if (!counts || !counts_out || !status) {
    Py_XDECREF(counts);
    Py_XDECREF(counts_out);
    Py_XDECREF(status);
    return NULL;
  }
  npy_int64 *n_in = (npy_int64 *)PyArray_DATA((PyArrayObject *)counts);
  npy_int64 *n_out = (npy_int64 *)PyArray_DATA((PyArrayObject *)counts_out);
  npy_int64 *st = (npy_int64 *)PyArray_DATA((PyArrayObject *)status);
  memcpy(in + OPTIK_CONF, optik_conf, sizeof(double) * 7);
  in[OPTIK_CONF + 7] = sort ? (q0s ? 1.0 : 2.0) : 0.0;
  if (!q0s) memset(in + OPTIK_Q0, 0, sizeof(double) * 6);
  optik_rows q_in = {0}, q_out = {0}, err = {0};
  int failed = 0, memory = 1; /* failed: the generated code reported an error */
  Py_BEGIN_ALLOW_THREADS;
  for (npy_intp i = 0; i < m && !failed && memory; ++i) {
    memcpy(in + OPTIK_T, t + 16 * i, sizeof(double) * 16);
    if (q0s) memcpy(in + OPTIK_Q0, q0s + q0_step * i, sizeof(double) * 6);
    if (optik_ik_all(in, out) != 0) {
      failed = 1;
      break;
    }
    st[i] = (npy_int64)out[0];
    n_in[i] = n_out[i] = 0;
    if (out[0] != 0.0) continue;
    const size_t a = (size_t)out[1], b = (size_t)out[2];
    memory = optik_rows_add(&q_in, out + 3, 6 * a) && optik_rows_add(&q_out, out + 3 + 6 * a, 6 * b) &&
             optik_rows_add(&err, out + 3 + 6 * (a + b), 2 * a);
    n_in[i] = (npy_int64)a;
    n_out[i] = (npy_int64)b;
  }
  Py_END_ALLOW_THREADS;
  PyObject *res = NULL;
  if (failed)
    PyErr_SetString(PyExc_RuntimeError, "optik_ik_all: evaluation of the generated code failed");
  else if (!memory)
    PyErr_NoMemory();
  else {
    PyObject *a = optik_py_rows(q_in.data, (npy_intp)(q_in.size / 6), 6);
    PyObject *e = optik_py_rows(err.data, (npy_intp)(err.size / 2), 2);
    PyObject *b = optik_py_rows(q_out.data, (npy_intp)(q_out.size / 6), 6);
    if (a && e && b) res = PyTuple_Pack(6, a, e, counts, b, counts_out, status);
    Py_XDECREF(a);
    Py_XDECREF(e);
    Py_XDECREF(b);
  }
  PyMem_RawFree(q_in.data);
  PyMem_RawFree(q_out.data);
  PyMem_RawFree(err.data);
  Py_DECREF(counts);
  Py_DECREF(counts_out);
  Py_DECREF(status);
  return res;
}

static PyMethodDef optik_py_def = {"ik_all", (PyCFunction)(void (*)(void))optik_py_ik_all, METH_FASTCALL,
                                   "Every solution of one target (optik.closed_form.ik_all)."};
static PyMethodDef optik_py_q_def = {"ik_all_q", (PyCFunction)(void (*)(void))optik_py_ik_all_q, METH_FASTCALL,
                                     "The solutions within the limits of one target (optik.closed_form.ik_all)."};
static PyMethodDef optik_py_many_def = {"ik_all_many", (PyCFunction)(void (*)(void))optik_py_ik_all_many,
                                        METH_FASTCALL, "Every solution of many targets (optik.closed_form.ik_all)."};

CASADI_SYMBOL_EXPORT PyObject *optik_ik_all_function(void) {
  if (PyArray_API == NULL && _import_array() < 0) return NULL;
  PyObject *one = PyCFunction_New(&optik_py_def, NULL), *many = PyCFunction_New(&optik_py_many_def, NULL);
  PyObject *rows = PyCFunction_New(&optik_py_q_def, NULL);
  PyObject *all = one && many && rows ? PyTuple_Pack(3, one, many, rows) : NULL;
  Py_XDECREF(one);
  Py_XDECREF(many);
  Py_XDECREF(rows);
  return all;
}
#endif
