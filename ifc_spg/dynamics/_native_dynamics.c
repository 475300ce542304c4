/* The Popov-Vereshchagin sweeps in C (ifc_spg.dynamics._native_dynamics).
 *
 * One Kernel object per chain: it copies the chain's constant arrays and allocates every
 * workspace once, when it is created; a call allocates only the arrays of its result.
 * The numpy code in ifc_spg/dynamics/vereshchagin.py (NumpyKernel) is the reference: the
 * same sweeps in the same ground (base) coordinates, Featherstone style, the same balance
 * of acceleration energy (eigen-decomposition of the coupling matrix, damped inverse when
 * it is rank-deficient), and the same box QP for static friction (box_qp.py). The tests
 * compare the two to 1e-10 on random chains.
 *
 * Spatial vectors are [linear; angular], wrenches [force; moment] (module docstring of
 * vereshchagin.py). Inputs are converted to float64 C arrays (no copy when they already
 * are); an input of the wrong shape or with a non-finite entry is handed to the Python
 * checks (the `check` callable), which raise the error with its message.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>
#include <string.h>

#define MAXC 6 /* constraints on the last segment */

typedef struct {
    PyObject_HEAD
    int n, nq, rmax, kmax;
    /* constants of the chain */
    double *rev, *axis, *sk, *sk2, *Rp, *pp, *mass, *com, *Ic, *arm;
    npy_intp *iq;
    unsigned char *unb;
    double tip[16], g0[6], rank_tol, damping;
    PyObject *result_type, *check;
    /* workspace (one allocation, sized for n joints, rmax torque columns) */
    double *mem;
    double *T, *R, *p, *S, *Iw, *pb, *cb, *Cb, *Mx, *xs, *D, *Es, *K, *qddc, *nuc, *rhs;
    double *qdd, *nu, *mu, *taue, *acol, *th, *qdv;
    double *gG, *gg, *gf, *ggrad, *gp, *gL;
    npy_intp *joints;
    int *state, *fi;
    double Aw[6 * MAXC], A[6 * MAXC], b[MAXC], ptip[3], a0[6], L[MAXC * MAXC];
    int m, r, rank, singular;
} Kernel;

/* ---- small linear algebra ------------------------------------------------------------ */

