/*
 * analysis._json_checks: the analysis's acceptance tests of decoded JSON arrays in one pass each
 * (analysis.json_checks' batch forms).
 *
 * Each function answers whether every item of a list (or tuple) is acceptable: a JSON number (an exact int or
 * float, never a bool) within [lo, hi], an [x, y] pair of such numbers, or a boolean; tables_within and
 * tables_booleans answer it for whole TPT tables (rows of cells), fields_within for scalar fields of objects.
 * The Python forms build sets of types, chained lists, a min and a max: five passes and their temporary lists
 * over an episode's thousands of TPT coordinates.
 * The answers are the Python forms' (a property test compares them on mutated values); a NaN is refused here, as
 * the item-by-item rule refuses it (decoded JSON has none). Ints are compared with the bounds as Python compares
 * them (exactly), floats as doubles. table_pairs reads accepted tables' coordinates into a float64 buffer for the
 * TPT scoring (analysis.tpt_errors).
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


/* the length of a row of table i (ks[i], an exact int) or -1 when it is not one */
static Py_ssize_t exact_size(PyObject *value) {
    if (!PyLong_CheckExact(value)) return -1;
    Py_ssize_t n = PyLong_AsSsize_t(value);
    if (n == -1 && PyErr_Occurred()) {
        PyErr_Clear();  /* beyond Py_ssize_t: no list is that long */
        return -1;
    }
    return n;
}

/* 1: `table` is an exact list of `rows` exact lists of `k` cells each, every cell accepted by `cell_ok` (points:
 * a list of two numbers within [lo, hi]; booleans: True or False); 0: it is not; -1: an exception is set */
static int table_ok(PyObject *table, Py_ssize_t rows, Py_ssize_t k, int points, double lo, double hi,
                    PyObject *lo_obj, PyObject *hi_obj) {
    if (!PyList_CheckExact(table) || PyList_GET_SIZE(table) != rows) return 0;
    for (Py_ssize_t r = 0; r < rows; r++) {
        PyObject *row = PyList_GET_ITEM(table, r);
        if (!PyList_CheckExact(row) || PyList_GET_SIZE(row) != k) return 0;
        for (Py_ssize_t c = 0; c < k; c++) {
            PyObject *cell = PyList_GET_ITEM(row, c);
            if (!points) {
                if (cell != Py_True && cell != Py_False) return 0;
                continue;
            }
            if (!PyList_CheckExact(cell) || PyList_GET_SIZE(cell) != 2) return 0;
            for (Py_ssize_t j = 0; j < 2; j++) {
                int ok = number_within(PyList_GET_ITEM(cell, j), lo, hi, lo_obj, hi_obj);
                if (ok != 1) return ok;
            }
        }
    }
    return 1;
}

/* tables_within(tables, rows, ks, lo, hi) and tables_booleans(tables, rows, ks): tables[i] is a list of rows[i]
 * lists of ks[i] cells each — [x, y] pairs of numbers within [lo, hi], or booleans (a TPT's obstacles_cm and
 * collide). rows and ks are lists of the same length as tables; a row count that is not an exact int is refused,
 * as the Python form refuses it (itertools.repeat raises on it). */
static PyObject *tables_check(PyObject *args, const char *name, int points) {
    PyObject *tables, *rows, *ks, *lo_obj = NULL, *hi_obj = NULL;
    double lo = 0.0, hi = 0.0;
    if (!PyArg_UnpackTuple(args, name, points ? 5 : 3, points ? 5 : 3, &tables, &rows, &ks, &lo_obj, &hi_obj))
        return NULL;
    if (points) {
        if (!PyFloat_CheckExact(lo_obj) || !PyFloat_CheckExact(hi_obj)) {
            PyErr_Format(PyExc_TypeError, "%s: the bounds must be floats", name);
            return NULL;
        }
        lo = PyFloat_AS_DOUBLE(lo_obj);
        hi = PyFloat_AS_DOUBLE(hi_obj);
    }
    if (!PyList_CheckExact(tables) || !PyList_CheckExact(rows) || !PyList_CheckExact(ks)) {
        PyErr_Format(PyExc_TypeError, "%s: tables, rows and ks must be lists", name);
        return NULL;
    }
    Py_ssize_t n = PyList_GET_SIZE(tables);
    if (PyList_GET_SIZE(rows) != n || PyList_GET_SIZE(ks) != n) {
        PyErr_Format(PyExc_ValueError, "%s: tables, rows and ks of different lengths", name);
        return NULL;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        Py_ssize_t r = exact_size(PyList_GET_ITEM(rows, i)), k = exact_size(PyList_GET_ITEM(ks, i));
        if (r < 0 || k < 0) Py_RETURN_FALSE;
        int ok = table_ok(PyList_GET_ITEM(tables, i), r, k, points, lo, hi, lo_obj, hi_obj);
        if (ok < 0) return NULL;
        if (!ok) Py_RETURN_FALSE;
    }
    Py_RETURN_TRUE;
}

