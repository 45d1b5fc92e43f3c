/* Compiled core of slamkit's grid A* / Dijkstra (see slamkit/planning/grid_search.py).
 *
 * A best-first search on a 4- or 8-connected grid (Hart, Nilsson & Raphael 1968) with an
 * indexed binary heap: each cell is in the heap at most once and a cheaper route lowers its key
 * in place (decrease-key). Lazy deletion (pushing duplicates) was measured first: with the
 * octile heuristic about half of all pushes were duplicates and the heap grew to ~140k entries
 * on a 1000 x 1000 map, making A* 2x slower than with decrease-key. Ties in f are broken
 * towards larger g (deeper nodes), which on open maps avoids expanding plateaus of equal f.
 *
 * Only the Python C API and the buffer protocol are used, so building it needs nothing beyond
 * the Python headers (no numpy headers). The Python side allocates every array.
 *
 *   search(cost, height, width, start, goal, connectivity, corner_cutting, heuristic, h_scale,
 *          g_out, parent_out, path_out, order_out[, enter_cost])
 *       -> (goal_cost, path_len, expansions, n_order, opened)
 *
 * cost       float64[H*W]  traversal multiplier per cell, +inf = blocked (must be >= 0)
 * enter_cost 0 (default): a move costs step * the mean of its two cells' multipliers;
 *            1: step * the multiplier of the cell it enters (the textbook grid model);
 *            2: step * the multiplier of the cell it leaves: the enter model's graph with every
 *               edge reversed (D* Lite's backward search from the goal)
 * heuristic  0 zero, 1 euclidean, 2 manhattan, 3 octile, 4 chebyshev  (in cells, times h_scale)
 * g_out      float64[H*W]  cost-to-come of every closed / opened cell (inf elsewhere)
 * parent_out int64[H*W]    predecessor (-1 for none)
 * path_out   int64[H*W]    the path, start first, written only if the goal is reached
 * order_out  int64[H*W] or None: expansion order (for viewers); recorded only when given
 * goal_cost  +inf when the goal cannot be reached (the whole reachable component was closed)
 * opened     number of distinct cells ever put on the open list
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* 16 bytes so more of a large open list stays in cache; g only breaks ties, float is enough */
typedef struct {
    double f;
    float g;
    uint32_t idx;
} entry_t;

typedef struct {
    entry_t *data;
    Py_ssize_t size;
    Py_ssize_t cap;
    uint32_t *pos;   /* slot + 1 of each cell in the heap, 0 if absent */
} heap_t;

static inline int less(const entry_t *a, const entry_t *b) {
    if (a->f != b->f) return a->f < b->f;
    return a->g > b->g;
}

static inline void sift_up(heap_t *h, Py_ssize_t i, entry_t e) {
    entry_t *d = h->data;
    while (i > 0) {
        Py_ssize_t p = (i - 1) >> 1;
        if (!less(&e, &d[p])) break;
        d[i] = d[p];
        h->pos[d[i].idx] = (uint32_t)(i + 1);
        i = p;
    }
    d[i] = e;
    h->pos[e.idx] = (uint32_t)(i + 1);
}

/* insert, or lower the key of a cell already in the heap */
static int heap_push(heap_t *h, double f, double g, int64_t idx) {
    entry_t e = {f, (float)g, (uint32_t)idx};
    uint32_t p = h->pos[idx];
    if (p) { sift_up(h, (Py_ssize_t)p - 1, e); return 0; }
    if (h->size == h->cap) {
        Py_ssize_t ncap = h->cap ? 2 * h->cap : 1024;
        entry_t *nd = (entry_t *)realloc(h->data, (size_t)ncap * sizeof(entry_t));
        if (!nd) return -1;
        h->data = nd;
        h->cap = ncap;
    }
    sift_up(h, h->size++, e);
    return 0;
}

static entry_t heap_pop(heap_t *h) {
    entry_t *d = h->data;
    entry_t top = d[0];
    h->pos[top.idx] = 0;
    entry_t last = d[--h->size];
    Py_ssize_t n = h->size;
    if (n == 0) return top;
    Py_ssize_t i = 0;
    for (;;) {
        Py_ssize_t c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && less(&d[c + 1], &d[c])) c++;
        d[i] = d[c];
        h->pos[d[i].idx] = (uint32_t)(i + 1);
        i = c;
    }
    sift_up(h, i, last);
    return top;
}