static inline void cross3(const double *a, const double *b, double *o) {
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

static inline void mat3_vec(const double *M, const double *v, double *o) {
    o[0] = M[0] * v[0] + M[1] * v[1] + M[2] * v[2];
    o[1] = M[3] * v[0] + M[4] * v[1] + M[5] * v[2];
    o[2] = M[6] * v[0] + M[7] * v[1] + M[8] * v[2];
}

static inline void mat3_mul(const double *A, const double *B, double *o) {
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            o[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/* Eigen-decomposition of the symmetric m x m matrix X (cyclic Jacobi): X = V diag(lam) V^T,
 * V column-major in vec (vec[i * m + k] = V[i][k]). X is overwritten. */
static void jacobi_eig(double *X, int m, double *lam, double *vec) {
    for (int i = 0; i < m * m; i++) vec[i] = 0.0;
    for (int i = 0; i < m; i++) vec[i * m + i] = 1.0;
    for (int sweep = 0; sweep < 100; sweep++) {
        double off = 0.0, diag = 0.0;
        for (int i = 0; i < m; i++) {
            diag += X[i * m + i] * X[i * m + i];
            for (int j = i + 1; j < m; j++) off += X[i * m + j] * X[i * m + j];
        }
        if (off <= 1e-36 * diag || off == 0.0) break;
        for (int pI = 0; pI < m; pI++) {
            for (int q = pI + 1; q < m; q++) {
                double apq = X[pI * m + q];
                if (apq == 0.0) continue;
                double app = X[pI * m + pI], aqq = X[q * m + q];
                double theta = (aqq - app) / (2.0 * apq);
                double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < m; k++) {
                    double xkp = X[k * m + pI], xkq = X[k * m + q];
                    X[k * m + pI] = c * xkp - s * xkq;
                    X[k * m + q] = s * xkp + c * xkq;
                }
                for (int k = 0; k < m; k++) {
                    double xpk = X[pI * m + k], xqk = X[q * m + k];
                    X[pI * m + k] = c * xpk - s * xqk;
                    X[q * m + k] = s * xpk + c * xqk;
                }
                for (int k = 0; k < m; k++) {
                    double vkp = vec[k * m + pI], vkq = vec[k * m + q];
                    vec[k * m + pI] = c * vkp - s * vkq;
                    vec[k * m + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    for (int i = 0; i < m; i++) lam[i] = X[i * m + i];
}

/* Cholesky solve of the k x k SPD matrix M (row stride ld) for rhs -> x; 0 if not SPD. */
static int chol_solve(double *M, int k, int ld, double *x) {
    for (int j = 0; j < k; j++) {
        double d = M[j * ld + j];
        for (int l = 0; l < j; l++) d -= M[j * ld + l] * M[j * ld + l];
        if (!(d > 0.0)) return 0;
        d = sqrt(d);
        M[j * ld + j] = d;
        for (int i = j + 1; i < k; i++) {
            double v = M[i * ld + j];
            for (int l = 0; l < j; l++) v -= M[i * ld + l] * M[j * ld + l];
            M[i * ld + j] = v / d;
        }
    }
    for (int i = 0; i < k; i++) {
        double v = x[i];
        for (int l = 0; l < i; l++) v -= M[i * ld + l] * x[l];
        x[i] = v / M[i * ld + i];
    }
    for (int i = k - 1; i >= 0; i--) {
        double v = x[i];
        for (int l = i + 1; l < k; l++) v -= M[l * ld + i] * x[l];
        x[i] = v / M[i * ld + i];
    }
    return 1;
}


static inline double dmax2(double a, double b) { return a >= b ? a : b; }

/* ---- the box QP of static friction (box_qp.py: the same algorithm in numpy) ------------ */

/* argmin 1/2 x^T G x + g^T x  s.t.  -f <= x <= f, G (k x k, row-major) symmetric PSD.
 * Primal active-set method from x = 0 (feasible): on the current face a Newton step with
 * Cholesky of G_FF + eps I (eps = 1e-14 max(1, max diag G); along a singular direction this
 * is a long step that ends on a bound), cut at the first bound it crosses (which joins the
 * active set); at the minimum of a face the bound with the most violated multiplier leaves
 * it. Returns 1 when x satisfies the KKT conditions to the tolerance of box_qp.py, else 0.
 * Workspace: state, fi (k ints), grad, p (k), Lw (k * k). */
static int box_qp_solve(int k, const double *G, const double *g, const double *f, double *x,
                        int *state, int *fi, double *grad, double *p, double *Lw) {
    double dmx = 1.0, gmax = 0.0, Gmax = 0.0, fmx = 0.0;
    for (int i = 0; i < k; i++) {
        dmx = dmax2(dmx, G[i * k + i]);
        gmax = dmax2(gmax, fabs(g[i]));
        fmx = dmax2(fmx, f[i]);
        for (int j = 0; j < k; j++) Gmax = dmax2(Gmax, fabs(G[i * k + j]));
        x[i] = 0.0;
        state[i] = 0;
    }
    const double eps = 1e-14 * dmx;
    const double tol = 1e-9 * dmax2(1.0, dmax2(gmax, Gmax * fmx));
    int newton = 1;
    for (int it = 0; it < 20 * k + 20; it++) {
        for (int i = 0; i < k; i++) {
            double v = g[i];
            for (int j = 0; j < k; j++) v += G[i * k + j] * x[j];
            grad[i] = v;
        }
        if (newton) {
            int nf = 0;
            for (int i = 0; i < k; i++)
                if (state[i] == 0) fi[nf++] = i;
            for (int a = 0; a < nf; a++) {
                for (int c = 0; c < nf; c++) Lw[a * nf + c] = G[fi[a] * k + fi[c]];
                Lw[a * nf + a] += eps;
                p[a] = -grad[fi[a]];
            }
            if (nf && !chol_solve(Lw, nf, nf, p)) return 0;
            double alpha = 1.0;
            int block = -1, side = 0;
            for (int a = 0; a < nf; a++) {
                int i = fi[a];
                if (p[a] > 0.0 && x[i] + p[a] > f[i]) {
                    double t = (f[i] - x[i]) / p[a];
                    if (t < alpha) { alpha = t; block = i; side = 1; }
                } else if (p[a] < 0.0 && x[i] + p[a] < -f[i]) {
                    double t = (-f[i] - x[i]) / p[a];
                    if (t < alpha) { alpha = t; block = i; side = -1; }
                }
            }
            if (alpha < 0.0) alpha = 0.0;
            for (int a = 0; a < nf; a++) x[fi[a]] += alpha * p[a];
            if (block >= 0) {          /* a bound joins the active set; Newton on the face */
                state[block] = side;
                x[block] = side * f[block];
            } else {
                newton = 0;            /* minimum of this face: check the multipliers */
            }
            continue;
        }
        int worst = -1;
        double viol = tol;
        for (int i = 0; i < k; i++) {
            double v = state[i] == 1 ? grad[i] : (state[i] == -1 ? -grad[i] : 0.0);
            if (v > viol) { viol = v; worst = i; }
        }
        if (worst < 0) break;
        state[worst] = 0;
        newton = 1;
    }
    for (int i = 0; i < k; i++) {     /* KKT */
        double v = g[i];
        for (int j = 0; j < k; j++) v += G[i * k + j] * x[j];
        if (state[i] == 0 && (fabs(v) > tol || fabs(x[i]) > f[i])) return 0;
        if (state[i] == 1 && v > tol) return 0;
        if (state[i] == -1 && v < -tol) return 0;
    }
    return 1;
}

/* ---- inputs ---------------------------------------------------------------------------- */

typedef struct {
    PyObject *held[12];
    int nh;
} Held;

static void release(Held *h) {
    for (int i = 0; i < h->nh; i++) Py_DECREF(h->held[i]);
    h->nh = 0;
}

/* float64 C-contiguous view of o (converted when needed as np.asarray(o, dtype=float) does,
 * kept in h), or NULL (no error). */
static PyArrayObject *as_f64(Held *h, PyObject *o) {
    if (PyArray_CheckExact(o)) {
        PyArrayObject *a = (PyArrayObject *)o;
        if (PyArray_TYPE(a) == NPY_DOUBLE && PyArray_IS_C_CONTIGUOUS(a) && PyArray_ISALIGNED(a))
            return a;
    }
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(
        o, NPY_DOUBLE, 0, 0, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED | NPY_ARRAY_FORCECAST);
    if (a == NULL) {
        PyErr_Clear();
        return NULL;
    }
    h->held[h->nh++] = (PyObject *)a;
    return a;
}

static int all_finite(const double *x, npy_intp size) {
    for (npy_intp i = 0; i < size; i++)
        if (!isfinite(x[i])) return 0;
    return 1;
}

/* Read q, qd, tau, a0, fext, A, b (Python objects, None for defaults) into the workspace:
 * th and qd (n), T column 0 (tau), a0, A, b, m; *fext the external wrenches or NULL.
 * Returns 0 when an input is not of the expected shape or not finite. */
static int read_inputs(Kernel *s, Held *h, PyObject *const *args, double *th, double *qdv,
                       const double **fext) {
    const int n = s->n;
    PyArrayObject *a;
    const double *d;
    /* q -> joint angles */
    if (!(a = as_f64(h, args[0])) || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != s->nq) return 0;
    d = (const double *)PyArray_DATA(a);
    if (!all_finite(d, s->nq)) return 0;
    for (int i = 0; i < n; i++)
        th[i] = s->unb[i] ? atan2(d[s->iq[i] + 1], d[s->iq[i]]) : d[s->iq[i]];
    /* qd */
    if (!(a = as_f64(h, args[1])) || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != n) return 0;
    d = (const double *)PyArray_DATA(a);
    if (!all_finite(d, n)) return 0;
    memcpy(qdv, d, sizeof(double) * n);
    /* tau */
    if (args[2] == Py_None) {
        for (int i = 0; i < n; i++) s->taue[i] = 0.0;
    } else {
        if (!(a = as_f64(h, args[2])) || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != n) return 0;
        d = (const double *)PyArray_DATA(a);
        if (!all_finite(d, n)) return 0;
        memcpy(s->taue, d, sizeof(double) * n);
    }
    /* base acceleration */
    if (args[3] == Py_None) {
        memcpy(s->a0, s->g0, sizeof(s->a0));
    } else {
        if (!(a = as_f64(h, args[3])) || PyArray_NDIM(a) != 1 || PyArray_DIM(a, 0) != 6) return 0;
        d = (const double *)PyArray_DATA(a);
        if (!all_finite(d, 6)) return 0;
        memcpy(s->a0, d, sizeof(s->a0));
    }
    /* external wrenches */
    *fext = NULL;
    if (args[4] != Py_None) {
        if (!(a = as_f64(h, args[4])) || PyArray_NDIM(a) != 2 || PyArray_DIM(a, 0) != n ||
            PyArray_DIM(a, 1) != 6)
            return 0;
        d = (const double *)PyArray_DATA(a);
        if (!all_finite(d, 6 * (npy_intp)n)) return 0;
        *fext = d;
    }
    /* constraints */
    if (args[5] == Py_None) {
        if (args[6] != Py_None) {
            if (!(a = as_f64(h, args[6])) || PyArray_SIZE(a) != 0) return 0;
        }
        s->m = 0;
        return 1;
    }
    if (!(a = as_f64(h, args[5]))) return 0;
    int m;
    if (PyArray_NDIM(a) == 1 && PyArray_DIM(a, 0) == 6) {
        m = 1;
    } else if (PyArray_NDIM(a) == 2 && PyArray_DIM(a, 0) == 6 && PyArray_DIM(a, 1) <= MAXC) {
        m = (int)PyArray_DIM(a, 1);
    } else {
        return 0;
    }
    d = (const double *)PyArray_DATA(a);
    if (!all_finite(d, 6 * m)) return 0;
    memcpy(s->A, d, sizeof(double) * 6 * m);
    s->m = m;
    if (args[6] == Py_None) {
        for (int c = 0; c < m; c++) s->b[c] = 0.0;
    } else {
        if (!(a = as_f64(h, args[6])) || PyArray_SIZE(a) != m) return 0;
        d = (const double *)PyArray_DATA(a);
        if (!all_finite(d, m)) return 0;
        memcpy(s->b, d, sizeof(double) * m);
    }
    return 1;
}

/* The inputs were rejected: let the Python checks raise their error (NULL returned). */
static int reject(Kernel *s, PyObject *const *args) {
    PyObject *r = PyObject_CallFunctionObjArgs(s->check, args[0], args[1], args[2], args[3],
                                               args[4], args[5], args[6], NULL);
    if (r == NULL) return 0;
    Py_DECREF(r);
    PyErr_SetString(PyExc_RuntimeError,
                    "the compiled dynamics kernel rejected inputs that the checks accept "
                    "(a bug: please report it); IFC_SPG_NATIVE=0 selects the numpy code");
    return 0;
}

/* ---- the sweeps ------------------------------------------------------------------------- */

/* Run the three sweeps for the torque columns s->T (n x r, column 0 with the bias terms):
 * fills qddc (n x r), nuc (m x r), L, rank, singular and the per-segment S, p, Iw, pb, Cb. */
static void sweeps(Kernel *s, const double *th, const double *qd, const double *fext) {
    const int n = s->n, r = s->r, m = s->m, k = 6 + r + m;
    double Rprev[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, pprev[3] = {0, 0, 0};
    double V[6] = {0, 0, 0, 0, 0, 0};
    /* ---- outward sweep 1: poses, velocities, bias accelerations and forces ---- */
    for (int i = 0; i < n; i++) {
        double HR[9], Hp[3], t3[3];
        const double *Rp = s->Rp + 9 * i, *pp = s->pp + 3 * i, *ax = s->axis + 3 * i;
        if (s->rev[i] != 0.0) {
            double sn = sin(th[i]), cm = 1.0 - cos(th[i]), Rj[9];
            const double *k1 = s->sk + 9 * i, *k2 = s->sk2 + 9 * i;
            for (int e = 0; e < 9; e++) Rj[e] = sn * k1[e] + cm * k2[e];
            Rj[0] += 1.0;
            Rj[4] += 1.0;
            Rj[8] += 1.0;
            mat3_mul(Rp, Rj, HR);
            Hp[0] = pp[0], Hp[1] = pp[1], Hp[2] = pp[2];
        } else {
            double ax_t[3] = {ax[0] * th[i], ax[1] * th[i], ax[2] * th[i]};
            memcpy(HR, Rp, sizeof(HR));
            mat3_vec(Rp, ax_t, t3);
            Hp[0] = pp[0] + t3[0], Hp[1] = pp[1] + t3[1], Hp[2] = pp[2] + t3[2];
        }
        double *R = s->R + 9 * i, *p = s->p + 3 * i, *S = s->S + 6 * i;
        mat3_mul(Rprev, HR, R);
        mat3_vec(Rprev, Hp, t3);
        p[0] = pprev[0] + t3[0], p[1] = pprev[1] + t3[1], p[2] = pprev[2] + t3[2];
        memcpy(Rprev, R, sizeof(Rprev));
        memcpy(pprev, p, sizeof(pprev));
        double z[3];
        mat3_vec(R, ax, z);
        if (s->rev[i] != 0.0) {
            cross3(p, z, S);
            S[3] = z[0], S[4] = z[1], S[5] = z[2];
        } else {
            S[0] = z[0], S[1] = z[1], S[2] = z[2];
            S[3] = S[4] = S[5] = 0.0;
        }
        double Sq[6];
        for (int e = 0; e < 6; e++) {
            Sq[e] = S[e] * qd[i];
            V[e] += Sq[e];
        }
        /* spatial inertia in base coordinates, at the base origin */
        double cw[3], RI[9], Icw[9];
        mat3_vec(R, s->com + 3 * i, t3);
        cw[0] = p[0] + t3[0], cw[1] = p[1] + t3[1], cw[2] = p[2] + t3[2];
        mat3_mul(R, s->Ic + 9 * i, RI);
        for (int a = 0; a < 3; a++)
            for (int c = 0; c < 3; c++)
                Icw[3 * a + c] = RI[3 * a] * R[3 * c] + RI[3 * a + 1] * R[3 * c + 1] +
                                 RI[3 * a + 2] * R[3 * c + 2];
        const double ms = s->mass[i];
        const double C[9] = {0, -cw[2], cw[1], cw[2], 0, -cw[0], -cw[1], cw[0], 0};
        double *Ib = s->Iw + 36 * i;
        for (int a = 0; a < 3; a++) {
            for (int c = 0; c < 3; c++) {
                double cc = C[3 * a] * C[c] + C[3 * a + 1] * C[3 + c] + C[3 * a + 2] * C[6 + c];
                Ib[6 * a + c] = a == c ? ms : 0.0;
                Ib[6 * a + 3 + c] = -ms * C[3 * a + c];
                Ib[6 * (3 + a) + c] = ms * C[3 * a + c];
                Ib[6 * (3 + a) + 3 + c] = Icw[3 * a + c] - ms * cc;
            }
        }
        double hv[6];
        for (int a = 0; a < 6; a++) {
            double v = 0.0;
            for (int c = 0; c < 6; c++) v += Ib[6 * a + c] * V[c];
            hv[a] = v;
        }
        /* c_i = v x S qd (motion cross product), p_i = v x* I v (force cross product) */
        double *cb = s->cb + 6 * i, *pb = s->pb + 6 * i, u[3], w3[3];
        cross3(V + 3, Sq, cb);
        cross3(V, Sq + 3, u);
        cb[0] += u[0], cb[1] += u[1], cb[2] += u[2];
        cross3(V + 3, Sq + 3, cb + 3);
        cross3(V + 3, hv, pb);
        cross3(V, hv, pb + 3);
        cross3(V + 3, hv + 3, w3);
        pb[3] += w3[0], pb[4] += w3[1], pb[5] += w3[2];
        if (fext != NULL) {
            const double *F = fext + 6 * i;
            double pF[3];
            cross3(p, F, pF);
            for (int e = 0; e < 3; e++) {
                pb[e] -= F[e];
                pb[3 + e] -= F[3 + e] + pF[e];
            }
        }
    }
    /* ---- inward sweep: articulated inertias, bias forces, constraint propagation ---- */
    {
        const double *R = s->R + 9 * (n - 1), *p = s->p + 3 * (n - 1);
        double tp[3] = {s->tip[3], s->tip[7], s->tip[11]}, t3[3];
        mat3_vec(R, tp, t3);
        s->ptip[0] = p[0] + t3[0], s->ptip[1] = p[1] + t3[1], s->ptip[2] = p[2] + t3[2];
    }
    for (int c = 0; c < m; c++) {
        double f3[3] = {s->A[0 * m + c], s->A[1 * m + c], s->A[2 * m + c]}, mo[3];
        cross3(s->ptip, f3, mo);
        for (int e = 0; e < 3; e++) {
            s->Aw[e * m + c] = f3[e];
            s->Aw[(3 + e) * m + c] = s->A[(3 + e) * m + c] + mo[e];
        }
    }
    double *Mx = s->Mx;
    memset(Mx, 0, sizeof(double) * 6 * k);
    for (int e = 0; e < 6; e++)
        for (int c = 0; c < m; c++) Mx[e * k + 6 + r + c] = s->Aw[e * m + c];
    for (int i = n - 1; i >= 0; i--) {
        const double *Ib = s->Iw + 36 * i, *pb = s->pb + 6 * i, *S = s->S + 6 * i,
                     *cb = s->cb + 6 * i;
        for (int a = 0; a < 6; a++) {
            for (int c = 0; c < 6; c++) Mx[a * k + c] += Ib[6 * a + c];
            Mx[a * k + 6] += pb[a];
        }
        double *x = s->xs + (npy_intp)k * i;
        for (int c = 0; c < k; c++) {
            double v = 0.0;
            for (int a = 0; a < 6; a++) v += S[a] * Mx[a * k + c];
            x[c] = v;
        }
        double D = s->arm[i];
        for (int a = 0; a < 6; a++) D += x[a] * S[a];
        for (int c = 0; c < r; c++) x[6 + c] -= s->T[(npy_intp)r * i + c];
        for (int a = 0; a < 6; a++) {
            double ua = x[a] / D;
            for (int c = 0; c < k; c++) Mx[a * k + c] -= ua * x[c];
        }
        for (int a = 0; a < 6; a++) {
            double v = 0.0;
            for (int c = 0; c < 6; c++) v += Mx[a * k + c] * cb[c];
            Mx[a * k + 6] += v;
        }
        s->D[i] = D;
        double *E = s->Es + 6 * MAXC * i;
        for (int a = 0; a < 6; a++)
            for (int c = 0; c < m; c++) E[a * m + c] = Mx[a * k + 6 + r + c];
    }
    /* ---- balance of acceleration energy at the base: nu = L0^-1 (b - E0^T a0 - U0) ---- */
    s->rank = 0;
    s->singular = 0;
    if (m) {
        double *rhs = s->rhs, X[MAXC * MAXC], lam[MAXC], vec[MAXC * MAXC];
        for (int a = 0; a < m; a++) {
            for (int c = 0; c < m; c++) s->L[a * m + c] = 0.0;
            for (int c = 0; c < r; c++) rhs[a * r + c] = 0.0;
        }
        for (int i = 0; i < n; i++) {
            const double *x = s->xs + (npy_intp)k * i, *sE = x + 6 + r, *E = s->Es + 6 * MAXC * i,
                         *cb = s->cb + 6 * i;
            const double D = s->D[i];
            for (int a = 0; a < m; a++) {
                double sd = sE[a] / D;
                for (int c = 0; c < m; c++) s->L[a * m + c] -= sd * sE[c];
                for (int c = 0; c < r; c++) rhs[a * r + c] += sd * x[6 + c];  /* -U0 = sd (-u) */
                double v = 0.0;
                for (int e = 0; e < 6; e++) v += E[e * m + a] * cb[e];
                rhs[a * r] -= v;
            }
        }
        const double *E0 = s->Es;
        for (int a = 0; a < m; a++) {
            double v = 0.0;
            for (int e = 0; e < 6; e++) v += E0[e * m + a] * s->a0[e];
            rhs[a * r] += s->b[a] - v;
        }
        for (int e = 0; e < m * m; e++) X[e] = -s->L[e];
        jacobi_eig(X, m, lam, vec);
        double lmax = 0.0;
        for (int a = 0; a < m; a++) lmax = dmax2(lmax, lam[a]);
        int rank = 0;
        if (lmax > 0)
            for (int a = 0; a < m; a++) rank += lam[a] > s->rank_tol * lmax;
        s->rank = rank;
        s->singular = rank < m;
        double inv[MAXC];
        if (s->singular) {
            double delta2 = lmax > 0 ? (s->damping * lmax) * (s->damping * lmax) : 1e-300;
            for (int a = 0; a < m; a++) inv[a] = lam[a] / (lam[a] * lam[a] + delta2);
        } else {
            for (int a = 0; a < m; a++) inv[a] = 1.0 / lam[a];
        }
        /* nu = -V diag(inv) V^T rhs  (m x r) */
        for (int c = 0; c < r; c++) {
            double y[MAXC];
            for (int j = 0; j < m; j++) {
                double v = 0.0;
                for (int a = 0; a < m; a++) v += vec[a * m + j] * rhs[a * r + c];
                y[j] = v * inv[j];
            }
            for (int a = 0; a < m; a++) {
                double v = 0.0;
                for (int j = 0; j < m; j++) v += vec[a * m + j] * y[j];
                s->nuc[a * r + c] = -v;
            }
        }
    }
    /* K_i = (u_i - sE_i nu) / D_i, u = -x[6:6+r] */
    for (int i = 0; i < n; i++) {
        const double *x = s->xs + (npy_intp)k * i, *sE = x + 6 + r;
        double *K = s->K + (npy_intp)r * i;
        for (int c = 0; c < r; c++) {
            double v = -x[6 + c];
            for (int a = 0; a < m; a++) v -= sE[a] * s->nuc[a * r + c];
            K[c] = v / s->D[i];
        }
    }
    /* ---- outward sweep 2: joint accelerations; Cb_i = a0 + sum_{k<=i} c_k ---- */
    double *a = s->acol;
    memset(a, 0, sizeof(double) * 6 * r);
    double Cb[6];
    memcpy(Cb, s->a0, sizeof(Cb));
    for (int i = 0; i < n; i++) {
        const double *x = s->xs + (npy_intp)k * i, *S = s->S + 6 * i, *cb = s->cb + 6 * i;
        const double D = s->D[i];
        double *K = s->K + (npy_intp)r * i, *q = s->qddc + (npy_intp)r * i;
        for (int e = 0; e < 6; e++) {
            Cb[e] += cb[e];
            s->Cb[6 * i + e] = Cb[e];
        }
        double uc = 0.0;
        for (int e = 0; e < 6; e++) uc += x[e] * Cb[e];
        K[0] -= uc / D;
        for (int c = 0; c < r; c++) {
            double v = K[c];
            for (int e = 0; e < 6; e++) v -= x[e] / D * a[e * r + c];
            q[c] = v;
            for (int e = 0; e < 6; e++) a[e * r + c] += S[e] * v;
        }
    }
}

/* ---- results ----------------------------------------------------------------------------- */

static PyObject *new_array(int nd, npy_intp d0, npy_intp d1, double **data) {
    npy_intp dims[2] = {d0, d1};
    PyObject *a = PyArray_SimpleNew(nd, dims, NPY_DOUBLE);
    if (a != NULL) *data = (double *)PyArray_DATA((PyArrayObject *)a);
    return a;
}

/* The VereshchaginResult for the torque-column weights (1, mu_1..mu_{r-1}) (mu NULL: 1, 0..),
 * with the effective feed-forward torques s->taue; writes q̈ to s->qdd. */
static PyObject *build_result(Kernel *s, const double *mu, int gauss) {
    const int n = s->n, r = s->r, m = s->m;
    double *qdd = s->qdd, *nu = s->nu;
    for (int i = 0; i < n; i++) {
        const double *q = s->qddc + (npy_intp)r * i;
        double v = q[0];
        if (mu)
            for (int c = 1; c < r; c++) v += mu[c - 1] * q[c];
        qdd[i] = v;
    }
    for (int a = 0; a < m; a++) {
        double v = s->nuc[a * r];
        if (mu)
            for (int c = 1; c < r; c++) v += mu[c - 1] * s->nuc[a * r + c];
        nu[a] = v;
    }
    double *o_qdd, *o_nu, *o_tc, *o_tk, *o_seg, *o_tip, *o_res, *o_L;
    PyObject *arr[8];
    arr[0] = new_array(1, n, 0, &o_qdd);
    arr[1] = new_array(1, m, 0, &o_nu);
    arr[2] = new_array(1, n, 0, &o_tc);
    arr[3] = new_array(1, n, 0, &o_tk);
    arr[4] = new_array(2, n, 6, &o_seg);
    arr[5] = new_array(1, 6, 0, &o_tip);
    arr[6] = new_array(1, m, 0, &o_res);
    arr[7] = new_array(2, m, m, &o_L);
    for (int j = 0; j < 8; j++) {
        if (arr[j] == NULL) {
            for (int l = 0; l < 8; l++) Py_XDECREF(arr[l]);
            return NULL;
        }
    }
    double w[6];                      /* A_N nu at the base origin */
    for (int e = 0; e < 6; e++) {
        double v = 0.0;
        for (int a = 0; a < m; a++) v += s->Aw[e * m + a] * nu[a];
        w[e] = v;
    }
    double acc[6] = {0, 0, 0, 0, 0, 0}, z = 0.0;
    for (int i = 0; i < n; i++) {
        const double *S = s->S + 6 * i, *Cb = s->Cb + 6 * i, *p = s->p + 3 * i;
        double ai[6], t3[3], tcn = 0.0;
        for (int e = 0; e < 6; e++) {
            acc[e] += S[e] * qdd[i];
            ai[e] = acc[e] + Cb[e];
            tcn -= S[e] * w[e];
        }
        o_qdd[i] = qdd[i];
        o_tk[i] = tcn;
        o_tc[i] = s->taue[i] + tcn;
        cross3(p, ai + 3, t3);
        double *seg = o_seg + 6 * i;
        for (int e = 0; e < 3; e++) {
            seg[e] = ai[e] - t3[e];
            seg[3 + e] = ai[3 + e];
        }
        if (gauss) {
            const double *Ib = s->Iw + 36 * i, *pb = s->pb + 6 * i;
            double q2 = 0.0;
            for (int a = 0; a < 6; a++) {
                double v = 0.0;
                for (int c = 0; c < 6; c++) v += Ib[6 * a + c] * ai[c];
                q2 += ai[a] * v;
                z += pb[a] * ai[a];
            }
            z += 0.5 * q2 + 0.5 * s->arm[i] * qdd[i] * qdd[i] - s->taue[i] * qdd[i];
        }
        if (i == n - 1) {
            cross3(s->ptip, ai + 3, t3);
            for (int e = 0; e < 3; e++) {
                o_tip[e] = ai[e] - t3[e];
                o_tip[3 + e] = ai[3 + e];
            }
        }
    }
    for (int a = 0; a < m; a++) {
        o_nu[a] = nu[a];
        double v = -s->b[a];
        for (int e = 0; e < 6; e++) v += s->A[e * m + a] * o_tip[e];
        o_res[a] = v;
        for (int c = 0; c < m; c++) o_L[a * m + c] = s->L[a * m + c];
    }
    PyObject *fields = PyTuple_New(11);
    if (fields == NULL) {
        for (int l = 0; l < 8; l++) Py_DECREF(arr[l]);
        return NULL;
    }
    for (int j = 0; j < 7; j++) PyTuple_SET_ITEM(fields, j, arr[j]);
    PyTuple_SET_ITEM(fields, 7, PyBool_FromLong(s->singular));
    PyTuple_SET_ITEM(fields, 8, PyLong_FromLong(s->rank));
    PyTuple_SET_ITEM(fields, 9, arr[7]);
    PyTuple_SET_ITEM(fields, 10, PyFloat_FromDouble(gauss ? z : NAN));
    PyObject *res = PyObject_Call(s->result_type, fields, NULL);
    Py_DECREF(fields);
    return res;
}

/* ---- methods ------------------------------------------------------------------------------ */

PyDoc_STRVAR(solve_doc,
"solve(q, qd, tau, base_acceleration, external_wrenches, A_N, b_N, gauss) -> VereshchaginResult\n\n"
"NumpyKernel.solve in C (None selects a default, as in VereshchaginSolver.solve).");

static PyObject *k_solve(Kernel *s, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 8) {
        PyErr_SetString(PyExc_TypeError, "solve takes 8 arguments");
        return NULL;
    }
    int gauss = PyObject_IsTrue(args[7]);
    if (gauss < 0) return NULL;
    Held h = {{0}, 0};
    const double *fext;
    if (!read_inputs(s, &h, args, s->th, s->qdv, &fext)) {
        release(&h);
        reject(s, args);
        return NULL;
    }
    s->r = 1;
    memcpy(s->T, s->taue, sizeof(double) * s->n);
    sweeps(s, s->th, s->qdv, fext);
    release(&h);
    return build_result(s, NULL, gauss);
}

/* Torque columns [tau | e_j for j in joints] (joints already checked to be in range). */
static void set_columns(Kernel *s, const npy_intp *joints, int k) {
    const int n = s->n, r = 1 + k;
    s->r = r;
    memset(s->T, 0, sizeof(double) * n * r);
    for (int i = 0; i < n; i++) s->T[(npy_intp)r * i] = s->taue[i];
    for (int c = 0; c < k; c++) s->T[(npy_intp)r * joints[c] + 1 + c] = 1.0;
}

PyDoc_STRVAR(sensitivity_doc,
"sensitivity(q, qd, tau, joints, base_acceleration, external_wrenches, A_N, b_N)\n"
"    -> (VereshchaginResult, G)\n\n"
"One pass with the unit-torque columns of `joints`: the result for tau and\n"
"G (n, k) = d qdd / d tau_joints.");

static PyObject *k_sensitivity(Kernel *s, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 8) {
        PyErr_SetString(PyExc_TypeError, "sensitivity takes 8 arguments");
        return NULL;
    }
    PyArrayObject *jo = (PyArrayObject *)PyArray_FROMANY(args[3], NPY_INTP, 0, 1,
                                                         NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED);
    if (jo == NULL) return NULL;
    npy_intp k = PyArray_SIZE(jo);
    const npy_intp *jd = (const npy_intp *)PyArray_DATA(jo);
    if (k > s->n) {
        Py_DECREF(jo);
        PyErr_Format(PyExc_ValueError, "at most %d joints", s->n);
        return NULL;
    }
    for (npy_intp c = 0; c < k; c++) {
        if (jd[c] < 0 || jd[c] >= s->n) {
            PyErr_Format(PyExc_IndexError, "joint index %zd out of range for %d joints",
                         (Py_ssize_t)jd[c], s->n);
            Py_DECREF(jo);
            return NULL;
        }
        s->joints[c] = jd[c];
    }
    Py_DECREF(jo);
    PyObject *const a7[7] = {args[0], args[1], args[2], args[4], args[5], args[6], args[7]};
    Held h = {{0}, 0};
    const double *fext;
    if (!read_inputs(s, &h, a7, s->th, s->qdv, &fext)) {
        release(&h);
        reject(s, a7);
        return NULL;
    }
    set_columns(s, s->joints, (int)k);
    sweeps(s, s->th, s->qdv, fext);
    release(&h);
    double *G;
    PyObject *Ga = new_array(2, s->n, k, &G);
    if (Ga == NULL) return NULL;
    for (int i = 0; i < s->n; i++)
        for (npy_intp c = 0; c < k; c++) G[i * k + c] = s->qddc[(npy_intp)s->r * i + 1 + c];
    PyObject *res = build_result(s, NULL, 0);
    if (res == NULL) {
        Py_DECREF(Ga);
        return NULL;
    }
    return Py_BuildValue("(NN)", res, Ga);
}

PyDoc_STRVAR(friction_doc,
"friction(q, qd, tau, base_acceleration, external_wrenches, A_N, b_N, breakaway, eps)\n"
"    -> (result, mu, stationary, stick, qdd0, G, ok)\n\n"
"StaticFrictionSolver's exact method (NumpyKernel.friction): one pass with the unit-torque\n"
"columns of the joints at rest (|qd_j| <= eps, breakaway_j > 0), the box QP over them, the\n"
"result at mu* with the acceleration energy. ok is False when the box QP's answer failed\n"
"its KKT check (the caller then uses a general QP solver).");

static PyObject *k_friction(Kernel *s, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 9) {
        PyErr_SetString(PyExc_TypeError, "friction takes 9 arguments");
        return NULL;
    }
    const int n = s->n;
    double eps = PyFloat_AsDouble(args[8]);
    if (eps == -1.0 && PyErr_Occurred()) return NULL;
    PyObject *const a7[7] = {args[0], args[1], args[2], args[3], args[4], args[5], args[6]};
    Held h = {{0}, 0};
    const double *fext;
    PyArrayObject *fo = as_f64(&h, args[7]);
    if (fo == NULL || PyArray_SIZE(fo) != n) {
        release(&h);
        PyErr_Format(PyExc_ValueError, "breakaway must have %d entries", n);
        return NULL;
    }
    const double *brk = (const double *)PyArray_DATA(fo);
    if (!read_inputs(s, &h, a7, s->th, s->qdv, &fext)) {
        release(&h);
        reject(s, a7);
        return NULL;
    }
    int k = 0;
    for (int i = 0; i < n; i++)
        if (fabs(s->qdv[i]) <= eps && brk[i] > 0) s->joints[k++] = i;
    set_columns(s, s->joints, k);
    sweeps(s, s->th, s->qdv, fext);
    const int r = s->r;
    double *G, *mu, *qdd0;
    PyObject *Ga = new_array(2, k, k, &G);
    PyObject *mua = new_array(1, n, 0, &mu);
    PyObject *q0a = new_array(1, n, 0, &qdd0);
    npy_intp dn = n;
    PyObject *sta = PyArray_ZEROS(1, &dn, NPY_BOOL, 0);
    PyObject *sti = PyArray_ZEROS(1, &dn, NPY_BOOL, 0);
    if (!Ga || !mua || !q0a || !sta || !sti) {
        Py_XDECREF(Ga), Py_XDECREF(mua), Py_XDECREF(q0a), Py_XDECREF(sta), Py_XDECREF(sti);
        release(&h);
        return NULL;
    }
    for (int a = 0; a < k; a++) {
        const npy_intp ja = s->joints[a];
        for (int c = 0; c < k; c++)
            G[a * k + c] = 0.5 * (s->qddc[r * ja + 1 + c] + s->qddc[r * s->joints[c] + 1 + a]);
        s->gg[a] = s->qddc[r * ja];
        s->gf[a] = brk[ja];
    }
    int ok = 1;
    if (k) ok = box_qp_solve(k, G, s->gg, s->gf, s->mu, s->state, s->fi, s->ggrad, s->gp, s->gL);
    for (int i = 0; i < n; i++) {
        mu[i] = 0.0;
        qdd0[i] = s->qddc[(npy_intp)r * i];
    }
    npy_bool *stb = (npy_bool *)PyArray_DATA((PyArrayObject *)sta),
             *skb = (npy_bool *)PyArray_DATA((PyArrayObject *)sti);
    for (int a = 0; a < k; a++) {
        const npy_intp ja = s->joints[a];
        mu[ja] = s->mu[a];
        s->taue[ja] += s->mu[a];
        stb[ja] = 1;
        skb[ja] = fabs(s->mu[a]) < brk[ja] * (1.0 - 1e-7);
    }
    release(&h);
    PyObject *res = build_result(s, s->mu, 1);
    if (res == NULL) {
        Py_DECREF(Ga), Py_DECREF(mua), Py_DECREF(q0a), Py_DECREF(sta), Py_DECREF(sti);
        return NULL;
    }
    return Py_BuildValue("(NNNNNNO)", res, mua, sta, sti, q0a, Ga, ok ? Py_True : Py_False);
}

/* ---- the type --------------------------------------------------------------------------- */

static const char *const kw_new[] = {"n", "nq", "revolute", "axis", "axis_skew", "axis_skew2",
                                     "R_parent", "p_parent", "mass", "com", "inertia_com",
                                     "armature", "idx_q", "unbounded", "tip_placement",
                                     "gravity0", "rank_tol", "damping", "result_type", "check",
                                     NULL};

static int copy_in(PyObject *o, double *dst, npy_intp size, const char *name) {
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(o, NPY_DOUBLE, 0, 0,
                                                        NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED);
    if (a == NULL) return 0;
    if (PyArray_SIZE(a) != size) {
        PyErr_Format(PyExc_ValueError, "%s must have %zd entries", name, (Py_ssize_t)size);
        Py_DECREF(a);
        return 0;
    }
    memcpy(dst, PyArray_DATA(a), sizeof(double) * size);
    Py_DECREF(a);
    return 1;
}

static void k_dealloc(Kernel *s) {
    PyMem_Free(s->mem);
    PyMem_Free(s->iq);
    PyMem_Free(s->unb);
    PyMem_Free(s->joints);
    PyMem_Free(s->state);
    PyMem_Free(s->fi);
    Py_XDECREF(s->result_type);
    Py_XDECREF(s->check);
    Py_TYPE(s)->tp_free((PyObject *)s);
}

static PyObject *k_new(PyTypeObject *type, PyObject *args, PyObject *kwds) {
    int n, nq;
    PyObject *o[15], *result_type, *check;
    double rank_tol, damping;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "iiOOOOOOOOOOOOOOddOO", (char **)kw_new, &n,
                                     &nq, &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6],
                                     &o[7], &o[8], &o[9], &o[10], &o[11], &o[12], &o[13],
                                     &rank_tol, &damping, &result_type, &check))
        return NULL;
    if (n < 1 || nq < n) {
        PyErr_SetString(PyExc_ValueError, "need n >= 1 joints and nq >= n");
        return NULL;
    }
    Kernel *s = (Kernel *)type->tp_alloc(type, 0);
    if (s == NULL) return NULL;
    s->n = n;
    s->nq = nq;
    s->rmax = 1 + n;
    s->kmax = 6 + s->rmax + MAXC;
    s->rank_tol = rank_tol;
    s->damping = damping;
    Py_INCREF(result_type);
    s->result_type = result_type;
    Py_INCREF(check);
    s->check = check;
    const npy_intp N = n, rm = s->rmax, km = s->kmax;
    /* constants, then the workspace */
    npy_intp sizes[] = {N,     3 * N,  9 * N,  9 * N,  9 * N,  3 * N,  N,     3 * N,  9 * N,
                        N,     N * rm, 9 * N,  3 * N,  6 * N,  36 * N, 6 * N, 6 * N,  6 * N,
                        6 * km, N * km, N,     6 * MAXC * N, N * rm, N * rm, MAXC * rm,
                        MAXC * rm, N, MAXC, N, N, 6 * rm, N, N, N * N, N, N, N, N, N * N};
    double **ptrs[] = {&s->rev,  &s->axis, &s->sk,   &s->sk2,  &s->Rp,   &s->pp,   &s->mass,
                       &s->com,  &s->Ic,   &s->arm,  &s->T,    &s->R,    &s->p,    &s->S,
                       &s->Iw,   &s->pb,   &s->cb,   &s->Cb,   &s->Mx,   &s->xs,   &s->D,
                       &s->Es,   &s->K,    &s->qddc, &s->nuc,  &s->rhs,  &s->qdd,  &s->nu,
                       &s->mu,   &s->taue, &s->acol, &s->th,   &s->qdv,  &s->gG,   &s->gg,
                       &s->gf,   &s->ggrad, &s->gp,  &s->gL};
    const int count = (int)(sizeof(sizes) / sizeof(sizes[0]));
    npy_intp total = 0;
    for (int j = 0; j < count; j++) total += sizes[j];
    s->mem = PyMem_Calloc((size_t)total, sizeof(double));
    s->iq = PyMem_Calloc((size_t)N, sizeof(npy_intp));
    s->unb = PyMem_Calloc((size_t)N, 1);
    s->joints = PyMem_Calloc((size_t)N, sizeof(npy_intp));
    s->state = PyMem_Calloc((size_t)N, sizeof(int));
    s->fi = PyMem_Calloc((size_t)N, sizeof(int));
    if (!s->mem || !s->iq || !s->unb || !s->joints || !s->state || !s->fi) {
        Py_DECREF(s);
        return PyErr_NoMemory();
    }
    double *q = s->mem;
    for (int j = 0; j < count; j++) {
        *ptrs[j] = q;
        q += sizes[j];
    }
    const char *names[] = {"revolute", "axis", "axis_skew", "axis_skew2", "R_parent",
                           "p_parent", "mass", "com", "inertia_com", "armature"};
    for (int j = 0; j < 10; j++)
        if (!copy_in(o[j], *ptrs[j], sizes[j], names[j])) goto fail;
    {
        double *tq = s->gG; /* n x n workspace, free here */
        if (!copy_in(o[10], tq, N, "idx_q")) goto fail;
        for (int i = 0; i < n; i++) {
            s->iq[i] = (npy_intp)tq[i];
            if (s->iq[i] < 0 || s->iq[i] >= nq) goto fail_size;
        }
        if (!copy_in(o[11], tq, N, "unbounded")) goto fail;
        for (int i = 0; i < n; i++) {
            s->unb[i] = tq[i] != 0.0;
            if (s->unb[i] && s->iq[i] + 1 >= nq) goto fail_size;
        }
    }
    if (!copy_in(o[12], s->tip, 16, "tip_placement") || !copy_in(o[13], s->g0, 6, "gravity0"))
        goto fail;
    return (PyObject *)s;
fail_size:
    PyErr_SetString(PyExc_ValueError, "idx_q / unbounded do not fit nq");
fail:
    Py_DECREF(s);
    return NULL;
}

static PyMethodDef k_methods[] = {
    {"solve", (PyCFunction)(void (*)(void))k_solve, METH_FASTCALL, solve_doc},
    {"sensitivity", (PyCFunction)(void (*)(void))k_sensitivity, METH_FASTCALL, sensitivity_doc},
    {"friction", (PyCFunction)(void (*)(void))k_friction, METH_FASTCALL, friction_doc},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject KernelType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "ifc_spg.dynamics._native_dynamics.Kernel",
    .tp_basicsize = sizeof(Kernel),
    .tp_dealloc = (destructor)k_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_BASETYPE,
    .tp_doc = "Kernel(n, nq, <chain arrays>, tip_placement, gravity0, rank_tol, damping,\n"
              "       result_type, check): the sweeps of one chain with its workspace.",
    .tp_methods = k_methods,
    .tp_new = k_new,
};

PyDoc_STRVAR(box_qp_doc,
"box_qp(G, g, f) -> (x, ok)\n\n"
"argmin 1/2 x^T G x + g^T x s.t. -f <= x <= f (G symmetric PSD), box_qp.py's active-set\n"
"method; ok: the KKT conditions hold.");

static PyObject *box_qp(PyObject *self, PyObject *args) {
    PyObject *Go, *go, *fo;
    if (!PyArg_ParseTuple(args, "OOO", &Go, &go, &fo)) return NULL;
    Held h = {{0}, 0};
    PyArrayObject *G = as_f64(&h, Go), *g = as_f64(&h, go), *f = as_f64(&h, fo);
    if (!G || !g || !f || PyArray_NDIM(G) != 2) {
        release(&h);
        PyErr_SetString(PyExc_TypeError, "G (k, k), g (k,), f (k,) must be float arrays");
        return NULL;
    }
    npy_intp k = PyArray_DIM(G, 0);
    if (PyArray_DIM(G, 1) != k || PyArray_SIZE(g) != k || PyArray_SIZE(f) != k) {
        release(&h);
        PyErr_SetString(PyExc_ValueError, "G must be (k, k) and g, f (k,)");
        return NULL;
    }
    double *x;
    PyObject *xo = new_array(1, k, 0, &x);
    double *work = PyMem_Malloc(sizeof(double) * (size_t)(2 * k + k * k + 1));
    int *iw = PyMem_Malloc(sizeof(int) * (size_t)(2 * k + 1));
    int ok = 0;
    if (xo && work && iw)
        ok = box_qp_solve((int)k, (const double *)PyArray_DATA(G),
                          (const double *)PyArray_DATA(g), (const double *)PyArray_DATA(f), x,
                          iw, iw + k, work, work + k, work + 2 * k);
    PyMem_Free(work);
    PyMem_Free(iw);
    release(&h);
    if (xo == NULL) return NULL;
    return Py_BuildValue("(NO)", xo, ok ? Py_True : Py_False);
}

static PyMethodDef methods[] = {
    {"box_qp", box_qp, METH_VARARGS, box_qp_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_native_dynamics",
    "The Popov-Vereshchagin sweeps in C (the numpy NumpyKernel is the reference).",
    -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__native_dynamics(void) {
    import_array();
    if (PyType_Ready(&KernelType) < 0) return NULL;
    PyObject *mod = PyModule_Create(&module);
    if (mod == NULL) return NULL;
    Py_INCREF(&KernelType);
    if (PyModule_AddObject(mod, "Kernel", (PyObject *)&KernelType) < 0) {
        Py_DECREF(&KernelType);
        Py_DECREF(mod);
        return NULL;
    }
    return mod;
}
