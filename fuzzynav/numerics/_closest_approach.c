/*
 * fuzzynav.numerics._closest_approach: fuzzynav.numerics.geometry.closest_approach's numpy form in one loop.
 *
 * For each pair (rel0, step) of 2-vectors: s = clip(-(rel0 . step) / (|step|^2 or 1 when 0), 0, 1) and
 * |rel0 + s step|, each operation the numpy form's, in its order (IEEE basic operations and sqrt, each correctly
 * rounded), so the distances are its bits (tests/test_geometry.py compares them). The clip's sign of a zero s may
 * differ from numpy's; it cannot reach the result (rel0 + (+-0) step squares to the same). A NaN result is NaN in
 * both, its sign bit not always the same (nothing observes it: comparisons are false, the logs write null). No
 * floating-point warnings (numpy's errstate does not apply). Built with -ffp-contract=off (no fused multiply-adds);
 * refuses -ffast-math and x87 arithmetic. Lengths in cm. The pair's formula is _closest_approach.h's.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#include "_closest_approach.h"

#if defined(__FAST_MATH__)
#error "fuzzynav.numerics._closest_approach must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.numerics._closest_approach needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* a C-contiguous float64 buffer, its item count in *n (fn names the function in the error) */
static int get(PyObject *obj, Py_buffer *view, int writable, Py_ssize_t *n, const char *fn, const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    if (view->itemsize != 8 || view->format == NULL || strcmp(view->format, "d") != 0) {
        PyErr_Format(PyExc_ValueError, "%s: %s must be a C-contiguous float64 array", fn, what);
        PyBuffer_Release(view);
        return -1;
    }
    *n = view->len / 8;
    return 0;
}

/* closest_approach(rel0 (n, 2), step (n, 2), out (n,)): the smallest |rel0 + s step| over s in [0, 1], into out */
static PyObject *closest_approach(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objs[3];
    if (!PyArg_UnpackTuple(args, "closest_approach", 3, 3, &objs[0], &objs[1], &objs[2])) return NULL;
    static const char *what[3] = {"rel0", "step", "out"};
    Py_buffer v[3];
    Py_ssize_t len[3];
    int got = 0;
    PyObject *result = NULL;
    for (; got < 3; got++)
        if (get(objs[got], &v[got], got == 2, &len[got], "closest_approach", what[got]) < 0) goto done;
    Py_ssize_t n = len[2];
    if (len[0] != 2 * n || len[1] != 2 * n) {
        PyErr_SetString(PyExc_ValueError, "closest_approach: rel0 and step must hold two numbers per item of out");
        goto done;
    }
    const double *r = v[0].buf, *d = v[1].buf;
    double *out = v[2].buf;
    for (Py_ssize_t i = 0; i < n; i++)
        out[i] = closest_approach_length(r[2 * i], r[2 * i + 1], d[2 * i], d[2 * i + 1]);
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

/* segment_point_clearance(start (2,), ends (S, 2), points (P, 2), out (S,)): for each move start -> ends[i], the
 * smallest closest_approach(start - points[p], ends[i] - start) over the points (clearance.py's numpy form:
 * segment_point_distance(...).min(axis=1), without its (S, P, 2) arrays); NaN when one of them is NaN, as numpy's
 * min. P must be at least 1. */
static PyObject *segment_point_clearance(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objs[4];
    if (!PyArg_UnpackTuple(args, "segment_point_clearance", 4, 4, &objs[0], &objs[1], &objs[2], &objs[3]))
        return NULL;
    static const char *what[4] = {"start", "ends", "points", "out"};
    Py_buffer v[4];
    Py_ssize_t len[4];
    int got = 0;
    PyObject *result = NULL;
    for (; got < 4; got++)
        if (get(objs[got], &v[got], got == 3, &len[got], "segment_point_clearance", what[got]) < 0) goto done;
    Py_ssize_t n_moves = len[3], n_points = len[2] / 2;
    if (len[0] != 2 || len[1] != 2 * n_moves || len[2] != 2 * n_points || n_points < 1) {
        PyErr_SetString(PyExc_ValueError, "segment_point_clearance: start (2,), ends (S, 2), points (P >= 1, 2), "
                                          "out (S,)");
        goto done;
    }
    const double *a = v[0].buf, *e = v[1].buf, *q = v[2].buf;
    double *out = v[3].buf;
    for (Py_ssize_t i = 0; i < n_moves; i++) {
        double dx = e[2 * i] - a[0], dy = e[2 * i + 1] - a[1]; /* b - a */
        double dd = dx * dx + dy * dy;
        double den = dd > 0 ? dd : 1.0;
        double best = INFINITY;
        int nan = 0;
        for (Py_ssize_t k = 0; k < n_points; k++) {
            double rx = a[0] - q[2 * k], ry = a[1] - q[2 * k + 1]; /* a - points */
            double s = -(rx * dx + ry * dy) / den;
            if (s < 0.0) s = 0.0;
            if (s > 1.0) s = 1.0;
            double px = rx + s * dx, py = ry + s * dy;
            double d = sqrt(px * px + py * py);
            if (d != d) nan = 1;
            else if (d < best) best = d;
        }
        out[i] = nan ? NAN : best;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"segment_point_clearance", segment_point_clearance, METH_VARARGS,
     "segment_point_clearance(start, ends, points, out): each move's smallest distance to the points, into out"},
    {"closest_approach", closest_approach, METH_VARARGS,
     "closest_approach(rel0, step, out): the smallest |rel0 + s step| over s in [0, 1] per pair, into out"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.numerics._closest_approach",
    "fuzzynav.numerics.geometry.closest_approach in C (bit-identical to its numpy form).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__closest_approach(void) { return PyModule_Create(&module); }