/* the ternaries compile to branch-free maxsd/minsd */
static inline __attribute__((always_inline)) double heur(int kind, int64_t x, int64_t y, int64_t gx,
                                                         int64_t gy, double scale) {
    double dx = fabs((double)(x - gx)), dy = fabs((double)(y - gy));
    switch (kind) {
        case 1: return scale * sqrt(dx * dx + dy * dy);
        case 2: return scale * (dx + dy);
        case 3: {
            const double mx = dx > dy ? dx : dy, mn = dx > dy ? dy : dx;
            return scale * (mx + (M_SQRT2 - 1.0) * mn);
        }
        case 4: return scale * (dx > dy ? dx : dy);
        default: return 0.0;
    }
}

/* The search proper; returns 1 when out of memory. */
static inline __attribute__((always_inline)) int run(
        const int hkind, const double *cost, Py_ssize_t H, Py_ssize_t W, Py_ssize_t start,
        Py_ssize_t goal, int conn, int corner_cutting, int enter_cost, double hscale, double *g,
        int64_t *parent,
        int64_t *path, int64_t *order, double *goal_cost_out, Py_ssize_t *path_len_out,
        Py_ssize_t *expansions_out, Py_ssize_t *n_order_out, Py_ssize_t *opened_out) {
    /* neighbour offsets: the 4 straight moves first, then the diagonals */
    static const int DX[8] = {1, -1, 0, 0, 1, 1, -1, -1};
    static const int DY[8] = {0, 0, 1, -1, 1, -1, 1, -1};
    const int nmoves = conn == 4 ? 4 : 8;
    const Py_ssize_t N = H * W;
    double goal_cost = INFINITY;
    Py_ssize_t expansions = 0, n_order = 0, path_len = 0, opened = 1;
    int oom = 0;
    unsigned char *closed = (unsigned char *)calloc((size_t)N, 1);
    heap_t heap = {NULL, 0, 0, (uint32_t *)calloc((size_t)N, sizeof(uint32_t))};
    if (!closed || !heap.pos) {
        oom = 1;
    } else {
        for (Py_ssize_t i = 0; i < N; i++) { g[i] = INFINITY; parent[i] = -1; }
        const int64_t gx = goal % W, gy = goal / W;
        g[start] = 0.0;
        if (heap_push(&heap, heur(hkind, start % W, start / W, gx, gy, hscale), 0.0, start) < 0) oom = 1;
        while (!oom && heap.size > 0) {
            entry_t e = heap_pop(&heap);
            int64_t u = e.idx;
            if (closed[u]) continue;      /* cannot happen with decrease-key; kept as a guard */
            closed[u] = 1;
            expansions++;
            if (order) order[n_order++] = u;
            if (u == goal) { goal_cost = g[u]; break; }
            const int64_t ux = u % W, uy = u / W;
            const double cu = cost[u], gu = g[u];
            for (int k = 0; k < nmoves; k++) {
                const int64_t vx = ux + DX[k], vy = uy + DY[k];
                if (vx < 0 || vy < 0 || vx >= W || vy >= H) continue;
                const int64_t v = vy * W + vx;
                const double cv = cost[v];
                if (closed[v] || !isfinite(cv)) continue;
                double step = 1.0;
                if (k >= 4) {
                    /* a diagonal squeezes past two orthogonal cells: without corner cutting
                       both must be free (the MovingAI rule) */
                    if (!corner_cutting &&
                        (!isfinite(cost[uy * W + vx]) || !isfinite(cost[vy * W + ux]))) continue;
                    step = M_SQRT2;
                }
                const double ng = gu + step * (enter_cost == 1 ? cv : enter_cost == 2 ? cu : 0.5 * (cu + cv));
                if (ng < g[v]) {
                    if (g[v] == INFINITY) opened++;
                    g[v] = ng;
                    parent[v] = u;
                    if (heap_push(&heap, ng + heur(hkind, vx, vy, gx, gy, hscale), ng, v) < 0) { oom = 1; break; }
                }
            }
        }
        if (!oom && isfinite(goal_cost)) {
            /* walk the parents back, then reverse in place */
            for (int64_t v = goal; v != -1; v = parent[v]) path[path_len++] = v;
            for (Py_ssize_t i = 0, j = path_len - 1; i < j; i++, j--) {
                int64_t t = path[i]; path[i] = path[j]; path[j] = t;
            }
        }
    }
    free(closed);
    free(heap.data);
    free(heap.pos);
    *goal_cost_out = goal_cost; *path_len_out = path_len; *expansions_out = expansions; *n_order_out = n_order;
    *opened_out = opened;
    return oom;
}

