/* Compiled 2D k-d tree and point-to-line ICP loop of slamkit's scan matcher (see
 * slamkit/frontend/icp.py, whose ``icp`` / ``_finish`` / ``estimate_normals`` are the same
 * algorithm in numpy + scipy's cKDTree and the reference the tests compare this kernel against).
 *
 * Why: the lidar SLAM frontend runs ~14 point-to-line iterations per match on a few hundred
 * points; in numpy every iteration is ~20 calls on tiny arrays plus a cKDTree query, and on the
 * whole FR079 log (odometry) ICP was 74% of the CPU. Here an iteration is one pass over the scan.
 *
 * What is the same as the reference, exactly:
 *   - nearest neighbours are exact (a k-d tree searched with the squared gate as the initial
 *     bound, as cKDTree's ``distance_upper_bound``: a neighbour counts when d^2 < gate^2);
 *   - gating, trimming (the ceil(trim_fraction * n) closest, at least min_correspondences, only
 *     when more than min_correspondences are gated), the break below min_correspondences, the
 *     convergence and the correspondence-cycle tests, the left-composed increment and the
 *     wrapping of the heading;
 *   - the normals: PCA of each target point's k nearest neighbours in closed form.
 * What is not bit for bit: sums are taken in source-index order (numpy's einsum/BLAS order
 * differs), the 3x3 system is solved by Gaussian elimination with partial pivoting (LAPACK's
 * dgesv pivots the same way but orders its operations differently), cos/sin/atan2 are libm's.
 * These move the pose in the last bits; tests/frontend/test_icp_kernel.py states the measured
 * spread. A correspondence tied in distance at the trimming threshold is kept in index order
 * (numpy's argpartition keeps one of the tied arbitrarily), and a correspondence set repeats
 * when its (source, target) pairs do (the reference compares them in argpartition's order).
 * An exactly singular system returns status 1 and the caller runs the reference instead.
 *
 * Only the Python C API and the buffer protocol are used (no numpy headers); the Python side
 * allocates every array.
 *
 *   build(points, M, leaf, perm, sorted, dims, splits, n_dims)
 *       points float64[M*2] -> perm int64[M] (sorted[i] = points[perm[i]]), sorted float64[M*2],
 *       dims int8[n_dims] and splits float64[n_dims] the split axis and value of every internal
 *       node (heap order: children 2i+1, 2i+2; node i covers a range [lo, hi) of sorted, split at
 *       mid = lo + (hi - lo) / 2, every point before mid <= the split value <= every point from
 *       mid on; a range of at most ``leaf`` points is a leaf)
 *   normals(sorted, M, leaf, dims, splits, n_dims, k, out)  out float64[M*2]: the unit normal of
 *       sorted[i] from its k nearest neighbours (itself included)
 *   nearest(sorted, M, leaf, dims, splits, n_dims, perm, queries, Q, bound, out_dist, out_idx)
 *       cKDTree.query(queries, k=1, distance_upper_bound=bound): distance (inf when none is
 *       closer than bound) and the index into the original points (M when none)
 *   icp(sorted, M, leaf, dims, splits, n_dims, normals_sorted, source, N, x, y, theta, max_iterations,
 *       max_correspondence, trim_fraction, min_correspondences, translation_tol, rotation_tol,
 *       cycle_tol_m, cycle_tol_rad, fitness_distance)
 *       -> (status, x, y, theta, iterations, converged, fitness, n, A00, A01, A02, A11, A12, A22,
 *           e^T e, sum of squared residual norms)
 *       the point-to-line loop of ``icp`` and the statistics ``_finish`` needs at the result
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define MAX_DEPTH 64

typedef struct {
    const double *pts; /* sorted, M x 2 */
    Py_ssize_t M;
    Py_ssize_t leaf;
    const int8_t *dims;
    const double *splits;
} tree_t;

/* ---- build ---------------------------------------------------------------------------------- */

static void swap_idx(int64_t *a, Py_ssize_t i, Py_ssize_t j) { int64_t t = a[i]; a[i] = a[j]; a[j] = t; }

/* Rearranges idx[lo, hi) so that idx[mid] holds the element of rank mid - lo along axis d,
 * with every element before it <= and every one after it >= (quickselect, median of three). */
