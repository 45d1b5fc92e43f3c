/* Compiled depth-first descent of slamkit's branch-and-bound scan matcher (see
 * slamkit/frontend/branch_and_bound.py, whose ``_descend_python`` is the same algorithm line by
 * line and the reference the tests compare this kernel against).
 *
 * Why: the descent visits one node at a time (a node's four children are scored, sorted by their
 * bound and descended into best first), so in Python every node costs a few numpy calls on a
 * few hundred points; on the whole Intel log (odometry, the logs pipeline) it took ~4.4 s of a
 * 33 s profile over the first 900 s, and more on the later revisits. Here a node costs one pass
 * over the scan's cells.
 *
 * The traversal, the pruning and the tie order are the Python version's exactly, so the optimum,
 * its score and the count of scored nodes are the same:
 *   - candidates of one level are taken in the given order (sorted by bound, best first, stable);
 *     a bound below the best score so far ends the level;
 *   - a node whose bound equals the best score is descended into only when it may hold a
 *     candidate nearer the guess (``_rank``: squared distance in steps and cells, then heading,
 *     y and x index);
 *   - at height <= leaf_height every candidate of the block is scored at full resolution, in
 *     row-major (y, x) order.
 *
 * Only the Python C API and the buffer protocol are used (no numpy headers); the Python side
 * allocates every array.
 *
 *   descend(levels, depth, H, W, iy, ix, T, N, n, k, top_h, leaf_h, min_sum,
 *           bounds, ts, oys, oxs, M) -> (found, t, oy, ox, best_sum, scored)
 *
 * levels   int32[depth*H*W]  the max-grid pyramid, heights 0..depth-1, each H x W row-major
 * iy, ix   int64[T*N]        cells of every heading's points at offset (0, 0)
 * n        offsets -n..n cells;  k the guess's heading index
 * bounds, ts, oys, oxs  int64[M]  the top-height nodes to descend, in the order to visit them
 * scored   the nodes scored below the top height (the caller counts the top ones)
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct {
    const int32_t *levels;
    Py_ssize_t H, W, N;
    const int64_t *iy, *ix;
    int64_t n, k;
    int leaf_h;
    int have_best;
    int64_t best_sum;
    int64_t rank[4];        /* the best's rank (squared distance, t, oy, ox) */
    int64_t best[3];        /* t, oy, ox */
    int64_t scored;
} state_t;

static inline int64_t clampi(int64_t v, int64_t hi) { return v < 0 ? 0 : (v > hi ? hi : v); }

static int64_t sum_at(const state_t *s, int h, int64_t t, int64_t oy, int64_t ox) {
    const int32_t *lv = s->levels + (Py_ssize_t)h * s->H * s->W;
    const int64_t *iy = s->iy + t * s->N, *ix = s->ix + t * s->N;
    const int64_t H1 = s->H - 1, W1 = s->W - 1, W = s->W;
    int64_t total = 0;
    for (Py_ssize_t j = 0; j < s->N; j++)
        total += lv[clampi(iy[j] + oy, H1) * W + clampi(ix[j] + ox, W1)];
    return total;
}

static inline int rank_less(const int64_t *a, const int64_t *b) {
    for (int i = 0; i < 4; i++)
        if (a[i] != b[i]) return a[i] < b[i];
    return 0;
}

static inline int64_t axis_dist(int64_t o, int h, int64_t n) {
    int64_t hi = o + ((int64_t)1 << h) - 1;
    if (hi > n) hi = n;
    if (o <= 0 && 0 <= hi) return 0;
    int64_t a = o < 0 ? -o : o, b = hi < 0 ? -hi : hi;
    return a < b ? a : b;
}

static void leaves(state_t *s, int64_t t, int64_t oy, int64_t ox, int h) {
    int64_t side = (int64_t)1 << h;
    int64_t y_end = oy + side < s->n + 1 ? oy + side : s->n + 1;
    int64_t x_end = ox + side < s->n + 1 ? ox + side : s->n + 1;
    if (y_end <= oy || x_end <= ox) return;
    int64_t top = INT64_MIN;
    for (int64_t y = oy; y < y_end; y++)
        for (int64_t x = ox; x < x_end; x++) {
            int64_t v = sum_at(s, 0, t, y, x);
            s->scored++;
            if (v > top) top = v;
        }
    if (top < s->best_sum) return;
    for (int64_t y = oy; y < y_end; y++)
        for (int64_t x = ox; x < x_end; x++) {
            /* scored again only when a block ties its maximum (leaf blocks are one cell by default) */
            if (side > 1 && sum_at(s, 0, t, y, x) != top) continue;
            int64_t r[4] = {(t - s->k) * (t - s->k) + y * y + x * x, t, y, x};
            if (top > s->best_sum || !s->have_best || rank_less(r, s->rank)) {
                s->have_best = 1;
                s->best_sum = top;
                for (int i = 0; i < 4; i++) s->rank[i] = r[i];
                s->best[0] = t; s->best[1] = y; s->best[2] = x;
            }
        }
}

