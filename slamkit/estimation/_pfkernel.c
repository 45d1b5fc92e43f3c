/* Fused per-particle kernels of slamkit's particle filter: see particle_filter.py.
 *
 * Every function takes C-contiguous float64 buffers (numpy arrays, bytes, memoryviews) and writes
 * into caller-allocated writable buffers, so no numpy C API is needed. Each loop is the same
 * arithmetic, in the same order, as the numpy expression it replaces in particle_filter.py /
 * diff_drive.motion / range_bearing.observe / _common.weighted_pose_mean_cov; results agree with
 * the numpy path to rounding (sums over particles are sequential here, pairwise/BLAS in numpy).
 *
 *   motion(particles, draws, out, v, omega, sigma_v, sigma_omega, dt)
 *       exact-arc motion (Probabilistic Robotics, Table 5.3) of N poses with noisy controls
 *       (v + sigma_v d0, omega + sigma_omega d1), draws (N, 2) standard normals from numpy's rng.
 *   rb_loglik(particles, landmarks, z, a, b, c, const, loglik_out, resid_out)
 *       known-correspondence range-bearing log-likelihood: per particle and landmark the
 *       predicted range/bearing, wrapped residual nu = z - h(x, m) and nu^T R^-1 nu with
 *       R^-1 = [[a, b], [b, c]]; loglik = -0.5 sum maha - const, residuals (N, m, 2).
 *   innovations(resid, weights, m, r00, r01, r10, r11, nu_out, s_out, nis_out)
 *       weighted mean nu (m, 2) and weighted 2 x 2 covariance of the residuals plus R (m, 2, 2),
 *       and the NIS nu^T S^-1 nu (m,).
 *   pose_mean_cov(poses, weights, out)
 *       weighted planar pose mean (circular heading mean) and covariance: out = [mean(3), cov(9)].
 *   systematic(weights, offset, idx_out)
 *       systematic resampling indices (int64) for positions offset + i/n.
 */
#define PY_SSIZE_T_CLEAN
/* sqrt of a sum of squares never needs errno; without this gcc keeps a scalar errno branch
 * that blocks vectorisation */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC optimize("no-math-errno")
#endif
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.141592653589793
#define TWO_PI 6.283185307179586

/* floor without a libm call (baseline x86-64 has no roundsd): exact for |x| < 2^52, where the
 * int64 conversion truncates exactly; anything else (huge, inf, nan) goes to floor() */
static inline double fast_floor(double x) {
    if (!(fabs(x) < 4503599627370496.0)) return floor(x);
    double t = (double)(int64_t)x;
    return t - (double)(t > x);
}

/* atan and atan2 after Cephes (S. L. Moshier, Cephes Math Library, atan.c): range reduction to
 * |x| <= 0.66 with the pivots tan(3 pi / 8) and pi / 4, then a (4, 5) rational approximation;
 * relative error ~2e-16, several times cheaper than glibc's atan2, which dominated the update.
 * The difference from numpy's arctan2 is a few ulp (tests/estimation/test_pf_kernel.py). */
static const double ATAN_P[5] = {-8.750608600031904122785e-1, -1.615753718733365076637e1,
                                 -7.500855792314704667340e1, -1.228866684490136173410e2,
                                 -6.485021904942025371773e1};
static const double ATAN_Q[5] = {2.485846490142306297962e1, 1.650270098316988542046e2,
                                 4.328810604912902668951e2, 4.853903996359136964868e2,
                                 1.945506571482613964425e2};
#define T3P8 2.41421356237309504880
#define MOREBITS 6.123233995736765886130e-17
#define PIO2 1.57079632679489661923
#define PIO4 0.78539816339744830962
#define PI_LO 1.2246467991473532e-16

/* atan2(y, x) with t = |y| / |x|: Cephes reduces t > tan(3 pi / 8) to pi/2 + atan(-1/t) and
 * t > 0.66 to pi/4 + atan((t - 1)/(t + 1)); written on |x|, |y| each reduction is one division
 * (-|x|/|y|, (|y| - |x|)/(|y| + |x|)). Selects only, no branches, so the per-landmark loop
 * vectorises (branches on the quadrant of random particles would also mispredict half the
 * time). Returns nan exactly where x = y = 0 or an input is not finite (0/0, inf/inf); the
 * caller redoes those rare entries with the C library's atan2. */