static void select_nth(int64_t *idx, const double *p, Py_ssize_t lo, Py_ssize_t hi, Py_ssize_t mid, int d) {
    Py_ssize_t l = lo, r = hi - 1;
    while (r > l) {
        Py_ssize_t m = l + (r - l) / 2;
        /* median of three to idx[m] */
        if (p[2 * idx[m] + d] < p[2 * idx[l] + d]) swap_idx(idx, m, l);
        if (p[2 * idx[r] + d] < p[2 * idx[l] + d]) swap_idx(idx, r, l);
        if (p[2 * idx[r] + d] < p[2 * idx[m] + d]) swap_idx(idx, r, m);
        double pivot = p[2 * idx[m] + d];
        Py_ssize_t i = l, j = r;
        while (i <= j) {
            while (p[2 * idx[i] + d] < pivot) i++;
            while (p[2 * idx[j] + d] > pivot) j--;
            if (i <= j) { swap_idx(idx, i, j); i++; j--; }
        }
        if (mid <= j) r = j;
        else if (mid >= i) l = i;
        else break;
    }
}

static int build_node(int64_t *idx, const double *p, int8_t *dims, double *splits, Py_ssize_t n_dims,
                      Py_ssize_t node, Py_ssize_t lo, Py_ssize_t hi, Py_ssize_t leaf) {
    if (hi - lo <= leaf) return 0;
    if (node >= n_dims) return -1;
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    for (Py_ssize_t i = lo; i < hi; i++) {
        double x = p[2 * idx[i]], y = p[2 * idx[i] + 1];
        if (x < x0) x0 = x;
        if (x > x1) x1 = x;
        if (y < y0) y0 = y;
        if (y > y1) y1 = y;
    }
    int d = (x1 - x0 >= y1 - y0) ? 0 : 1;
    Py_ssize_t mid = lo + (hi - lo) / 2;
    select_nth(idx, p, lo, hi, mid, d);
    dims[node] = (int8_t)d;
    /* the split value is kept: the children's own selection moves another point to mid */
    splits[node] = p[2 * idx[mid] + d];
    if (build_node(idx, p, dims, splits, n_dims, 2 * node + 1, lo, mid, leaf) < 0) return -1;
    return build_node(idx, p, dims, splits, n_dims, 2 * node + 2, mid, hi, leaf);
}

/* ---- queries -------------------------------------------------------------------------------- */

/* the subtrees a query still has to visit: node, point range and the squared distance to its plane */
typedef struct {
    Py_ssize_t node[MAX_DEPTH], lo[MAX_DEPTH], hi[MAX_DEPTH];
    double plane[MAX_DEPTH];
} kd_stack_t;

/* From (node, lo, hi) down to the leaf on the query's side of every split, pushing the far
 * subtrees; returns the new stack size. */
static int descend(const tree_t *t, double qx, double qy, Py_ssize_t *node, Py_ssize_t *lo, Py_ssize_t *hi,
                   kd_stack_t *st, int sp) {
    while (*hi - *lo > t->leaf) {
        int d = t->dims[*node];
        Py_ssize_t mid = *lo + (*hi - *lo) / 2;
        double diff = (d ? qy : qx) - t->splits[*node];
        if (diff < 0) {   /* near: left; far: right */
            st->node[sp] = 2 * *node + 2; st->lo[sp] = mid; st->hi[sp] = *hi; st->plane[sp] = diff * diff; sp++;
            *node = 2 * *node + 1; *hi = mid;
        } else {
            st->node[sp] = 2 * *node + 1; st->lo[sp] = *lo; st->hi[sp] = mid; st->plane[sp] = diff * diff; sp++;
            *node = 2 * *node + 2; *lo = mid;
        }
    }
    return sp;
}

/* The nearest point to (qx, qy) with d^2 < *best_d2 (updated), its sorted index in *best (left
 * unchanged when there is none). Exact: a subtree is skipped only when the split plane alone is
 * at least as far as the best so far. */
static void nn(const tree_t *t, double qx, double qy, double *best_d2, Py_ssize_t *best) {
    kd_stack_t st;
    int sp = 0;
    Py_ssize_t node = 0, lo = 0, hi = t->M;
    double bd2 = *best_d2;
    Py_ssize_t b = *best;
    for (;;) {
        sp = descend(t, qx, qy, &node, &lo, &hi, &st, sp);
        for (Py_ssize_t i = lo; i < hi; i++) {
            double dx = qx - t->pts[2 * i], dy = qy - t->pts[2 * i + 1];
            double d2 = dx * dx + dy * dy;
            if (d2 < bd2) { bd2 = d2; b = i; }
        }
        for (;;) {
            if (sp == 0) { *best_d2 = bd2; *best = b; return; }
            sp--;
            if (st.plane[sp] < bd2) break;
        }
        node = st.node[sp]; lo = st.lo[sp]; hi = st.hi[sp];
    }
}

