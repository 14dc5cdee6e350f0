/*
 * fuzzynav.pedestrians._orca: the new velocities of an `orca` pedestrian group for one substep, in C
 * (fuzzynav.pedestrians.orca.PedestrianOrcaModel._velocity for every own pedestrian, with what it calls in
 * fuzzynav.numerics.orca_lp: edge_lines (_covered, _leg_left, _leg_right, _through), static_point_line, orca_line,
 * choose_velocity, solve_lp2, _lp1, solve_lp3, _deepest, violation, _det, _dot, _unit, and
 * fuzzynav.numerics.portable_math.hypot). `substep` also computes its inputs as the substep loop of
 * PedestrianOrcaModel.step does: _neighbours (its stable argsort as an ordered selection), _edges_within_reach (its
 * numpy elementwise operations and stable argsort) and fuzzynav.numerics.geometry.away_from_static for the circles
 * with those within reach; `velocities` takes those as arrays (the tests drive it with arbitrary ones).
 *
 * The Python path computes with Python floats: IEEE doubles, one rounding per operation, left to right as written,
 * math.sqrt correctly rounded. This file performs the same operations in the same order (each Python expression
 * is transcribed with its parentheses), so its velocities are the Python path's bits
 * (tests/test_orca_kernel.py). Python's min/max/abs are written out with their tie and NaN behaviour (min(a, b) is
 * b if b < a else a; max(a, b) is b if b > a else a; max over a sequence keeps the first of equal items).
 * Where Python would raise (a division by zero: ZeroDivisionError; math.sqrt of a negative number: ValueError)
 * the pedestrian is flagged instead and the caller runs the Python path for it, which raises the same error.
 * Built with -ffp-contract=off (no fused multiply-adds); refuses -ffast-math and x87 arithmetic.
 * Units: cm, s, cm/s.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#if defined(__FAST_MATH__)
#error "fuzzynav.pedestrians._orca must not be built with -ffast-math"
#endif
#if defined(__i386__) && !defined(__SSE2_MATH__)
#error "fuzzynav.pedestrians._orca needs SSE2 doubles on 32-bit x86 (x87 excess precision would change results)"
#endif
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

/* fuzzynav.numerics.orca_lp's constants, set by set_constants() from Python (one definition: orca_lp.py's) */
static double PARALLEL = NAN, SLACK_REL = NAN, SLACK_ABS = NAN, COVERED = NAN;
static int constants_set = 0;

/* fuzzynav.policies.orca.Line: the velocities left of the line through (px, py) along the unit vector (dx, dy) */
typedef struct {
    double px, py, dx, dy;
} Line;

/* a / b; b == 0 (either sign) is where Python raises ZeroDivisionError: flagged */
static inline double divide(double a, double b, int *bad) {
    if (b == 0.0) *bad = 1;
    return a / b;
}

/* math.sqrt: a negative argument is where Python raises ValueError (NaN passes through, as in Python) */
static inline double py_sqrt(double x, int *bad) {
    if (x < 0.0) *bad = 1;
    return sqrt(x);
}

/* portable_math.hypot: sqrt(x * x + y * y) */
static inline double hypot_(double x, double y, int *bad) { return py_sqrt(x * x + y * y, bad); }

/* Python's min(a, b) and max(a, b): the first argument unless the second is strictly smaller/larger */
static inline double py_min(double a, double b) { return b < a ? b : a; }
static inline double py_max(double a, double b) { return b > a ? b : a; }

/* orca.violation: _det(direction, point - v) */
static inline double violation(const Line *l, double vx, double vy) {
    return l->dx * (l->py - vy) - l->dy * (l->px - vx);
}

/* orca.orca_line */
static void orca_line(double px, double py, double rvx, double rvy, double combined_radius, double horizon_s,
                      double dt, double responsibility, double velx, double vely, Line *out, int *bad) {
    double dist_sq = px * px + py * py;
    double r = combined_radius;
    double r_sq = r * r;
    double dx, dy, ux, uy;
    if (dist_sq > r_sq) {
        double inv_tau = divide(1.0, horizon_s, bad);
        double wx = rvx - inv_tau * px, wy = rvy - inv_tau * py;
        double w_sq = wx * wx + wy * wy;
        double w_dot_p = wx * px + wy * py;
        if (w_dot_p < 0.0 && w_dot_p * w_dot_p > r_sq * w_sq) {
            double w_len = py_sqrt(w_sq, bad);
            double nx = divide(wx, w_len, bad), ny = divide(wy, w_len, bad);
            dx = ny;
            dy = -nx;
            double shift = r * inv_tau - w_len;
            ux = shift * nx;
            uy = shift * ny;
        } else {
            double leg = py_sqrt(dist_sq - r_sq, bad);
            if (px * wy - py * wx > 0.0) {
                dx = divide(px * leg - py * r, dist_sq, bad);
                dy = divide(px * r + py * leg, dist_sq, bad);
            } else {
                /* Python: -(a) / b is (-(a)) / b */
                dx = divide(-(px * leg + py * r), dist_sq, bad);
                dy = divide(-(-px * r + py * leg), dist_sq, bad);
            }
            double along = rvx * dx + rvy * dy;
            ux = along * dx - rvx;
            uy = along * dy - rvy;
        }
    } else {
        double inv_dt = divide(1.0, dt, bad);
        double wx = rvx - inv_dt * px, wy = rvy - inv_dt * py;
        double w_len = hypot_(wx, wy, bad);
        double nx, ny;
        if (w_len == 0.0) {
            double d = py_sqrt(dist_sq, bad);
            if (d > 0.0) {
                nx = divide(-px, d, bad);
                ny = divide(-py, d, bad);
            } else {
                nx = 1.0;
                ny = 0.0;
            }
        } else {
            nx = divide(wx, w_len, bad);
            ny = divide(wy, w_len, bad);
        }
        dx = ny;
        dy = -nx;
        double shift = r * inv_dt - w_len;
        ux = shift * nx;
        uy = shift * ny;
    }
    out->px = velx + responsibility * ux;
    out->py = vely + responsibility * uy;
    out->dx = dx;
    out->dy = dy;
}