static inline double vec_atan2(double y, double x) {
    double ax = fabs(x), ay = fabs(y);
    int big = ay > T3P8 * ax, mid = ay > 0.66 * ax;
    double num = big ? -ax : (mid ? ay - ax : ay);
    double den = big ? ay : (mid ? ay + ax : ax);
    double base = big ? PIO2 : (mid ? PIO4 : 0.0);
    double extra = big ? MOREBITS : (mid ? 0.5 * MOREBITS : 0.0);
    double r = num / den;
    double z = r * r;
    double p = (((ATAN_P[0] * z + ATAN_P[1]) * z + ATAN_P[2]) * z + ATAN_P[3]) * z + ATAN_P[4];
    double q = ((((z + ATAN_Q[0]) * z + ATAN_Q[1]) * z + ATAN_Q[2]) * z + ATAN_Q[3]) * z + ATAN_Q[4];
    z = z * p / q;
    z = r * z + r;
    double a = base + (z + extra);
    a = x < 0.0 ? (PI_LO - a) + PI : a;
    return copysign(a, y);
}

/* floor by the round-to-nearest magic constant 2^52 with the sign of x: (x + C) - C rounds x to
 * an integer exactly for |x| < 2^52; larger doubles are integers already, nan and inf pass
 * through. Vectorisable, unlike the int64 conversion. */
static inline double vec_floor(double x) {
    double c = copysign(4503599627370496.0, x);
    double t = (x + c) - c;
    t = t > x ? t - 1.0 : t;
    return fabs(x) < 4503599627370496.0 ? t : x;
}

/* particle_filter._wrap_for_square: into [-pi, pi] with one floor (the residual is squared,
 * so the +-pi boundary does not matter); a multiplication by 1/(2 pi) instead of numpy's
 * division, which differs only for residuals within an ulp of +-pi (tests compare mod 2 pi) */
static inline double vec_wrap_for_square(double a) {
    return a - TWO_PI * vec_floor((a + PI) * (1.0 / TWO_PI));
}

/* slamkit.geometry.angles.wrap_angle: into [-pi, pi) */
static inline double wrap_angle(double a) {
    double w = a - TWO_PI * fast_floor((a + PI) * (1.0 / TWO_PI));
    if (w >= PI) w -= TWO_PI;
    if (w < -PI) w = -PI;
    return w;
}

/* diff_drive.sinc(z) = numpy.sinc(z / pi), written the way numpy evaluates it */
static inline double np_sinc_of(double z) {
    double x = z / PI;
    double y = PI * (x == 0.0 ? 1.0e-20 : x);
    return sin(y) / y;
}

static int check_len(Py_buffer *buf, Py_ssize_t n_doubles, const char *name) {
    if (buf->len != n_doubles * (Py_ssize_t)sizeof(double)) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd float64 values, got %zd bytes", name,
                     n_doubles, buf->len);
        return 0;
    }
    return 1;
}

static PyObject *motion(PyObject *self, PyObject *args) {
    Py_buffer pb, db, ob;
    double v, om, sv, sw, dt;
    if (!PyArg_ParseTuple(args, "y*y*w*ddddd", &pb, &db, &ob, &v, &om, &sv, &sw, &dt)) return NULL;
    PyObject *res = NULL;
    Py_ssize_t n = pb.len / (Py_ssize_t)(3 * sizeof(double));
    if (!check_len(&pb, 3 * n, "particles") || !check_len(&db, 2 * n, "draws") ||
        !check_len(&ob, 3 * n, "out"))
        goto done;
    const double *p = (const double *)pb.buf, *d = (const double *)db.buf;
    double *o = (double *)ob.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < n; i++) {
        double vi = v + d[2 * i] * sv;
        double wi = om + d[2 * i + 1] * sw;
        double th = p[3 * i + 2];
        double dist = vi * dt;
        double a = wi * dt;
        double s = np_sinc_of(0.5 * a);
        double phi = th + 0.5 * a;
        double ds = dist * s;
        o[3 * i] = p[3 * i] + ds * cos(phi);
        o[3 * i + 1] = p[3 * i + 1] + ds * sin(phi);
        o[3 * i + 2] = wrap_angle(th + a);
    }
    Py_END_ALLOW_THREADS
    res = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&pb);
    PyBuffer_Release(&db);
    PyBuffer_Release(&ob);
    return res;
}

