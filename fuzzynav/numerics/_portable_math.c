/*
 * fuzzynav.numerics._portable_math: fuzzynav.numerics.portable_math's sin_cos_deg, atan2_deg, sin_cos_deg_array and atan2_deg_array
 * in C.
 *
 * Each performs its Python/numpy form's operations one by one in the same order (IEEE basic operations and sqrt,
 * each correctly rounded; nearbyint and fmod, which are exact), so the results are the same bits
 * (tests/test_portable_math.py compares them). The series coefficients and constants are given once by
 * portable_math (configure): one definition, there. The scalar functions are what a simulation step calls a few
 * times to a few dozen times (headings, arrows, wedges): a Python call of the series costs ~2-3 us, this ~0.1 us.
 * The array forms replace ~20 numpy calls each (a random-walk crowd's headings, the TPT's obstacle angles, DWA's
 * and VFH's directions).
 * No floating-point warnings (numpy's errstate does not apply). Built with -ffp-contract=off (no fused
 * multiply-adds); refuses -ffast-math and x87 arithmetic.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fuzzynav.numerics._portable_math must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.numerics._portable_math needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#define MAX_TERMS 32
static double sin_c[MAX_TERMS], cos_c[MAX_TERMS], atan_c[MAX_TERMS];
static Py_ssize_t n_sin = 0, n_cos = 0, n_atan = 0;
static double rad_per_deg, deg_per_rad, tan_pi_8;

/* portable_math._horner: c0 + z (c1 + z (c2 + ...)), from the last coefficient inwards */
static double horner(double z, const double *c, Py_ssize_t n) {
    double acc = c[n - 1];
    for (Py_ssize_t i = n - 2; i >= 0; i--) acc = acc * z + c[i];
    return acc;
}

/* sin_cos_deg / sin_cos_deg_array for one finite angle: the nearest quadrant, the reduced angle's series, the
 * quadrant's signs (0 - x: negation without producing -0.0) */
static void sin_cos_finite(double a, double *sin_a, double *cos_a) {
    double q = nearbyint(a / 90.0);
    double r = (a - 90.0 * q) * rad_per_deg;
    double z = r * r;
    double s = r + r * z * horner(z, sin_c, n_sin);
    double c = 1.0 + z * horner(z, cos_c, n_cos);
    double ns = 0.0 - s, nc = 0.0 - c;
    double k = fmod(q, 4.0); /* Python's q % 4 and np.remainder: the sign of the divisor */
    if (k < 0.0) k += 4.0;
    if (k == 0.0) {
        *sin_a = s;
        *cos_a = c;
    } else if (k == 1.0) {
        *sin_a = c;
        *cos_a = ns;
    } else if (k == 2.0) {
        *sin_a = ns;
        *cos_a = nc;
    } else {
        *sin_a = nc;
        *cos_a = s;
    }
}

/* portable_math._atan_reduced_deg: atan(u) in degrees for |u| <= tan(pi/8), one half-angle step and the series */
static double atan_reduced_deg(double u) {
    double w = u / (1.0 + sqrt(1.0 + u * u));
    double z = w * w;
    return (2.0 * (w + w * z * horner(z, atan_c, n_atan))) * deg_per_rad;
}

static int configured(void) {
    if (n_sin && n_cos && n_atan) return 1;
    PyErr_SetString(PyExc_RuntimeError, "fuzzynav.numerics._portable_math: configure() was not called");
    return 0;
}

static int copy_series(PyObject *seq, double *dst, Py_ssize_t *n, const char *what) {
    /* a tuple copy: an item's __float__ may change the sequence given, not the copy that owns the items */
    PyObject *fast = PySequence_Tuple(seq);
    if (fast == NULL) return -1;
    Py_ssize_t len = PyTuple_GET_SIZE(fast);
    if (len < 1 || len > MAX_TERMS) {
        Py_DECREF(fast);
        PyErr_Format(PyExc_ValueError, "configure: %s must have 1 to %d terms", what, MAX_TERMS);
        return -1;
    }
    for (Py_ssize_t i = 0; i < len; i++) {
        double v = PyFloat_AsDouble(PyTuple_GET_ITEM(fast, i));
        if (v == -1.0 && PyErr_Occurred()) {
            Py_DECREF(fast);
            return -1;
        }
        dst[i] = v;
    }
    Py_DECREF(fast);
    *n = len;
    return 0;
}