static void descend(state_t *s, const int64_t *bounds, const int64_t *ts, const int64_t *oys,
                    const int64_t *oxs, Py_ssize_t m, int h) {
    for (Py_ssize_t c = 0; c < m; c++) {
        int64_t bound = bounds[c], t = ts[c], oy = oys[c], ox = oxs[c];
        if (bound < s->best_sum) return;   /* sorted best bound first: no later node can win */
        int worth = bound > s->best_sum || (bound == s->best_sum && !s->have_best);
        if (!worth) {
            int64_t d = (t - s->k) * (t - s->k);
            int64_t ay = axis_dist(oy, h, s->n), ax = axis_dist(ox, h, s->n);
            worth = bound == s->best_sum && d + ay * ay + ax * ax <= s->rank[0];
        }
        if (!worth) continue;
        if (h <= s->leaf_h) {
            leaves(s, t, oy, ox, h);
            continue;
        }
        int64_t half = (int64_t)1 << (h - 1);
        int64_t kb[4], kt[4], ky[4], kx[4];
        Py_ssize_t nk = 0;
        for (int a = 0; a < 2; a++)
            for (int b = 0; b < 2; b++) {
                int64_t y = oy + a * half, x = ox + b * half;
                if (y <= s->n && x <= s->n) {
                    kb[nk] = sum_at(s, h - 1, t, y, x);
                    kt[nk] = t; ky[nk] = y; kx[nk] = x;
                    nk++;
                }
            }
        s->scored += nk;
        /* stable insertion sort, largest bound first (numpy's argsort(-sums, kind="stable")) */
        for (Py_ssize_t i = 1; i < nk; i++) {
            int64_t vb = kb[i], vy = ky[i], vx = kx[i];
            Py_ssize_t j = i - 1;
            while (j >= 0 && kb[j] < vb) {
                kb[j + 1] = kb[j]; ky[j + 1] = ky[j]; kx[j + 1] = kx[j];
                j--;
            }
            kb[j + 1] = vb; ky[j + 1] = vy; kx[j + 1] = vx;
        }
        descend(s, kb, kt, ky, kx, nk, h - 1);
    }
}

static int get_buf(PyObject *obj, Py_buffer *view, Py_ssize_t nbytes, const char *name) {
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS) < 0) return -1;
    if (view->len < nbytes) {
        PyErr_Format(PyExc_ValueError, "%s: buffer too small (%zd < %zd bytes)", name, view->len, nbytes);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

static PyObject *py_descend(PyObject *self, PyObject *args) {
    PyObject *lv_o, *iy_o, *ix_o, *b_o, *t_o, *oy_o, *ox_o;
    int depth, top_h, leaf_h;
    Py_ssize_t H, W, T, N, M;
    long long n, k, min_sum;
    if (!PyArg_ParseTuple(args, "OinnOOnnLLiiLOOOOn", &lv_o, &depth, &H, &W, &iy_o, &ix_o, &T, &N, &n, &k,
                          &top_h, &leaf_h, &min_sum, &b_o, &t_o, &oy_o, &ox_o, &M))
        return NULL;
    if (depth < 1 || top_h < 0 || top_h >= depth || H < 1 || W < 1 || T < 0 || N < 0 || M < 0) {
        PyErr_SetString(PyExc_ValueError, "descend: bad sizes");
        return NULL;
    }
    Py_buffer bufs[7];
    PyObject *objs[7] = {lv_o, iy_o, ix_o, b_o, t_o, oy_o, ox_o};
    Py_ssize_t sizes[7] = {(Py_ssize_t)depth * H * W * 4, T * N * 8, T * N * 8, M * 8, M * 8, M * 8, M * 8};
    const char *names[7] = {"levels", "iy", "ix", "bounds", "ts", "oys", "oxs"};
    for (int i = 0; i < 7; i++) {
        if (get_buf(objs[i], &bufs[i], sizes[i], names[i]) < 0) {
            for (int j = 0; j < i; j++) PyBuffer_Release(&bufs[j]);
            return NULL;
        }
    }
    const int64_t *ts = (const int64_t *)bufs[4].buf;
    for (Py_ssize_t c = 0; c < M; c++) {
        if (ts[c] < 0 || ts[c] >= T) {
            for (int j = 0; j < 7; j++) PyBuffer_Release(&bufs[j]);
            PyErr_SetString(PyExc_ValueError, "descend: heading index out of range");
            return NULL;
        }
    }
    state_t s = {0};
    s.levels = (const int32_t *)bufs[0].buf;
    s.H = H; s.W = W; s.N = N;
    s.iy = (const int64_t *)bufs[1].buf;
    s.ix = (const int64_t *)bufs[2].buf;
    s.n = n; s.k = k; s.leaf_h = leaf_h;
    s.best_sum = min_sum;
    Py_BEGIN_ALLOW_THREADS
    descend(&s, (const int64_t *)bufs[3].buf, ts, (const int64_t *)bufs[5].buf, (const int64_t *)bufs[6].buf,
            M, top_h);
    Py_END_ALLOW_THREADS
    for (int j = 0; j < 7; j++) PyBuffer_Release(&bufs[j]);
    return Py_BuildValue("iLLLLL", s.have_best, (long long)s.best[0], (long long)s.best[1], (long long)s.best[2],
                         (long long)s.best_sum, (long long)s.scored);
}

static PyMethodDef methods[] = {
    {"descend", py_descend, METH_VARARGS, "Branch-and-bound descent; see the module comment."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef moduledef = {PyModuleDef_HEAD_INIT, "_bnbkernel",
                                       "Compiled branch-and-bound descent of the global scan matcher.", -1, methods};

PyMODINIT_FUNC PyInit__bnbkernel(void) { return PyModule_Create(&moduledef); }