/* orca.static_point_line: 0 for None, else 1 with *out set */
static int static_point_line(double px, double py, double combined_radius, double horizon_s, double dt,
                             double velx, double vely, Line *out, int *bad) {
    if (px * px + py * py > combined_radius * combined_radius) {
        orca_line(px, py, velx, vely, combined_radius, horizon_s, dt, 1.0, velx, vely, out, bad);
        return 1;
    }
    double d = hypot_(px, py, bad);
    if (d == 0.0) return 0;
    out->px = 0.0;
    out->py = 0.0;
    out->dx = divide(-py, d, bad);
    out->dy = divide(px, d, bad);
    return 1;
}

/* The walls and static polygons as orca_lp.ObstacleVertices: points (V, 2), directions (V, 2), next and previous
 * vertex (V,), convex (V,) */
typedef struct {
    const double *pts, *dirs;
    const int64_t *next, *prev;
    const unsigned char *convex;
} Vertices;

/* orca_lp._covered */
static int covered(const Line *lines, Py_ssize_t count, double r1x, double r1y, double r2x, double r2y,
                   double inv_tau, double radius) {
    double margin = inv_tau * radius;
    double c1x = inv_tau * r1x, c1y = inv_tau * r1y;
    double c2x = inv_tau * r2x, c2y = inv_tau * r2y;
    for (Py_ssize_t j = 0; j < count; j++) {
        const Line *l = &lines[j];
        if ((c1x - l->px) * l->dy - (c1y - l->py) * l->dx - margin >= -COVERED &&
            (c2x - l->px) * l->dy - (c2y - l->py) * l->dx - margin >= -COVERED)
            return 1;
    }
    return 0;
}

/* orca_lp._leg_left (left != 0) and _leg_right */
static void leg(double rx, double ry, double dist_sq, double radius, int left, double *dx, double *dy, int *bad) {
    double leg_len = py_sqrt(py_max(dist_sq - radius * radius, 0.0), bad);
    if (left) {
        *dx = divide(rx * leg_len - ry * radius, dist_sq, bad);
        *dy = divide(rx * radius + ry * leg_len, dist_sq, bad);
    } else {
        *dx = divide(rx * leg_len + ry * radius, dist_sq, bad);
        *dy = divide(-rx * radius + ry * leg_len, dist_sq, bad);
    }
}

/* orca_lp._unit */
static inline void unit(double ax, double ay, double *ux, double *uy, int *bad) {
    double norm = hypot_(ax, ay, bad);
    *ux = divide(ax, norm, bad);
    *uy = divide(ay, norm, bad);
}

/* orca_lp._through */
static inline void through(double cx, double cy, double scale, double dx, double dy, Line *out) {
    out->px = cx + scale * -dy;
    out->py = cy + scale * dx;
    out->dx = dx;
    out->dy = dy;
}