/* configure(sin_series, cos_series, atan_series, rad_per_deg, deg_per_rad, tan_pi_8) */
static PyObject *configure(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *s, *c, *a;
    double r, d, t;
    if (!PyArg_ParseTuple(args, "OOOddd:configure", &s, &c, &a, &r, &d, &t)) return NULL;
    double s_buf[MAX_TERMS], c_buf[MAX_TERMS], a_buf[MAX_TERMS];
    Py_ssize_t ns, nc, na;
    if (copy_series(s, s_buf, &ns, "sin_series") < 0 || copy_series(c, c_buf, &nc, "cos_series") < 0 ||
        copy_series(a, a_buf, &na, "atan_series") < 0)
        return NULL;
    memcpy(sin_c, s_buf, sizeof s_buf);
    memcpy(cos_c, c_buf, sizeof c_buf);
    memcpy(atan_c, a_buf, sizeof a_buf);
    n_sin = ns;
    n_cos = nc;
    n_atan = na;
    rad_per_deg = r;
    deg_per_rad = d;
    tan_pi_8 = t;
    Py_RETURN_NONE;
}

/* sin_cos_deg(angle_deg: float) -> (sin, cos); (nan, nan) for a non-finite angle */
static PyObject *sin_cos_deg(PyObject *self, PyObject *arg) {
    (void)self;
    if (!configured()) return NULL;
    double a = PyFloat_AsDouble(arg);
    if (a == -1.0 && PyErr_Occurred()) return NULL;
    double s = NAN, c = NAN;
    if (isfinite(a)) sin_cos_finite(a, &s, &c);
    return Py_BuildValue("(dd)", s, c);
}

/* atan2_deg(y: float, x: float) -> angle of (x, y) in degrees, in [-180, 180]; 0 for the zero vector, NaN when
 * either is NaN */
static PyObject *atan2_deg(PyObject *self, PyObject *const *args, Py_ssize_t nargs) {
    (void)self;
    if (!configured()) return NULL;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "atan2_deg(y, x) takes two floats");
        return NULL;
    }
    double y = PyFloat_AsDouble(args[0]);
    if (y == -1.0 && PyErr_Occurred()) return NULL;
    double x = PyFloat_AsDouble(args[1]);
    if (x == -1.0 && PyErr_Occurred()) return NULL;
    if (isnan(x) || isnan(y)) return PyFloat_FromDouble(NAN);
    double ax = fabs(x), ay = fabs(y);
    if (ax == 0.0 && ay == 0.0) return PyFloat_FromDouble(0.0);
    double t = ax >= ay ? ay / ax : ax / ay;
    double a = t > tan_pi_8 ? 45.0 + atan_reduced_deg((t - 1.0) / (t + 1.0)) : atan_reduced_deg(t);
    if (ay > ax) a = 90.0 - a;
    if (x < 0.0) a = 180.0 - a;
    return PyFloat_FromDouble(y < 0.0 ? -a : a);
}

/* a C-contiguous float64 buffer, its item count in *n */
static int get(PyObject *obj, Py_buffer *view, int writable, Py_ssize_t *n, const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    if (view->itemsize != 8 || view->format == NULL || strcmp(view->format, "d") != 0) {
        PyErr_Format(PyExc_ValueError, "%s must be a C-contiguous float64 array", what);
        PyBuffer_Release(view);
        return -1;
    }
    *n = view->len / 8;
    return 0;
}