static PyObject *tables_within(PyObject *self, PyObject *args) {
    (void)self;
    return tables_check(args, "tables_within", 1);
}

static PyObject *tables_booleans(PyObject *self, PyObject *args) {
    (void)self;
    return tables_check(args, "tables_booleans", 0);
}

/* table_pairs(tables, k): the numbers of tables of rows of k [x, y] pairs, in order, as the bytes of a float64
 * array: each an exact float, or an exact int rounded as float() rounds it (OverflowError beyond a double's
 * range). ValueError for a row that is not k pairs or a pair that is not two items, TypeError for anything that
 * is not a list or a number. Only exact types are read, so no Python code runs and no list can change. */
static PyObject *table_pairs(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *tables;
    Py_ssize_t k;
    if (!PyArg_ParseTuple(args, "O!n:table_pairs", &PyList_Type, &tables, &k)) return NULL;
    if (k < 0) {
        PyErr_SetString(PyExc_ValueError, "table_pairs: k must be >= 0");
        return NULL;
    }
    Py_ssize_t n = PyList_GET_SIZE(tables), count = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *table = PyList_GET_ITEM(tables, i);
        if (!PyList_CheckExact(table)) {
            PyErr_SetString(PyExc_TypeError, "table_pairs: a table is not a list");
            return NULL;
        }
        count += PyList_GET_SIZE(table);
    }
    if (k > 0 && count > PY_SSIZE_T_MAX / (Py_ssize_t)(2 * sizeof(double)) / k) return PyErr_NoMemory();
    PyObject *out = PyBytes_FromStringAndSize(NULL, count * k * 2 * (Py_ssize_t)sizeof(double));
    if (out == NULL) return NULL;
    double *v = (double *)PyBytes_AS_STRING(out);
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *table = PyList_GET_ITEM(tables, i);
        for (Py_ssize_t r = 0; r < PyList_GET_SIZE(table); r++) {
            PyObject *row = PyList_GET_ITEM(table, r);
            if (!PyList_CheckExact(row)) {
                PyErr_SetString(PyExc_TypeError, "table_pairs: a row is not a list");
                goto fail;
            }
            if (PyList_GET_SIZE(row) != k) {
                PyErr_Format(PyExc_ValueError, "table_pairs: a row of %zd pairs, expected %zd", PyList_GET_SIZE(row),
                             k);
                goto fail;
            }
            for (Py_ssize_t c = 0; c < k; c++) {
                PyObject *pair = PyList_GET_ITEM(row, c);
                if (!PyList_CheckExact(pair)) {
                    PyErr_SetString(PyExc_TypeError, "table_pairs: a pair is not a list");
                    goto fail;
                }
                if (PyList_GET_SIZE(pair) != 2) {
                    PyErr_SetString(PyExc_ValueError, "table_pairs: a pair is not two numbers");
                    goto fail;
                }
                for (Py_ssize_t j = 0; j < 2; j++) {
                    PyObject *item = PyList_GET_ITEM(pair, j);
                    if (PyFloat_CheckExact(item)) {
                        *v++ = PyFloat_AS_DOUBLE(item);
                    } else if (PyLong_CheckExact(item)) {
                        double x = PyLong_AsDouble(item);
                        if (x == -1.0 && PyErr_Occurred()) goto fail;
                        *v++ = x;
                    } else {
                        PyErr_SetString(PyExc_TypeError, "table_pairs: a value is not a number");
                        goto fail;
                    }
                }
            }
        }
    }
    return out;
fail:
    Py_DECREF(out);
    return NULL;
}

/* 1: `item` is of `kind` — 0: a number within [lo, hi]; 1: an exact int within [lo_obj, hi_obj] (Python ints);
 * 2: a boolean; 3: a str —, 0: it is not, -1: an exception is set */
static int field_ok(PyObject *item, int kind, double lo, double hi, PyObject *lo_obj, PyObject *hi_obj) {
    switch (kind) {
    case 0:
        return number_within(item, lo, hi, lo_obj, hi_obj);
    case 1: {
        if (!PyLong_CheckExact(item)) return 0;
        int ok = PyObject_RichCompareBool(item, lo_obj, Py_GE);
        if (ok != 1) return ok;
        return PyObject_RichCompareBool(item, hi_obj, Py_LE);
    }
    case 2:
        return item == Py_True || item == Py_False;
    default:
        return PyUnicode_CheckExact(item);
    }
}