/* orca_lp.edge_lines for the `n_edges` edges (first vertices) `edges`: the lines appended at lines[*count] on */
static void edge_lines(const Vertices *vx, const int64_t *edges, Py_ssize_t n_edges, double posx, double posy,
                       double velx, double vely, double radius, double horizon_s, Line *lines, Py_ssize_t *count,
                       int *bad) {
    double inv_tau = divide(1.0, horizon_s, bad);
    double r = radius;
    double r_sq = r * r;
    const double *pts = vx->pts, *dirs = vx->dirs;
    Py_ssize_t first = *count, n = *count;
    for (Py_ssize_t q = 0; q < n_edges; q++) {
        int64_t k1 = edges[q], k2 = vx->next[k1];
        double r1x = pts[2 * k1] - posx, r1y = pts[2 * k1 + 1] - posy;
        double r2x = pts[2 * k2] - posx, r2y = pts[2 * k2 + 1] - posy;
        if (covered(lines + first, n - first, r1x, r1y, r2x, r2y, inv_tau, r)) continue;
        double dist_sq1 = r1x * r1x + r1y * r1y;
        double dist_sq2 = r2x * r2x + r2y * r2y;
        double ex = pts[2 * k2] - pts[2 * k1], ey = pts[2 * k2 + 1] - pts[2 * k1 + 1];
        double s = divide(-(r1x * ex + r1y * ey), ex * ex + ey * ey, bad);
        double offx = -r1x - s * ex, offy = -r1y - s * ey;
        double dist_sq_line = offx * offx + offy * offy;
        Line *out = &lines[n];
        if (s < 0.0 && dist_sq1 <= r_sq) {
            if (vx->convex[k1]) {
                out->px = 0.0;
                out->py = 0.0;
                unit(-r1y, r1x, &out->dx, &out->dy, bad);
                n++;
            }
            continue;
        }
        if (s > 1.0 && dist_sq2 <= r_sq) {
            if (vx->convex[k2] && r2x * dirs[2 * k2 + 1] - r2y * dirs[2 * k2] >= 0.0) {
                out->px = 0.0;
                out->py = 0.0;
                unit(-r2y, r2x, &out->dx, &out->dy, bad);
                n++;
            }
            continue;
        }
        if (0.0 <= s && s <= 1.0 && dist_sq_line <= r_sq) {
            out->px = 0.0;
            out->py = 0.0;
            out->dx = -dirs[2 * k1];
            out->dy = -dirs[2 * k1 + 1];
            n++;
            continue;
        }
        double lx, ly, rx, ry;
        if (s < 0.0 && dist_sq_line <= r_sq) {
            if (!vx->convex[k1]) continue;
            k2 = k1;
            r2x = r1x;
            r2y = r1y;
            leg(r1x, r1y, dist_sq1, r, 1, &lx, &ly, bad);
            leg(r1x, r1y, dist_sq1, r, 0, &rx, &ry, bad);
        } else if (s > 1.0 && dist_sq_line <= r_sq) {
            if (!vx->convex[k2]) continue;
            k1 = k2;
            r1x = r2x;
            r1y = r2y;
            leg(r2x, r2y, dist_sq2, r, 1, &lx, &ly, bad);
            leg(r2x, r2y, dist_sq2, r, 0, &rx, &ry, bad);
        } else {
            if (vx->convex[k1]) {
                leg(r1x, r1y, dist_sq1, r, 1, &lx, &ly, bad);
            } else {
                lx = -dirs[2 * k1];
                ly = -dirs[2 * k1 + 1];
            }
            if (vx->convex[k2]) {
                leg(r2x, r2y, dist_sq2, r, 0, &rx, &ry, bad);
            } else {
                rx = dirs[2 * k1];
                ry = dirs[2 * k1 + 1];
            }
        }
        const double *before = dirs + 2 * vx->prev[k1];
        int left_foreign = 0, right_foreign = 0;
        if (vx->convex[k1] && lx * -before[1] - ly * -before[0] >= 0.0) {
            lx = -before[0];
            ly = -before[1];
            left_foreign = 1;
        }
        if (vx->convex[k2] && rx * dirs[2 * k2 + 1] - ry * dirs[2 * k2] <= 0.0) {
            rx = dirs[2 * k2];
            ry = dirs[2 * k2 + 1];
            right_foreign = 1;
        }
        double lcx = inv_tau * r1x, lcy = inv_tau * r1y;
        double rcx = inv_tau * r2x, rcy = inv_tau * r2y;
        double cx = rcx - lcx, cy = rcy - lcy;
        double flx = velx - lcx, fly = vely - lcy;
        double frx = velx - rcx, fry = vely - rcy;
        int one_vertex = k1 == k2;
        double t = one_vertex ? 0.5 : divide(flx * cx + fly * cy, cx * cx + cy * cy, bad);
        double t_left = flx * lx + fly * ly;
        double t_right = frx * rx + fry * ry;
        double scale = r * inv_tau;
        if ((t < 0.0 && t_left < 0.0) || (one_vertex && t_left < 0.0 && t_right < 0.0)) {
            double wx, wy;
            unit(flx, fly, &wx, &wy, bad);
            out->px = lcx + scale * wx;
            out->py = lcy + scale * wy;
            out->dx = wy;
            out->dy = -wx;
            n++;
            continue;
        }
        if (t > 1.0 && t_right < 0.0) {
            double wx, wy;
            unit(frx, fry, &wx, &wy, bad);
            out->px = rcx + scale * wx;
            out->py = rcy + scale * wy;
            out->dx = wy;
            out->dy = -wx;
            n++;
            continue;
        }
        double d_cut, d_left, d_right;
        if (t < 0.0 || t > 1.0 || one_vertex) {
            d_cut = INFINITY;
        } else {
            double ox = velx - (lcx + t * cx), oy = vely - (lcy + t * cy);
            d_cut = ox * ox + oy * oy;
        }
        if (t_left < 0.0) {
            d_left = INFINITY;
        } else {
            double ox = velx - (lcx + t_left * lx), oy = vely - (lcy + t_left * ly);
            d_left = ox * ox + oy * oy;
        }
        if (t_right < 0.0) {
            d_right = INFINITY;
        } else {
            double ox = velx - (rcx + t_right * rx), oy = vely - (rcy + t_right * ry);
            d_right = ox * ox + oy * oy;
        }
        if (d_cut <= d_left && d_cut <= d_right) {
            through(lcx, lcy, scale, -dirs[2 * k1], -dirs[2 * k1 + 1], out);
            n++;
        } else if (d_left <= d_right) {
            if (!left_foreign) {
                through(lcx, lcy, scale, lx, ly, out);
                n++;
            }
        } else if (!right_foreign) {
            through(rcx, rcy, scale, -rx, -ry, out);
            n++;
        }
    }
    *count = n;
}

/* orca._lp1: 0 for None, else 1 with the point in (*rx, *ry) */
static int lp1(const Line *lines, Py_ssize_t k, double radius, double optx, double opty, int direction_opt,
               double *rx, double *ry, int *bad) {
    const Line *line = &lines[k];
    double p0 = line->px, p1 = line->py, d0 = line->dx, d1 = line->dy;
    double along = p0 * d0 + p1 * d1;
    double disc = along * along + radius * radius - (p0 * p0 + p1 * p1);
    if (disc < 0.0) return 0;
    double root = py_sqrt(disc, bad);
    double t_left = -along - root, t_right = -along + root;
    for (Py_ssize_t i = 0; i < k; i++) {
        const Line *other = &lines[i];
        double denominator = d0 * other->dy - d1 * other->dx;
        double numerator = other->dx * (p1 - other->py) - other->dy * (p0 - other->px);
        if (fabs(denominator) <= PARALLEL) {
            if (numerator < 0.0) return 0;
            continue;
        }
        double t = divide(numerator, denominator, bad);
        if (denominator >= 0.0)
            t_right = py_min(t_right, t);
        else
            t_left = py_max(t_left, t);
        if (t_left > t_right) return 0;
    }
    double t;
    if (direction_opt)
        t = (optx * d0 + opty * d1) > 0.0 ? t_right : t_left;
    else
        t = py_min(py_max(d0 * (optx - p0) + d1 * (opty - p1), t_left), t_right);
    *rx = p0 + t * d0;
    *ry = p1 + t * d1;
    return 1;
}

