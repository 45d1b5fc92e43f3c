/* Fast path of slamkit's tagged-line text readers (g2o, TORO, iSAM): see _records.py.
 *
 * Two functions over the raw bytes of a file:
 *
 *   tags(data: bytes) -> dict[str, bytearray] | None
 *       first token of every line -> one-based line numbers (native int64) of its lines, in
 *       order of first appearance. Blank lines and lines whose first token starts with '#' are
 *       skipped. Lines end at "\n" or "\r\n" (the shared rule of slamkit/_text.py). Returns None
 *       when the data holds a byte other than printable ASCII, tab, CR or LF, or a CR not
 *       followed by LF: the Python path, which keeps such characters inside their line and
 *       reports decoding errors, handles those files.
 *
 *   scan(data: bytes, tag: str, ncols: int) -> (bytearray, bytearray) | None
 *       for every line whose first token is ``tag``: exactly ``ncols`` numbers after the tag,
 *       returned as K*ncols native doubles and K int64 line numbers. Returns None at the first
 *       line with another token count or a token that is not a plain decimal number (sign,
 *       digits, '.', exponent) or nan/inf/infinity: the caller then reruns its Python path, which
 *       names the line and field exactly as before. The grammar accepted here is a subset of what
 *       numpy.loadtxt accepts, so a file loads the same or not at all whichever path reads it.
 *
 * Numbers are converted with Clinger's exact fast path (W. D. Clinger, "How to read floating
 * point numbers accurately", PLDI 1990): a decimal with at most 15 significant digits and a
 * power of ten within 1e+-22 is one correctly rounded IEEE multiplication or division of two
 * exactly representable doubles; anything else goes to the C library's strtod, which is also
 * correctly rounded (glibc). numpy's parser rounds correctly too, so both paths give the same
 * bits.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static const double POW10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                 1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static inline int is_blank(char c) { return c == ' ' || c == '\t'; }

/* advance *pos past one line; returns the line's end (exclusive, before the terminator) */
static inline Py_ssize_t line_end(const char *s, Py_ssize_t n, Py_ssize_t *pos) {
    Py_ssize_t i = *pos;
    while (i < n && s[i] != '\n' && s[i] != '\r') i++;
    Py_ssize_t end = i;
    if (i < n) {
        if (s[i] == '\r' && i + 1 < n && s[i + 1] == '\n') i += 2;
        else i += 1;
    }
    *pos = i;
    return end;
}

static int ci_equal(const char *p, Py_ssize_t len, const char *word) {
    Py_ssize_t k = (Py_ssize_t)strlen(word);
    if (len != k) return 0;
    for (Py_ssize_t i = 0; i < k; i++) {
        char c = p[i];
        if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
        if (c != word[i]) return 0;
    }
    return 1;
}

/* Parse the token [p, end); 1 on success. The byte at ``end`` is whitespace, a line break or the
 * bytes object's terminating NUL, so strtod cannot run past the token. */
static int parse_number(const char *p, const char *end, double *out) {
    const char *q = p;
    int negative = 0;
    if (q < end && (*q == '+' || *q == '-')) {
        negative = (*q == '-');
        q++;
    }
    if (q < end && !(*q >= '0' && *q <= '9') && *q != '.') {
        Py_ssize_t len = end - q;
        if (ci_equal(q, len, "nan")) { *out = negative ? -NAN : NAN; return 1; }
        if (ci_equal(q, len, "inf") || ci_equal(q, len, "infinity")) {
            *out = negative ? -INFINITY : INFINITY;
            return 1;
        }
        return 0;
    }
    uint64_t mantissa = 0;
    int significant = 0, digits = 0, frac_digits = 0, overflow = 0;
    while (q < end && *q >= '0' && *q <= '9') {
        if (mantissa || *q != '0') {
            if (significant < 19) mantissa = mantissa * 10 + (uint64_t)(*q - '0');
            else overflow = 1;
            significant++;
        }
        digits++;
        q++;
    }
    if (q < end && *q == '.') {
        q++;
        while (q < end && *q >= '0' && *q <= '9') {
            if (mantissa || *q != '0') {
                if (significant < 19) mantissa = mantissa * 10 + (uint64_t)(*q - '0');
                else overflow = 1;
                significant++;
            }
            digits++;
            frac_digits++;
            q++;
        }
    }
    if (digits == 0) return 0;
    long exponent = 0;
    if (q < end && (*q == 'e' || *q == 'E')) {
        q++;
        int exp_negative = 0, exp_digits = 0;
        if (q < end && (*q == '+' || *q == '-')) {
            exp_negative = (*q == '-');
            q++;
        }
        while (q < end && *q >= '0' && *q <= '9') {
            if (exponent < 100000) exponent = exponent * 10 + (*q - '0');
            exp_digits++;
            q++;
        }
        if (exp_digits == 0) return 0;
        if (exp_negative) exponent = -exponent;
    }
    if (q != end) return 0;
    /* digits dropped past 19 significant ones do not shift the scale: the overflow case goes to
     * strtod below, so only the fast path uses exponent - frac_digits */
    long scale = exponent - frac_digits;
    if (!overflow && significant <= 15 && scale >= -22 && scale <= 22) {
        double v = (double)mantissa; /* exact: mantissa < 1e15 < 2^53 */
        v = scale >= 0 ? v * POW10[scale] : v / POW10[-scale];
        *out = negative ? -v : v;
        return 1;
    }
    char *stop = NULL;
    double v = strtod(p, &stop);
    if (stop != end) return 0; /* e.g. a non-C LC_NUMERIC locale: let the Python path decide */
    *out = v;
    return 1;
}

