/*
 * fuzzynav._raycast: the nearest hit of each laser beam in C (fuzzynav.raycast.cast_rays's inner part).
 *
 * The numpy path computes, for every ray and every segment or circle kept after culling, the same elementwise
 * IEEE operations as below (subtractions, products, one division, one square root, each correctly rounded on
 * every CPU), then keeps per ray the first minimum, strictly nearer than the range so far (segments first,
 * then circles). This file performs those operations in the same order without the (rays x objects) arrays,
 * so its ranges and hit indices are the numpy path's bits (tests/test_raycast_kernel.py). Built with
 * -ffp-contract=off (no fused multiply-adds); refuses -ffast-math and x87 arithmetic. Lengths in cm.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fuzzynav._raycast must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav._raycast needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* a C-contiguous buffer of `itemsize`-byte items whose format is one of `formats` and whose length is a
 * multiple of `width` items; its row count in *rows */
static int get(PyObject *obj, Py_buffer *view, int writable, const char *formats, Py_ssize_t width,
               Py_ssize_t *rows, const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    const char *fmt = view->format ? view->format : "B";
    if (view->itemsize != 8 || strlen(fmt) != 1 || strchr(formats, fmt[0]) == NULL ||
        view->len % (8 * width) != 0) {
        PyErr_Format(PyExc_ValueError, "nearest: %s must be a C-contiguous %s array with rows of %zd", what,
                     formats[0] == 'd' ? "float64" : "int64", width);
        PyBuffer_Release(view);
        return -1;
    }
    *rows = view->len / (8 * width);
    return 0;
}

/* nearest(ox, oy, directions (N, 2), segments (M, 4), segment_ids (M,), circles (C, 3), circle_ids (C,),
 *         best (N,) in/out, hit (N,) in/out)
 * best and hit hold the range cap and -1 on entry (or an earlier result); each ray's first nearest segment,
 * then circle, strictly nearer than best replaces them. */
static PyObject *nearest(PyObject *self, PyObject *args) {
    (void)self;
    double ox, oy;
    PyObject *objs[7];
    if (!PyArg_ParseTuple(args, "ddOOOOOOO", &ox, &oy, &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5],
                          &objs[6]))
        return NULL;
    static const char *what[7] = {"directions", "segments", "segment_ids", "circles", "circle_ids", "best", "hit"};
    static const char *formats[7] = {"d", "d", "lq", "d", "lq", "d", "lq"};
    static const Py_ssize_t widths[7] = {2, 4, 1, 3, 1, 1, 1};
    Py_buffer v[7];
    Py_ssize_t rows[7];
    int got = 0;
    PyObject *result = NULL;
    double *seg_pre = NULL;
    for (; got < 7; got++)
        if (get(objs[got], &v[got], got >= 5, formats[got], widths[got], &rows[got], what[got]) < 0) goto done;
    Py_ssize_t n = rows[0], m = rows[1], c = rows[3];
    if (rows[2] != m || rows[4] != c || rows[5] != n || rows[6] != n) {
        PyErr_SetString(PyExc_ValueError, "nearest: ids must match their objects and best/hit the directions");
        goto done;
    }
    const double *d = v[0].buf, *seg = v[1].buf, *circ = v[3].buf;
    const int64_t *seg_ids = v[2].buf, *circ_ids = v[4].buf;
    double *best = v[5].buf;
    int64_t *hit = v[6].buf;
    /* per segment: ax, ay, ex, ey and ax * ey - ay * ex (the numpy path's (M,) arrays); per circle: cx, cy,
     * c = cx * cx + cy * cy - r * r */
    seg_pre = PyMem_Malloc((size_t)(5 * m + 3 * c + 1) * sizeof(double));
    if (seg_pre == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    double *circ_pre = seg_pre + 5 * m;
    for (Py_ssize_t k = 0; k < m; k++) {
        const double *s = seg + 4 * k;
        double ax = s[0] - ox, ay = s[1] - oy, ex = s[2] - s[0], ey = s[3] - s[1];
        double *p = seg_pre + 5 * k;
        p[0] = ax;
        p[1] = ay;
        p[2] = ex;
        p[3] = ey;
        p[4] = ax * ey - ay * ex;
    }
    for (Py_ssize_t k = 0; k < c; k++) {
        const double *q = circ + 3 * k;
        double cx = q[0] - ox, cy = q[1] - oy, r2 = q[2] * q[2];
        double *p = circ_pre + 3 * k;
        p[0] = cx;
        p[1] = cy;
        p[2] = cx * cx + cy * cy - r2;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        double dx = d[2 * i], dy = d[2 * i + 1], b_i = best[i];
        int64_t h_i = hit[i];
        for (Py_ssize_t k = 0; k < m; k++) {
            const double *p = seg_pre + 5 * k;
            double denom = dx * p[3] - dy * p[2];
            double t = p[4] / denom;
            double u = (p[0] * dy - p[1] * dx) / denom;
            if (fabs(denom) <= 1e-12 || !(t >= 0.0) || !(u >= 0.0) || !(u <= 1.0)) continue;  /* a miss: inf */
            if (t < b_i) {
                b_i = t;
                h_i = seg_ids[k];
            }
        }
        for (Py_ssize_t k = 0; k < c; k++) {
            const double *p = circ_pre + 3 * k;
            double t;
            if (p[2] <= 0.0) {
                t = 0.0;  /* the origin is inside: range 0 for every ray */
            } else {
                double b = dx * p[0] + dy * p[1];
                double disc = b * b - p[2];
                if (!(disc >= 0.0)) continue;
                t = b - sqrt(disc);
                if (!(t >= 0.0)) continue;
            }
            if (t < b_i) {
                b_i = t;
                h_i = circ_ids[k];
            }
        }
        best[i] = b_i;
        hit[i] = h_i;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    PyMem_Free(seg_pre);
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"nearest", nearest, METH_VARARGS,
     "nearest(ox, oy, directions, segments, segment_ids, circles, circle_ids, best, hit): each ray's first "
     "nearest hit, in place"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav._raycast",
    "Each laser beam's nearest hit in C (bit-identical to fuzzynav.raycast's numpy path).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__raycast(void) { return PyModule_Create(&module); }