/* orca.solve_lp2: the failed line's index or n; the velocity in (*rx, *ry) */
static Py_ssize_t solve_lp2(const Line *lines, Py_ssize_t n, double radius, double optx, double opty,
                            int direction_opt, double *rx, double *ry, int *bad) {
    double resx, resy;
    if (direction_opt) {
        resx = optx * radius;
        resy = opty * radius;
    } else if (optx * optx + opty * opty > radius * radius) {
        double norm = hypot_(optx, opty, bad);
        double unitx = divide(optx, norm, bad), unity = divide(opty, norm, bad);
        resx = unitx * radius;
        resy = unity * radius;
    } else {
        resx = optx;
        resy = opty;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        if (violation(&lines[i], resx, resy) > 0.0) {
            double fx, fy;
            if (!lp1(lines, i, radius, optx, opty, direction_opt, &fx, &fy, bad)) {
                *rx = resx;
                *ry = resy;
                return i;
            }
            resx = fx;
            resy = fy;
        }
    }
    *rx = resx;
    *ry = resy;
    return n;
}

/* orca.solve_lp3; `projected` has room for n lines */
static void solve_lp3(const Line *lines, Py_ssize_t n, Py_ssize_t hard, Py_ssize_t begin, double radius,
                      double startx, double starty, Line *projected, double *rx, double *ry, int *bad) {
    double resx = startx, resy = starty;
    double worst = 0.0;
    /* list(lines[:hard]): the first `hard` entries are never overwritten below */
    if (hard > 0) memcpy(projected, lines, (size_t)hard * sizeof(Line));
    for (Py_ssize_t i = begin; i < n; i++) {
        const Line *line = &lines[i];
        if (violation(line, resx, resy) <= worst) continue;
        Py_ssize_t count = hard;
        double d0 = line->dx, d1 = line->dy;
        for (Py_ssize_t j = hard; j < i; j++) {
            const Line *other = &lines[j];
            double determinant = d0 * other->dy - d1 * other->dx;
            double pointx, pointy;
            if (fabs(determinant) <= PARALLEL) {
                if (d0 * other->dx + d1 * other->dy > 0.0) continue;
                pointx = 0.5 * (line->px + other->px);
                pointy = 0.5 * (line->py + other->py);
            } else {
                double t = divide(other->dx * (line->py - other->py) - other->dy * (line->px - other->px),
                                  determinant, bad);
                pointx = line->px + t * d0;
                pointy = line->py + t * d1;
            }
            double ex = other->dx - d0, ey = other->dy - d1;
            double norm = hypot_(ex, ey, bad);
            Line *out = &projected[count++];
            out->px = pointx;
            out->py = pointy;
            out->dx = divide(ex, norm, bad);
            out->dy = divide(ey, norm, bad);
        }
        double fx, fy;
        Py_ssize_t failed = solve_lp2(projected, count, radius, -d1, d0, 1, &fx, &fy, bad);
        if (failed == count) {
            resx = fx;
            resy = fy;
        }
        worst = violation(line, resx, resy);
    }
    *rx = resx;
    *ry = resy;
}

/* orca._deepest (the first of equal maxima, as Python's max) */
static double deepest(const Line *lines, Py_ssize_t n, double vx, double vy) {
    double m = 0.0;  /* max(..., default=0.0) */
    for (Py_ssize_t i = 0; i < n; i++) {
        double x = violation(&lines[i], vx, vy);
        if (i == 0 || x > m) m = x;
    }
    return py_max(0.0, m);
}

/* orca.choose_velocity(...).velocity; `widened` and `projected` have room for n lines each */
static void choose_velocity(const Line *lines, Py_ssize_t n, Py_ssize_t hard, double radius, double prefx,
                            double prefy, Line *widened, Line *projected, double *rx, double *ry, int *bad) {
    double vx, vy;
    Py_ssize_t failed = solve_lp2(lines, n, radius, prefx, prefy, 0, &vx, &vy, bad);
    if (failed == n) {
        *rx = vx;
        *ry = vy;
        return;
    }
    double lx, ly;
    solve_lp3(lines, n, hard, failed, radius, vx, vy, projected, &lx, &ly, bad);
    double depth = deepest(lines + hard, n - hard, lx, ly);
    double slack = depth + depth * SLACK_REL + SLACK_ABS;
    for (Py_ssize_t i = 0; i < n; i++) {
        widened[i] = lines[i];
        if (i >= hard) {
            widened[i].px = lines[i].px + slack * lines[i].dy;
            widened[i].py = lines[i].py - slack * lines[i].dx;
        }
    }
    double cx, cy;
    failed = solve_lp2(widened, n, radius, prefx, prefy, 0, &cx, &cy, bad);
    if (failed == n) {
        *rx = cx;
        *ry = cy;
    } else {
        *rx = lx;
        *ry = ly;
    }
}

/* _velocity for own pedestrian i after its `hard` static lines (in lines[0..hard-1]): one line per neighbour
 * (near_i: indices into everyone; rel_i (m, 2): everyone relative to pedestrian i), the preferred velocity
 * limited to the speed disc, choose_velocity; into new_v[i] */
static void finish(Py_ssize_t i, Py_ssize_t hard, const int64_t *near_i, int64_t count_i, const double *rel_i,
                   const double *v, const double *vel, const double *radii, const double *share, const double *pref,
                   const double *max_speed, double horizon, double h, Line *lines, Line *widened, Line *projected,
                   double *new_v, int *bad) {
    double velx = v[2 * i], vely = v[2 * i + 1];
    double r = radii[i];
    Py_ssize_t count = hard;
    for (int64_t q = 0; q < count_i; q++) {
        int64_t j = near_i[q];
        const double *p = rel_i + 2 * j;
        orca_line(p[0], p[1], velx - vel[2 * j], vely - vel[2 * j + 1], r + radii[j], horizon, h, share[j], velx,
                  vely, &lines[count++], bad);
    }
    double prefx = pref[2 * i], prefy = pref[2 * i + 1], top = max_speed[i];
    double speed = hypot_(prefx, prefy, bad);
    if (speed > top) {
        /* Python: preferred[0] * max_speed / speed, left to right */
        double sx = divide(prefx * top, speed, bad), sy = divide(prefy * top, speed, bad);
        prefx = sx;
        prefy = sy;
    }
    choose_velocity(lines, count, hard, top, prefx, prefy, widened, projected, &new_v[2 * i], &new_v[2 * i + 1],
                    bad);
}

