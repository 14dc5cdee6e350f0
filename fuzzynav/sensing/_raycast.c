/*
 * fuzzynav.sensing._raycast: the nearest hit of each laser beam in C (fuzzynav.sensing.raycast.cast_rays: `cast` whole, with the
 * culling; `nearest` its per-ray part alone).
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
#error "fuzzynav.sensing._raycast must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.sensing._raycast needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
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
        PyErr_Format(PyExc_ValueError, "raycast: %s must be a C-contiguous %s array with rows of %zd", what,
                     formats[0] == 'd' ? "float64" : "int64", width);
        PyBuffer_Release(view);
        return -1;
    }
    *rows = view->len / (8 * width);
    return 0;
}

/* the per-object values of the numpy path's (M,) and (C,) arrays: per segment ax, ay, ex, ey and
 * ax * ey - ay * ex; per circle cx, cy and cx * cx + cy * cy - r * r (positions relative to the origin) */
static void prepare_segment(const double *s, double ox, double oy, double *p) {
    double ax = s[0] - ox, ay = s[1] - oy, ex = s[2] - s[0], ey = s[3] - s[1];
    p[0] = ax;
    p[1] = ay;
    p[2] = ex;
    p[3] = ey;
    p[4] = ax * ey - ay * ex;
}

static void prepare_circle(const double *q, double ox, double oy, double *p) {
    double cx = q[0] - ox, cy = q[1] - oy, r2 = q[2] * q[2];
    p[0] = cx;
    p[1] = cy;
    p[2] = cx * cx + cy * cy - r2;
}

