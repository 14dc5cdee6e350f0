/*
 * fuzzynav.sensing._tracking: the laser tracker's clusters and disc fits in C (fuzzynav.sensing.tracking._clusters, detect and
 * fit_disc, up to the final "concave side towards us" test, which stays in Python because it uses math.hypot).
 *
 * The same IEEE operations as the Python and numpy forms, in the same order: link lengths and cluster extents
 * as sqrt(dx * dx + dy * dy) (portable_math.norm2), exact minima and maxima, and Kasa's fit with correctly
 * rounded sums — math.fsum's result is the correctly rounded sum whatever the algorithm, and this file uses
 * CPython's own (Shewchuk's partials with its half-even correction). So the detections are the Python form's
 * bits (tests/test_tracking_kernel.py). Anything the Python form would treat specially (a non-finite value, an
 * intermediate overflow in a sum) makes this module answer None and the Python form run. Built with
 * -ffp-contract=off; refuses -ffast-math and x87 arithmetic. Lengths in cm.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fuzzynav.sensing._tracking must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.sensing._tracking needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#define MAX_PARTIALS 128  /* non-overlapping partials of doubles number at most ~40 */

/* Accumulates like math.fsum; `ok` is cleared on anything the Python form would handle specially. */
typedef struct {
    double p[MAX_PARTIALS];
    int n;
    int ok;
} FSum;

static void fsum_init(FSum *s) {
    s->n = 0;
    s->ok = 1;
}

static void fsum_add(FSum *s, double x) {
    if (!isfinite(x)) {
        s->ok = 0;
        return;
    }
    int i = 0;
    for (int j = 0; j < s->n; j++) {
        double y = s->p[j];
        if (fabs(x) < fabs(y)) {
            double t = x;
            x = y;
            y = t;
        }
        double hi = x + y;
        double yr = hi - x;
        double lo = y - yr;
        if (lo != 0.0) s->p[i++] = lo;
        x = hi;
    }
    s->n = i;
    if (x != 0.0) {
        if (!isfinite(x) || s->n >= MAX_PARTIALS) {  /* intermediate overflow: Python raises */
            s->ok = 0;
            return;
        }
        s->p[s->n++] = x;
    }
}

static double fsum_result(FSum *s) {
    int n = s->n;
    double hi = 0.0, lo = 0.0;
    if (n > 0) {
        hi = s->p[--n];
        while (n > 0) {
            double x = hi, y = s->p[--n];
            hi = x + y;
            double yr = hi - x;
            lo = y - yr;
            if (lo != 0.0) break;
        }
        if (n > 0 && ((lo < 0.0 && s->p[n - 1] < 0.0) || (lo > 0.0 && s->p[n - 1] > 0.0))) {
            double y = lo * 2.0, x = hi + y, yr = x - hi;
            if (y == yr) hi = x;
        }
    }
    return hi;
}

/* tracking.fit_disc on points (n, 2) row-major; 0, or -1 when the Python form must run */
static int fit_disc(const double *pts, Py_ssize_t n, double *u, double *v, double *z, double out[4]) {
    FSum s;
    double nf = (double)n;
    fsum_init(&s);
    for (Py_ssize_t i = 0; i < n; i++) fsum_add(&s, pts[2 * i]);
    double mx = fsum_result(&s) / nf;
    if (!s.ok) return -1;
    fsum_init(&s);
    for (Py_ssize_t i = 0; i < n; i++) fsum_add(&s, pts[2 * i + 1]);
    double my = fsum_result(&s) / nf;
    if (!s.ok) return -1;
    for (Py_ssize_t i = 0; i < n; i++) {
        u[i] = pts[2 * i] - mx;
        v[i] = pts[2 * i + 1] - my;
        z[i] = u[i] * u[i] + v[i] * v[i];
    }
    FSum suu_s, svv_s, suv_s, suz_s, svz_s;
    fsum_init(&suu_s);
    fsum_init(&svv_s);
    fsum_init(&suv_s);
    fsum_init(&suz_s);
    fsum_init(&svz_s);
    for (Py_ssize_t i = 0; i < n; i++) fsum_add(&suu_s, u[i] * u[i]);
    for (Py_ssize_t i = 0; i < n; i++) fsum_add(&svv_s, v[i] * v[i]);
    for (Py_ssize_t i = 0; i < n; i++) fsum_add(&suv_s, u[i] * v[i]);
    for (Py_ssize_t i = 0; i < n; i++) fsum_add(&suz_s, u[i] * z[i]);
    for (Py_ssize_t i = 0; i < n; i++) fsum_add(&svz_s, v[i] * z[i]);
    double suu = fsum_result(&suu_s), svv = fsum_result(&svv_s), suv = fsum_result(&suv_s);
    double suz = fsum_result(&suz_s), svz = fsum_result(&svz_s);
    if (!(suu_s.ok && svv_s.ok && suv_s.ok && suz_s.ok && svz_s.ok)) return -1;
    double det = suu * svv - suv * suv;
    if (!(det > 1e-12 * (suu + svv) * (suu + svv))) {
        out[0] = mx;
        out[1] = my;
        out[2] = INFINITY;
        out[3] = INFINITY;
        return 0;
    }
    double a = (suz * svv - svz * suv) / (2.0 * det);
    double b = (svz * suu - suz * suv) / (2.0 * det);
    FSum zs;
    fsum_init(&zs);
    for (Py_ssize_t i = 0; i < n; i++) fsum_add(&zs, z[i]);
    double zmean = fsum_result(&zs) / nf;
    if (!zs.ok) return -1;
    double r2 = a * a + b * b + zmean;
    if (!(r2 >= 0.0)) return -1;  /* Python's math.sqrt would raise (never for real points) */
    double r = sqrt(r2);
    FSum es;
    fsum_init(&es);
    for (Py_ssize_t i = 0; i < n; i++) {
        double du = u[i] - a, dv = v[i] - b;
        double e = sqrt(du * du + dv * dv) - r;
        fsum_add(&es, e * e);
    }
    double rms2 = fsum_result(&es) / nf;
    if (!es.ok || !(rms2 >= 0.0)) return -1;
    out[0] = mx + a;
    out[1] = my + b;
    out[2] = r;
    out[3] = sqrt(rms2);
    return 0;
}