/* a C-contiguous buffer of format `format` ('d' float64, 'q' int64 (also 'l' when 8 bytes), '?' bool) with `ndim`
 * dimensions; dims[k] >= 0 must match, dims[k] < 0 is read from the buffer */
static int get(PyObject *obj, Py_buffer *view, int writable, char format, int ndim, Py_ssize_t *dims,
               const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) return -1;
    const char *fmt = view->format ? view->format : "B";
    if (fmt[0] == '=' || fmt[0] == '<' || fmt[0] == '@') fmt++;
    int ok = strlen(fmt) == 1 && view->ndim == ndim;
    if (ok && format == 'd') ok = fmt[0] == 'd' && view->itemsize == 8;
    if (ok && format == 'q') ok = (fmt[0] == 'q' || fmt[0] == 'l') && view->itemsize == 8;
    if (ok && format == '?') ok = fmt[0] == '?' && view->itemsize == 1;
    for (int k = 0; ok && k < ndim; k++) {
        if (dims[k] < 0)
            dims[k] = view->shape[k];
        else
            ok = view->shape[k] == dims[k];
    }
    if (!ok) {
        PyErr_Format(PyExc_ValueError, "orca velocities: %s must be a C-contiguous %s array of %d dimensions "
                     "matching the others", what, format == 'd' ? "float64" : (format == 'q' ? "int64" : "bool"),
                     ndim);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* get() with the expected sizes given as pointers to shared size variables (n, m, ...; NULL: the 2 of (x, y)): a
 * size still unknown (< 0) is read from this buffer and written back, so the later arrays must match it */
static int get_shaped(PyObject *obj, Py_buffer *view, int writable, char format, int ndim, Py_ssize_t *const *shape,
                      const char *what) {
    Py_ssize_t dims[3];
    for (int k = 0; k < ndim; k++) dims[k] = shape[k] != NULL ? *shape[k] : 2;
    if (get(obj, view, writable, format, ndim, dims, what) < 0) return -1;
    for (int k = 0; k < ndim; k++)
        if (shape[k] != NULL) *shape[k] = dims[k];
    return 0;
}

/* set_constants(parallel, slack_rel, slack_abs, covered): fuzzynav.numerics.orca_lp's _PARALLEL, _SLACK_REL,
 * _SLACK_ABS, _COVERED */
static PyObject *set_constants(PyObject *self, PyObject *args) {
    (void)self;
    if (!PyArg_ParseTuple(args, "dddd", &PARALLEL, &SLACK_REL, &SLACK_ABS, &COVERED)) return NULL;
    constants_set = 1;
    Py_RETURN_NONE;
}

/* the vertex arrays' indices (next, previous: (V,) int64) lie in 0..V-1; else a ValueError and -1 */
static int check_vertices(const Vertices *vx, Py_ssize_t n_vertices, const char *who) {
    for (Py_ssize_t k = 0; k < n_vertices; k++) {
        if (vx->next[k] < 0 || vx->next[k] >= n_vertices || vx->prev[k] < 0 || vx->prev[k] >= n_vertices) {
            PyErr_Format(PyExc_ValueError, "%s: a vertex's next or previous index is out of range", who);
            return -1;
        }
    }
    return 0;
}

enum {
    X, V, PREF, MAX_SPEED, REL, VEL, RADII, SHARE, PTS, DIRS, NEXT, PREV, CONVEX, EDGES, EDGE_COUNTS, GAPS, AWAY,
    CLOSE, NEAR, COUNTS, NEW_V, BAD, N_ARRAYS
};

/* velocities(time_horizon_obst_s, time_horizon_s, h, x (n, 2), v (n, 2), pref (n, 2), max_speed (n,),
 *            rel (n, m, 2), vel (m, 2), radii (m,), share (m,), points (V, 2), directions (V, 2), next (V,) int64,
 *            previous (V,) int64, convex (V,) bool, edges (n, E) int64, edge_counts (n,) int64, gaps (n, K),
 *            away (n, K, 2), close (n, K) bool, near (n, NB) int64, counts (n,) int64, new_v (n, 2) out,
 *            bad (n,) bool out) -> int
 * PedestrianOrcaModel._velocity(i, v[i], pref[i], max_speed[i], the vertices, edges[i, :edge_counts[i]], the k
 * with close[i, k], near[i, :counts[i]], ...) for every own pedestrian i into new_v[i]; bad[i] is set (and
 * new_v[i] meaningless) where the Python path raises. Returns the number of bad pedestrians. */
static PyObject *velocities(PyObject *self, PyObject *args) {
    (void)self;
    double horizon_obst, horizon, h;
    PyObject *objs[N_ARRAYS];
    if (!PyArg_ParseTuple(args, "dddOOOOOOOOOOOOOOOOOOOOOO", &horizon_obst, &horizon, &h, &objs[0], &objs[1],
                          &objs[2], &objs[3], &objs[4], &objs[5], &objs[6], &objs[7], &objs[8], &objs[9],
                          &objs[10], &objs[11], &objs[12], &objs[13], &objs[14], &objs[15], &objs[16], &objs[17],
                          &objs[18], &objs[19], &objs[20], &objs[21]))
        return NULL;
    if (!constants_set) {
        PyErr_SetString(PyExc_RuntimeError, "fuzzynav.pedestrians._orca: set_constants() was not called");
        return NULL;
    }
    static const char *what[N_ARRAYS] = {"x", "v", "pref", "max_speed", "rel", "vel", "radii", "share", "points",
                                         "directions", "next", "previous", "convex", "edges", "edge_counts", "gaps",
                                         "away", "close", "near", "counts", "new_v", "bad"};
    Py_ssize_t n = -1, m = -1, K = -1, NB = -1, NV = -1, E = -1;
    /* the shapes, in terms of n, m, K, NB, NV (vertices), E (each read from the first array that has it) */
    Py_ssize_t *shapes[N_ARRAYS][3] = {
        {&n, NULL, NULL}, {&n, NULL, NULL}, {&n, NULL, NULL}, {&n, NULL, NULL}, {&n, &m, NULL}, {&m, NULL, NULL},
        {&m, NULL, NULL}, {&m, NULL, NULL}, {&NV, NULL, NULL}, {&NV, NULL, NULL}, {&NV, NULL, NULL},
        {&NV, NULL, NULL}, {&NV, NULL, NULL}, {&n, &E, NULL}, {&n, NULL, NULL}, {&n, &K, NULL}, {&n, &K, NULL},
        {&n, &K, NULL}, {&n, &NB, NULL}, {&n, NULL, NULL}, {&n, NULL, NULL}, {&n, NULL, NULL}};
    static const int ndims[N_ARRAYS] = {2, 2, 2, 1, 3, 2, 1, 1, 2, 2, 1, 1, 1, 2, 1, 2, 3, 2, 2, 1, 2, 1};
    static const char formats[N_ARRAYS] = {'d', 'd', 'd', 'd', 'd', 'd', 'd', 'd', 'd', 'd', 'q',
                                           'q', '?', 'q', 'q', 'd', 'd', '?', 'q', 'q', 'd', '?'};
    Py_buffer b[N_ARRAYS];
    int got = 0;
    PyObject *result = NULL;
    Line *work = NULL;
    for (; got < N_ARRAYS; got++)
        if (get_shaped(objs[got], &b[got], got >= NEW_V, formats[got], ndims[got], shapes[got], what[got]) < 0)
            goto done;
    if (n > m) {
        PyErr_SetString(PyExc_ValueError, "orca velocities: the own pedestrians must be the first of everyone");
        goto done;
    }
    const double *x = b[X].buf, *v = b[V].buf, *pref = b[PREF].buf, *max_speed = b[MAX_SPEED].buf;
    const double *rel = b[REL].buf, *vel = b[VEL].buf, *radii = b[RADII].buf, *share = b[SHARE].buf;
    const double *gaps = b[GAPS].buf, *away = b[AWAY].buf;
    const Vertices vx = {b[PTS].buf, b[DIRS].buf, b[NEXT].buf, b[PREV].buf, b[CONVEX].buf};
    const int64_t *edges = b[EDGES].buf, *edge_counts = b[EDGE_COUNTS].buf;
    const unsigned char *close = b[CLOSE].buf;
    const int64_t *near = b[NEAR].buf, *counts = b[COUNTS].buf;
    double *new_v = b[NEW_V].buf;
    unsigned char *bad_out = b[BAD].buf;
    if (check_vertices(&vx, NV, "orca velocities") < 0) goto done;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (counts[i] < 0 || counts[i] > NB || edge_counts[i] < 0 || edge_counts[i] > E) {
            PyErr_SetString(PyExc_ValueError, "orca velocities: counts must be within 0..near's width and "
                                              "edge_counts within 0..edges' width");
            goto done;
        }
        for (int64_t q = 0; q < counts[i]; q++) {
            int64_t j = near[i * NB + q];
            if (j < 0 || j >= m) {
                PyErr_SetString(PyExc_ValueError, "orca velocities: a neighbour index is out of range");
                goto done;
            }
        }
        for (int64_t q = 0; q < edge_counts[i]; q++) {
            int64_t k = edges[i * E + q];
            if (k < 0 || k >= NV) {
                PyErr_SetString(PyExc_ValueError, "orca velocities: an edge index is out of range");
                goto done;
            }
        }
    }
    /* at most E + K + NB lines per pedestrian: the lines, their widened copies, solve_lp3's projected program */
    Py_ssize_t cap = E + K + NB + 1;
    work = PyMem_Malloc((size_t)(3 * cap) * sizeof(Line));
    if (work == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    Line *lines = work, *widened = work + cap, *projected = work + 2 * cap;
    Py_ssize_t n_bad = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int bad = 0;
        double velx = v[2 * i], vely = v[2 * i + 1];
        double r = radii[i];
        Py_ssize_t count = 0;
        edge_lines(&vx, edges + i * E, edge_counts[i], x[2 * i], x[2 * i + 1], velx, vely, r, horizon_obst, lines,
                   &count, &bad);
        for (Py_ssize_t k = 0; k < K; k++) {
            if (!close[i * K + k]) continue;
            /* the nearest point of the rim relative to the pedestrian: (-away * g) */
            double g = gaps[i * K + k];
            const double *a = away + 2 * (i * K + k);
            double px = -a[0] * g, py = -a[1] * g;
            if (static_point_line(px, py, r, horizon_obst, h, velx, vely, &lines[count], &bad)) count++;
        }
        finish(i, count, near + i * NB, counts[i], rel + 2 * i * m, v, vel, radii, share, pref, max_speed, horizon,
               h, lines, widened, projected, new_v, &bad);
        bad_out[i] = (unsigned char)(bad != 0);
        n_bad += bad != 0;
    }
    result = PyLong_FromSsize_t(n_bad);
done:
    PyMem_Free(work);
    for (int k = 0; k < got; k++) PyBuffer_Release(&b[k]);
    return result;
}

