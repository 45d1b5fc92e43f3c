/* Compiled core of slamkit's grid ray caster: see raycast.py.
 *
 *   cast(occupied, height, width, g, d, max_t, res, no_hit) -> bytearray | None
 *       occupied: height*width bytes (row major, occupied[iy * width + ix] != 0 is an obstacle);
 *       g: N*2 native doubles, ray origins in cell units relative to the grid origin (gx, gy);
 *       d: N*2 native doubles, unit directions (dx, dy); max_t: maximum range in cell units;
 *       res: metres per cell. Returns N native doubles: the range in metres to the boundary
 *       where each ray enters its first occupied cell (0 when the origin's cell is occupied),
 *       ``no_hit`` when there is none within max_t. Returns None when an origin lies 2^52
 *       cells or more from the grid (there the int64 cell index and its float conversion stop
 *       being exact): the caller then uses its numpy path.
 *
 * The walk is Amanatides and Woo, "A fast voxel traversal algorithm for ray tracing",
 * Eurographics 1987, written to reproduce raycast.cast_ray_loop and the numpy RayCaster bit for
 * bit: the n-th crossing time is tx0 + n * tdx (computed afresh, never accumulated), x steps
 * first on ties, cells outside the grid are free, a ray outside the grid and moving away from
 * it stops. The caller computes g and d with numpy (np.cos/np.sin), so both paths start from
 * the same doubles; everything here is IEEE +, -, *, / in double precision, which is why
 * floating-point contraction (a*b+c -> fma) must stay off and excess precision is refused.
 */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <float.h>
#include <math.h>
#include <stdint.h>

#if !defined(FLT_EVAL_METHOD) || FLT_EVAL_METHOD != 0
#error "double arithmetic with excess precision would not match numpy; use the numpy path"
#endif

/* One ray; returns the range in cell units, or NAN for no hit. */
static inline double walk(const unsigned char *occ, int64_t height, int64_t width, double gx,
                          double gy, double dx, double dy, double max_t) {
    const double fx = floor(gx), fy = floor(gy);
    const int64_t ix0 = (int64_t)fx, iy0 = (int64_t)fy;
    int64_t ix = ix0, iy = iy0;
    if ((uint64_t)ix < (uint64_t)width && (uint64_t)iy < (uint64_t)height && occ[iy * width + ix])
        return 0.0;
    /* numpy path: rays with max_t < 0 (or NaN) are dropped after the start-cell test */
    if (!(max_t >= 0)) return NAN;
    const int64_t stepx = dx > 0 ? 1 : -1, stepy = dy > 0 ? 1 : -1;
    const double tdx = dx != 0 ? 1.0 / fabs(dx) : 0.0;
    const double tdy = dy != 0 ? 1.0 / fabs(dy) : 0.0;
    const double tx0 = dx > 0 ? ((double)(ix0 + 1) - gx) / dx
                              : (dx < 0 ? (gx - (double)ix0) / -dx : INFINITY);
    const double ty0 = dy > 0 ? ((double)(iy0 + 1) - gy) / dy
                              : (dy < 0 ? (gy - (double)iy0) / -dy : INFINITY);
    /* leaving for good: below/left of the grid moving away, or above/right moving away */
    const int x_lo_gone = dx <= 0, x_hi_gone = dx >= 0, y_lo_gone = dy <= 0, y_hi_gone = dy >= 0;
    int64_t nx = 0, ny = 0;
    double tx = tx0, ty = ty0, t;
    for (;;) {
        if (tx <= ty) {
            t = tx;
            nx++;
            ix += stepx;
            tx = tx0 + (double)nx * tdx;
        } else {
            t = ty;
            ny++;
            iy += stepy;
            ty = ty0 + (double)ny * tdy;
        }
        if (t > max_t) return NAN;
        if ((uint64_t)ix < (uint64_t)width && (uint64_t)iy < (uint64_t)height) {
            if (occ[iy * width + ix]) return t;
        } else if ((ix < 0 && x_lo_gone) || (ix >= width && x_hi_gone) || (iy < 0 && y_lo_gone) ||
                   (iy >= height && y_hi_gone)) {
            return NAN;
        }
    }
}

static PyObject *cast(PyObject *self, PyObject *args) {
    Py_buffer occ_v, g_v, d_v;
    Py_ssize_t height, width;
    double max_t, res, no_hit;
    if (!PyArg_ParseTuple(args, "y*nny*y*ddd", &occ_v, &height, &width, &g_v, &d_v, &max_t, &res,
                          &no_hit))
        return NULL;
    PyObject *result = NULL;
    if (height <= 0 || width <= 0 || occ_v.len != height * width) {
        PyErr_SetString(PyExc_ValueError, "occupied must hold height * width bytes");
        goto done;
    }
    if (g_v.len % (Py_ssize_t)(2 * sizeof(double)) != 0 || d_v.len != g_v.len) {
        PyErr_SetString(PyExc_ValueError, "g and d must hold N * 2 doubles each");
        goto done;
    }
    Py_ssize_t n = g_v.len / (Py_ssize_t)(2 * sizeof(double));
    const double *g = g_v.buf, *d = d_v.buf;
    const double limit = 4503599627370496.0; /* 2^52 */
    for (Py_ssize_t i = 0; i < 2 * n; i++) {
        if (!(fabs(g[i]) < limit)) {
            result = Py_NewRef(Py_None);
            goto done;
        }
    }
    result = PyByteArray_FromStringAndSize(NULL, n * (Py_ssize_t)sizeof(double));
    if (!result) goto done;
    double *out = (double *)PyByteArray_AS_STRING(result);
    const unsigned char *occ = occ_v.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < n; i++) {
        double t = walk(occ, height, width, g[2 * i], g[2 * i + 1], d[2 * i], d[2 * i + 1], max_t);
        out[i] = isnan(t) ? no_hit : t * res;
    }
    Py_END_ALLOW_THREADS
done:
    PyBuffer_Release(&occ_v);
    PyBuffer_Release(&g_v);
    PyBuffer_Release(&d_v);
    return result;
}

static PyMethodDef METHODS[] = {
    {"cast", cast, METH_VARARGS,
     "cast(occupied, height, width, g, d, max_t, res, no_hit) -> bytearray | None: N float64 "
     "ranges (metres) of rays from g (N*2 float64, cell units) along d (N*2 float64); None if "
     "an origin is 2^52 cells or more away."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_raycast",
                                    "Amanatides-Woo grid ray casting for slamkit.maps.raycast.",
                                    -1, METHODS};

PyMODINIT_FUNC PyInit__raycast(void) { return PyModule_Create(&MODULE); }
