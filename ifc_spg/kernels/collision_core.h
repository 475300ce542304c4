/* The arithmetic of a collision-avoidance level (ifc_spg.geometry.PairQuery and
 * ifc_spg.tasks.CollisionAvoidanceTask), shared by the C kernels (_native.c: collision_cull,
 * collision_rows, collision_level) and the C++ narrowphase (_coal_native.cpp: Pairs.level, the
 * same steps in one call), so that both compute the same numbers in the same order.
 *
 * Plain C that also compiles as C++; arrays are C-contiguous float64, indices npy_intp
 * (include numpy's headers first).
 */
#ifndef IFC_SPG_COLLISION_CORE_H
#define IFC_SPG_COLLISION_CORE_H

#include <math.h>
#include <string.h>

/* The cull across calls: d[i] = last_bound[i] - sum_j lever[i, j] |q_j - last_q_j| over the m
 * pairs (lever (m, n)); returns how many pairs have d <= influence. */
static inline npy_intp ifc_collision_cull(npy_intp m, npy_intp n, const double *lb,
                                          const double *lev, const double *q, const double *lq,
                                          double influence, double *d) {
    npy_intp count = 0;
    for (npy_intp i = 0; i < m; i++) {
        double s = 0.0;
        const double *l = lev + n * i;
        for (npy_intp j = 0; j < n; j++) s += l[j] * fabs(q[j] - lq[j]);
        d[i] = lb[i] - s;
        if (d[i] <= influence) count++;
    }
    return count;
}

/* The distance Jacobian row of one pair: with witness points a, b (base frame) at distance d,
 * the unit normal nv = (b - a) / d where d > eps (else nv is kept: coal's), and
 * r = (nv^T J_v)(mask_b - mask_a) + ((b x nv)^T J_w) mask_b - ((a x nv)^T J_w) mask_a,
 * J (6, n) the joint Jacobian in the world frame (J_v = J[:3], J_w = J[3:]). */
static inline void ifc_collision_row(npy_intp n, const double *J, const double *a,
                                     const double *b, double d, double eps, double *nv,
                                     const double *mai, const double *mbi, double *r) {
    if (d > eps) {
        for (int c = 0; c < 3; c++) nv[c] = (b[c] - a[c]) / d;
    }
    double ca[3] = {a[1] * nv[2] - a[2] * nv[1], a[2] * nv[0] - a[0] * nv[2],
                    a[0] * nv[1] - a[1] * nv[0]};
    double cb[3] = {b[1] * nv[2] - b[2] * nv[1], b[2] * nv[0] - b[0] * nv[2],
                    b[0] * nv[1] - b[1] * nv[0]};
    for (npy_intp j = 0; j < n; j++) {
        double lin = 0.0, wa = 0.0, wb = 0.0;
        for (int c = 0; c < 3; c++) {
            lin += nv[c] * J[c * n + j];
            wa += ca[c] * J[(3 + c) * n + j];
            wb += cb[c] * J[(3 + c) * n + j];
        }
        r[j] = lin * (mbi[j] - mai[j]) + wb * mbi[j] - wa * mai[j];
    }
}

/* The velocity damper level: of the k pairs p (in that order), those with d < influence go to
 * w (returns their count); the first R of them fill A[t] = rows[p] (rows (m, n)) and
 * lower[t] = -gain (d - margin), the other rows of A (R, n) are zero with lower -inf. */
static inline npy_intp ifc_collision_level(npy_intp k, const npy_intp *p, npy_intp n,
                                           const double *rows, const double *d,
                                           double influence, double gain, double margin,
                                           npy_intp R, double *A, double *lower, npy_intp *w) {
    npy_intp r = 0;
    for (npy_intp t = 0; t < k; t++) {
        npy_intp i = p[t];
        if (!(d[i] < influence)) continue;
        w[r] = i;
        if (r < R) {
            memcpy(A + r * n, rows + i * n, (size_t)n * sizeof(double));
            lower[r] = -gain * (d[i] - margin);
        }
        r++;
    }
    for (npy_intp t = r < R ? r : R; t < R; t++) {
        memset(A + t * n, 0, (size_t)n * sizeof(double));
        lower[t] = -INFINITY;
    }
    return r;
}

#endif /* IFC_SPG_COLLISION_CORE_H */
