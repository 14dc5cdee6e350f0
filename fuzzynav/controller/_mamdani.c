/*
 * fuzzynav.controller._mamdani: the single-decision path of fuzzynav.controller.fuzzy_fast.FastEvaluator in C.
 *
 * It performs the same IEEE double operations, in the same order, as FastEvaluator._evaluate_scalar and
 * _centroid (the Python path, which stays the definition and the fallback when this module is not built):
 * the interpolated memberships a * (1 - f) + b * f, exact min/max for activations, cuts and the output
 * membership, the grid integrals as products added strictly left to right from the same first grid point,
 * and the crossing-point triangles added in increasing x. Results are bit-identical to the Python path, so
 * a log does not depend on whether the kernel was built (tests/test_mamdani_kernel.py checks both paths on
 * random definitions and inputs).
 *
 * That needs IEEE double arithmetic with no contraction into fused multiply-adds and no reassociation:
 * the build passes -ffp-contract=off (pyproject.toml), and the checks below refuse x87 excess precision and
 * -ffast-math (the build then fails and, being optional, leaves the Python path).
 *
 * The tables are built by fuzzy_fast._kernel_tables from the evaluator's own scalar tables and copied here.
 * Units: those of the controller definition (inputs as given; outputs degrees and cm/s).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fuzzynav.controller._mamdani must not be built with -ffast-math (it would reorder the sums)"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.controller._mamdani needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#define N_SIZES 14  /* the sizes header (see Kernel_init) */

typedef struct {
    PyObject_HEAD
    PyObject *names;          /* tuple of str: the inputs in the definition's order */
    Py_ssize_t n_in;
    double *in_f;             /* n_in x 3: universe min, universe max, grid step */
    int64_t *in_i;            /* n_in x 3: crisp (0/1), count (segments or terms), offset */
    int64_t *seg_i;           /* per input grid segment: live offset, live count, rule mask */
    int64_t *live_i;          /* per live term of a segment: index into mu */
    double *live_f;           /* per live term of a segment: membership at the segment's start and end */
    int64_t *crisp_i;         /* per crisp term: index into mu, rule mask */
    double *crisp_f;          /* per crisp term: [a, b) */
    Py_ssize_t n_mu;          /* input terms + 1 (the last, 1.0, pads one-clause rules) */
    Py_ssize_t n_rules, width;
    uint64_t all_rules;
    int64_t *ant;             /* n_rules x width: indices into mu */
    int64_t *cons_off;        /* n_rules + 1 */
    int64_t *cons;            /* consequent output terms (dtheta's first, then v's) */
    Py_ssize_t n_out;         /* output terms */
    Py_ssize_t n_dtheta;      /* dtheta's terms (the first n_dtheta) */
    Py_ssize_t g;             /* concatenated grid length (dtheta's grid, then v's) */
    Py_ssize_t block1;        /* first column of v's grid */
    double *mfs;              /* n_out x g: sampled output memberships (zero outside their own output) */
    double *w;                /* 4 x g: area and moment weights of dtheta, then of v */
    int64_t *term_i;          /* n_out x 8: window lo, hi; support lo, hi (concatenated columns);
                                 rise offset, rise length, fall offset, fall length */
    int64_t *fall_start;      /* n_out: index of the last maximum (own grid) */
    double *rise;             /* per term: samples up to the first maximum */
    double *fall;             /* per term: negated samples from the last maximum */
    double *grid;             /* g: the two grids concatenated */
    double step[2], fallback[2];
    /* scratch, used only while the GIL is held */
    double *mu, *cuts, *y;
    Py_ssize_t win_start, win_end;   /* the grid window of the decision being made */
    double *pts_x;
    int64_t *pts_seg, *pts_t, *higher;
} Kernel;

static void Kernel_free_arrays(Kernel *k) {
    void **arrays[] = {(void **)&k->in_f, (void **)&k->in_i, (void **)&k->seg_i, (void **)&k->live_i,
                       (void **)&k->live_f, (void **)&k->crisp_i, (void **)&k->crisp_f, (void **)&k->ant,
                       (void **)&k->cons_off, (void **)&k->cons, (void **)&k->mfs, (void **)&k->w,
                       (void **)&k->term_i, (void **)&k->fall_start, (void **)&k->rise, (void **)&k->fall,
                       (void **)&k->grid, (void **)&k->mu, (void **)&k->cuts, (void **)&k->y,
                       (void **)&k->pts_x, (void **)&k->pts_seg, (void **)&k->pts_t, (void **)&k->higher};
    for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); i++) {
        PyMem_Free(*arrays[i]);
        *arrays[i] = NULL;
    }
}