/* The k nearest points of (qx, qy) (k <= M), ascending: d2[0..k), idx[0..k) sorted indices. */
static void knn(const tree_t *t, double qx, double qy, Py_ssize_t k, double *d2, Py_ssize_t *idx) {
    kd_stack_t st;
    int sp = 0;
    Py_ssize_t node = 0, lo = 0, hi = t->M, have = 0;
    for (;;) {
        sp = descend(t, qx, qy, &node, &lo, &hi, &st, sp);
        for (Py_ssize_t i = lo; i < hi; i++) {
            double dx = qx - t->pts[2 * i], dy = qy - t->pts[2 * i + 1];
            double dd = dx * dx + dy * dy;
            if (have == k && !(dd < d2[k - 1])) continue;
            Py_ssize_t j = have < k ? have++ : k - 1;
            while (j > 0 && d2[j - 1] > dd) { d2[j] = d2[j - 1]; idx[j] = idx[j - 1]; j--; }
            d2[j] = dd; idx[j] = i;
        }
        for (;;) {
            if (sp == 0) return;
            sp--;
            if (have < k || st.plane[sp] < d2[k - 1]) break;
        }
        node = st.node[sp]; lo = st.lo[sp]; hi = st.hi[sp];
    }
}

/* ---- ICP ------------------------------------------------------------------------------------ */

static double wrap(double a) {
    const double two_pi = 2.0 * M_PI;
    double w = a - two_pi * floor((a + M_PI) * (1.0 / two_pi));
    return w >= M_PI ? w - two_pi : (w < -M_PI ? -M_PI : w);
}

/* the selected correspondences of one pass: src[0..n) ascending, tgt[] their sorted target index */
typedef struct {
    Py_ssize_t n;
    int64_t *src, *tgt;
} corr_t;

/* Moves the source by (x, y, theta) into moved[], queries every point's nearest target within the
 * gate (d2[i], nb[i]; nb -1 when none) and selects the gated, trimmed correspondences into *c. */
static void correspond(const tree_t *t, const double *src, Py_ssize_t N, double x, double y, double th,
                       double gate2, double trim, Py_ssize_t min_corr, double *moved, double *d2,
                       Py_ssize_t *nb, double *scratch, corr_t *c) {
    double cs = cos(th), sn = sin(th);
    Py_ssize_t n = 0;
    for (Py_ssize_t i = 0; i < N; i++) {
        double mx = x + cs * src[2 * i] - sn * src[2 * i + 1];
        double my = y + sn * src[2 * i] + cs * src[2 * i + 1];
        moved[2 * i] = mx; moved[2 * i + 1] = my;
        double bd2 = gate2;
        Py_ssize_t b = -1;
        nn(t, mx, my, &bd2, &b);
        nb[i] = b; d2[i] = bd2;
        if (b >= 0) scratch[n++] = bd2;
    }
    Py_ssize_t keep = n;
    double thr = INFINITY;
    if (trim < 1.0 && n > min_corr) {
        keep = (Py_ssize_t)ceil(trim * (double)n);
        if (keep < min_corr) keep = min_corr;
        if (keep < n) {
            /* the keep-th smallest squared distance (quickselect on the scratch copy) */
            Py_ssize_t l = 0, r = n - 1, kk = keep - 1;
            while (l < r) {
                double pivot = scratch[l + (r - l) / 2];
                Py_ssize_t i = l, j = r;
                while (i <= j) {
                    while (scratch[i] < pivot) i++;
                    while (scratch[j] > pivot) j--;
                    if (i <= j) { double tmp = scratch[i]; scratch[i] = scratch[j]; scratch[j] = tmp; i++; j--; }
                }
                if (kk <= j) r = j;
                else if (kk >= i) l = i;
                else break;
            }
            thr = scratch[kk];
        }
    }
    /* keep every d2 < thr, then those == thr in index order until keep */
    Py_ssize_t below = 0;
    if (keep < n) for (Py_ssize_t i = 0; i < N; i++) if (nb[i] >= 0 && d2[i] < thr) below++;
    Py_ssize_t ties = keep - below, m = 0;
    for (Py_ssize_t i = 0; i < N; i++) {
        if (nb[i] < 0) continue;
        if (keep < n) {
            if (d2[i] > thr) continue;
            if (d2[i] == thr) { if (ties <= 0) continue; ties--; }
        }
        c->src[m] = i; c->tgt[m] = nb[i]; m++;
    }
    c->n = m;
}

