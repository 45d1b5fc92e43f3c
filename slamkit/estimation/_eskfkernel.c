/* One IMU step of slamkit's error-state EKF (eskf.py), fused in C.
 *
 *   propagate(x, P, accel, gyro, dt, gx, gy, gz, qa, qg, qba, qbg) -> bool
 *
 * x: writable float64 buffer of 21 numbers, the nominal state p(3) v(3) R(9, row-major) ba(3)
 * bg(3); P: writable float64 buffer of 15 x 15 (row-major) error covariance; accel, gyro: float64
 * buffers of 3 readings; dt > 0; g = (gx, gy, gz); q* the squared noise densities (accel white,
 * gyro white, accel bias walk, gyro bias walk). Returns False (and changes nothing) when a reading
 * is not finite. The arithmetic is that of ErrorStateEKF._propagate_numpy, in the same order:
 *
 *   a = accel - ba, w = gyro - bg, Ra = R a, dR = Exp(w dt), Rn = R dR,
 *   dF (9 x 15): [0:3, 3:6] = I dt, [0:3, 6:9] = -dt^2/2 hat(Ra), [0:3, 9:12] = -dt^2/2 R,
 *                [3:6, 6:9] = -dt hat(Ra), [3:6, 9:12] = -dt R, [6:9, 12:15] = -dt Rn (I - hat(w dt)/2),
 *   A = P; A[0:9] += dF P; A[:, 0:9] += A dF^T; A += Q_d (diagonal blocks, see eskf.py),
 *   p += v dt + dt^2/2 (Ra + g), v += (Ra + g) dt, R = Rn.
 *
 * No numpy C API: buffers through the buffer protocol (as _pfkernel.c).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#define N 15

static void hat(const double v[3], double out[9]) {
    out[0] = 0.0;   out[1] = -v[2]; out[2] = v[1];
    out[3] = v[2];  out[4] = 0.0;   out[5] = -v[0];
    out[6] = -v[1]; out[7] = v[0];  out[8] = 0.0;
}

static void exp_so3(const double phi[3], double R[9]) {
    double x = phi[0], y = phi[1], z = phi[2];
    double t2 = x * x + y * y + z * z, a, b;
    if (t2 < 1e-8) {
        a = 1.0 - t2 / 6.0;
        b = 0.5 - t2 / 24.0;
    } else {
        double t = sqrt(t2);
        a = sin(t) / t;
        b = (1.0 - cos(t)) / t2;
    }
    R[0] = 1.0 - b * (y * y + z * z); R[1] = b * x * y - a * z;         R[2] = b * x * z + a * y;
    R[3] = b * x * y + a * z;         R[4] = 1.0 - b * (x * x + z * z); R[5] = b * y * z - a * x;
    R[6] = b * x * z - a * y;         R[7] = b * y * z + a * x;         R[8] = 1.0 - b * (x * x + y * y);
}

static void matmul3(const double A[9], const double B[9], double C[9]) {
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

static void put_block(double dF[9 * N], int row, int col, const double M[9], double scale) {
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            dF[(row + i) * N + col + j] = scale * M[3 * i + j];
}

static PyObject *propagate(PyObject *self, PyObject *args) {
    Py_buffer xb, Pb, ab, wb;
    double dt, g[3], qa, qg, qba, qbg;
    if (!PyArg_ParseTuple(args, "w*w*y*y*dddddddd", &xb, &Pb, &ab, &wb, &dt, &g[0], &g[1], &g[2],
                          &qa, &qg, &qba, &qbg))
        return NULL;
    PyObject *result = NULL;
    if (xb.len != 21 * (Py_ssize_t)sizeof(double) || Pb.len != N * N * (Py_ssize_t)sizeof(double) ||
        ab.len != 3 * (Py_ssize_t)sizeof(double) || wb.len != 3 * (Py_ssize_t)sizeof(double)) {
        PyErr_SetString(PyExc_ValueError, "propagate: x needs 21, P 225, accel and gyro 3 float64 values");
        goto done;
    }
    double *x = (double *)xb.buf, *P = (double *)Pb.buf;
    const double *am = (const double *)ab.buf, *wm = (const double *)wb.buf;
    for (int i = 0; i < 3; i++) {
        if (!isfinite(am[i]) || !isfinite(wm[i])) {
            result = Py_False;
            Py_INCREF(result);
            goto done;
        }
    }
    double *p = x, *v = x + 3, *R = x + 6, *ba = x + 15, *bg = x + 18;
    double a[3], w[3], wdt[3], Ra[3], world_a[3];
    for (int i = 0; i < 3; i++) {
        a[i] = am[i] - ba[i];
        w[i] = wm[i] - bg[i];
        wdt[i] = w[i] * dt;
    }
    for (int i = 0; i < 3; i++) {
        Ra[i] = R[3 * i] * a[0] + R[3 * i + 1] * a[1] + R[3 * i + 2] * a[2];
        world_a[i] = Ra[i] + g[i];
    }
    double dR[9], Rn[9], Jr[9], RJr[9], hRa[9], hw[9];
    exp_so3(wdt, dR);
    matmul3(R, dR, Rn);
    hat(wdt, hw);
    for (int i = 0; i < 9; i++) Jr[i] = -0.5 * hw[i];
    Jr[0] += 1.0; Jr[4] += 1.0; Jr[8] += 1.0;
    matmul3(Rn, Jr, RJr);
    hat(Ra, hRa);
    double h2 = 0.5 * dt * dt;
    double dF[9 * N];
    memset(dF, 0, sizeof dF);
    double I3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    put_block(dF, 0, 3, I3, dt);
    put_block(dF, 0, 6, hRa, -h2);
    put_block(dF, 0, 9, R, -h2);
    put_block(dF, 3, 6, hRa, -dt);
    put_block(dF, 3, 9, R, -dt);
    put_block(dF, 6, 12, RJr, -dt);
    /* A = P, A[0:9] += dF P */
    double A[N * N];
    memcpy(A, P, sizeof A);
    for (int i = 0; i < 9; i++)
        for (int j = 0; j < N; j++) {
            double s = 0.0;
            for (int k = 0; k < N; k++) s += dF[i * N + k] * P[k * N + j];
            A[i * N + j] += s;
        }
    /* P = A, P[:, 0:9] += A dF^T */
    memcpy(P, A, sizeof A);
    for (int i = 0; i < N; i++)
        for (int j = 0; j < 9; j++) {
            double s = 0.0;
            for (int k = 0; k < N; k++) s += A[i * N + k] * dF[j * N + k];
            P[i * N + j] += s;
        }
    double c_pp = qa / dt * h2 * h2, c_pv = qa / dt * h2 * dt, c_vv = qa * dt;
    double c_th = qg * dt, c_ba = qba * dt, c_bg = qbg * dt;
    for (int i = 0; i < 3; i++) {
        P[i * N + i] += c_pp;
        P[i * N + 3 + i] += c_pv;
        P[(3 + i) * N + i] += c_pv;
        P[(3 + i) * N + 3 + i] += c_vv;
        P[(6 + i) * N + 6 + i] += c_th;
        P[(9 + i) * N + 9 + i] += c_ba;
        P[(12 + i) * N + 12 + i] += c_bg;
    }
    for (int i = 0; i < 3; i++) {
        p[i] = p[i] + v[i] * dt + h2 * world_a[i];
        v[i] = v[i] + world_a[i] * dt;
    }
    memcpy(R, Rn, sizeof Rn);
    result = Py_True;
    Py_INCREF(result);
done:
    PyBuffer_Release(&xb);
    PyBuffer_Release(&Pb);
    PyBuffer_Release(&ab);
    PyBuffer_Release(&wb);
    return result;
}

static PyMethodDef methods[] = {
    {"propagate", propagate, METH_VARARGS, "One fused ES-EKF IMU step (see the file header)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_eskfkernel", NULL, -1, methods};

PyMODINIT_FUNC PyInit__eskfkernel(void) { return PyModule_Create(&module); }