/* geometry.away_from_static for the point (px, py) and circle q = (x, y, radius): d - radius and the unit vector
 * from the centre (+x at the centre) */
static void away_from_circle(double px, double py, const double *q, double *gap, double *ax_, double *ay_) {
    double fx = px - q[0], fy = py - q[1];
    double d = sqrt(fx * fx + fy * fy);
    if (d > 0.0) {
        *ax_ = fx / d;
        *ay_ = fy / d;
    } else {
        *ax_ = 1.0;
        *ay_ = 0.0;
    }
    *gap = d - q[2];
}

/* PedestrianOrcaModel._edges_within_reach for the pedestrian at (px, py) with obstacle range `reach` (cm): the
 * edges' first vertices into edges[], nearest first (equal distances in vertex order: the stable argsort), their
 * squared distances into dist[]; returns how many */
static Py_ssize_t edges_within_reach(const Vertices *vx, Py_ssize_t n_vertices, double px, double py, double reach,
                                     int64_t *edges, double *dist) {
    double range_sq = reach * reach;
    Py_ssize_t count = 0;
    for (Py_ssize_t k = 0; k < n_vertices; k++) {
        const double *a = vx->pts + 2 * k, *b = vx->pts + 2 * vx->next[k];
        double ex = b[0] - a[0], ey = b[1] - a[1];
        double left = (a[0] - px) * ey - (a[1] - py) * ex;
        double fax = px - a[0], fay = py - a[1];
        double along = (fax * ex + fay * ey) / (ex * ex + ey * ey);
        double d;
        if (along < 0.0) {
            d = fax * fax + fay * fay;
        } else if (along > 1.0) {
            double fbx = px - b[0], fby = py - b[1];
            d = fbx * fbx + fby * fby;
        } else {
            double fx = px - (a[0] + along * ex), fy = py - (a[1] + along * ey);
            d = fx * fx + fy * fy;
        }
        if (!(left < 0.0 && d < range_sq)) continue;
        Py_ssize_t at = count;
        while (at > 0 && dist[at - 1] > d) {
            dist[at] = dist[at - 1];
            edges[at] = edges[at - 1];
            at--;
        }
        dist[at] = d;
        edges[at] = k;
        count++;
    }
    return count;
}