/* A = J^T J (upper: a00 a01 a02 a11 a12 a22), g = J^T e, ee = e^T e, rss = sum |moved - q|^2 */
static void normal_equations(const tree_t *t, const double *normals, const double *moved, const corr_t *c,
                             double A[6], double g[3], double *ee, double *rss) {
    double a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0, g0 = 0, g1 = 0, g2 = 0, s = 0, r = 0;
    for (Py_ssize_t k = 0; k < c->n; k++) {
        Py_ssize_t i = c->src[k], j = c->tgt[k];
        double mx = moved[2 * i], my = moved[2 * i + 1];
        double nx = normals[2 * j], ny = normals[2 * j + 1];
        double dx = mx - t->pts[2 * j], dy = my - t->pts[2 * j + 1];
        double e = nx * dx + ny * dy;
        double j2 = ny * mx - nx * my;
        a00 += nx * nx; a01 += nx * ny; a02 += nx * j2;
        a11 += ny * ny; a12 += ny * j2; a22 += j2 * j2;
        g0 += nx * e; g1 += ny * e; g2 += j2 * e;
        s += e * e;
        r += dx * dx + dy * dy;
    }
    A[0] = a00; A[1] = a01; A[2] = a02; A[3] = a11; A[4] = a12; A[5] = a22;
    g[0] = g0; g[1] = g1; g[2] = g2;
    *ee = s; *rss = r;
}

/* x = A^-1 b by Gaussian elimination with partial pivoting; -1 when a pivot is exactly 0 */
static int solve3(const double As[6], const double b[3], double x[3]) {
    double M[3][4] = {{As[0], As[1], As[2], b[0]}, {As[1], As[3], As[4], b[1]}, {As[2], As[4], As[5], b[2]}};
    for (int col = 0; col < 3; col++) {
        int piv = col;
        for (int r = col + 1; r < 3; r++) if (fabs(M[r][col]) > fabs(M[piv][col])) piv = r;
        if (M[piv][col] == 0.0) return -1;
        if (piv != col) for (int k = 0; k < 4; k++) { double tmp = M[col][k]; M[col][k] = M[piv][k]; M[piv][k] = tmp; }
        for (int r = col + 1; r < 3; r++) {
            double f = M[r][col] / M[col][col];
            for (int k = col; k < 4; k++) M[r][k] -= f * M[col][k];
        }
    }
    for (int r = 2; r >= 0; r--) {
        double v = M[r][3];
        for (int k = r + 1; k < 3; k++) v -= M[r][k] * x[k];
        x[r] = v / M[r][r];
    }
    return 0;
}

static int same_set(const corr_t *a, const corr_t *b) {
    return a->n == b->n && memcmp(a->src, b->src, (size_t)a->n * sizeof(int64_t)) == 0 &&
           memcmp(a->tgt, b->tgt, (size_t)a->n * sizeof(int64_t)) == 0;
}

/* ---- Python glue ---------------------------------------------------------------------------- */

