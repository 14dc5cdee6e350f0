/*
 * fuzzynav._json_checks: the analysis's acceptance tests of decoded JSON arrays in one pass each
 * (analysis.json_checks' batch forms).
 *
 * Each function answers whether every item of a list (or tuple) is acceptable: a JSON number (an exact int or
 * float, never a bool) within [lo, hi], an [x, y] pair of such numbers, or a boolean. The Python forms build
 * sets of types, chained lists, a min and a max: five passes and their temporary lists over an episode's
 * thousands of TPT coordinates. The answers are the Python forms' (a property test compares them on mutated
 * values); a NaN is refused here, as the item-by-item rule refuses it (decoded JSON has none). Ints are compared
 * with the bounds as Python compares them (exactly), floats as doubles.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

/* 1: `item` is a number within [lo, hi]; 0: it is not; -1: an exception is set */
static int number_within(PyObject *item, double lo, double hi, PyObject *lo_obj, PyObject *hi_obj) {
    if (PyFloat_CheckExact(item)) {
        double v = PyFloat_AS_DOUBLE(item);
        return lo <= v && v <= hi;
    }
    if (PyLong_CheckExact(item)) {
        int ok = PyObject_RichCompareBool(item, lo_obj, Py_GE);
        if (ok != 1) return ok;
        return PyObject_RichCompareBool(item, hi_obj, Py_LE);
    }
    return 0;
}

/* the items of an exact list or tuple and their count in *n; 0 for anything else (an empty list's item array
 * may be NULL: the count, not the pointer, says it is empty) */
static int items_of(PyObject *seq, PyObject ***items, Py_ssize_t *n) {
    if (PyList_CheckExact(seq)) {
        *n = PyList_GET_SIZE(seq);
        *items = ((PyListObject *)seq)->ob_item;
        return 1;
    }
    if (PyTuple_CheckExact(seq)) {
        *n = PyTuple_GET_SIZE(seq);
        *items = ((PyTupleObject *)seq)->ob_item;
        return 1;
    }
    return 0;
}

static int parse(PyObject *args, const char *name, PyObject **seq, PyObject **lo_obj, PyObject **hi_obj, double *lo,
                 double *hi) {
    if (!PyArg_UnpackTuple(args, name, 3, 3, seq, lo_obj, hi_obj)) return -1;
    if (!PyFloat_CheckExact(*lo_obj) || !PyFloat_CheckExact(*hi_obj)) {
        PyErr_Format(PyExc_TypeError, "%s: the bounds must be floats", name);
        return -1;
    }
    *lo = PyFloat_AS_DOUBLE(*lo_obj);
    *hi = PyFloat_AS_DOUBLE(*hi_obj);
    return 0;
}

/* numbers_within(values, lo, hi): every item is a number (not a bool) within [lo, hi] (True when empty; False
 * when `values` is not a list or tuple) */
static PyObject *numbers_within(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *seq, *lo_obj, *hi_obj;
    double lo, hi;
    if (parse(args, "numbers_within", &seq, &lo_obj, &hi_obj, &lo, &hi) < 0) return NULL;
    Py_ssize_t n;
    PyObject **items;
    if (!items_of(seq, &items, &n)) Py_RETURN_FALSE;
    for (Py_ssize_t i = 0; i < n; i++) {
        int ok = number_within(items[i], lo, hi, lo_obj, hi_obj);
        if (ok < 0) return NULL;
        if (!ok) Py_RETURN_FALSE;
    }
    Py_RETURN_TRUE;
}

/* points_within(values, lo, hi): every item is a list of exactly two numbers within [lo, hi] */
static PyObject *points_within(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *seq, *lo_obj, *hi_obj;
    double lo, hi;
    if (parse(args, "points_within", &seq, &lo_obj, &hi_obj, &lo, &hi) < 0) return NULL;
    Py_ssize_t n;
    PyObject **items;
    if (!items_of(seq, &items, &n)) Py_RETURN_FALSE;
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *pair = items[i];
        if (!PyList_CheckExact(pair) || PyList_GET_SIZE(pair) != 2) Py_RETURN_FALSE;
        /* the list is not changed during the loop: no Python code runs but int comparisons */
        for (Py_ssize_t j = 0; j < 2; j++) {
            int ok = number_within(PyList_GET_ITEM(pair, j), lo, hi, lo_obj, hi_obj);
            if (ok < 0) return NULL;
            if (!ok) Py_RETURN_FALSE;
        }
    }
    Py_RETURN_TRUE;
}

/* all_booleans(values): every item is True or False */
static PyObject *all_booleans(PyObject *self, PyObject *seq) {
    (void)self;
    Py_ssize_t n;
    PyObject **items;
    if (!items_of(seq, &items, &n)) Py_RETURN_FALSE;
    for (Py_ssize_t i = 0; i < n; i++)
        if (items[i] != Py_True && items[i] != Py_False) Py_RETURN_FALSE;
    Py_RETURN_TRUE;
}

static PyMethodDef methods[] = {
    {"numbers_within", numbers_within, METH_VARARGS,
     "numbers_within(values, lo, hi): every item of a list or tuple is a JSON number within [lo, hi]"},
    {"points_within", points_within, METH_VARARGS,
     "points_within(values, lo, hi): every item is a list of two JSON numbers within [lo, hi]"},
    {"all_booleans", all_booleans, METH_O, "all_booleans(values): every item of a list or tuple is a bool"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav._json_checks",
    "The analysis's acceptance tests of decoded JSON arrays in one pass (analysis.json_checks).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__json_checks(void) { return PyModule_Create(&module); }
