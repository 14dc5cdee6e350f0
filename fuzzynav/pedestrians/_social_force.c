/*
 * fuzzynav.pedestrians._social_force: the force on every pedestrian of a social-force group for one substep, in C
 * (fuzzynav.pedestrians.social_force._substep_force_numpy's numpy code: the driving force, the field-of-view-weighted
 * repulsions of agent_repulsion, the walls' and circles' repulsions of wall_repulsion / away_from_static).
 *
 * The numpy path computes every (pedestrian x other) and (pedestrian x static item) term with elementwise
 * IEEE operations (+ - * / and sqrt, each correctly rounded on every CPU), exp with portable_math.exp_array's
 * polynomial, and sums the terms strictly left to right (sequential_sum). This file performs those
 * operations in the same order, one rounding each, without the (n x m) arrays, so its forces are the numpy
 * path's bits (tests/test_social_force_kernel.py). Built with -ffp-contract=off (no fused multiply-adds);
 * refuses -ffast-math and x87 arithmetic. No libm transcendental is called: only sqrt (correctly rounded)
 * and, for exp's extreme arguments, ldexp (exact, or correctly rounded for a subnormal result). Units: cm, cm/s, cm/s², s.
 *
 * numpy semantics mirrored (measured with numpy 2.4 on x86-64; the cases are listed where they are used):
 * - np.maximum(a, b) returns b when a == b (np.maximum(-0.0, 0.0) is 0.0, np.maximum(0.0, -0.0) is -0.0)
 *   and a NaN operand (a first): (a > b || a != a) ? a : b;
 * - np.clip(a, lo, hi) keeps a when it equals a bound (np.clip(-0.0, 0.0, 1.0) is -0.0) and keeps a NaN a:
 *   a < lo ? lo : (a > hi ? hi : a);
 * - np.where(cond, p, q) picks without arithmetic, a comparison with NaN is false (so the same branches);
 * - np.add.accumulate(a)[-1] starts from a[0], not from 0.0 (0.0 + -0.0 would lose a sign);
 * - np.rint is nearbyint (ties to even in the default rounding mode), np.ldexp is C ldexp.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fuzzynav.pedestrians._social_force must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.pedestrians._social_force needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* fuzzynav.pedestrians.social_force.B_FLOOR_CM: the floor of b in the gradient's 1/b */
#define B_FLOOR_CM 1.0

/* portable_math's constants, bit for bit (tests compare this exp with exp_array): _INV_LN2 = 1 / math.log(2)
 * (only chooses k), fdlibm's ln 2 split (_LN2_HI, _LN2_LO), and _EXP's Taylor coefficients 1/n!, n = 0..16,
 * each correctly rounded */
static const double INV_LN2 = 0x1.71547652b82fep+0;
static const double LN2_HI = 0x1.62e42fee00000p-1;
static const double LN2_LO = 0x1.a39ef35793c76p-33;
#define N_EXP 17
static const double EXP_C[N_EXP] = {
    0x1.0000000000000p+0,  0x1.0000000000000p+0,  0x1.0000000000000p-1,  0x1.5555555555555p-3,
    0x1.5555555555555p-5,  0x1.1111111111111p-7,  0x1.6c16c16c16c17p-10, 0x1.a01a01a01a01ap-13,
    0x1.a01a01a01a01ap-16, 0x1.71de3a556c734p-19, 0x1.27e4fb7789f5cp-22, 0x1.ae64567f544e4p-26,
    0x1.1eed8eff8d898p-29, 0x1.6124613a86d09p-33, 0x1.93974a8c07c9dp-37, 0x1.ae7f3e733b81fp-41,
    0x1.ae7f3e733b81fp-45,
};

/* np.nan's bits (a positive quiet NaN): what exp_array's np.where(np.isnan(x), np.nan, ...) returns */
static double positive_nan(void) {
    uint64_t bits = UINT64_C(0x7ff8000000000000);
    double d;
    memcpy(&d, &bits, sizeof d);
    return d;
}

/* np.maximum(a, b) (see the header) */
static inline double np_maximum(double a, double b) { return (a > b || a != a) ? a : b; }

/* np.clip(a, lo, hi) (see the header) */
static inline double np_clip(double a, double lo, double hi) { return a < lo ? lo : (a > hi ? hi : a); }

/* np.rint(t) (= nearbyint) for |t| < 2**51, without a library call: adding and subtracting 1.5 * 2**52 rounds
 * to an integer in the default rounding mode (ties to even), exactly; copysign restores rint's sign of a zero
 * result (rint(-0.3) is -0.0) */