static void Kernel_dealloc(Kernel *k) {
    Kernel_free_arrays(k);
    Py_XDECREF(k->names);
    Py_TYPE(k)->tp_free((PyObject *)k);
}

/* A copy of a bytes object holding `count` items of `size` bytes (NULL with an exception when it does not). */
static void *copy_bytes(PyObject *obj, Py_ssize_t count, size_t size, const char *what) {
    if (!PyBytes_Check(obj)) {
        PyErr_Format(PyExc_TypeError, "kernel table %s: expected bytes", what);
        return NULL;
    }
    if (count < 0 || count > PY_SSIZE_T_MAX / (Py_ssize_t)size ||
        PyBytes_GET_SIZE(obj) != (Py_ssize_t)(count * (Py_ssize_t)size)) {
        PyErr_Format(PyExc_ValueError, "kernel table %s: expected %zd items", what, count);
        return NULL;
    }
    void *out = PyMem_Malloc(count > 0 ? (size_t)count * size : 1);
    if (out == NULL) {
        PyErr_NoMemory();
        return NULL;
    }
    if (count > 0) memcpy(out, PyBytes_AS_STRING(obj), (size_t)count * size);
    return out;
}

static void *scratch(Py_ssize_t count, size_t size) {
    void *out = PyMem_Calloc(count > 0 ? (size_t)count : 1, size);
    if (out == NULL) PyErr_NoMemory();
    return out;
}

#define N_TABLES 17

static int check_range(const int64_t *a, Py_ssize_t n, int64_t lo, int64_t hi, const char *what) {
    for (Py_ssize_t i = 0; i < n; i++)
        if (a[i] < lo || a[i] >= hi) {
            PyErr_Format(PyExc_ValueError, "kernel table %s: index out of range", what);
            return -1;
        }
    return 0;
}

/* Kernel(names, sizes, tables, scalars): names a tuple of the input names; sizes, scalars and each of the
 * N_TABLES tables native-endian int64 or float64 bytes, in the order of fuzzy_fast._kernel_tables. */
