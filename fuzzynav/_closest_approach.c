/*
 * fuzzynav._closest_approach: fuzzynav.geometry.closest_approach's numpy form in one loop.
 *
 * For each pair (rel0, step) of 2-vectors: s = clip(-(rel0 . step) / (|step|^2 or 1 when 0), 0, 1) and
 * |rel0 + s step|, each operation the numpy form's, in its order (IEEE basic operations and sqrt, each correctly
 * rounded), so the distances are its bits (tests/test_geometry.py compares them). The clip's sign of a zero s may
 * differ from numpy's; it cannot reach the result (rel0 + (+-0) step squares to the same). A NaN result is NaN in
 * both, its sign bit not always the same (nothing observes it: comparisons are false, the logs write null). No
 * floating-point warnings (numpy's errstate does not apply). Built with -ffp-contract=off (no fused multiply-adds); refuses -ffast-math and x87 arithmetic. Lengths in cm.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fuzzynav._closest_approach must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav._closest_approach needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* a C-contiguous float64 buffer, its item count in *n */
static int get(PyObject *obj, Py_buffer *view, int writable, Py_ssize_t *n, const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    if (view->itemsize != 8 || view->format == NULL || strcmp(view->format, "d") != 0) {
        PyErr_Format(PyExc_ValueError, "closest_approach: %s must be a C-contiguous float64 array", what);
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
        if (get(objs[got], &v[got], got == 2, &len[got], what[got]) < 0) goto done;
    Py_ssize_t n = len[2];
    if (len[0] != 2 * n || len[1] != 2 * n) {
        PyErr_SetString(PyExc_ValueError, "closest_approach: rel0 and step must hold two numbers per item of out");
        goto done;
    }
    const double *r = v[0].buf, *d = v[1].buf;
    double *out = v[2].buf;
    for (Py_ssize_t i = 0; i < n; i++) {
        double rx = r[2 * i], ry = r[2 * i + 1], dx = d[2 * i], dy = d[2 * i + 1];
        double dd = dx * dx + dy * dy;                        /* dot2(step, step) */
        double q = -(rx * dx + ry * dy) / (dd > 0 ? dd : 1.0); /* -dot2(rel0, step) / where(dd > 0, dd, 1) */
        double s = q;                                         /* np.clip(q, 0, 1): NaN stays NaN */
        if (s < 0.0) s = 0.0;
        if (s > 1.0) s = 1.0;
        double px = rx + s * dx, py = ry + s * dy;            /* rel0 + s[..., None] * step */
        out[i] = sqrt(px * px + py * py);                     /* norm2 */
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"closest_approach", closest_approach, METH_VARARGS,
     "closest_approach(rel0, step, out): the smallest |rel0 + s step| over s in [0, 1] per pair, into out"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav._closest_approach",
    "fuzzynav.geometry.closest_approach in C (bit-identical to its numpy form).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__closest_approach(void) { return PyModule_Create(&module); }