/* one landmark for all particles: bearing_tmp <- atan2(dy, dx) (nan marks entries to redo) */
static void rb_bearings(const double *p, Py_ssize_t n, double mx, double my, double *tmp) {
    for (Py_ssize_t i = 0; i < n; i++) tmp[i] = vec_atan2(my - p[3 * i + 1], mx - p[3 * i]);
    for (Py_ssize_t i = 0; i < n; i++)
        if (isnan(tmp[i])) tmp[i] = atan2(my - p[3 * i + 1], mx - p[3 * i]);
}

/* one landmark for all particles: residuals into nu[:, k, :] and the Mahalanobis term added to
 * acc (acc starts at 0, so the sum over landmarks has numpy's order) */
static void rb_residuals(const double *p, Py_ssize_t n, Py_ssize_t m, Py_ssize_t k, double mx,
                         double my, double zr, double zb, double a, double b, double c,
                         const double *tmp, double *nu, double *acc) {
    for (Py_ssize_t i = 0; i < n; i++) {
        double dx = mx - p[3 * i], dy = my - p[3 * i + 1];
        double r = sqrt(dx * dx + dy * dy);
        /* numpy wraps the predicted bearing and then the residual; one wrap of
         * z_b - (atan2 - theta) is the same angle up to the rounding of the first wrap's
         * 2 pi k subtraction (< 1e-15), and saves a third of this loop */
        double e0 = zr - r;
        double e1 = vec_wrap_for_square(zb - (tmp[i] - p[3 * i + 2]));
        nu[2 * (i * m + k)] = e0;
        nu[2 * (i * m + k) + 1] = e1;
        acc[i] += a * e0 * e0 + 2.0 * b * e0 * e1 + c * e1 * e1;
    }
}