static int Kernel_init(Kernel *k, PyObject *args, PyObject *kwds) {
    PyObject *names, *sizes_b, *tables, *scalars_b;
    if (kwds != NULL && PyDict_GET_SIZE(kwds) > 0) {
        PyErr_SetString(PyExc_TypeError, "Kernel takes positional arguments only");
        return -1;
    }
    if (!PyArg_ParseTuple(args, "O!SO!S", &PyTuple_Type, &names, &sizes_b, &PyTuple_Type, &tables, &scalars_b))
        return -1;
    if (PyTuple_GET_SIZE(tables) != N_TABLES) {
        PyErr_SetString(PyExc_ValueError, "kernel tables: wrong number of tables");
        return -1;
    }
    int64_t sizes[N_SIZES];
    double scalars[4];
    if (PyBytes_GET_SIZE(sizes_b) != (Py_ssize_t)sizeof(sizes) ||
        PyBytes_GET_SIZE(scalars_b) != (Py_ssize_t)sizeof(scalars)) {
        PyErr_SetString(PyExc_ValueError, "kernel tables: wrong header size");
        return -1;
    }
    /* made once: a second __init__ could run from Python code that decide calls (a key's __eq__, a value's
     * __float__) and free the tables, names and sizes that call is using */
    if (k->names != NULL) {
        PyErr_SetString(PyExc_TypeError, "fuzzynav.controller._mamdani.Kernel: already initialised");
        return -1;
    }
    memcpy(sizes, PyBytes_AS_STRING(sizes_b), sizeof(sizes));
    memcpy(scalars, PyBytes_AS_STRING(scalars_b), sizeof(scalars));
    Py_INCREF(names);
    k->names = names;
    k->n_in = (Py_ssize_t)sizes[0];
    Py_ssize_t n_seg = sizes[1], n_live = sizes[2], n_crisp = sizes[3];
    k->n_mu = sizes[4];
    k->n_rules = sizes[5];
    k->width = sizes[6];
    Py_ssize_t n_cons = sizes[7];
    k->n_out = sizes[8];
    k->n_dtheta = sizes[9];
    k->g = sizes[10];
    k->block1 = sizes[11];
    Py_ssize_t n_rise = sizes[12], n_fall = sizes[13];
    for (int i = 0; i < 2; i++) {
        k->step[i] = scalars[i];
        k->fallback[i] = scalars[2 + i];
    }
    int ok = 1;
    for (int i = 0; i < N_SIZES; i++) ok = ok && sizes[i] >= 0 && sizes[i] <= ((int64_t)1 << 40);
    ok = ok && PyTuple_GET_SIZE(names) == k->n_in && k->n_in > 0 && k->n_mu > 0 && k->n_rules > 0 &&
             k->n_rules <= 64 && k->width > 0 && k->n_out > k->n_dtheta && k->n_dtheta > 0 && k->block1 > 1 &&
             k->g > k->block1 + 1 && n_seg >= 0 && n_live >= 0 && n_crisp >= 0 && n_cons >= 0 && n_rise >= 0 &&
             n_fall >= 0 && k->n_mu <= 1 + n_live + n_crisp &&  /* every input term is live somewhere */
             k->n_out <= ((int64_t)1 << 40) / k->g;  /* n_out x g (mfs) stays far from overflowing */
    for (Py_ssize_t i = 0; ok && i < k->n_in; i++) ok = PyUnicode_Check(PyTuple_GET_ITEM(names, i));
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "kernel tables: inconsistent sizes");
        return -1;
    }
    k->all_rules = k->n_rules == 64 ? ~(uint64_t)0 : (((uint64_t)1 << k->n_rules) - 1);
    struct { void **dst; Py_ssize_t count; size_t size; const char *what; } spec[N_TABLES] = {
        {(void **)&k->in_f, 3 * k->n_in, sizeof(double), "in_f"},
        {(void **)&k->in_i, 3 * k->n_in, sizeof(int64_t), "in_i"},
        {(void **)&k->seg_i, 3 * n_seg, sizeof(int64_t), "seg_i"},
        {(void **)&k->live_i, n_live, sizeof(int64_t), "live_i"},
        {(void **)&k->live_f, 2 * n_live, sizeof(double), "live_f"},
        {(void **)&k->crisp_i, 2 * n_crisp, sizeof(int64_t), "crisp_i"},
        {(void **)&k->crisp_f, 2 * n_crisp, sizeof(double), "crisp_f"},
        {(void **)&k->ant, k->n_rules * k->width, sizeof(int64_t), "ant"},
        {(void **)&k->cons_off, k->n_rules + 1, sizeof(int64_t), "cons_off"},
        {(void **)&k->cons, n_cons, sizeof(int64_t), "cons"},
        {(void **)&k->mfs, k->n_out * k->g, sizeof(double), "mfs"},
        {(void **)&k->w, 4 * k->g, sizeof(double), "w"},
        {(void **)&k->term_i, 8 * k->n_out, sizeof(int64_t), "term_i"},
        {(void **)&k->fall_start, k->n_out, sizeof(int64_t), "fall_start"},
        {(void **)&k->rise, n_rise, sizeof(double), "rise"},
        {(void **)&k->fall, n_fall, sizeof(double), "fall"},
        {(void **)&k->grid, k->g, sizeof(double), "grid"},
    };
    for (int i = 0; i < N_TABLES; i++)
        if (!(*spec[i].dst = copy_bytes(PyTuple_GET_ITEM(tables, i), spec[i].count, spec[i].size, spec[i].what)))
            return -1;
    /* every index the evaluation follows stays inside its array (no sum of two table entries is formed before
     * both are known to be in [0, 2^40]: entries are any int64) */
    for (Py_ssize_t i = 0; i < k->n_in; i++) {
        int64_t crisp = k->in_i[3 * i], count = k->in_i[3 * i + 1], off = k->in_i[3 * i + 2];
        int64_t rows = crisp ? n_crisp : n_seg;
        if (count < 1 || off < 0 || count > rows || off > rows - count) {
            PyErr_SetString(PyExc_ValueError, "kernel table in_i: index out of range");
            return -1;
        }
    }
    for (Py_ssize_t s = 0; s < n_seg; s++) {
        int64_t off = k->seg_i[3 * s], cnt = k->seg_i[3 * s + 1];
        if (off < 0 || cnt < 0 || cnt > n_live || off > n_live - cnt) {
            PyErr_SetString(PyExc_ValueError, "kernel table seg_i: index out of range");
            return -1;
        }
    }
    if (check_range(k->live_i, n_live, 0, k->n_mu, "live_i") < 0) return -1;
    for (Py_ssize_t c = 0; c < n_crisp; c++)
        if (check_range(k->crisp_i + 2 * c, 1, 0, k->n_mu, "crisp_i") < 0) return -1;
    if (check_range(k->ant, k->n_rules * k->width, 0, k->n_mu, "ant") < 0) return -1;
    if (check_range(k->cons_off, k->n_rules + 1, 0, n_cons + 1, "cons_off") < 0) return -1;
    if (check_range(k->cons, n_cons, 0, k->n_out, "cons") < 0) return -1;
    for (Py_ssize_t r = 0; r < k->n_rules; r++)
        if (k->cons_off[r] > k->cons_off[r + 1]) {
            PyErr_SetString(PyExc_ValueError, "kernel table cons_off: not increasing");
            return -1;
        }
    for (Py_ssize_t t = 0; t < k->n_out; t++) {
        const int64_t *ti = k->term_i + 8 * t;
        int64_t own = t < k->n_dtheta ? k->block1 : k->g - k->block1;  /* the term's own grid length */
        if (ti[0] < 0 || ti[1] > k->g || ti[0] > ti[1] || ti[2] < 0 || ti[3] > k->g || ti[2] > ti[3] ||
            ti[4] < 0 || ti[5] < 0 || ti[5] > n_rise || ti[4] > n_rise - ti[5] || ti[5] > own || ti[6] < 0 ||
            ti[7] < 0 || ti[7] > n_fall || ti[6] > n_fall - ti[7] || ti[7] > own || k->fall_start[t] < 0 ||
            k->fall_start[t] > own - ti[7]) {
            PyErr_SetString(PyExc_ValueError, "kernel table term_i: index out of range");
            return -1;
        }
    }
    if (!(k->mu = scratch(k->n_mu, sizeof(double))) || !(k->cuts = scratch(k->n_out, sizeof(double))) ||
        !(k->y = scratch(k->g, sizeof(double))) || !(k->pts_x = scratch(2 * k->n_out, sizeof(double))) ||
        !(k->pts_seg = scratch(2 * k->n_out, sizeof(int64_t))) ||
        !(k->pts_t = scratch(2 * k->n_out, sizeof(int64_t))) || !(k->higher = scratch(k->n_out, sizeof(int64_t))))
        return -1;
    return 0;
}