/* each ray's first nearest segment, then circle, strictly nearer than best[i]: best and hit updated */
static void nearest_core(const double *d, Py_ssize_t n, const double *seg_pre, const int64_t *seg_ids, Py_ssize_t m,
                         const double *circ_pre, const int64_t *circ_ids, Py_ssize_t c, double *best, int64_t *hit) {
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
    for (Py_ssize_t k = 0; k < m; k++) prepare_segment(seg + 4 * k, ox, oy, seg_pre + 5 * k);
    for (Py_ssize_t k = 0; k < c; k++) prepare_circle(circ + 3 * k, ox, oy, circ_pre + 3 * k);
    nearest_core(d, n, seg_pre, seg_ids, m, circ_pre, circ_ids, c, best, hit);
    result = Py_None;
    Py_INCREF(result);
done:
    PyMem_Free(seg_pre);
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

/* cast(ox, oy, max_range, reach, directions (N, 2), segments (M, 4), circles (C, 3), best (N,) out, hit (N,) out)
 * fuzzynav.sensing.raycast.cast_rays whole: best = max_range and hit = -1, the segments and circles within `reach` of the
 * origin kept (the numpy path's culling, with its formulas: the distance from the origin to a segment as
 * fuzzynav.numerics.geometry.segment_point_distance computes it, and |centre - origin| - r for a circle; NaN is dropped),
 * then nearest_core with their indices (segments 0..M-1, circles M..M+C-1). */
/* cast_rays whole: best = max_range and hit = -1, then the kept objects' nearest hits; -1 (MemoryError set) when
 * the work arrays cannot be allocated */
static int cast_core(double ox, double oy, double max_range, double reach, const double *d, Py_ssize_t n,
                     const double *seg, Py_ssize_t m, const double *circ, Py_ssize_t c, double *best, int64_t *hit) {
    for (Py_ssize_t i = 0; i < n; i++) {
        best[i] = max_range;
        hit[i] = -1;
    }
    /* the kept objects' values and their indices (stored after the doubles: one allocation) */
    double *pre = PyMem_Malloc((size_t)(5 * m + 3 * c + 1) * sizeof(double) + (size_t)(m + c + 1) * sizeof(int64_t));
    if (pre == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    int64_t *ids = (int64_t *)(pre + 5 * m + 3 * c + 1);
    Py_ssize_t kept_m = 0, kept_c = 0;
    for (Py_ssize_t k = 0; k < m; k++) {
        /* segment_point_distance(a, b, origin) = closest_approach(a - o, b - a): s = clip(-(r . e) / dd, 0, 1)
         * with dd = e . e (1 when 0), then |r + s e| */
        const double *q = seg + 4 * k;
        double rx = q[0] - ox, ry = q[1] - oy, ex = q[2] - q[0], ey = q[3] - q[1];
        double dd = ex * ex + ey * ey;
        double f = -(rx * ex + ry * ey) / (dd > 0 ? dd : 1.0);
        f = isnan(f) ? f : (f > 0.0 ? f : 0.0);
        f = isnan(f) ? f : (f < 1.0 ? f : 1.0);
        double gx = rx + f * ex, gy = ry + f * ey;
        if (!(sqrt(gx * gx + gy * gy) <= reach)) continue;
        prepare_segment(q, ox, oy, pre + 5 * kept_m);
        ids[kept_m++] = k;
    }
    double *circ_pre = pre + 5 * kept_m;
    int64_t *circ_ids = ids + kept_m;
    for (Py_ssize_t k = 0; k < c; k++) {
        const double *q = circ + 3 * k;
        double cx = q[0] - ox, cy = q[1] - oy;
        if (!(sqrt(cx * cx + cy * cy) - q[2] <= reach)) continue;
        prepare_circle(q, ox, oy, circ_pre + 3 * kept_c);
        circ_ids[kept_c++] = m + k;
    }
    nearest_core(d, n, pre, ids, kept_m, circ_pre, circ_ids, kept_c, best, hit);
    PyMem_Free(pre);
    return 0;
}

/* cast(ox, oy, max_range, reach, directions (N, 2), segments (M, 4), circles (C, 3), best (N,) out, hit (N,) out)
 * fuzzynav.sensing.raycast.cast_rays whole: the segments and circles within `reach` of the origin kept (the numpy path's
 * culling, with its formulas: the distance from the origin to a segment as fuzzynav.numerics.geometry.segment_point_distance
 * computes it, and |centre - origin| - r for a circle; NaN is dropped), then nearest_core with their indices
 * (segments 0..M-1, circles M..M+C-1). */
static PyObject *cast(PyObject *self, PyObject *args) {
    (void)self;
    double ox, oy, max_range, reach;
    PyObject *objs[5];
    if (!PyArg_ParseTuple(args, "ddddOOOOO", &ox, &oy, &max_range, &reach, &objs[0], &objs[1], &objs[2], &objs[3],
                          &objs[4]))
        return NULL;
    static const char *what[5] = {"directions", "segments", "circles", "best", "hit"};
    static const char *formats[5] = {"d", "d", "d", "d", "lq"};
    static const Py_ssize_t widths[5] = {2, 4, 3, 1, 1};
    Py_buffer v[5];
    Py_ssize_t rows[5];
    int got = 0;
    PyObject *result = NULL;
    for (; got < 5; got++)
        if (get(objs[got], &v[got], got >= 3, formats[got], widths[got], &rows[got], what[got]) < 0) goto done;
    if (rows[3] != rows[0] || rows[4] != rows[0]) {
        PyErr_SetString(PyExc_ValueError, "cast: best and hit must match the directions");
        goto done;
    }
    if (cast_core(ox, oy, max_range, reach, v[0].buf, rows[0], v[1].buf, rows[1], v[2].buf, rows[2], v[3].buf,
                  v[4].buf) < 0)
        goto done;
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

/* laser_frame(ox, oy, sin_h, cos_h, max_range, reach, n_static, clip_hi, rel_sin (N,), rel_cos (N,),
 *             segments (M, 4), circles (C, 3), draws (N,) or None, ranges (N,) out, directions (N, 2) out,
 *             labels (N,) out, xy (N, 2) out)
 * fuzzynav.sensing.laser.scan after its sin/cos and noise draws, in its numpy operations' order: the beam directions
 * (cos_h * rel_cos - sin_h * rel_sin, sin_h * rel_cos + cos_h * rel_sin), cast_rays, with draws the noisy range
 * min(max(range + draw, 0), clip_hi) of every beam that hit something, the labels (-1 nothing, 0 static: an
 * index below n_static, k + 1 moving obstacle k) and the end points (origin + range * direction). */
static PyObject *laser_frame(PyObject *self, PyObject *args) {
    (void)self;
    double ox, oy, sin_h, cos_h, max_range, reach, clip_hi;
    Py_ssize_t n_static;
    PyObject *objs[9];
    if (!PyArg_ParseTuple(args, "ddddddndOOOOOOOOO", &ox, &oy, &sin_h, &cos_h, &max_range, &reach, &n_static,
                          &clip_hi, &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5], &objs[6], &objs[7],
                          &objs[8]))
        return NULL;
    static const char *what[9] = {"rel_sin", "rel_cos", "segments", "circles", "draws", "ranges", "directions",
                                  "labels", "xy"};
    static const char *formats[9] = {"d", "d", "d", "d", "d", "d", "d", "lq", "d"};
    static const Py_ssize_t widths[9] = {1, 1, 4, 3, 1, 1, 2, 1, 2};
    Py_buffer v[9];
    Py_ssize_t rows[9];
    int got = 0, have[9] = {0};
    PyObject *result = NULL;
    for (; got < 9; got++) {
        if (got == 4 && objs[got] == Py_None) {
            rows[got] = -1;
            continue;
        }
        if (get(objs[got], &v[got], got >= 5, formats[got], widths[got], &rows[got], what[got]) < 0) goto done;
        have[got] = 1;
    }
    Py_ssize_t n = rows[0];
    if (rows[1] != n || (have[4] && rows[4] != n) || rows[5] != n || rows[6] != n || rows[7] != n || rows[8] != n) {
        PyErr_SetString(PyExc_ValueError, "laser_frame: every per-beam array must have the beams' length");
        goto done;
    }
    const double *rel_sin = v[0].buf, *rel_cos = v[1].buf;
    double *ranges = v[5].buf, *d = v[6].buf, *xy = v[8].buf;
    int64_t *labels = v[7].buf;
    for (Py_ssize_t i = 0; i < n; i++) {
        d[2 * i] = cos_h * rel_cos[i] - sin_h * rel_sin[i];
        d[2 * i + 1] = sin_h * rel_cos[i] + cos_h * rel_sin[i];
    }
    if (cast_core(ox, oy, max_range, reach, d, n, v[2].buf, rows[2], v[3].buf, rows[3], ranges, labels) < 0)
        goto done;
    if (have[4]) {
        /* numpy's clip: max, then min, each keeping its first operand only when strictly beyond (the sums are
         * finite here) */
        const double *draws = v[4].buf;
        for (Py_ssize_t i = 0; i < n; i++) {
            if (labels[i] < 0) continue;
            double r = ranges[i] + draws[i];
            r = r > 0.0 ? r : 0.0;
            ranges[i] = r < clip_hi ? r : clip_hi;
        }
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t h = labels[i];
        labels[i] = h < 0 ? -1 : (h < n_static ? 0 : h - n_static + 1);
        xy[2 * i] = ox + ranges[i] * d[2 * i];
        xy[2 * i + 1] = oy + ranges[i] * d[2 * i + 1];
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++)
        if (have[i]) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"nearest", nearest, METH_VARARGS,
     "nearest(ox, oy, directions, segments, segment_ids, circles, circle_ids, best, hit): each ray's first "
     "nearest hit, in place"},
    {"cast", cast, METH_VARARGS,
     "cast(ox, oy, max_range, reach, directions, segments, circles, best, hit): cast_rays whole (culling "
     "included), into best and hit"},
    {"laser_frame", laser_frame, METH_VARARGS,
     "laser_frame(ox, oy, sin_h, cos_h, max_range, reach, n_static, clip_hi, rel_sin, rel_cos, segments, circles, "
     "draws, ranges, directions, labels, xy): fuzzynav.sensing.laser.scan's frame, into the four output arrays"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.sensing._raycast",
    "Each laser beam's nearest hit in C (bit-identical to fuzzynav.sensing.raycast's numpy path).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__raycast(void) { return PyModule_Create(&module); }