static inline double rint_small(double t) {
    const double shift = 0x1.8p52;
    double k = (t + shift) - shift;
    return copysign(k, t);
}

/* ldexp(a, k) without a library call where it is one exact multiplication: for -1022 <= k <= 1023, 2**k is a
 * normal double and a * 2**k is the exact product rounded once, which is what ldexp returns (also when the
 * result is subnormal or overflows); other k go to ldexp */
static inline double ldexp_fast(double a, int k) {
    if (k < -1022 || k > 1023) return ldexp(a, k);
    uint64_t bits = (uint64_t)(k + 1023) << 52;
    double p;
    memcpy(&p, &bits, sizeof p);
    return a * p;
}

/* portable_math.exp_array on one value: k = clip(rint(x / ln 2)), r = (x - k ln2_hi) - k ln2_lo,
 * ldexp(horner(r), k); 0 below -746, inf above 710, np.nan for NaN (the np.where chain, whose conditions
 * exclude each other, so the polynomial is only needed when none holds; there |x / ln 2| < 1077) */
static double exp_portable(double x) {
    if (x != x) return positive_nan();
    if (x < -746.0) return 0.0;
    if (x > 710.0) return INFINITY;
    double k = np_clip(rint_small(x * INV_LN2), -1100.0, 1100.0);
    double r = (x - k * LN2_HI) - k * LN2_LO;
    double acc = EXP_C[N_EXP - 1]; /* _horner: acc = c[-1], then acc * z + c for the others, last to first */
    for (int i = N_EXP - 2; i >= 0; i--) acc = acc * r + EXP_C[i];
    return ldexp_fast(acc, (int)k); /* k.astype(np.int32): k is an integer in [-1100, 1100] */
}

/* a C-contiguous float64 buffer whose length is a multiple of `width` items; its row count in *rows */
static int get(PyObject *obj, Py_buffer *view, int writable, Py_ssize_t width, Py_ssize_t *rows, const char *fn,
               const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    const char *fmt = view->format ? view->format : "B";
    if (view->itemsize != 8 || strcmp(fmt, "d") != 0 || view->len % (8 * width) != 0) {
        PyErr_Format(PyExc_ValueError, "%s: %s must be a C-contiguous float64 array with rows of %zd", fn, what,
                     width);
        PyBuffer_Release(view);
        return -1;
    }
    *rows = view->len / (8 * width);
    return 0;
}

/* exp_many's common case: k = rint(x / ln 2) is in [-1021, 1023], so that ldexp is one multiplication */
static inline int exp_common(double x) { return x >= -708.0 && x <= 709.0; }

/* exp_portable over x[0..n) into out: the common case in a loop without branches or library calls (short
 * iterations that the CPU overlaps), then the others one by one */
static void exp_many(const double *x, double *out, Py_ssize_t n) {
    for (Py_ssize_t i = 0; i < n; i++) {
        double xi = x[i];
        double xa = exp_common(xi) ? xi : 0.0;
        double k = rint_small(xa * INV_LN2); /* in [-1021, 1023]: np.clip to +-1100 changes nothing */
        double r = (xa - k * LN2_HI) - k * LN2_LO;
        double acc = EXP_C[N_EXP - 1];
        for (int c = N_EXP - 2; c >= 0; c--) acc = acc * r + EXP_C[c];
        int64_t ki = (int64_t)k;
        uint64_t bits = (uint64_t)(ki + 1023) << 52;
        double p;
        memcpy(&p, &bits, sizeof p);
        out[i] = acc * p;
    }
    for (Py_ssize_t i = 0; i < n; i++)
        if (!exp_common(x[i])) out[i] = exp_portable(x[i]);
}

/* forces(x (n, 2), v (n, 2), pref (n, 2), o_pos0 (k, 2), o_vel (k, 2), tau, radii (n,), segments (M, 4),
 *        circles (C, 3), relaxation_s, agent_strength, agent_range, step_time, wall_strength, wall_range,
 *        cos_fov, fov_weight, desired, out (n, 2))
 * The others at this substep are the group (x, v), then the other obstacles at o_pos0 + o_vel * tau moving at
 * o_vel (m = n + k of them). Each other's step ahead is its velocity times step_time; with `desired` (the
 * step_ahead reading desired_direction) a group member with a preferred velocity steps at its speed along that
 * velocity's direction instead. out = (pref - v) / relaxation_s + Σ_j (FOV-weighted pair force of other j)
 * + Σ_k (force of static item k), each sum left to right (j in that order; k over the segments, then the
 * circles). An empty sum adds nothing (as _substep_force_numpy). */
