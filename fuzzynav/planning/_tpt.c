/*
 * fuzzynav.planning._tpt: fuzzynav.planning.tpt.build_tpt's tables (the robot's predicted rows, the obstacles' rows and the collision
 * marks) in one pass.
 *
 * Each number is its numpy form's (tpt._tables_numpy), operation for operation in the same order (IEEE basic
 * operations and sqrt, each correctly rounded; the swept marks by _closest_approach.h's pair formula, which is
 * geometry.closest_approach's), so the tables are the same bits (tests/test_tpt_kernel.py compares them). The
 * table is built every step by every TPT navigator: as ~40 small numpy calls it cost ~30-40 us, here ~2 us. No
 * floating-point warnings (numpy's errstate does not apply). Built with -ffp-contract=off (no fused
 * multiply-adds); refuses -ffast-math and x87 arithmetic. Units: cm, s, cm/s.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#include "_closest_approach.h"

#if defined(__FAST_MATH__)
#error "fuzzynav.planning._tpt must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.planning._tpt needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* a C-contiguous buffer of float64 ("d") or, with boolean, of numpy bools ("?"); its item count in *n */
static int get(PyObject *obj, Py_buffer *view, int writable, int boolean, Py_ssize_t *n, const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    const char *format = boolean ? "?" : "d";
    if (view->itemsize != (boolean ? 1 : 8) || view->format == NULL || strcmp(view->format, format) != 0) {
        PyErr_Format(PyExc_ValueError, "tables: %s must be a C-contiguous %s array", what,
                     boolean ? "bool" : "float64");
        PyBuffer_Release(view);
        return -1;
    }
    *n = view->len / view->itemsize;
    return 0;
}

/* tables(px, py, gx, gy, speed, dt, robot_radius, safety_margin, swept, pos0 (J, 2), vel (J, 2), radii (J,),
 *        robot (n+1, 2), obstacles (n+1, J, 2), collide (n+1, J)): the last three are filled */
static PyObject *tables(PyObject *self, PyObject *args) {
    (void)self;
    double px, py, gx, gy, speed, dt, robot_radius, margin;
    int swept;
    PyObject *objs[6];
    if (!PyArg_ParseTuple(args, "ddddddddpOOOOOO:tables", &px, &py, &gx, &gy, &speed, &dt, &robot_radius, &margin,
                          &swept, &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5]))
        return NULL;
    static const char *what[6] = {"pos0", "vel", "radii", "robot", "obstacles", "collide"};
    Py_buffer v[6];
    Py_ssize_t len[6];
    int got = 0;
    PyObject *result = NULL;
    for (; got < 6; got++)
        if (get(objs[got], &v[got], got >= 3, got == 5, &len[got], what[got]) < 0) goto done;
    Py_ssize_t j_count = len[2], rows = len[3] / 2;
    if (rows < 2 || len[3] != 2 * rows || len[0] != 2 * j_count || len[1] != 2 * j_count ||
        len[4] != 2 * rows * j_count || len[5] != rows * j_count) {
        PyErr_SetString(PyExc_ValueError, "tables: pos0 and vel (J, 2), radii (J,), robot (n+1 >= 2, 2), "
                                          "obstacles (n+1, J, 2), collide (n+1, J)");
        goto done;
    }
    const double *pos0 = v[0].buf, *vel = v[1].buf, *radii = v[2].buf;
    double *robot = v[3].buf, *obstacles = v[4].buf;
    char *collide = v[5].buf;

    /* predict_robot: straight at the goal, at speed, stopping on it */
    double dx = gx - px, dy = gy - py;
    double dist = sqrt(dx * dx + dy * dy);  /* portable_math.hypot */
    double ux = dist > 0 ? dx / dist : 0.0, uy = dist > 0 ? dy / dist : 0.0;
    for (Py_ssize_t i = 0; i < rows; i++) {
        double step = (double)i * speed * dt;                             /* np.arange(n + 1) * speed * dt */
        double travel = (isnan(step) || step <= dist) ? step : dist;     /* np.minimum(steps, dist) */
        robot[2 * i] = px + travel * ux;                                  /* p + travel[:, None] * unit */
        robot[2 * i + 1] = py + travel * uy;
    }
    /* the obstacles' rows, the relative positions' lengths against the limits */
    for (Py_ssize_t i = 0; i < rows; i++) {
        double k = (double)i * dt;                                        /* np.arange(n + 1)[:, None, None] * dt */
        for (Py_ssize_t j = 0; j < j_count; j++) {
            double ox = pos0[2 * j] + vel[2 * j] * k, oy = pos0[2 * j + 1] + vel[2 * j + 1] * k;
            obstacles[2 * (i * j_count + j)] = ox;
            obstacles[2 * (i * j_count + j) + 1] = oy;
            double rx = ox - robot[2 * i], ry = oy - robot[2 * i + 1];   /* rel */
            double limit = robot_radius + radii[j] + margin;
            collide[i * j_count + j] = sqrt(rx * rx + ry * ry) < limit;  /* norm2(rel) < limit */
        }
    }
    /* swept: a pass between rows i and i+1 marks row i+1 unless row i (a predicted row) is already marked; rows
     * from the last down, so that row i is still the sampled mark when row i+1 is updated (numpy's "earlier" copy) */
    if (swept) {
        for (Py_ssize_t i = rows - 2; i >= 0; i--) {
            for (Py_ssize_t j = 0; j < j_count; j++) {
                const double *o0 = obstacles + 2 * (i * j_count + j), *o1 = obstacles + 2 * ((i + 1) * j_count + j);
                double r0x = o0[0] - robot[2 * i], r0y = o0[1] - robot[2 * i + 1];
                double r1x = o1[0] - robot[2 * (i + 1)], r1y = o1[1] - robot[2 * (i + 1) + 1];
                double limit = robot_radius + radii[j] + margin;
                int between = closest_approach_length(r0x, r0y, r1x - r0x, r1y - r0y) < limit;
                int earlier = i > 0 && collide[i * j_count + j];
                if (between && !earlier) collide[(i + 1) * j_count + j] = 1;
            }
        }
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&v[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"tables", tables, METH_VARARGS,
     "tables(px, py, gx, gy, speed, dt, robot_radius, safety_margin, swept, pos0, vel, radii, robot, obstacles, "
     "collide): build_tpt's tables, into the last three"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.planning._tpt",
    "fuzzynav.planning.tpt.build_tpt's tables in C (bit-identical to their numpy form).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__tpt(void) { return PyModule_Create(&module); }