typedef struct {
    char *data;
    Py_ssize_t size, cap; /* bytes */
} Buffer;

static int buffer_push(Buffer *b, const void *item, Py_ssize_t size) {
    if (b->size + size > b->cap) {
        Py_ssize_t cap = b->cap ? b->cap * 2 : 4096;
        while (cap < b->size + size) cap *= 2;
        char *grown = PyMem_Realloc(b->data, (size_t)cap);
        if (!grown) { PyErr_NoMemory(); return -1; }
        b->data = grown;
        b->cap = cap;
    }
    memcpy(b->data + b->size, item, (size_t)size);
    b->size += size;
    return 0;
}

static PyObject *tags(PyObject *self, PyObject *args) {
    Py_buffer view;
    if (!PyArg_ParseTuple(args, "y*", &view)) return NULL;
    const char *s = view.buf;
    Py_ssize_t n = view.len;
    for (Py_ssize_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)s[i];
        /* a lone CR is not a line break (slamkit._text's rule): the Python path keeps it in its line */
        if (c > 0x7f || (c < 0x20 && c != '\t' && c != '\n' && c != '\r')
            || (c == '\r' && (i + 1 >= n || s[i + 1] != '\n'))) {
            PyBuffer_Release(&view);
            Py_RETURN_NONE;
        }
    }
    PyObject *index = PyDict_New(); /* tag -> position in ``buffers`` */
    Buffer *buffers = NULL;
    PyObject **names = NULL;
    Py_ssize_t ntags = 0, captags = 0;
    const char *last = NULL;
    Py_ssize_t last_len = -1, last_tag = -1;
    PyObject *result = NULL;
    if (!index) goto done;
    Py_ssize_t pos = 0;
    int64_t lineno = 0;
    while (pos < n) {
        Py_ssize_t start = pos;
        Py_ssize_t end = line_end(s, n, &pos);
        lineno++;
        while (start < end && is_blank(s[start])) start++;
        if (start == end || s[start] == '#') continue;
        Py_ssize_t stop = start;
        while (stop < end && !is_blank(s[stop])) stop++;
        Py_ssize_t len = stop - start, which;
        if (len == last_len && memcmp(s + start, last, (size_t)len) == 0) {
            which = last_tag;
        } else {
            PyObject *name = PyUnicode_DecodeASCII(s + start, len, NULL);
            if (!name) goto done;
            PyObject *found = PyDict_GetItemWithError(index, name);
            if (found) {
                which = PyLong_AsSsize_t(found);
                Py_DECREF(name);
            } else if (PyErr_Occurred()) {
                Py_DECREF(name);
                goto done;
            } else {
                if (ntags == captags) {
                    Py_ssize_t cap = captags ? captags * 2 : 8;
                    Buffer *nb = PyMem_Realloc(buffers, (size_t)cap * sizeof(Buffer));
                    if (!nb) { Py_DECREF(name); PyErr_NoMemory(); goto done; }
                    buffers = nb;
                    PyObject **nn = PyMem_Realloc(names, (size_t)cap * sizeof(PyObject *));
                    if (!nn) { Py_DECREF(name); PyErr_NoMemory(); goto done; }
                    names = nn;
                    captags = cap;
                }
                which = ntags;
                PyObject *value = PyLong_FromSsize_t(which);
                if (!value || PyDict_SetItem(index, name, value) < 0) {
                    Py_XDECREF(value);
                    Py_DECREF(name);
                    goto done;
                }
                Py_DECREF(value);
                memset(&buffers[ntags], 0, sizeof(Buffer));
                names[ntags] = name; /* owns the reference */
                ntags++;
            }
            last = s + start;
            last_len = len;
            last_tag = which;
        }
        if (buffer_push(&buffers[which], &lineno, sizeof lineno) < 0) goto done;
    }
    result = PyDict_New();
    if (!result) goto done;
    for (Py_ssize_t t = 0; t < ntags; t++) {
        PyObject *lines = PyByteArray_FromStringAndSize(buffers[t].data, buffers[t].size);
        if (!lines || PyDict_SetItem(result, names[t], lines) < 0) {
            Py_XDECREF(lines);
            Py_CLEAR(result);
            goto done;
        }
        Py_DECREF(lines);
    }
