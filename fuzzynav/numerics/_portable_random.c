/*
 * fuzzynav.numerics._portable_random: fuzzynav.numerics.portable_random.standard_normal's Box-Muller transform in C.
 *
 * radius = sqrt(-2 log(1 - u0)) and (sin, cos) of 360 u1 degrees, with fuzzynav.numerics.portable_math's log_array and
 * sin_cos_deg_array performed operation by operation in numpy's order (basic IEEE operations, each correctly
 * rounded; frexp, rint and fmod, which are exact), so the normals are the numpy form's bits
 * (tests/test_portable_random_kernel.py). The series coefficients and constants come from Python at each call: one
 * definition, in portable_math. Built with -ffp-contract=off (no fused multiply-adds); refuses -ffast-math and x87
 * arithmetic.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fuzzynav.numerics._portable_random must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.numerics._portable_random needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* a C-contiguous float64 buffer, its item count in *n */
static int get(PyObject *obj, Py_buffer *view, int writable, Py_ssize_t *n, const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    if (view->itemsize != 8 || view->format == NULL || strcmp(view->format, "d") != 0) {
        PyErr_Format(PyExc_ValueError, "normal_pairs: %s must be a C-contiguous float64 array", what);
        PyBuffer_Release(view);
        return -1;
    }
    *n = view->len / 8;
    return 0;
}

/* portable_math._horner: c0 + z (c1 + z (c2 + ...)), from the last coefficient inwards */
static double horner(double z, const double *c, Py_ssize_t n) {
    double acc = c[n - 1];
    for (Py_ssize_t i = n - 2; i >= 0; i--) acc = acc * z + c[i];
    return acc;
}

/* normal_pairs(u0 (P,), u1 (P,), sin_series, cos_series, atanh_series, constants (4,): rad_per_deg, ln2_hi,
 *              ln2_lo, sqrt_half, out (2P,))
 * out[:P] = radius * cos, out[P:] = radius * sin, as standard_normal's numpy form before its [:size] */
static PyObject *normal_pairs(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objs[7];
    if (!PyArg_UnpackTuple(args, "normal_pairs", 7, 7, &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5],
                           &objs[6]))
        return NULL;
    static const char *what[7] = {"u0", "u1", "sin_series", "cos_series", "atanh_series", "constants", "out"};
    Py_buffer v[7];
    Py_ssize_t len[7];
    int got = 0;
    PyObject *result = NULL;
    for (; got < 7; got++)
        if (get(objs[got], &v[got], got == 6, &len[got], what[got]) < 0) goto done;
    Py_ssize_t p = len[0];
    if (len[1] != p || len[6] != 2 * p || len[2] < 1 || len[3] < 1 || len[4] < 1 || len[5] != 4) {
        PyErr_SetString(PyExc_ValueError, "normal_pairs: u0, u1 of one length, out twice it, series not empty, "
                                          "four constants");
        goto done;
    }
    const double *u0 = v[0].buf, *u1 = v[1].buf, *sin_c = v[2].buf, *cos_c = v[3].buf, *atanh_c = v[4].buf;
    const double *k = v[5].buf;
    const double rad_per_deg = k[0], ln2_hi = k[1], ln2_lo = k[2], sqrt_half = k[3];
    double *out = v[6].buf;
    for (Py_ssize_t i = 0; i < p; i++) {
        /* log_array(1 - u0): frexp, the mantissa into [sqrt(1/2), sqrt(2)), then 2 atanh(s) */
        double x = 1.0 - u0[i];
        int e_int;
        double m = frexp(x, &e_int);
        double e;
        if (m < sqrt_half) {
            m = m * 2.0;
            e = (double)(e_int - 1);
        } else {
            e = (double)e_int;
        }
        double s = (m - 1.0) / (m + 1.0);
        double z = s * s;
        double two_s = 2.0 * s;
        double log_x = e * ln2_hi + ((two_s + two_s * z * horner(z, atanh_c, len[4])) + e * ln2_lo);
        if (!(x > 0.0)) log_x = x == 0.0 ? -INFINITY : NAN;
        double radius = sqrt(-2.0 * log_x);
        /* sin_cos_deg_array(360 u1): the nearest quadrant, the reduced angle's series, the quadrant's signs */
        double a = 360.0 * u1[i];
        int finite = isfinite(a);
        if (!finite) a = 0.0;
        double q = nearbyint(a / 90.0);
        double r = (a - 90.0 * q) * rad_per_deg;
        double rz = r * r;
        double sn = r + r * rz * horner(rz, sin_c, len[2]);
        double cs = 1.0 + rz * horner(rz, cos_c, len[3]);
        double nsn = 0.0 - sn, ncs = 0.0 - cs;
        double quadrant = fmod(q, 4.0);  /* np.remainder: the sign of the divisor */
        if (quadrant != 0.0 && quadrant < 0.0) quadrant += 4.0;
        double sin_a, cos_a;
        if (quadrant == 0.0) {
            sin_a = sn;
            cos_a = cs;
        } else if (quadrant == 1.0) {
            sin_a = cs;
            cos_a = nsn;
        } else if (quadrant == 2.0) {
            sin_a = nsn;
            cos_a = ncs;
        } else {
            sin_a = ncs;
            cos_a = sn;
        }
        if (!finite) sin_a = cos_a = NAN;
        out[i] = radius * cos_a;
        out[p + i] = radius * sin_a;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"normal_pairs", normal_pairs, METH_VARARGS,
     "normal_pairs(u0, u1, sin_series, cos_series, atanh_series, constants, out): Box-Muller normals, into out"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.numerics._portable_random",
    "fuzzynav.numerics.portable_random's Box-Muller transform in C (bit-identical to its numpy form).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__portable_random(void) { return PyModule_Create(&module); }