static int get(PyObject *obj, Py_buffer *view, int writable, char format, Py_ssize_t itemsize, Py_ssize_t width,
               Py_ssize_t *rows, const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    const char *fmt = view->format ? view->format : "B";
    int fmt_ok = strlen(fmt) == 1 && (fmt[0] == format || (format == 'q' && fmt[0] == 'l'));
    if (view->itemsize != itemsize || !fmt_ok || view->len % (itemsize * width) != 0) {
        PyErr_Format(PyExc_ValueError, "discs: %s has the wrong type or shape", what);
        PyBuffer_Release(view);
        return -1;
    }
    *rows = view->len / (itemsize * width);
    return 0;
}

/* discs(xy (N, 2), ranges (N,), returned (N,) bool, gap_cm, min_points, max_extent_cm, max_radius_cm,
 *       max_fit_rms_cm, beams_out (N,) int64)
 * -> None (the Python form must run), or (count, [(start, end, cx, cy, radius, nearest_range), ...]): the
 * clusters' beams in beams_out[:count] (tracking._clusters' order), and per disc-shaped cluster candidate its
 * slice of them, its fitted centre and radius and its nearest range (cm). */
static PyObject *discs(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objs[4];
    double gap, max_extent, max_radius, max_rms;
    Py_ssize_t min_points;
    if (!PyArg_ParseTuple(args, "OOOdndddO", &objs[0], &objs[1], &objs[2], &gap, &min_points, &max_extent,
                          &max_radius, &max_rms, &objs[3]))
        return NULL;
    Py_buffer v[4];
    Py_ssize_t rows[4];
    static const char formats[4] = {'d', 'd', '?', 'q'};
    static const Py_ssize_t sizes[4] = {8, 8, 1, 8}, widths[4] = {2, 1, 1, 1};
    static const char *what[4] = {"xy", "ranges", "returned", "beams_out"};
    int got = 0;
    PyObject *result = NULL, *found = NULL;
    int64_t *starts = NULL;
    double *work = NULL;
    for (; got < 4; got++)
        if (get(objs[got], &v[got], got == 3, formats[got], sizes[got], widths[got], &rows[got], what[got]) < 0)
            goto done;
    Py_ssize_t n = rows[0];
    if (rows[1] != n || rows[2] != n || rows[3] != n) {
        PyErr_SetString(PyExc_ValueError, "discs: one row per beam in every array");
        goto done;
    }
    const double *xy = v[0].buf, *ranges = v[1].buf;
    const unsigned char *ret = v[2].buf;
    int64_t *beams = v[3].buf;
    for (Py_ssize_t i = 0; i < 2 * n; i++)
        if (!isfinite(xy[i])) {
            result = Py_None;  /* the Python form decides what a non-finite point means */
            Py_INCREF(result);
            goto done;
        }
    found = PyList_New(0);
    if (found == NULL) goto done;
    Py_ssize_t count = 0, n_clusters = 0;
    starts = PyMem_Malloc((size_t)(n + 1) * sizeof(int64_t));
    work = PyMem_Malloc((size_t)(3 * n + 2 * n + 1) * sizeof(double));
    if (starts == NULL || work == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    int any = 0;
    for (Py_ssize_t i = 0; i < n; i++) any |= ret[i] != 0;
    if (n > 0 && any) {
        /* linked[i]: beam i and the next (wrapping) both returned and at most gap apart */
        unsigned char *linked = (unsigned char *)(work + 3 * n);  /* n bytes inside the spare 2n doubles */
        int all_linked = 1;
        for (Py_ssize_t i = 0; i < n; i++) {
            Py_ssize_t j = i + 1 < n ? i + 1 : 0;
            double dx = xy[2 * j] - xy[2 * i], dy = xy[2 * j + 1] - xy[2 * i + 1];
            linked[i] = ret[i] && ret[j] && sqrt(dx * dx + dy * dy) <= gap;
            all_linked &= linked[i];
        }
        if (all_linked) {
            for (Py_ssize_t i = 0; i < n; i++) beams[i] = i;
            count = n;
            starts[0] = 0;
            n_clusters = 1;
        } else {
            /* a cluster starts at each returned beam not linked from its predecessor; the returned beams from
             * the first start on, wrapping around */
            Py_ssize_t first = -1;
            for (Py_ssize_t i = 0; i < n && first < 0; i++)
                if (ret[i] && !linked[i > 0 ? i - 1 : n - 1]) first = i;
            if (first < 0) first = 0;  /* numpy's argmax of an all-false mask (cannot happen: see above) */
            for (Py_ssize_t k = 0; k < n; k++) {
                Py_ssize_t i = (first + k) % n;
                if (!ret[i]) continue;
                if (!linked[i > 0 ? i - 1 : n - 1]) starts[n_clusters++] = count;
                beams[count++] = i;
            }
            if (n_clusters == 0 || starts[0] != 0) {  /* the first listed beam always starts one */
                memmove(starts + 1, starts, (size_t)n_clusters * sizeof(int64_t));
                starts[0] = 0;
                n_clusters++;
            }
        }
    }
    starts[n_clusters] = count;
    /* per cluster: its points in work[0, 2m), Kasa's u, v, z in work[2n, 2n + 3m) (the links are not needed
     * any more) */
    double *pts = work;
    for (Py_ssize_t c = 0; c < n_clusters; c++) {
        Py_ssize_t i0 = (Py_ssize_t)starts[c], i1 = (Py_ssize_t)starts[c + 1], m = i1 - i0;
        double xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY, nearest = INFINITY;
        for (Py_ssize_t k = i0; k < i1; k++) {
            const double *p = xy + 2 * beams[k];
            if (p[0] < xmin) xmin = p[0];
            if (p[0] > xmax) xmax = p[0];
            if (p[1] < ymin) ymin = p[1];
            if (p[1] > ymax) ymax = p[1];
            double r = ranges[beams[k]];
            if (r < nearest || isnan(r)) nearest = r;
        }
        double ex = xmax - xmin, ey = ymax - ymin;
        if (!(m >= min_points && sqrt(ex * ex + ey * ey) <= max_extent)) continue;
        for (Py_ssize_t k = 0; k < m; k++) {
            pts[2 * k] = xy[2 * beams[i0 + k]];
            pts[2 * k + 1] = xy[2 * beams[i0 + k] + 1];
        }
        double fit[4];
        if (fit_disc(pts, m, work + 2 * n, work + 2 * n + m, work + 2 * n + 2 * m, fit) < 0) {
            Py_CLEAR(found);
            result = Py_None;
            Py_INCREF(result);
            goto done;
        }
        if (fit[2] > max_radius || fit[3] > max_rms) continue;
        PyObject *item = Py_BuildValue("(nndddd)", i0, i1, fit[0], fit[1], fit[2], nearest);
        if (item == NULL || PyList_Append(found, item) < 0) {
            Py_XDECREF(item);
            goto done;
        }
        Py_DECREF(item);
    }
    result = Py_BuildValue("(nO)", count, found);
done:
    Py_XDECREF(found);
    PyMem_Free(starts);
    PyMem_Free(work);
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"discs", discs, METH_VARARGS,
     "discs(xy, ranges, returned, gap_cm, min_points, max_extent_cm, max_radius_cm, max_fit_rms_cm, beams_out)"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.sensing._tracking",
    "The laser tracker's clusters and disc fits in C (bit-identical to fuzzynav.sensing.tracking's Python form).", -1,
    methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__tracking(void) { return PyModule_Create(&module); }