/* CPython's bisect.bisect_left and bisect_right, step for step */
static Py_ssize_t bisect_left(const double *a, Py_ssize_t n, double x) {
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (a[mid] < x) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

static Py_ssize_t bisect_right(const double *a, Py_ssize_t n, double x) {
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (x < a[mid]) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

/* fuzzy_fast._centroid for output b (0: dtheta, 1: v): the grid integrals plus the crossing points */
static double centroid(Kernel *k, int b, double area, double moment) {
    Py_ssize_t t0 = b == 0 ? 0 : k->n_dtheta, t1 = b == 0 ? k->n_dtheta : k->n_out;
    Py_ssize_t boff = b == 0 ? 0 : k->block1;
    const double *grid = k->grid + boff, *cuts = k->cuts, *y = k->y + boff;
    double h = k->step[b];
    Py_ssize_t n_pts = 0, n_higher = 0;
    for (Py_ssize_t t = t0; t < t1; t++) {
        double level = cuts[t];
        if (level <= 0.0) continue;
        const int64_t *ti = k->term_i + 8 * t;
        k->higher[n_higher++] = t;
        const double *rise = k->rise + ti[4], *fall = k->fall + ti[6];
        Py_ssize_t n_rise = ti[5], n_fall = ti[7];
        Py_ssize_t j = bisect_left(rise, n_rise, level);
        if (1 <= j && j < n_rise) {
            k->pts_x[n_pts] = grid[j - 1] + (level - rise[j - 1]) * h / (rise[j] - rise[j - 1]);
            k->pts_seg[n_pts] = j - 1;
            k->pts_t[n_pts++] = t;
        }
        Py_ssize_t cnt = bisect_right(fall, n_fall, -level);
        if (1 <= cnt && cnt < n_fall) {
            Py_ssize_t kk = cnt - 1, start = k->fall_start[t];
            k->pts_x[n_pts] = grid[start + kk] + (level + fall[kk]) * h / (fall[kk] - fall[kk + 1]);
            k->pts_seg[n_pts] = start + kk;
            k->pts_t[n_pts++] = t;
        }
    }
    if (n_pts == 0) return area > 0 ? moment / area : k->fallback[b];
    /* sorted by (x, segment, term) as Python's tuple sort (no two points share all three) */
    for (Py_ssize_t i = 1; i < n_pts; i++) {
        double x = k->pts_x[i];
        int64_t s = k->pts_seg[i], t = k->pts_t[i];
        Py_ssize_t j = i;
        while (j > 0 && (k->pts_x[j - 1] > x || (k->pts_x[j - 1] == x && (k->pts_seg[j - 1] > s ||
                                                  (k->pts_seg[j - 1] == s && k->pts_t[j - 1] > t))))) {
            k->pts_x[j] = k->pts_x[j - 1];
            k->pts_seg[j] = k->pts_seg[j - 1];
            k->pts_t[j] = k->pts_t[j - 1];
            j--;
        }
        k->pts_x[j] = x;
        k->pts_seg[j] = s;
        k->pts_t[j] = t;
    }
    int64_t seg_open = -1;
    double xa = 0.0, ya = 0.0, xb = 0.0, yb = 0.0;
    for (Py_ssize_t p = 0; p < n_pts; p++) {
        double x = k->pts_x[p];
        int64_t seg = k->pts_seg[p], t = k->pts_t[p];
        if (seg != seg_open) {
            if (boff + seg < k->win_start || boff + seg + 1 >= k->win_end) {
                PyErr_SetString(PyExc_SystemError, "fuzzynav.controller._mamdani: a crossing point outside the grid window");
                return NAN;
            }
            seg_open = seg;
            xa = grid[seg];
            ya = y[seg];
            xb = grid[seg + 1];
            yb = y[seg + 1];
        }
        double level = cuts[t], yx = level;
        double f = (x - grid[seg]) / h;
        for (Py_ssize_t i = 0; i < n_higher; i++) {
            double c = cuts[k->higher[i]];
            if (c > level) {
                const double *row = k->mfs + k->higher[i] * k->g + boff;
                double value = row[seg] * (1.0 - f) + row[seg + 1] * f;
                if (value < c) c = value;  /* Python's min(c, value) */
                if (c > yx) yx = c;
            }
        }
        double triangle = 0.5 * (yx * (xb - xa) - ya * (xb - x) - yb * (x - xa));
        area += triangle;
        moment += triangle * (xa + x + xb) / 3.0;
        xa = x;
        ya = yx;
    }
    return area > 0 ? moment / area : k->fallback[b];
}

/* input i's value clipped to its universe: Python's min(max(x, lo), hi) (a NaN stays NaN) */
static double clip_input(const Kernel *k, Py_ssize_t i, double x) {
    double lo = k->in_f[3 * i], hi = k->in_f[3 * i + 1];
    if (lo > x) x = lo;
    if (hi < x) x = hi;
    return x;
}

/* the grid position of fuzzy input i at its clipped value x */
static double input_position(const Kernel *k, Py_ssize_t i, double x) {
    return (x - k->in_f[3 * i]) / k->in_f[3 * i + 2];
}

/* whether decide raises at input i (a fuzzy input whose position is NaN or infinite), as the Python path
 * does before it reads the inputs after it */
static int input_raises(const Kernel *k, Py_ssize_t i, double x) {
    return !k->in_i[3 * i] && !isfinite(input_position(k, i, clip_input(k, i, x)));
}

/* FastEvaluator._evaluate_scalar on inputs x (the definition's input order): 0, or -1 with an exception.
 * It reads x[i] only after inputs 0..i-1 were taken without error. */
static int decide(Kernel *k, const double *x_in, double *out) {
    double *mu = k->mu, *cuts = k->cuts, *y = k->y;
    for (Py_ssize_t i = 0; i < k->n_mu - 1; i++) mu[i] = 0.0;
    mu[k->n_mu - 1] = 1.0;
    uint64_t alive = k->all_rules;
    for (Py_ssize_t i = 0; i < k->n_in; i++) {
        double hi = k->in_f[3 * i + 1];
        int64_t crisp = k->in_i[3 * i], count = k->in_i[3 * i + 1], off = k->in_i[3 * i + 2];
        double x = clip_input(k, i, x_in[i]);
        if (crisp) {
            uint64_t inside = 0;
            for (int64_t c = off; c < off + count; c++) {
                double a = k->crisp_f[2 * c], b = k->crisp_f[2 * c + 1];
                if ((a <= x && x < b) || (b >= hi && a <= x && x <= b)) {
                    mu[k->crisp_i[2 * c]] = 1.0;
                    inside |= (uint64_t)k->crisp_i[2 * c + 1];
                }
            }
            alive &= inside;
            continue;
        }
        double pos = input_position(k, i, x);
        if (isnan(pos)) {
            PyErr_SetString(PyExc_ValueError, "cannot convert float NaN to integer");
            return -1;
        }
        if (isinf(pos)) {
            PyErr_SetString(PyExc_OverflowError, "cannot convert float infinity to integer");
            return -1;
        }
        double fl = floor(pos);
        int64_t seg = fl < 0.0 ? 0 : (fl > (double)(count - 1) ? count - 1 : (int64_t)fl);
        double f = pos - (double)seg, g = 1.0 - f;
        const int64_t *s = k->seg_i + 3 * (off + seg);
        for (int64_t l = s[0]; l < s[0] + s[1]; l++) mu[k->live_i[l]] = k->live_f[2 * l] * g + k->live_f[2 * l + 1] * f;
        alive &= (uint64_t)s[2];
    }
    for (Py_ssize_t t = 0; t < k->n_out; t++) cuts[t] = 0.0;
    for (Py_ssize_t r = 0; alive; r++, alive >>= 1) {
        if (!(alive & 1)) continue;
        const int64_t *ant = k->ant + r * k->width;
        double act = mu[ant[0]];
        for (Py_ssize_t j = 1; j < k->width; j++)
            if (mu[ant[j]] < act) act = mu[ant[j]];  /* Python's min() */
        /* the Python path's antecedents are at least two wide: a one-wide table is padded with the constant
         * 1.0, which caps a membership interpolated a hair above 1 (an input at the top of a universe whose
         * width is a hair over a whole number of steps) */
        if (k->width == 1 && mu[k->n_mu - 1] < act) act = mu[k->n_mu - 1];
        for (int64_t c = k->cons_off[r]; c < k->cons_off[r + 1]; c++)
            if (act > cuts[k->cons[c]]) cuts[k->cons[c]] = act;
    }
    /* the grid window of fuzzy_fast: from the first fired dtheta column to the last fired v column */
    Py_ssize_t start = k->block1 - 1, end = k->block1;
    int fired = 0;
    for (Py_ssize_t t = 0; t < k->n_out; t++) {
        if (!(cuts[t] > 0.0)) continue;
        fired = 1;
        const int64_t *ti = k->term_i + 8 * t;
        if (t < k->n_dtheta) {
            if (ti[0] < start) start = ti[0];
        } else if (ti[1] > end) {
            end = ti[1];
        }
    }
    if (!fired) {
        out[0] = k->fallback[0];
        out[1] = k->fallback[1];
        return 0;
    }
    /* y = max_t min(cut_t, mf_t) on the window; every sample is >= +0.0 (checked when the tables are
     * built), so the terms that did not fire (min = +0.0) and the columns outside a term's support change
     * nothing and are skipped */
    for (Py_ssize_t c = start; c < end; c++) y[c] = 0.0;
    for (Py_ssize_t t = 0; t < k->n_out; t++) {
        double cut = cuts[t];
        if (!(cut > 0.0)) continue;
        const int64_t *ti = k->term_i + 8 * t;
        Py_ssize_t lo = ti[2] > start ? ti[2] : start, hi = ti[3] < end ? ti[3] : end;
        const double *row = k->mfs + t * k->g;
        for (Py_ssize_t c = lo; c < hi; c++) {
            double m = row[c] < cut ? row[c] : cut;
            if (m > y[c]) y[c] = m;
        }
    }
    /* products added strictly left to right from the window's first column (np.add.accumulate) */
    double sums[4];
    for (int r = 0; r < 4; r++) {
        const double *w = k->w + r * k->g;
        Py_ssize_t last = r < 2 ? k->block1 - 1 : end - 1;
        double s = w[start] * y[start];
        for (Py_ssize_t c = start + 1; c <= last; c++) s += w[c] * y[c];
        sums[r] = s;
    }
    k->win_start = start;
    k->win_end = end;
    out[0] = centroid(k, 0, sums[0], sums[1]);
    out[1] = centroid(k, 1, sums[2], sums[3]);
    return PyErr_Occurred() ? -1 : 0;
}

/* the inputs of one decision from a dict, or 1 (no error) when the Python path must take them: a mapping
 * that is not a dict, or a value that is not a float or an int (arrays go to the batch).
 * As the Python path: each value is float(inputs[name]) (a subclass's __float__ included), read in the
 * definition's order, and the reading stops at the first input the decision raises at (so a NaN before a
 * missing key is the NaN's ValueError, not a KeyError). Python code can run here (a key's __eq__, a value's
 * __float__): the kernel cannot be re-initialised, and each value is held while it is converted. */
static int gather(Kernel *k, PyObject *inputs, double *x) {
    if (!PyDict_CheckExact(inputs)) return 1;
    Py_ssize_t pos = 0;
    PyObject *key, *value;
    while (PyDict_Next(inputs, &pos, &key, &value))
        if (!PyFloat_Check(value) && !PyLong_Check(value)) return 1;
    for (Py_ssize_t i = 0; i < k->n_in; i++) {
        PyObject *name = PyTuple_GET_ITEM(k->names, i);
        value = PyDict_GetItemWithError(inputs, name);
        if (value == NULL) {
            if (!PyErr_Occurred()) PyErr_SetObject(PyExc_KeyError, name);
            return -1;
        }
        if (PyFloat_CheckExact(value)) {
            x[i] = PyFloat_AS_DOUBLE(value);
        } else if (PyLong_CheckExact(value)) {
            x[i] = PyLong_AsDouble(value);
            if (x[i] == -1.0 && PyErr_Occurred()) return -1;
        } else {  /* float(value): a subclass (bool, numpy.float64, ...) may convert in its own way */
            Py_INCREF(value);
            PyObject *number = PyNumber_Float(value);
            Py_DECREF(value);
            if (number == NULL) return -1;
            x[i] = PyFloat_AS_DOUBLE(number);
            Py_DECREF(number);
        }
        if (input_raises(k, i, x[i])) return 0;  /* decide raises at input i, reading no later one */
    }
    return 0;
}

#define MAX_STACK_INPUTS 16

static int initialised(Kernel *k) {
    if (k->mu != NULL) return 1;
    PyErr_SetString(PyExc_ValueError, "fuzzynav.controller._mamdani.Kernel: not initialised");
    return 0;
}

static PyObject *Kernel_decide(Kernel *k, PyObject *inputs) {
    if (!initialised(k)) return NULL;
    double stack[MAX_STACK_INPUTS], out[2];
    double *x = k->n_in <= MAX_STACK_INPUTS ? stack : PyMem_Malloc((size_t)k->n_in * sizeof(double));
    if (x == NULL) return PyErr_NoMemory();
    int status = gather(k, inputs, x);
    if (status == 0) status = decide(k, x, out);
    if (x != stack) PyMem_Free(x);
    if (status < 0) return NULL;
    if (status > 0) Py_RETURN_NONE;
    PyObject *a = PyFloat_FromDouble(out[0]), *b = a ? PyFloat_FromDouble(out[1]) : NULL;
    if (b == NULL) {
        Py_XDECREF(a);
        return NULL;
    }
    PyObject *result = PyTuple_New(2);
    if (result == NULL) {
        Py_DECREF(a);
        Py_DECREF(b);
        return NULL;
    }
    PyTuple_SET_ITEM(result, 0, a);
    PyTuple_SET_ITEM(result, 1, b);
    return result;
}

/* fill(columns, dtheta, v): one decision per row; columns a tuple of C-contiguous float64 buffers (the
 * definition's input order, no NaN: the caller checks), dtheta and v writable float64 buffers of the same
 * length. The results are the single decisions' bits. */
static PyObject *Kernel_fill(Kernel *k, PyObject *args) {
    PyObject *columns, *dtheta_obj, *v_obj;
    if (!initialised(k) || !PyArg_ParseTuple(args, "O!OO", &PyTuple_Type, &columns, &dtheta_obj, &v_obj))
        return NULL;
    if (PyTuple_GET_SIZE(columns) != k->n_in) {
        PyErr_SetString(PyExc_ValueError, "fill: one column per input");
        return NULL;
    }
    Py_ssize_t n_buf = k->n_in + 2, got = 0;
    Py_buffer *views = PyMem_Calloc((size_t)n_buf, sizeof(Py_buffer));
    double *x = PyMem_Malloc((size_t)k->n_in * sizeof(double));
    PyObject *result = NULL;
    if (views == NULL || x == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < n_buf; i++) {
        PyObject *obj = i < k->n_in ? PyTuple_GET_ITEM(columns, i) : (i == k->n_in ? dtheta_obj : v_obj);
        int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (i >= k->n_in ? PyBUF_WRITABLE : 0);
        if (PyObject_GetBuffer(obj, &views[i], flags) < 0) goto done;
        got++;
        if (views[i].itemsize != sizeof(double) || views[i].format == NULL || strcmp(views[i].format, "d") != 0 ||
            views[i].len != views[0].len) {
            PyErr_SetString(PyExc_ValueError, "fill: float64 buffers of one length expected");
            goto done;
        }
    }
    Py_ssize_t n = views[0].len / (Py_ssize_t)sizeof(double);
    double *dtheta = views[k->n_in].buf, *v = views[k->n_in + 1].buf;
    for (Py_ssize_t row = 0; row < n; row++) {
        double out[2];
        for (Py_ssize_t i = 0; i < k->n_in; i++) x[i] = ((const double *)views[i].buf)[row];
        if (decide(k, x, out) < 0) goto done;
        dtheta[row] = out[0];
        v[row] = out[1];
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (Py_ssize_t i = 0; i < got; i++) PyBuffer_Release(&views[i]);
    PyMem_Free(views);
    PyMem_Free(x);
    return result;
}

static PyMethodDef Kernel_methods[] = {
    {"decide", (PyCFunction)Kernel_decide, METH_O,
     "decide(inputs: dict) -> (dtheta, v), or None when the inputs are not all floats or ints"},
    {"fill", (PyCFunction)Kernel_fill, METH_VARARGS, "fill(columns, dtheta, v): one decision per row"},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject KernelType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "fuzzynav.controller._mamdani.Kernel",
    .tp_doc = "The tables of one controller definition (built by fuzzynav.controller.fuzzy_fast).",
    .tp_basicsize = sizeof(Kernel),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)Kernel_init,
    .tp_dealloc = (destructor)Kernel_dealloc,
    .tp_methods = Kernel_methods,
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.controller._mamdani",
    "The single-decision Mamdani evaluation of fuzzynav.controller.fuzzy_fast in C (bit-identical to its Python path).",
    -1, NULL, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__mamdani(void) {
    if (PyType_Ready(&KernelType) < 0) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    Py_INCREF(&KernelType);
    if (PyModule_AddObject(m, "Kernel", (PyObject *)&KernelType) < 0) {
        Py_DECREF(&KernelType);
        Py_DECREF(m);
        return NULL;
    }
    if (PyModule_AddIntConstant(m, "N_SIZES", N_SIZES) < 0 || PyModule_AddIntConstant(m, "N_TABLES", N_TABLES) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