static int get_buf(PyObject *obj, Py_buffer *view, Py_ssize_t nbytes, const char *name, int writable) {
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | (writable ? PyBUF_WRITABLE : 0)) < 0) return -1;
    if (view->len < nbytes) {
        PyErr_Format(PyExc_ValueError, "%s: buffer too small (%zd < %zd bytes)", name, view->len, nbytes);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

static int get_bufs(int n, PyObject **objs, Py_buffer *bufs, const Py_ssize_t *sizes, const char **names,
                    const int *writable) {
    for (int i = 0; i < n; i++) {
        if (get_buf(objs[i], &bufs[i], sizes[i], names[i], writable[i]) < 0) {
            for (int j = 0; j < i; j++) PyBuffer_Release(&bufs[j]);
            return -1;
        }
    }
    return 0;
}

static void release(int n, Py_buffer *bufs) { for (int j = 0; j < n; j++) PyBuffer_Release(&bufs[j]); }

static int check_tree(Py_ssize_t M, Py_ssize_t leaf, Py_ssize_t n_dims) {
    if (M < 1 || leaf < 1) { PyErr_SetString(PyExc_ValueError, "k-d tree: M and leaf must be >= 1"); return -1; }
    /* the depth of the tree: a range of n splits into at most (n + 1) / 2 */
    Py_ssize_t n = M, depth = 0;
    while (n > leaf) { n = (n + 1) / 2; depth++; }
    if (depth >= MAX_DEPTH - 1 || n_dims < ((Py_ssize_t)1 << (depth + 1)) - 1) {
        PyErr_SetString(PyExc_ValueError, "k-d tree: dims array too small for M and leaf");
        return -1;
    }
    return 0;
}

static PyObject *py_build(PyObject *self, PyObject *args) {
    PyObject *p_o, *perm_o, *s_o, *d_o, *sp_o;
    Py_ssize_t M, leaf, n_dims;
    if (!PyArg_ParseTuple(args, "OnnOOOOn", &p_o, &M, &leaf, &perm_o, &s_o, &d_o, &sp_o, &n_dims)) return NULL;
    if (check_tree(M, leaf, n_dims) < 0) return NULL;
    Py_buffer b[5];
    PyObject *objs[5] = {p_o, perm_o, s_o, d_o, sp_o};
    Py_ssize_t sizes[5] = {M * 16, M * 8, M * 16, n_dims, n_dims * 8};
    const char *names[5] = {"points", "perm", "sorted", "dims", "splits"};
    int wr[5] = {0, 1, 1, 1, 1};
    if (get_bufs(5, objs, b, sizes, names, wr) < 0) return NULL;
    const double *p = (const double *)b[0].buf;
    int64_t *perm = (int64_t *)b[1].buf;
    double *sorted = (double *)b[2].buf;
    int8_t *dims = (int8_t *)b[3].buf;
    double *splits = (double *)b[4].buf;
    int rc;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < M; i++) perm[i] = i;
    memset(dims, -1, (size_t)n_dims);
    for (Py_ssize_t i = 0; i < n_dims; i++) splits[i] = 0.0;
    rc = build_node(perm, p, dims, splits, n_dims, 0, 0, M, leaf);
    for (Py_ssize_t i = 0; i < M; i++) { sorted[2 * i] = p[2 * perm[i]]; sorted[2 * i + 1] = p[2 * perm[i] + 1]; }
    Py_END_ALLOW_THREADS
    release(5, b);
    if (rc < 0) { PyErr_SetString(PyExc_ValueError, "k-d tree: dims array too small"); return NULL; }
    Py_RETURN_NONE;
}

static PyObject *py_normals(PyObject *self, PyObject *args) {
    PyObject *s_o, *d_o, *sp_o, *out_o;
    Py_ssize_t M, leaf, n_dims, k;
    if (!PyArg_ParseTuple(args, "OnnOOnnO", &s_o, &M, &leaf, &d_o, &sp_o, &n_dims, &k, &out_o)) return NULL;
    if (check_tree(M, leaf, n_dims) < 0) return NULL;
    if (k < 1 || k > M || k > 1024) {
        PyErr_SetString(PyExc_ValueError, "normals: need 1 <= k <= min(M, 1024)");
        return NULL;
    }
    Py_buffer b[4];
    PyObject *objs[4] = {s_o, d_o, sp_o, out_o};
    Py_ssize_t sizes[4] = {M * 16, n_dims, n_dims * 8, M * 16};
    const char *names[4] = {"sorted", "dims", "splits", "out"};
    int wr[4] = {0, 0, 0, 1};
    if (get_bufs(4, objs, b, sizes, names, wr) < 0) return NULL;
    tree_t t = {(const double *)b[0].buf, M, leaf, (const int8_t *)b[1].buf, (const double *)b[2].buf};
    double *out = (double *)b[3].buf;
    double d2[1024];
    Py_ssize_t idx[1024];
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < M; i++) {
        knn(&t, t.pts[2 * i], t.pts[2 * i + 1], k, d2, idx);
        double mx = 0, my = 0;
        for (Py_ssize_t j = 0; j < k; j++) { mx += t.pts[2 * idx[j]]; my += t.pts[2 * idx[j] + 1]; }
        mx /= (double)k; my /= (double)k;
        double a = 0, bb = 0, c = 0;
        for (Py_ssize_t j = 0; j < k; j++) {
            double cx = t.pts[2 * idx[j]] - mx, cy = t.pts[2 * idx[j] + 1] - my;
            a += cx * cx; bb += cx * cy; c += cy * cy;
        }
        double phi = 0.5 * atan2(2.0 * bb, a - c);
        out[2 * i] = -sin(phi);
        out[2 * i + 1] = cos(phi);
    }
    Py_END_ALLOW_THREADS
    release(4, b);
    Py_RETURN_NONE;
}