static PyObject *rb_loglik(PyObject *self, PyObject *args) {
    Py_buffer pb, lb, zb, llb, rb;
    double a, b, c, cst;
    if (!PyArg_ParseTuple(args, "y*y*y*ddddw*w*", &pb, &lb, &zb, &a, &b, &c, &cst, &llb, &rb))
        return NULL;
    PyObject *res = NULL;
    double *tmp = NULL;
    Py_ssize_t n = pb.len / (Py_ssize_t)(3 * sizeof(double));
    Py_ssize_t m = lb.len / (Py_ssize_t)(2 * sizeof(double));
    if (!check_len(&pb, 3 * n, "particles") || !check_len(&lb, 2 * m, "landmarks") ||
        !check_len(&zb, 2 * m, "z") || !check_len(&llb, n, "loglik_out") ||
        !check_len(&rb, 2 * n * m, "resid_out"))
        goto done;
    tmp = (double *)malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    if (tmp == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    const double *p = (const double *)pb.buf, *lm = (const double *)lb.buf, *z = (const double *)zb.buf;
    double *ll = (double *)llb.buf, *nu = (double *)rb.buf;
    Py_BEGIN_ALLOW_THREADS
    /* landmark-major, so each inner loop is straight-line arithmetic the compiler vectorises */
    for (Py_ssize_t i = 0; i < n; i++) ll[i] = 0.0;
    for (Py_ssize_t k = 0; k < m; k++) {
        rb_bearings(p, n, lm[2 * k], lm[2 * k + 1], tmp);
        rb_residuals(p, n, m, k, lm[2 * k], lm[2 * k + 1], z[2 * k], z[2 * k + 1], a, b, c, tmp, nu, ll);
    }
    for (Py_ssize_t i = 0; i < n; i++) ll[i] = -0.5 * ll[i] - cst;
    Py_END_ALLOW_THREADS
    res = Py_NewRef(Py_None);
done:
    free(tmp);
    PyBuffer_Release(&pb);
    PyBuffer_Release(&lb);
    PyBuffer_Release(&zb);
    PyBuffer_Release(&llb);
    PyBuffer_Release(&rb);
    return res;
}

static PyObject *innovations(PyObject *self, PyObject *args) {
    Py_buffer rb, wb, nb, sb, qb;
    Py_ssize_t m;
    double r00, r01, r10, r11;
    if (!PyArg_ParseTuple(args, "y*y*nddddw*w*w*", &rb, &wb, &m, &r00, &r01, &r10, &r11, &nb, &sb, &qb))
        return NULL;
    PyObject *res = NULL;
    Py_ssize_t n = wb.len / (Py_ssize_t)sizeof(double);
    if (m < 1) {
        PyErr_SetString(PyExc_ValueError, "m must be >= 1");
        goto done;
    }
    if (!check_len(&wb, n, "weights") || !check_len(&rb, 2 * m * n, "residuals") ||
        !check_len(&nb, 2 * m, "nu_out") || !check_len(&sb, 4 * m, "s_out") ||
        !check_len(&qb, m, "nis_out"))
        goto done;
    const double *e = (const double *)rb.buf, *w = (const double *)wb.buf;
    double *mean = (double *)nb.buf, *S = (double *)sb.buf, *nis = (double *)qb.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t j = 0; j < 2 * m; j++) mean[j] = 0.0;
    for (Py_ssize_t j = 0; j < 4 * m; j++) S[j] = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) {
        const double *row = e + 2 * m * i;
        for (Py_ssize_t j = 0; j < 2 * m; j++) mean[j] += w[i] * row[j];
    }
    /* centred second moments (two passes, like numpy's d = flat - nu) */
    for (Py_ssize_t i = 0; i < n; i++) {
        const double *row = e + 2 * m * i;
        for (Py_ssize_t k = 0; k < m; k++) {
            double d0 = row[2 * k] - mean[2 * k], d1 = row[2 * k + 1] - mean[2 * k + 1];
            double wd0 = d0 * w[i], wd1 = d1 * w[i];
            S[4 * k] += wd0 * d0;
            S[4 * k + 1] += wd0 * d1;
            S[4 * k + 3] += wd1 * d1;
        }
    }
    for (Py_ssize_t k = 0; k < m; k++) {
        double *Sk = S + 4 * k;
        Sk[2] = Sk[1];
        Sk[0] += r00;
        Sk[1] += r01;
        Sk[2] += r10;
        Sk[3] += r11;
        /* NIS nu^T S^-1 nu with the 2 x 2 inverse written out */
        double n0 = mean[2 * k], n1 = mean[2 * k + 1];
        double det = Sk[0] * Sk[3] - Sk[1] * Sk[2];
        nis[k] = (Sk[3] * n0 * n0 - (Sk[1] + Sk[2]) * n0 * n1 + Sk[0] * n1 * n1) / det;
    }
    Py_END_ALLOW_THREADS
    res = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&rb);
    PyBuffer_Release(&wb);
    PyBuffer_Release(&nb);
    PyBuffer_Release(&sb);
    PyBuffer_Release(&qb);
    return res;
}

static PyObject *pose_mean_cov(PyObject *self, PyObject *args) {
    Py_buffer pb, wb, ob;
    if (!PyArg_ParseTuple(args, "y*y*w*", &pb, &wb, &ob)) return NULL;
    PyObject *res = NULL;
    Py_ssize_t n = wb.len / (Py_ssize_t)sizeof(double);
    if (!check_len(&pb, 3 * n, "poses") || !check_len(&wb, n, "weights") ||
        !check_len(&ob, 12, "out"))
        goto done;
    const double *p = (const double *)pb.buf, *w = (const double *)wb.buf;
    double *o = (double *)ob.buf;
    Py_BEGIN_ALLOW_THREADS
    double total = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) total += w[i];
    double mx = 0.0, my = 0.0, ss = 0.0, cs = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) {
        double wi = w[i] / total;
        mx += wi * p[3 * i];
        my += wi * p[3 * i + 1];
        ss += wi * sin(p[3 * i + 2]);
        cs += wi * cos(p[3 * i + 2]);
    }
    double mth = atan2(ss, cs);
    double c00 = 0, c01 = 0, c02 = 0, c11 = 0, c12 = 0, c22 = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        double wi = w[i] / total;
        double d0 = p[3 * i] - mx, d1 = p[3 * i + 1] - my, d2 = wrap_angle(p[3 * i + 2] - mth);
        double w0 = d0 * wi, w1 = d1 * wi, w2 = d2 * wi;
        c00 += w0 * d0;
        c01 += w0 * d1;
        c02 += w0 * d2;
        c11 += w1 * d1;
        c12 += w1 * d2;
        c22 += w2 * d2;
    }
    o[0] = mx; o[1] = my; o[2] = mth;
    double *C = o + 3;
    C[0] = c00; C[1] = c01; C[2] = c02;
    C[3] = c01; C[4] = c11; C[5] = c12;
    C[6] = c02; C[7] = c12; C[8] = c22;
    Py_END_ALLOW_THREADS
    res = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&pb);
    PyBuffer_Release(&wb);
    PyBuffer_Release(&ob);
    return res;
}