static PyObject *forces(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objs[9];
    double tau, relaxation_s, agent_strength, agent_range, step_time, wall_strength, wall_range, cos_fov,
        fov_weight;
    int desired;
    if (!PyArg_ParseTuple(args, "OOOOOdOOOddddddddpO", &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &tau,
                          &objs[5], &objs[6], &objs[7], &relaxation_s, &agent_strength, &agent_range, &step_time,
                          &wall_strength, &wall_range, &cos_fov, &fov_weight, &desired, &objs[8]))
        return NULL;
    static const char *what[9] = {"x", "v", "pref", "o_pos0", "o_vel", "radii", "segments", "circles", "out"};
    static const Py_ssize_t widths[9] = {2, 2, 2, 2, 2, 1, 4, 3, 2};
    Py_buffer b[9];
    Py_ssize_t rows[9];
    int got = 0;
    PyObject *result = NULL;
    double *pre = NULL;
    for (; got < 9; got++)
        if (get(objs[got], &b[got], got == 8, widths[got], &rows[got], "forces", what[got]) < 0) goto done;
    Py_ssize_t n = rows[0], n_other = rows[3], n_seg = rows[6], n_circ = rows[7];
    if (rows[1] != n || rows[2] != n || rows[5] != n || rows[8] != n || rows[4] != n_other) {
        PyErr_SetString(PyExc_ValueError, "forces: v, pref, radii and out must have x's rows, o_vel o_pos0's");
        goto done;
    }
    const double *x = b[0].buf, *v = b[1].buf, *pref = b[2].buf, *o_pos0 = b[3].buf, *o_vel = b[4].buf;
    const double *radii = b[5].buf, *seg = b[6].buf, *circ = b[7].buf;
    double *out = b[8].buf;
    const Py_ssize_t m = n + n_other, n_static = n_seg + n_circ;

    /* per other j (the numpy path's all_pos / all_step rows and its (1, m) arrays: the same operations, done
     * once): position, step * step_time and s = norm2(step) * step_time; per static item: segments'
     * a, edge b - a, dd = dot2(edge, edge) and left normal / where(edge_len > 0, edge_len, 1); circles' centre
     * and radius. Then per pedestrian, scratch rows of m + n_static terms. */
    const Py_ssize_t n_pre = 5 * m + 7 * n_static + 5 * (m + n_static) + 1;
    pre = PyMem_Malloc((size_t)n_pre * sizeof(double));
    if (pre == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    double *opx = pre, *opy = opx + m, *ovx = opy + m, *ovy = ovx + m, *os = ovy + m;
    double *sa = os + m, *sb = sa + n_static, *sex = sb + n_static, *sey = sex + n_static, *sdd = sey + n_static,
           *snx = sdd + n_static, *sny = snx + n_static;
    const Py_ssize_t terms = m + n_static;
    double *arg = sny + n_static, *ex_ = arg + terms, *dirx = ex_ + terms, *diry = dirx + terms,
           *gate = diry + terms;
    for (Py_ssize_t j = 0; j < m; j++) {
        double px, py, vx, vy;
        if (j < n) {
            px = x[2 * j];
            py = x[2 * j + 1];
            vx = v[2 * j];
            vy = v[2 * j + 1];
            if (desired) {
                /* step = where(speed > 0, e * norm2(v), v), speed = norm2(pref), e = pref / speed (a NaN
                 * speed fails the comparison, as in numpy) */
                const double prx = pref[2 * j], pry = pref[2 * j + 1];
                const double speed = sqrt(prx * prx + pry * pry);
                if (speed > 0.0) {
                    const double e_x = prx / speed, e_y = pry / speed;
                    const double speed_v = sqrt(vx * vx + vy * vy);
                    vx = e_x * speed_v;
                    vy = e_y * speed_v;
                }
            }
        } else {
            const Py_ssize_t o = j - n;
            vx = o_vel[2 * o];
            vy = o_vel[2 * o + 1];
            px = o_pos0[2 * o] + vx * tau; /* o_pos0 + o_vel * tau */
            py = o_pos0[2 * o + 1] + vy * tau;
        }
        opx[j] = px;
        opy[j] = py;
        ovx[j] = vx * step_time; /* other_vel * step_time (other_vel: all_step's row) */
        ovy[j] = vy * step_time;
        os[j] = sqrt(vx * vx + vy * vy) * step_time; /* norm2(other_vel) * step_time */
    }
    for (Py_ssize_t k = 0; k < n_seg; k++) {
        const double *q = seg + 4 * k;
        double ex = q[2] - q[0], ey = q[3] - q[1];
        double edge_len = sqrt(ex * ex + ey * ey);
        double len_or_1 = edge_len > 0.0 ? edge_len : 1.0;
        sa[k] = q[0];
        sb[k] = q[1];
        sex[k] = ex;
        sey[k] = ey;
        sdd[k] = ex * ex + ey * ey;
        snx[k] = -ey / len_or_1;
        sny[k] = ex / len_or_1;
    }
    for (Py_ssize_t k = 0; k < n_circ; k++) { /* centre in sa, sb; radius in sex */
        const double *q = circ + 3 * k;
        sa[n_seg + k] = q[0];
        sb[n_seg + k] = q[1];
        sex[n_seg + k] = q[2];
    }
    /* strength / range_cm: a Python float in the numpy path, then multiplied into the arrays */
    const double agent_scale = agent_strength / agent_range, wall_scale = wall_strength / wall_range;

    for (Py_ssize_t i = 0; i < n; i++) {
        const double px = x[2 * i], py = x[2 * i + 1];
        const double prx = pref[2 * i], pry = pref[2 * i + 1];
        const double radius = radii[i];
        /* agent_repulsion(rel = x_i - all_pos_j, all_vel_j, ...) up to exp's argument: the gradient in
         * dir, where(apart1, 1.0, 0.0) in gate */
        for (Py_ssize_t j = 0; j < m; j++) {
            double rx = px - opx[j], ry = py - opy[j];
            double ax = rx - ovx[j], ay = ry - ovy[j]; /* ahead = rel - other_vel * step_time */
            double r1 = sqrt(rx * rx + ry * ry), r2 = sqrt(ax * ax + ay * ay);
            double s = os[j];
            double u = r1 + r2;
            double bb = 0.5 * sqrt(np_maximum(u * u - s * s, 0.0));
            int apart1 = r1 > 0.0, apart2 = r2 > 0.0;
            double r1_or_1 = apart1 ? r1 : 1.0, r2_or_1 = apart2 ? r2 : 1.0;
            double q1x = rx / r1_or_1, q1y = ry / r1_or_1; /* numpy divides everywhere, then picks */
            double q2x = ax / r2_or_1, q2y = ay / r2_or_1;
            double u1x = apart1 ? q1x : 0.0, u1y = apart1 ? q1y : 0.0;
            double u2x = apart2 ? q2x : 0.0, u2y = apart2 ? q2y : 0.0;
            double g = u / (4.0 * np_maximum(bb, B_FLOOR_CM));
            dirx[j] = g * (u1x + u2x);
            diry[j] = g * (u1y + u2y);
            arg[j] = -bb / agent_range;
            gate[j] = apart1 ? 1.0 : 0.0;
        }
        /* wall_repulsion: for each segment, then each circle, the gap (away_from_static) minus the radius,
         * floored at 0, and the unit vector away from it */
        for (Py_ssize_t k = 0; k < n_seg; k++) {
            /* closest_approach_fraction(a - pts, b - a): clip(-dot2(rel0, edge) / where(dd > 0, dd, 1), 0, 1);
             * -dot2 can be -0.0, which np.clip keeps */
            double rel0x = sa[k] - px, rel0y = sb[k] - py;
            double dd_or_1 = sdd[k] > 0.0 ? sdd[k] : 1.0;
            double t = np_clip(-(rel0x * sex[k] + rel0y * sey[k]) / dd_or_1, 0.0, 1.0);
            double offx = px - (sa[k] + t * sex[k]), offy = py - (sb[k] + t * sey[k]); /* pts - (a + s (b - a)) */
            double gap_seg = sqrt(offx * offx + offy * offy);
            double gap_or_1 = gap_seg > 0.0 ? gap_seg : 1.0;
            double qx = offx / gap_or_1, qy = offy / gap_or_1;
            dirx[m + k] = gap_seg > 0.0 ? qx : snx[k];
            diry[m + k] = gap_seg > 0.0 ? qy : sny[k];
            arg[m + k] = -np_maximum(gap_seg - radius, 0.0) / wall_range;
        }
        for (Py_ssize_t k = n_seg; k < n_static; k++) {
            double fcx = px - sa[k], fcy = py - sb[k]; /* from_centre = pts - centres */
            double d = sqrt(fcx * fcx + fcy * fcy);
            double d_or_1 = d > 0.0 ? d : 1.0;
            double qx = fcx / d_or_1, qy = fcy / d_or_1;
            dirx[m + k] = d > 0.0 ? qx : 1.0;
            diry[m + k] = d > 0.0 ? qy : 0.0;
            arg[m + k] = -np_maximum((d - sex[k]) - radius, 0.0) / wall_range;
        }
        exp_many(arg, ex_, terms);

        /* force = (pref - v) / c.relaxation_s */
        double fx = (prx - v[2 * i]) / relaxation_s, fy = (pry - v[2 * i + 1]) / relaxation_s;
        /* e = pref / where(speed > 0, speed, 1), speed = norm2(pref) */
        double speed = sqrt(prx * prx + pry * pry);
        double speed_or_1 = speed > 0.0 ? speed : 1.0;
        double e_x = prx / speed_or_1, e_y = pry / speed_or_1;
        double sum_x = 0.0, sum_y = 0.0;
        for (Py_ssize_t j = 0; j < m; j++) {
            /* strength / range_cm * exp_array(-b / range_cm) * where(apart1, 1.0, 0.0), left to right; the
             * product by 0.0 is kept (NaN for an infinite or NaN factor, as in numpy) */
            double mag = (agent_scale * ex_[j]) * gate[j];
            double pfx = mag * dirx[j], pfy = mag * diry[j];
            /* Eq. 7: towards = -(e_x f_x + e_y f_y); seen = towards >= norm2(f) * cos_fov */
            double towards = -(e_x * pfx + e_y * pfy);
            double w = towards >= sqrt(pfx * pfx + pfy * pfy) * cos_fov ? 1.0 : fov_weight;
            pfx = pfx * w;
            pfy = pfy * w;
            if (j == 0) { /* sequential_sum starts from the first term */
                sum_x = pfx;
                sum_y = pfy;
            } else {
                sum_x = sum_x + pfx;
                sum_y = sum_y + pfy;
            }
        }
        if (m > 0) {
            fx = fx + sum_x;
            fy = fy + sum_y;
        }
        for (Py_ssize_t k = m; k < terms; k++) {
            double mag = wall_scale * ex_[k]; /* strength / range_cm * exp_array(-gap / range_cm) */
            double wx = mag * dirx[k], wy = mag * diry[k];
            if (k == m) {
                sum_x = wx;
                sum_y = wy;
            } else {
                sum_x = sum_x + wx;
                sum_y = sum_y + wy;
            }
        }
        if (n_static > 0) {
            fx = fx + sum_x;
            fy = fy + sum_y;
        }
        out[2 * i] = fx;
        out[2 * i + 1] = fy;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    PyMem_Free(pre);
    for (int k = 0; k < got; k++) PyBuffer_Release(&b[k]);
    return result;
}

/* exp(x (N,), out (N,)): portable_math.exp_array elementwise, by forces' exp_many (for the tests) */
static PyObject *exp_(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *objs[2];
    if (!PyArg_ParseTuple(args, "OO", &objs[0], &objs[1])) return NULL;
    Py_buffer b[2];
    Py_ssize_t rows[2];
    if (get(objs[0], &b[0], 0, 1, &rows[0], "exp", "x") < 0) return NULL;
    if (get(objs[1], &b[1], 1, 1, &rows[1], "exp", "out") < 0) {
        PyBuffer_Release(&b[0]);
        return NULL;
    }
    PyObject *result = NULL;
    if (rows[0] != rows[1]) {
        PyErr_SetString(PyExc_ValueError, "exp: out must have x's length");
    } else {
        const double *x = b[0].buf;
        double *out = b[1].buf;
        exp_many(x, out, rows[0]);
        result = Py_None;
        Py_INCREF(result);
    }
    PyBuffer_Release(&b[0]);
    PyBuffer_Release(&b[1]);
    return result;
}

static PyMethodDef methods[] = {
    {"forces", forces, METH_VARARGS,
     "forces(x, v, pref, o_pos0, o_vel, tau, radii, segments, circles, relaxation_s, agent_strength, agent_range, "
     "step_time, wall_strength, wall_range, cos_fov, fov_weight, desired, out): each pedestrian's force (cm/s²) "
     "for one substep, into out (desired: the step_ahead reading desired_direction)"},
    {"exp", exp_, METH_VARARGS, "exp(x, out): portable_math.exp_array(x) into out"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.pedestrians._social_force",
    "The social-force pedestrians' forces in C (bit-identical to fuzzynav.pedestrians.social_force's numpy path).", -1,
    methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__social_force(void) { return PyModule_Create(&module); }