static int get_buf(PyObject *obj, Py_buffer *view, Py_ssize_t nbytes, int writable, const char *name) {
    if (PyObject_GetBuffer(obj, view, (writable ? PyBUF_WRITABLE : 0) | PyBUF_C_CONTIGUOUS) < 0)
        return -1;
    if (view->len < nbytes) {
        PyErr_Format(PyExc_ValueError, "%s: buffer too small (%zd < %zd bytes)", name, view->len, nbytes);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

static PyObject *search(PyObject *self, PyObject *args) {
    PyObject *cost_o, *g_o, *parent_o, *path_o, *order_o;
    Py_ssize_t H, W, start, goal;
    int conn, corner_cutting, hkind, enter_cost = 0;
    double hscale;
    if (!PyArg_ParseTuple(args, "OnnnniiidOOOO|i", &cost_o, &H, &W, &start, &goal, &conn,
                          &corner_cutting, &hkind, &hscale, &g_o, &parent_o, &path_o, &order_o,
                          &enter_cost))
        return NULL;
    Py_ssize_t N = H * W;
    if (H <= 0 || W <= 0 || N >= 4294967295LL || start < 0 || start >= N || goal < 0 || goal >= N) {
        PyErr_SetString(PyExc_ValueError, "grid search: bad shape (max 2^32-1 cells) or start/goal index");
        return NULL;
    }
    Py_buffer cb, gb, pb, pathb, ob;
    int have_order = order_o != Py_None;
    if (get_buf(cost_o, &cb, N * 8, 0, "cost") < 0) return NULL;
    if (get_buf(g_o, &gb, N * 8, 1, "g_out") < 0) { PyBuffer_Release(&cb); return NULL; }
    if (get_buf(parent_o, &pb, N * 8, 1, "parent_out") < 0) {
        PyBuffer_Release(&cb); PyBuffer_Release(&gb); return NULL;
    }
    if (get_buf(path_o, &pathb, N * 8, 1, "path_out") < 0) {
        PyBuffer_Release(&cb); PyBuffer_Release(&gb); PyBuffer_Release(&pb); return NULL;
    }
    if (have_order && get_buf(order_o, &ob, N * 8, 1, "order_out") < 0) {
        PyBuffer_Release(&cb); PyBuffer_Release(&gb); PyBuffer_Release(&pb); PyBuffer_Release(&pathb);
        return NULL;
    }
    const double *cost = (const double *)cb.buf;
    double *g = (double *)gb.buf;
    int64_t *parent = (int64_t *)pb.buf;
    int64_t *path = (int64_t *)pathb.buf;
    int64_t *order = have_order ? (int64_t *)ob.buf : NULL;

    double goal_cost = INFINITY;
    Py_ssize_t expansions = 0, n_order = 0, path_len = 0, opened = 0;
    int oom = 0;
    Py_BEGIN_ALLOW_THREADS
    /* one copy of the loop per heuristic, so the heuristic switch is resolved at compile time */
    switch (hkind) {
#define CALL(K) case K: oom = run(K, cost, H, W, start, goal, conn, corner_cutting, enter_cost, hscale, g, parent, \
                                  path, order, &goal_cost, &path_len, &expansions, &n_order, &opened); break;
        CALL(1) CALL(2) CALL(3) CALL(4)
        default: CALL(0)
#undef CALL
    }
    Py_END_ALLOW_THREADS

    PyBuffer_Release(&cb); PyBuffer_Release(&gb); PyBuffer_Release(&pb); PyBuffer_Release(&pathb);
    if (have_order) PyBuffer_Release(&ob);
    if (oom) return PyErr_NoMemory();
    return Py_BuildValue("dnnnn", goal_cost, path_len, expansions, n_order, opened);
}

static PyMethodDef methods[] = {
    {"search", search, METH_VARARGS, "Grid A*/Dijkstra; see the module comment."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef moduledef = {PyModuleDef_HEAD_INIT, "_gridsearch",
                                       "Compiled grid A*/Dijkstra core.", -1, methods};

PyMODINIT_FUNC PyInit__gridsearch(void) { return PyModule_Create(&moduledef); }
