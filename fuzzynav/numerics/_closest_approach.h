/*
 * The closest approach of one pair, shared by the kernels that need it (fuzzynav/numerics/_closest_approach.c, _tpt.c):
 * geometry.closest_approach's numpy form for one (rel0, step) pair of 2-vectors, each operation its own, in its
 * order (IEEE basic operations and sqrt, each correctly rounded), so the same bits. Lengths in cm.
 */
#ifndef FUZZYNAV_CLOSEST_APPROACH_H
#define FUZZYNAV_CLOSEST_APPROACH_H

#include <math.h>

/* the smallest |rel0 + s step| over s in [0, 1] */
static inline double closest_approach_length(double rx, double ry, double dx, double dy) {
    double dd = dx * dx + dy * dy;                        /* dot2(step, step) */
    double q = -(rx * dx + ry * dy) / (dd > 0 ? dd : 1.0); /* -dot2(rel0, step) / where(dd > 0, dd, 1) */
    double s = q;                                         /* np.clip(q, 0, 1): NaN stays NaN */
    if (s < 0.0) s = 0.0;
    if (s > 1.0) s = 1.0;
    double px = rx + s * dx, py = ry + s * dy;            /* rel0 + s[..., None] * step */
    return sqrt(px * px + py * py);                       /* norm2 */
}

#endif