static PyObject *py_nearest(PyObject *self, PyObject *args) {
    PyObject *s_o, *d_o, *sp_o, *perm_o, *q_o, *od_o, *oi_o;
    Py_ssize_t M, leaf, n_dims, Q;
    double bound;
    if (!PyArg_ParseTuple(args, "OnnOOnOOndOO", &s_o, &M, &leaf, &d_o, &sp_o, &n_dims, &perm_o, &q_o, &Q, &bound,
                          &od_o, &oi_o))
        return NULL;
    if (check_tree(M, leaf, n_dims) < 0) return NULL;
    Py_buffer b[7];
    PyObject *objs[7] = {s_o, d_o, sp_o, perm_o, q_o, od_o, oi_o};
    Py_ssize_t sizes[7] = {M * 16, n_dims, n_dims * 8, M * 8, Q * 16, Q * 8, Q * 8};
    const char *names[7] = {"sorted", "dims", "splits", "perm", "queries", "out_dist", "out_idx"};
    int wr[7] = {0, 0, 0, 0, 0, 1, 1};
    if (get_bufs(7, objs, b, sizes, names, wr) < 0) return NULL;
    tree_t t = {(const double *)b[0].buf, M, leaf, (const int8_t *)b[1].buf, (const double *)b[2].buf};
    const int64_t *perm = (const int64_t *)b[3].buf;
    const double *q = (const double *)b[4].buf;
    double *od = (double *)b[5].buf;
    int64_t *oi = (int64_t *)b[6].buf;
    double bound2 = bound * bound;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < Q; i++) {
        double bd2 = bound2;
        Py_ssize_t best = -1;
        nn(&t, q[2 * i], q[2 * i + 1], &bd2, &best);
        if (best < 0) { od[i] = INFINITY; oi[i] = M; }
        else { od[i] = sqrt(bd2); oi[i] = perm[best]; }
    }
    Py_END_ALLOW_THREADS
    release(7, b);
    Py_RETURN_NONE;
}

#define CYCLE 4