/* fields_within(values, names, kind, lo, hi): every item of the list `values` is a dict (exactly) holding each of
 * the `names` (a tuple of str) as a value of `kind` (see field_ok; lo and hi: floats for numbers, ints for
 * integers, ignored otherwise): analysis.json_checks.obj's batch test of its scalar fields. False for a missing
 * field, as the Python form's KeyError. */
static PyObject *fields_within(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *seq, *names, *lo_obj, *hi_obj;
    int kind;
    if (!PyArg_ParseTuple(args, "O!O!iOO:fields_within", &PyList_Type, &seq, &PyTuple_Type, &names, &kind, &lo_obj,
                          &hi_obj))
        return NULL;
    double lo = 0.0, hi = 0.0;
    if (kind == 0) {
        if (!PyFloat_CheckExact(lo_obj) || !PyFloat_CheckExact(hi_obj)) {
            PyErr_SetString(PyExc_TypeError, "fields_within: a number's bounds must be floats");
            return NULL;
        }
        lo = PyFloat_AS_DOUBLE(lo_obj);
        hi = PyFloat_AS_DOUBLE(hi_obj);
    } else if (kind == 1) {
        if (!PyLong_CheckExact(lo_obj) || !PyLong_CheckExact(hi_obj)) {
            PyErr_SetString(PyExc_TypeError, "fields_within: an integer's bounds must be ints");
            return NULL;
        }
    } else if (kind != 2 && kind != 3) {
        PyErr_Format(PyExc_ValueError, "fields_within: unknown kind %d", kind);
        return NULL;
    }
    Py_ssize_t m = PyTuple_GET_SIZE(names);
    for (Py_ssize_t j = 0; j < m; j++) {
        if (!PyUnicode_CheckExact(PyTuple_GET_ITEM(names, j))) {
            PyErr_SetString(PyExc_TypeError, "fields_within: the names must be str");
            return NULL;
        }
    }
    /* a key of another type with a str's hash would run its __eq__ during a lookup: each dict and value is held
     * while it is read, and the list's size is read again at every item */
    for (Py_ssize_t i = 0; i < PyList_GET_SIZE(seq); i++) {
        PyObject *v = PyList_GET_ITEM(seq, i);
        if (!PyDict_CheckExact(v)) Py_RETURN_FALSE;
        Py_INCREF(v);
        int ok = 1;
        for (Py_ssize_t j = 0; j < m && ok == 1; j++) {
            PyObject *item = PyDict_GetItemWithError(v, PyTuple_GET_ITEM(names, j));
            if (item == NULL) {
                ok = PyErr_Occurred() ? -1 : 0;
                break;
            }
            Py_INCREF(item);
            ok = field_ok(item, kind, lo, hi, lo_obj, hi_obj);
            Py_DECREF(item);
        }
        Py_DECREF(v);
        if (ok < 0) return NULL;
        if (!ok) Py_RETURN_FALSE;
    }
    Py_RETURN_TRUE;
}

static PyMethodDef methods[] = {
    {"numbers_within", numbers_within, METH_VARARGS,
     "numbers_within(values, lo, hi): every item of a list or tuple is a JSON number within [lo, hi]"},
    {"points_within", points_within, METH_VARARGS,
     "points_within(values, lo, hi): every item is a list of two JSON numbers within [lo, hi]"},
    {"all_booleans", all_booleans, METH_O, "all_booleans(values): every item of a list or tuple is a bool"},
    {"fields_within", fields_within, METH_VARARGS,
     "fields_within(values, names, kind, lo, hi): every item is a dict holding each name as a value of kind (0 a "
     "number within [lo, hi], 1 an int within [lo, hi], 2 a boolean, 3 a str)"},
    {"tables_within", tables_within, METH_VARARGS,
     "tables_within(tables, rows, ks, lo, hi): tables[i] is a list of rows[i] lists of ks[i] [x, y] pairs within "
     "[lo, hi]"},
    {"tables_booleans", tables_booleans, METH_VARARGS,
     "tables_booleans(tables, rows, ks): tables[i] is a list of rows[i] lists of ks[i] booleans"},
    {"table_pairs", table_pairs, METH_VARARGS,
     "table_pairs(tables, k): the float64 bytes of tables of rows of k [x, y] pairs, in order"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "analysis._json_checks",
    "The analysis's acceptance tests of decoded JSON arrays in one pass (analysis.json_checks).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__json_checks(void) { return PyModule_Create(&module); }