static PyObject *systematic(PyObject *self, PyObject *args) {
    Py_buffer wb, ib;
    double offset;
    if (!PyArg_ParseTuple(args, "y*dw*", &wb, &offset, &ib)) return NULL;
    PyObject *res = NULL;
    Py_ssize_t n = wb.len / (Py_ssize_t)sizeof(double);
    double *c = NULL;
    if (!check_len(&wb, n, "weights")) goto done;
    if (n < 1 || ib.len != n * (Py_ssize_t)sizeof(int64_t)) {
        PyErr_SetString(PyExc_ValueError, "systematic: need n >= 1 weights and n int64 outputs");
        goto done;
    }
    c = (double *)malloc((size_t)n * sizeof(double));
    if (c == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    const double *w = (const double *)wb.buf;
    int64_t *idx = (int64_t *)ib.buf;
    Py_BEGIN_ALLOW_THREADS
    /* particle_filter._cumulative: sequential cumsum, divided by the total, last entry 1 */
    double acc = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) {
        acc += w[i];
        c[i] = acc;
    }
    double last = c[n - 1];
    for (Py_ssize_t i = 0; i < n; i++) c[i] /= last;
    c[n - 1] = 1.0;
    /* _pick: searchsorted(c, pos, side="right") clipped to n - 1; positions increase */
    Py_ssize_t j = 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        double pos = offset + (double)k / (double)n;
        while (j < n - 1 && c[j] <= pos) j++;
        idx[k] = (int64_t)j;
    }
    Py_END_ALLOW_THREADS
    res = Py_NewRef(Py_None);
done:
    free(c);
    PyBuffer_Release(&wb);
    PyBuffer_Release(&ib);
    return res;
}

static PyMethodDef METHODS[] = {
    {"motion", motion, METH_VARARGS,
     "motion(particles, draws, out, v, omega, sigma_v, sigma_omega, dt): exact-arc motion of "
     "(N, 3) poses with controls (v + sigma_v d0, omega + sigma_omega d1) into out (N, 3)."},
    {"rb_loglik", rb_loglik, METH_VARARGS,
     "rb_loglik(particles, landmarks, z, a, b, c, const, loglik_out, resid_out): range-bearing "
     "log-likelihood (N,) and wrapped residuals (N, m, 2) for R^-1 = [[a, b], [b, c]]."},
    {"innovations", innovations, METH_VARARGS,
     "innovations(resid, weights, m, r00, r01, r10, r11, nu_out, s_out, nis_out): weighted "
     "mean (m, 2) and weighted covariance plus R (m, 2, 2) of residuals (N, m, 2), and NIS (m,)."},
    {"pose_mean_cov", pose_mean_cov, METH_VARARGS,
     "pose_mean_cov(poses, weights, out): out[:3] weighted pose mean (circular heading), "
     "out[3:] the 3 x 3 weighted covariance with wrapped heading residuals."},
    {"systematic", systematic, METH_VARARGS,
     "systematic(weights, offset, idx_out): int64 systematic-resampling indices."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_pfkernel",
                                    "Fused particle-filter kernels for slamkit.estimation.",
                                    -1, METHODS};

PyMODINIT_FUNC PyInit__pfkernel(void) { return PyModule_Create(&MODULE); }