done:
    for (Py_ssize_t t = 0; t < ntags; t++) {
        PyMem_Free(buffers[t].data);
        Py_DECREF(names[t]);
    }
    PyMem_Free(buffers);
    PyMem_Free(names);
    Py_XDECREF(index);
    PyBuffer_Release(&view);
    return result;
}

/* grow a malloc'd buffer (plain malloc: callable without the GIL); -1 when out of memory */
static int raw_reserve(Buffer *b, Py_ssize_t extra) {
    if (b->size + extra <= b->cap) return 0;
    Py_ssize_t cap = b->cap ? b->cap * 2 : 65536;
    while (cap < b->size + extra) cap *= 2;
    char *grown = realloc(b->data, (size_t)cap);
    if (!grown) return -1;
    b->data = grown;
    b->cap = cap;
    return 0;
}

static PyObject *scan(PyObject *self, PyObject *args) {
    PyObject *data;
    const char *tag;
    Py_ssize_t tag_len, ncols;
    if (!PyArg_ParseTuple(args, "Ss#n", &data, &tag, &tag_len, &ncols)) return NULL;
    if (ncols < 0 || ncols > 4096) {
        PyErr_SetString(PyExc_ValueError, "ncols must lie in [0, 4096]");
        return NULL;
    }
    /* a bytes object ends with a NUL, so strtod always finds a delimiter after the last token */
    const char *s = PyBytes_AS_STRING(data);
    Py_ssize_t n = PyBytes_GET_SIZE(data);
    Buffer values = {0}, lines = {0};
    int status = 1; /* 1 ok, 0 a line the Python path must judge, -1 out of memory */
    double *cells = malloc((size_t)(ncols ? ncols : 1) * sizeof(double));
    if (!cells) return PyErr_NoMemory();
    Py_BEGIN_ALLOW_THREADS
    Py_ssize_t pos = 0;
    int64_t lineno = 0;
    while (pos < n) {
        Py_ssize_t start = pos;
        Py_ssize_t end = line_end(s, n, &pos);
        lineno++;
        while (start < end && is_blank(s[start])) start++;
        Py_ssize_t stop = start;
        while (stop < end && !is_blank(s[stop])) stop++;
        if (stop - start != tag_len || memcmp(s + start, tag, (size_t)tag_len) != 0) continue;
        Py_ssize_t col = 0, i = stop;
        for (;;) {
            while (i < end && is_blank(s[i])) i++;
            if (i == end) break;
            Py_ssize_t t0 = i;
            while (i < end && !is_blank(s[i])) i++;
            if (col == ncols || !parse_number(s + t0, s + i, &cells[col])) { status = 0; break; }
            col++;
        }
        if (status != 1 || col != ncols) { status = 0; break; }
        Py_ssize_t row_bytes = ncols * (Py_ssize_t)sizeof(double);
        if (raw_reserve(&values, row_bytes) < 0 || raw_reserve(&lines, sizeof lineno) < 0) {
            status = -1;
            break;
        }
        memcpy(values.data + values.size, cells, (size_t)row_bytes);
        values.size += row_bytes;
        memcpy(lines.data + lines.size, &lineno, sizeof lineno);
        lines.size += (Py_ssize_t)sizeof lineno;
    }
    Py_END_ALLOW_THREADS
    PyObject *result = NULL;
    if (status == -1) {
        PyErr_NoMemory();
    } else if (status == 0) {
        result = Py_NewRef(Py_None);
    } else {
        PyObject *v = PyByteArray_FromStringAndSize(values.data ? values.data : "", values.size);
        PyObject *l = PyByteArray_FromStringAndSize(lines.data ? lines.data : "", lines.size);
        if (v && l) result = PyTuple_Pack(2, v, l);
        Py_XDECREF(v);
        Py_XDECREF(l);
    }
    free(cells);
    free(values.data);
    free(lines.data);
    return result;
}

static PyMethodDef METHODS[] = {
    {"tags", tags, METH_VARARGS,
     "tags(data: bytes) -> dict[str, bytearray] | None: first token -> int64 one-based line "
     "numbers; None if the data holds bytes other than printable ASCII, tab, CR, LF."},
    {"scan", scan, METH_VARARGS,
     "scan(data: bytes, tag: str, ncols: int) -> (bytearray, bytearray) | None: the ncols "
     "numbers after ``tag`` on each of its lines (float64, row major) and the line numbers "
     "(int64); None at the first line that does not hold exactly ncols plain numbers."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef MODULE = {PyModuleDef_HEAD_INIT, "_textscan",
                                    "Fast tagged-line scanning for slamkit's pose-graph readers.",
                                    -1, METHODS};

PyMODINIT_FUNC PyInit__textscan(void) { return PyModule_Create(&MODULE); }