enum {
    S_X, S_POS, S_VEL, S_RADII, S_SHARE, S_V, S_PREF, S_MAX_SPEED, S_PTS, S_DIRS, S_NEXT, S_PREV, S_CONVEX, S_CIRC,
    S_NEW_V, S_BAD, S_N
};

/* substep(neighbor_dist_cm, max_neighbors, time_horizon_obst_s, time_horizon_s, h, x (n, 2), pos_all (m, 2),
 *         vel_all (m, 2), rad_all (m,), share (m,), v (n, 2), pref (n, 2), max_speed (n,), points (V, 2),
 *         directions (V, 2), next (V,) int64, previous (V,) int64, convex (V,) bool, circles (C, 3),
 *         new_v (n, 2) out, bad (n,) bool out) -> int
 * The body of PedestrianOrcaModel.step's substep loop from pos_all on: rel = pos_all - x[i]; the neighbours of
 * _neighbours (the others j != i with |rel| < neighbor_dist_cm, nearest first, equal distances in index order:
 * its stable argsort; at most max_neighbors); the edges of _edges_within_reach; geometry.away_from_static's gaps
 * and directions of the circles, those within reach (gap - r < time_horizon_obst_s * max_speed + r); _velocity.
 * bad[i] as in velocities(). */
static PyObject *substep(PyObject *self, PyObject *args) {
    (void)self;
    double neighbor_dist, horizon_obst, horizon, h;
    Py_ssize_t max_nb;
    PyObject *objs[S_N];
    if (!PyArg_ParseTuple(args, "dndddOOOOOOOOOOOOOOOO", &neighbor_dist, &max_nb, &horizon_obst, &horizon, &h,
                          &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5], &objs[6], &objs[7], &objs[8],
                          &objs[9], &objs[10], &objs[11], &objs[12], &objs[13], &objs[14], &objs[15]))
        return NULL;
    if (!constants_set) {
        PyErr_SetString(PyExc_RuntimeError, "fuzzynav.pedestrians._orca: set_constants() was not called");
        return NULL;
    }
    if (max_nb < 0) {
        PyErr_SetString(PyExc_ValueError, "orca substep: max_neighbors must be >= 0");
        return NULL;
    }
    static const char *what[S_N] = {"x", "pos_all", "vel_all", "rad_all", "share", "v", "pref", "max_speed",
                                    "points", "directions", "next", "previous", "convex", "circles", "new_v", "bad"};
    Py_ssize_t n = -1, m = -1, NV = -1, C = -1;
    Py_ssize_t three = 3;
    Py_ssize_t *shapes[S_N][2] = {{&n, NULL}, {&m, NULL},  {&m, NULL},  {&m, NULL},  {&m, NULL},  {&n, NULL},
                                  {&n, NULL}, {&n, NULL},  {&NV, NULL}, {&NV, NULL}, {&NV, NULL}, {&NV, NULL},
                                  {&NV, NULL}, {&C, &three}, {&n, NULL}, {&n, NULL}};
    static const int ndims[S_N] = {2, 2, 2, 1, 1, 2, 2, 1, 2, 2, 1, 1, 1, 2, 2, 1};
    static const char formats[S_N] = {'d', 'd', 'd', 'd', 'd', 'd', 'd', 'd', 'd', 'd', 'q', 'q', '?', 'd', 'd', '?'};
    Py_buffer b[S_N];
    int got = 0;
    PyObject *result = NULL;
    void *work = NULL;
    for (; got < S_N; got++)
        if (get_shaped(objs[got], &b[got], got >= S_NEW_V, formats[got], ndims[got], shapes[got], what[got]) < 0)
            goto done;
    if (n > m) {
        PyErr_SetString(PyExc_ValueError, "orca substep: the own pedestrians must be the first of everyone");
        goto done;
    }
    const double *x = b[S_X].buf, *pos = b[S_POS].buf, *vel = b[S_VEL].buf, *radii = b[S_RADII].buf;
    const double *share = b[S_SHARE].buf, *v = b[S_V].buf, *pref = b[S_PREF].buf, *max_speed = b[S_MAX_SPEED].buf;
    const double *circ = b[S_CIRC].buf;
    const Vertices vx = {b[S_PTS].buf, b[S_DIRS].buf, b[S_NEXT].buf, b[S_PREV].buf, b[S_CONVEX].buf};
    double *new_v = b[S_NEW_V].buf;
    unsigned char *bad_out = b[S_BAD].buf;
    if (check_vertices(&vx, NV, "orca substep") < 0) goto done;
    /* one pedestrian's lines (at most one per edge, circle and neighbour), their widened copies, solve_lp3's
     * projected program; rel (m, 2); the neighbours' and edges' indices and distances */
    Py_ssize_t nb_cap = max_nb < m ? max_nb : m;
    Py_ssize_t cap = NV + C + nb_cap + 1;
    size_t bytes = (size_t)(3 * cap) * sizeof(Line) + (size_t)(2 * m + nb_cap + 1 + NV + 1) * sizeof(double) +
                   (size_t)(nb_cap + 1 + NV + 1) * sizeof(int64_t);
    work = PyMem_Malloc(bytes);
    if (work == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    Line *lines = work, *widened = lines + cap, *projected = lines + 2 * cap;
    double *rel = (double *)(lines + 3 * cap), *near_d = rel + 2 * m, *edge_d = near_d + nb_cap + 1;
    int64_t *near = (int64_t *)(edge_d + NV + 1), *edges = near + nb_cap + 1;
    Py_ssize_t n_bad = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int bad = 0;
        double px = x[2 * i], py = x[2 * i + 1];
        /* _neighbours: d = norm2(pos_all - x[i]) (d[i, i] = inf: never within), the stable argsort's first
         * max_neighbors of those within neighbor_dist_cm (NaN sorts last and is never within) */
        int64_t count_i = 0;
        for (Py_ssize_t j = 0; j < m; j++) {
            double rx = pos[2 * j] - px, ry = pos[2 * j + 1] - py;
            rel[2 * j] = rx;
            rel[2 * j + 1] = ry;
            double d = j == i ? INFINITY : sqrt(rx * rx + ry * ry);
            if (!(d < neighbor_dist)) continue;
            /* after every kept one at most as far: equal distances stay in index order */
            Py_ssize_t at = (Py_ssize_t)count_i;
            while (at > 0 && near_d[at - 1] > d) at--;
            if (at >= nb_cap) continue;
            Py_ssize_t last = count_i < nb_cap ? (Py_ssize_t)count_i : nb_cap - 1;
            for (Py_ssize_t q = last; q > at; q--) {
                near_d[q] = near_d[q - 1];
                near[q] = near[q - 1];
            }
            near_d[at] = d;
            near[at] = j;
            if (count_i < nb_cap) count_i++;
        }
        /* the edges within reach (edge_lines), then the circles within reach: static_point_line at -away * gap */
        double r = radii[i];
        double reach = horizon_obst * max_speed[i] + r;
        double velx = v[2 * i], vely = v[2 * i + 1];
        Py_ssize_t count = 0;
        Py_ssize_t n_edges = edges_within_reach(&vx, NV, px, py, reach, edges, edge_d);
        edge_lines(&vx, edges, n_edges, px, py, velx, vely, r, horizon_obst, lines, &count, &bad);
        for (Py_ssize_t k = 0; k < C; k++) {
            double g, awx, awy;
            away_from_circle(px, py, circ + 3 * k, &g, &awx, &awy);
            if (!((g - r) < reach)) continue;
            if (static_point_line(-awx * g, -awy * g, r, horizon_obst, h, velx, vely, &lines[count], &bad)) count++;
        }
        finish(i, count, near, count_i, rel, v, vel, radii, share, pref, max_speed, horizon, h, lines, widened,
               projected, new_v, &bad);
        bad_out[i] = (unsigned char)(bad != 0);
        n_bad += bad != 0;
    }
    result = PyLong_FromSsize_t(n_bad);