static PyObject *py_icp(PyObject *self, PyObject *args) {
    PyObject *s_o, *d_o, *sp_o, *n_o, *src_o;
    Py_ssize_t M, leaf, n_dims, N, max_iter, min_corr;
    double x, y, th, gate, trim, ttol, rtol, ctol_m, ctol_rad, fit_d;
    if (!PyArg_ParseTuple(args, "OnnOOnOOndddndndddddd", &s_o, &M, &leaf, &d_o, &sp_o, &n_dims, &n_o, &src_o, &N,
                          &x, &y, &th, &max_iter, &gate, &min_corr, &trim, &ttol, &rtol, &ctol_m, &ctol_rad, &fit_d))
        return NULL;
    if (check_tree(M, leaf, n_dims) < 0) return NULL;
    if (N < 1) { PyErr_SetString(PyExc_ValueError, "icp: no source points"); return NULL; }
    Py_buffer b[5];
    PyObject *objs[5] = {s_o, d_o, sp_o, n_o, src_o};
    Py_ssize_t sizes[5] = {M * 16, n_dims, n_dims * 8, M * 16, N * 16};
    const char *names[5] = {"sorted", "dims", "splits", "normals", "source"};
    int wr[5] = {0, 0, 0, 0, 0};
    if (get_bufs(5, objs, b, sizes, names, wr) < 0) return NULL;
    tree_t t = {(const double *)b[0].buf, M, leaf, (const int8_t *)b[1].buf, (const double *)b[2].buf};
    const double *normals = (const double *)b[3].buf;
    const double *src = (const double *)b[4].buf;

    /* one block: moved (2N), d2 (N), scratch (N) doubles; nb (N); CYCLE + 1 sets of 2N int64 */
    size_t nd = (size_t)N * 4, ni = (size_t)N + (size_t)(CYCLE + 1) * 2 * (size_t)N;
    char *mem = malloc(nd * sizeof(double) + ni * sizeof(int64_t));
    if (!mem) { release(5, b); return PyErr_NoMemory(); }
    double *moved = (double *)mem, *d2 = moved + 2 * N, *scratch = d2 + N;
    Py_ssize_t *nb = (Py_ssize_t *)(scratch + N);
    int64_t *ib = (int64_t *)(nb + N);
    corr_t sets[CYCLE + 1];
    for (int s = 0; s <= CYCLE; s++) {
        sets[s].n = 0;
        sets[s].src = ib + (size_t)s * 2 * N;
        sets[s].tgt = sets[s].src + N;
    }
    int n_recent = 0, newest = -1; /* ring of the last CYCLE sets; slot CYCLE is the current one */

    int status = 0, converged = 0;
    Py_ssize_t iterations = 0;
    double gate2 = gate * gate;
    double A[6] = {0}, g[3] = {0}, ee = 0.0, rss = 0.0, fitness = 0.0;
    Py_ssize_t n_final = 0;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t it = 1; it <= max_iter; it++) {
        iterations = it;
        corr_t *cur = &sets[CYCLE];
        correspond(&t, src, N, x, y, th, gate2, trim, min_corr, moved, d2, nb, scratch, cur);
        if (cur->n < min_corr) break;
        int cycling = 0;
        for (int r = 0; r < n_recent; r++) if (same_set(cur, &sets[r])) { cycling = 1; break; }
        /* remember it (replacing the oldest of the last CYCLE) */
        newest = (newest + 1) % CYCLE;
        if (n_recent < CYCLE) n_recent++;
        {
            corr_t tmp = sets[newest]; sets[newest] = *cur; sets[CYCLE] = tmp;
        }
        const corr_t *c = &sets[newest];
        normal_equations(&t, normals, moved, c, A, g, &ee, &rss);
        double sol[3];
        if (solve3(A, g, sol) < 0) { status = 1; break; }
        double dx = -sol[0], dy = -sol[1], dth = -sol[2];
        /* T = compose(delta, T): the increment acts in the target frame */
        double cd = cos(dth), sd = sin(dth);
        double nx_ = dx + cd * x - sd * y, ny_ = dy + sd * x + cd * y;
        x = nx_; y = ny_; th = wrap(dth + th);
        double step_m = hypot(dx, dy), step_rad = fabs(dth);
        if ((step_m < ttol && step_rad < rtol) || (cycling && step_m < ctol_m && step_rad < ctol_rad)) {
            converged = 1;
            break;
        }
    }
    if (status == 0) {
        /* _finish: one gated query at the result serves fitness and the final correspondences */
        corr_t *cur = &sets[CYCLE];
        correspond(&t, src, N, x, y, th, gate2, trim, min_corr, moved, d2, nb, scratch, cur);
        Py_ssize_t hit = 0;
        if (fit_d < gate) {
            for (Py_ssize_t i = 0; i < N; i++) if (nb[i] >= 0 && sqrt(d2[i]) <= fit_d) hit++;
        } else {
            for (Py_ssize_t i = 0; i < N; i++) {
                double bd2 = INFINITY;
                Py_ssize_t bi = -1;
                nn(&t, moved[2 * i], moved[2 * i + 1], &bd2, &bi);
                if (bi >= 0 && sqrt(bd2) <= fit_d) hit++;
            }
        }
        fitness = (double)hit / (double)N;
        n_final = cur->n;
        normal_equations(&t, normals, moved, cur, A, g, &ee, &rss);
    }
    Py_END_ALLOW_THREADS
    free(mem);
    release(5, b);
    return Py_BuildValue("idddnidndddddddd", status, x, y, th, iterations, converged, fitness, n_final, A[0], A[1],
                         A[2], A[3], A[4], A[5], ee, rss);
}

static PyMethodDef methods[] = {
    {"build", py_build, METH_VARARGS, "Build the k-d tree; see the module comment."},
    {"normals", py_normals, METH_VARARGS, "PCA normals of the tree's points; see the module comment."},
    {"nearest", py_nearest, METH_VARARGS, "Gated nearest neighbours; see the module comment."},
    {"icp", py_icp, METH_VARARGS, "Point-to-line ICP loop; see the module comment."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef moduledef = {PyModuleDef_HEAD_INIT, "_icpkernel",
                                       "Compiled k-d tree and point-to-line ICP of the scan matcher.", -1, methods};

PyMODINIT_FUNC PyInit__icpkernel(void) { return PyModule_Create(&moduledef); }