/* sin_cos_deg_array(angles (n,), out_sin (n,), out_cos (n,)): sin_cos_deg of each angle, into the outputs */
static PyObject *sin_cos_deg_array(PyObject *self, PyObject *args) {
    (void)self;
    if (!configured()) return NULL;
    PyObject *objs[3];
    if (!PyArg_UnpackTuple(args, "sin_cos_deg_array", 3, 3, &objs[0], &objs[1], &objs[2])) return NULL;
    static const char *what[3] = {"sin_cos_deg_array: angles", "sin_cos_deg_array: out_sin",
                                  "sin_cos_deg_array: out_cos"};
    Py_buffer v[3];
    Py_ssize_t len[3];
    int got = 0;
    PyObject *result = NULL;
    for (; got < 3; got++)
        if (get(objs[got], &v[got], got > 0, &len[got], what[got]) < 0) goto done;
    if (len[1] != len[0] || len[2] != len[0]) {
        PyErr_SetString(PyExc_ValueError, "sin_cos_deg_array: the outputs must have the angles' length");
        goto done;
    }
    const double *a = v[0].buf;
    double *out_s = v[1].buf, *out_c = v[2].buf;
    for (Py_ssize_t i = 0; i < len[0]; i++) {
        double s = NAN, c = NAN;
        if (isfinite(a[i])) sin_cos_finite(a[i], &s, &c);
        out_s[i] = s;
        out_c[i] = c;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

/* atan2_deg_array's numpy form for one element, operation for operation: its np.where selections become branches
 * and its divisor is 1 for the zero vector (whose answer is 0). A NaN input gives a NaN, as there. */
static double atan2_deg_element(double y, double x) {
    double ax = fabs(x), ay = fabs(y);
    int zero = ax == 0.0 && ay == 0.0;
    int ge = ax >= ay;
    double t = (ge ? ay : ax) / (zero ? 1.0 : (ge ? ax : ay));
    double a = t > tan_pi_8 ? 45.0 + atan_reduced_deg((t - 1.0) / (t + 1.0)) : atan_reduced_deg(t);
    if (ay > ax) a = 90.0 - a;
    if (x < 0.0) a = 180.0 - a;
    if (y < 0.0) a = -a;
    return zero ? 0.0 : a;
}

/* atan2_deg_array(y (n,), x (n,), out (n,)): atan2_deg_array of each pair, into out */
static PyObject *atan2_deg_array(PyObject *self, PyObject *args) {
    (void)self;
    if (!configured()) return NULL;
    PyObject *objs[3];
    if (!PyArg_UnpackTuple(args, "atan2_deg_array", 3, 3, &objs[0], &objs[1], &objs[2])) return NULL;
    static const char *what[3] = {"atan2_deg_array: y", "atan2_deg_array: x", "atan2_deg_array: out"};
    Py_buffer v[3];
    Py_ssize_t len[3];
    int got = 0;
    PyObject *result = NULL;
    for (; got < 3; got++)
        if (get(objs[got], &v[got], got == 2, &len[got], what[got]) < 0) goto done;
    if (len[1] != len[0] || len[2] != len[0]) {
        PyErr_SetString(PyExc_ValueError, "atan2_deg_array: y, x and out must have one length");
        goto done;
    }
    const double *y = v[0].buf, *x = v[1].buf;
    double *out = v[2].buf;
    for (Py_ssize_t i = 0; i < len[0]; i++) out[i] = atan2_deg_element(y[i], x[i]);
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"configure", configure, METH_VARARGS,
     "configure(sin_series, cos_series, atan_series, rad_per_deg, deg_per_rad, tan_pi_8): portable_math's constants"},
    {"sin_cos_deg", sin_cos_deg, METH_O, "sin_cos_deg(angle_deg) -> (sin, cos)"},
    {"atan2_deg", (PyCFunction)(void (*)(void))atan2_deg, METH_FASTCALL, "atan2_deg(y, x) -> degrees"},
    {"sin_cos_deg_array", sin_cos_deg_array, METH_VARARGS,
     "sin_cos_deg_array(angles, out_sin, out_cos): sin_cos_deg of each angle, into the outputs"},
    {"atan2_deg_array", atan2_deg_array, METH_VARARGS,
     "atan2_deg_array(y, x, out): atan2_deg_array of each pair, into out"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.numerics._portable_math",
    "fuzzynav.numerics.portable_math's sin_cos_deg, atan2_deg, sin_cos_deg_array and atan2_deg_array in C (the same bits).",
    -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__portable_math(void) { return PyModule_Create(&module); }