done:
    PyMem_Free(work);
    for (int k = 0; k < got; k++) PyBuffer_Release(&b[k]);
    return result;
}

static PyMethodDef methods[] = {
    {"set_constants", set_constants, METH_VARARGS,
     "set_constants(parallel, slack_rel, slack_abs, covered): fuzzynav.numerics.orca_lp's _PARALLEL, _SLACK_REL, "
     "_SLACK_ABS and _COVERED"},
    {"velocities", velocities, METH_VARARGS,
     "velocities(time_horizon_obst_s, time_horizon_s, h, x, v, pref, max_speed, rel, vel, radii, share, points, "
     "directions, next, previous, convex, edges, edge_counts, gaps, away, close, near, counts, new_v, bad) -> "
     "number of bad pedestrians: PedestrianOrcaModel._velocity for every own pedestrian, into new_v (bad[i]: the "
     "Python path raises for pedestrian i)"},
    {"substep", substep, METH_VARARGS,
     "substep(neighbor_dist_cm, max_neighbors, time_horizon_obst_s, time_horizon_s, h, x, pos_all, vel_all, "
     "rad_all, share, v, pref, max_speed, points, directions, next, previous, convex, circles, new_v, bad) -> "
     "number of bad pedestrians: one substep's neighbours, edges and circles within reach and velocities of "
     "PedestrianOrcaModel.step, into new_v"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "fuzzynav.pedestrians._orca",
    "The orca pedestrians' velocities in C (bit-identical to fuzzynav.pedestrians.orca's Python path).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__orca(void) { return PyModule_Create(&module); }
