/* The SPG tick's per-joint and per-row arithmetic in C (ifc_spg._native).
 *
 * Each function is a loop over a few joints or task rows that numpy would spread over
 * 5-15 calls of ~0.5-1 us each. The numpy versions in ifc_spg stay the reference: the
 * tests compare the two on random inputs, and ifc_spg uses them wherever this module was
 * not built (ifc_spg.native). Semantics follow numpy's exactly, NaN included (maximum and
 * minimum propagate NaN); see each function's numpy counterpart named in its docstring.
 *
 * Arrays are float64. Inputs may be any layout (converted if needed); outputs must be
 * C-contiguous writable float64 arrays of the stated size.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <math.h>
#include <string.h>
#include "collision_core.h"

static inline double np_max(double a, double b) {
    if (isnan(a)) return a;
    if (isnan(b)) return b;
    return a >= b ? a : b;
}

static inline double np_min(double a, double b) {
    if (isnan(a)) return a;
    if (isnan(b)) return b;
    return a <= b ? a : b;
}

/* A float64 C-contiguous view (or copy) of obj with ndim dimensions; new reference. */
static PyArrayObject *in_array(PyObject *obj, int ndim, const char *name) {
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(
        obj, NPY_DOUBLE, ndim, ndim, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED);
    if (a == NULL) {
        PyErr_Format(PyExc_TypeError, "%s must be a %d-D float array", name, ndim);
    }
    return a;
}

/* Check that obj is a writable C-contiguous float64 array of `size` elements. */
static double *out_data(PyObject *obj, npy_intp size, const char *name) {
    if (!PyArray_Check(obj)) {
        PyErr_Format(PyExc_TypeError, "%s must be a numpy array", name);
        return NULL;
    }
    PyArrayObject *a = (PyArrayObject *)obj;
    if (PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(a) ||
        !PyArray_ISWRITEABLE(a) || PyArray_SIZE(a) != size) {
        PyErr_Format(PyExc_ValueError,
                     "%s must be a writable C-contiguous float64 array of %zd elements",
                     name, (Py_ssize_t)size);
        return NULL;
    }
    return (double *)PyArray_DATA(a);
}

/* Like out_data, for read-only inputs that callers keep contiguous (no conversion). */
static const double *in_data(PyObject *obj, npy_intp size, const char *name) {
    if (!PyArray_Check(obj)) {
        PyErr_Format(PyExc_TypeError, "%s must be a numpy array", name);
        return NULL;
    }
    PyArrayObject *a = (PyArrayObject *)obj;
    if (PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(a) ||
        PyArray_SIZE(a) < size) {
        PyErr_Format(PyExc_ValueError,
                     "%s must be a C-contiguous float64 array of at least %zd elements",
                     name, (Py_ssize_t)size);
        return NULL;
    }
    return (const double *)PyArray_DATA(a);
}

/* count new float64 vectors of the given sizes into out (all, or none and NULL). */
static int new_vectors(PyArrayObject **out, const npy_intp *sizes, int count) {
    for (int k = 0; k < count; k++) {
        npy_intp size = sizes[k];
        out[k] = (PyArrayObject *)PyArray_SimpleNew(1, &size, NPY_DOUBLE);
        if (out[k] == NULL) {
            while (k-- > 0) Py_DECREF(out[k]);
            return 0;
        }
    }
    return 1;
}

static inline double *data_of(PyArrayObject *a) { return (double *)PyArray_DATA(a); }

/* The number of elements of the numpy array obj, or -1 with a TypeError. */
static npy_intp array_size(PyObject *obj, const char *name) {
    if (!PyArray_Check(obj)) {
        PyErr_Format(PyExc_TypeError, "%s must be a numpy array", name);
        return -1;
    }
    return PyArray_SIZE((PyArrayObject *)obj);
}

/* ---- the cascade (ifc_spg.hqp.DaqpCascade) ----------------------------------------- */

PyDoc_STRVAR(stack_rows_doc,
"stack_rows(levels, A, lower, upper, norm, A_unit, band, lock_tolerance)\n\n"
"Stack the levels' rows and bounds into A (R, n), lower, upper (R,); then per row\n"
"norm = max(|row|_2, 1e-300), A_unit = row / norm and\n"
"band = lock_tolerance (1 + |row|_1) / norm. Levels are (name, A, lower, upper, ...).");

static PyObject *stack_rows(PyObject *self, PyObject *args) {
    PyObject *levels, *A_o, *lo_o, *hi_o, *norm_o, *unit_o, *band_o;
    double tol;
    if (!PyArg_ParseTuple(args, "OOOOOOOd", &levels, &A_o, &lo_o, &hi_o, &norm_o, &unit_o,
                          &band_o, &tol))
        return NULL;
    if (!PyArray_Check(A_o) || PyArray_NDIM((PyArrayObject *)A_o) != 2) {
        PyErr_SetString(PyExc_ValueError, "A must be a 2-D array");
        return NULL;
    }
    npy_intp R = PyArray_DIM((PyArrayObject *)A_o, 0), n = PyArray_DIM((PyArrayObject *)A_o, 1);
    double *A = out_data(A_o, R * n, "A"), *lo = out_data(lo_o, R, "lower"),
           *hi = out_data(hi_o, R, "upper"), *norm = out_data(norm_o, R, "norm"),
           *unit = out_data(unit_o, R * n, "A_unit"), *band = out_data(band_o, R, "band");
    if (!A || !lo || !hi || !norm || !unit || !band) return NULL;
    PyObject *seq = PySequence_Fast(levels, "levels must be a sequence");
    if (seq == NULL) return NULL;
    Py_ssize_t count = PySequence_Fast_GET_SIZE(seq);
    npy_intp row = 0;
    for (Py_ssize_t k = 0; k < count; k++) {
        PyObject *lev = PySequence_Fast_GET_ITEM(seq, k);
        if (!PyTuple_Check(lev) || PyTuple_GET_SIZE(lev) < 4) {
            PyErr_SetString(PyExc_TypeError, "each level must be a Level (name, A, lower, upper, ...)");
            Py_DECREF(seq);
            return NULL;
        }
        PyArrayObject *a = in_array(PyTuple_GET_ITEM(lev, 1), 2, "level.A");
        PyArrayObject *l = a ? in_array(PyTuple_GET_ITEM(lev, 2), 1, "level.lower") : NULL;
        PyArrayObject *u = l ? in_array(PyTuple_GET_ITEM(lev, 3), 1, "level.upper") : NULL;
        if (u == NULL) {
            Py_XDECREF(a);
            Py_XDECREF(l);
            Py_DECREF(seq);
            return NULL;
        }
        npy_intp m = PyArray_DIM(a, 0);
        if (PyArray_DIM(a, 1) != n || PyArray_DIM(l, 0) != m || PyArray_DIM(u, 0) != m ||
            row + m > R) {
            PyErr_Format(PyExc_ValueError,
                         "level %zd: A is %zdx%zd with %zd/%zd bounds; expected %zd columns and "
                         "%zd rows in all", k, (Py_ssize_t)m, (Py_ssize_t)PyArray_DIM(a, 1),
                         (Py_ssize_t)PyArray_DIM(l, 0), (Py_ssize_t)PyArray_DIM(u, 0),
                         (Py_ssize_t)n, (Py_ssize_t)R);
            Py_DECREF(a);
            Py_DECREF(l);
            Py_DECREF(u);
            Py_DECREF(seq);
            return NULL;
        }
        const double *ad = (const double *)PyArray_DATA(a);
        const double *ld = (const double *)PyArray_DATA(l);
        const double *ud = (const double *)PyArray_DATA(u);
        for (npy_intp i = 0; i < m; i++) {
            double *dst = A + (row + i) * n, *udst = unit + (row + i) * n;
            const double *src = ad + i * n;
            double s2 = 0.0, s1 = 0.0;
            for (npy_intp j = 0; j < n; j++) {
                double v = src[j];
                dst[j] = v;
                s2 += v * v;
                s1 += fabs(v);
            }
            double nr = np_max(sqrt(s2), 1e-300);
            for (npy_intp j = 0; j < n; j++) udst[j] = src[j] / nr;
            norm[row + i] = nr;
            band[row + i] = tol * (1.0 + s1) / nr;
            lo[row + i] = ld[i];
            hi[row + i] = ud[i];
        }
        row += m;
        Py_DECREF(a);
        Py_DECREF(l);
        Py_DECREF(u);
    }
    Py_DECREF(seq);
    if (row != R) {
        PyErr_Format(PyExc_ValueError, "the levels have %zd rows, the workspace %zd",
                     (Py_ssize_t)row, (Py_ssize_t)R);
        return NULL;
    }
    Py_RETURN_NONE;
}

PyDoc_STRVAR(normal_form_doc,
"normal_form(A, beta, rho, H, f)\n\n"
"The cost of an equality level without slacks: H = rho I + A^T A, f = -A^T beta\n"
"(A (m, n) and beta (m,) contiguous; H (n, n) and f (n,) are written).");

static PyObject *normal_form(PyObject *self, PyObject *args) {
    PyObject *A_o, *b_o, *H_o, *f_o;
    double rho;
    if (!PyArg_ParseTuple(args, "OOdOO", &A_o, &b_o, &rho, &H_o, &f_o)) return NULL;
    if (!PyArray_Check(A_o) || PyArray_NDIM((PyArrayObject *)A_o) != 2) {
        PyErr_SetString(PyExc_ValueError, "A must be a 2-D array");
        return NULL;
    }
    npy_intp m = PyArray_DIM((PyArrayObject *)A_o, 0), n = PyArray_DIM((PyArrayObject *)A_o, 1);
    const double *A = in_data(A_o, m * n, "A"), *beta = in_data(b_o, m, "beta");
    double *H = out_data(H_o, n * n, "H"), *f = out_data(f_o, n, "f");
    if (!A || !beta || !H || !f) return NULL;
    for (npy_intp j = 0; j < n; j++) {
        for (npy_intp k = j; k < n; k++) {
            double s = 0.0;
            for (npy_intp i = 0; i < m; i++) s += A[i * n + j] * A[i * n + k];
            H[j * n + k] = s;
            H[k * n + j] = s;
        }
        H[j * n + j] += rho;
        double s = 0.0;
        for (npy_intp i = 0; i < m; i++) s += A[i * n + j] * beta[i];
        f[j] = -s;
    }
    Py_RETURN_NONE;
}

PyDoc_STRVAR(accept_doc,
"accept(x, bl, bu, A_unit, norm, beta, band, lock_lo, lock_hi) -> (qdot, slack)\n\n"
"Take an equality level's solution: qdot = x clipped into [bl[:n], bu[:n]],\n"
"a = A_unit qdot (unit-row coordinates), slack = a norm - beta, and unless lock_lo is\n"
"None the lock band lock_lo = a - band, lock_hi = a + band (m rows each).");

static PyObject *accept(PyObject *self, PyObject *args) {
    PyObject *x_o, *bl_o, *bu_o, *U_o, *nr_o, *b_o, *band_o, *llo_o, *lhi_o;
    if (!PyArg_ParseTuple(args, "OOOOOOOOO", &x_o, &bl_o, &bu_o, &U_o, &nr_o, &b_o, &band_o,
                          &llo_o, &lhi_o))
        return NULL;
    if (!PyArray_Check(x_o) || !PyArray_Check(U_o) ||
        PyArray_NDIM((PyArrayObject *)U_o) != 2) {
        PyErr_SetString(PyExc_ValueError, "x must be an array and A_unit a 2-D array");
        return NULL;
    }
    npy_intp m = PyArray_DIM((PyArrayObject *)U_o, 0), n = PyArray_DIM((PyArrayObject *)U_o, 1);
    const double *x = in_data(x_o, n, "x"), *bl = in_data(bl_o, n, "bl"),
                 *bu = in_data(bu_o, n, "bu"), *U = in_data(U_o, m * n, "A_unit"),
                 *nr = in_data(nr_o, m, "norm"), *beta = in_data(b_o, m, "beta"),
                 *band = in_data(band_o, m, "band");
    if (!x || !bl || !bu || !U || !nr || !beta || !band) return NULL;
    double *llo = NULL, *lhi = NULL;
    if (llo_o != Py_None) {
        llo = out_data(llo_o, m, "lock_lo");
        lhi = llo ? out_data(lhi_o, m, "lock_hi") : NULL;
        if (!lhi) return NULL;
    }
    PyArrayObject *v[2];
    const npy_intp sizes[2] = {n, m};
    if (!new_vectors(v, sizes, 2)) return NULL;
    double *qd = data_of(v[0]), *sd = data_of(v[1]);
    for (npy_intp j = 0; j < n; j++) qd[j] = np_min(np_max(x[j], bl[j]), bu[j]);
    for (npy_intp i = 0; i < m; i++) {
        double a = 0.0;
        for (npy_intp j = 0; j < n; j++) a += U[i * n + j] * qd[j];
        sd[i] = a * nr[i] - beta[i];
        if (llo) {
            llo[i] = a - band[i];
            lhi[i] = a + band[i];
        }
    }
    return Py_BuildValue("(NN)", v[0], v[1]);
}

PyDoc_STRVAR(lock_if_satisfied_doc,
"lock_if_satisfied(A, qdot, lower, upper, norm, band, lock_lo, lock_hi) -> bool\n\n"
"If lower <= A qdot <= upper holds on every row (NaN fails), lock the level at its own\n"
"bounds in unit-row coordinates, lock_lo = lower / norm - band and\n"
"lock_hi = upper / norm + band, and return True; otherwise write nothing, return False.");

static PyObject *lock_if_satisfied(PyObject *self, PyObject *args) {
    PyObject *A_o, *q_o, *lo_o, *hi_o, *nr_o, *band_o, *llo_o, *lhi_o;
    if (!PyArg_ParseTuple(args, "OOOOOOOO", &A_o, &q_o, &lo_o, &hi_o, &nr_o, &band_o, &llo_o,
                          &lhi_o))
        return NULL;
    if (!PyArray_Check(A_o) || PyArray_NDIM((PyArrayObject *)A_o) != 2) {
        PyErr_SetString(PyExc_ValueError, "A must be a 2-D array");
        return NULL;
    }
    npy_intp m = PyArray_DIM((PyArrayObject *)A_o, 0), n = PyArray_DIM((PyArrayObject *)A_o, 1);
    const double *A = in_data(A_o, m * n, "A"), *q = in_data(q_o, n, "qdot"),
                 *lo = in_data(lo_o, m, "lower"), *hi = in_data(hi_o, m, "upper"),
                 *nr = in_data(nr_o, m, "norm"), *band = in_data(band_o, m, "band");
    double *llo = out_data(llo_o, m, "lock_lo"), *lhi = out_data(lhi_o, m, "lock_hi");
    if (!A || !q || !lo || !hi || !nr || !band || !llo || !lhi) return NULL;
    for (npy_intp i = 0; i < m; i++) {
        double a = 0.0;
        for (npy_intp j = 0; j < n; j++) a += A[i * n + j] * q[j];
        if (!(lo[i] - a <= 0.0 && a - hi[i] <= 0.0)) Py_RETURN_FALSE;
    }
    for (npy_intp i = 0; i < m; i++) {
        llo[i] = lo[i] / nr[i] - band[i];
        lhi[i] = hi[i] / nr[i] + band[i];
    }
    Py_RETURN_TRUE;
}

PyDoc_STRVAR(slack_setup_doc,
"slack_setup(A_unit, A, start, end, ws_bl, ws_bu, lower, upper, C, bl, bu)\n\n"
"The rows and bounds of an inequality level's slack QP over w = [qdot_v; s]: the first\n"
"n columns of C (end, n + m) get the higher levels' unit rows A_unit[:start] and this\n"
"level's rows A[start:end]; bl/bu (n + m + end) get the box ws_bl/ws_bu[:n], the locks\n"
"ws_bl/ws_bu[n:n + start] and the level's lower/upper[start:end]. The slack columns\n"
"and entries n..n+m of bl/bu are left as they are.");

static PyObject *slack_setup(PyObject *self, PyObject *args) {
    PyObject *U_o, *A_o, *wbl_o, *wbu_o, *lo_o, *hi_o, *C_o, *bl_o, *bu_o;
    Py_ssize_t start, end;
    if (!PyArg_ParseTuple(args, "OOnnOOOOOOO", &U_o, &A_o, &start, &end, &wbl_o, &wbu_o,
                          &lo_o, &hi_o, &C_o, &bl_o, &bu_o))
        return NULL;
    if (!PyArray_Check(U_o) || PyArray_NDIM((PyArrayObject *)U_o) != 2 ||
        !PyArray_Check(C_o) || PyArray_NDIM((PyArrayObject *)C_o) != 2) {
        PyErr_SetString(PyExc_ValueError, "A_unit and C must be 2-D arrays");
        return NULL;
    }
    npy_intp n = PyArray_DIM((PyArrayObject *)U_o, 1), m = end - start;
    npy_intp R = PyArray_DIM((PyArrayObject *)U_o, 0);
    if (start < 0 || m < 1 || end > R || PyArray_DIM((PyArrayObject *)C_o, 0) != end ||
        PyArray_DIM((PyArrayObject *)C_o, 1) != n + m) {
        PyErr_Format(PyExc_ValueError, "rows %zd:%zd of %zd do not fit C (%zd x %zd)",
                     start, end, (Py_ssize_t)R, (Py_ssize_t)PyArray_DIM((PyArrayObject *)C_o, 0),
                     (Py_ssize_t)PyArray_DIM((PyArrayObject *)C_o, 1));
        return NULL;
    }
    const double *U = in_data(U_o, R * n, "A_unit"), *A = in_data(A_o, R * n, "A"),
                 *wbl = in_data(wbl_o, n + start, "ws_bl"),
                 *wbu = in_data(wbu_o, n + start, "ws_bu"), *lo = in_data(lo_o, end, "lower"),
                 *hi = in_data(hi_o, end, "upper");
    double *C = out_data(C_o, end * (n + m), "C"), *bl = out_data(bl_o, n + m + end, "bl"),
           *bu = out_data(bu_o, n + m + end, "bu");
    if (!U || !A || !wbl || !wbu || !lo || !hi || !C || !bl || !bu) return NULL;
    for (npy_intp i = 0; i < end; i++) {
        const double *src = i < start ? U + i * n : A + i * n;
        for (npy_intp j = 0; j < n; j++) C[i * (n + m) + j] = src[j];
    }
    for (npy_intp j = 0; j < n; j++) {
        bl[j] = wbl[j];
        bu[j] = wbu[j];
    }
    for (npy_intp i = 0; i < start; i++) {
        bl[n + m + i] = wbl[n + i];
        bu[n + m + i] = wbu[n + i];
    }
    for (npy_intp i = start; i < end; i++) {
        bl[n + m + i] = lo[i];
        bu[n + m + i] = hi[i];
    }
    Py_RETURN_NONE;
}

PyDoc_STRVAR(accept_slack_doc,
"accept_slack(w, bl, bu, A_unit, norm, lower, upper, band, lock_lo, lock_hi) -> (qdot, s)\n\n"
"Take a slack QP's solution w = [x; s]: qdot = x clipped into [bl[:n], bu[:n]],\n"
"a = (A_unit qdot) norm, and the lock [lower + s, upper + s] widened to contain a (a\n"
"itself on equal rows), in unit-row coordinates, widened by band.");

static PyObject *accept_slack(PyObject *self, PyObject *args) {
    PyObject *w_o, *bl_o, *bu_o, *U_o, *nr_o, *lo_o, *hi_o, *band_o, *llo_o, *lhi_o;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOO", &w_o, &bl_o, &bu_o, &U_o, &nr_o, &lo_o, &hi_o,
                          &band_o, &llo_o, &lhi_o))
        return NULL;
    if (!PyArray_Check(U_o) || PyArray_NDIM((PyArrayObject *)U_o) != 2) {
        PyErr_SetString(PyExc_ValueError, "A_unit must be a 2-D array");
        return NULL;
    }
    npy_intp m = PyArray_DIM((PyArrayObject *)U_o, 0), n = PyArray_DIM((PyArrayObject *)U_o, 1);
    const double *w = in_data(w_o, n + m, "w"), *bl = in_data(bl_o, n, "bl"),
                 *bu = in_data(bu_o, n, "bu"), *U = in_data(U_o, m * n, "A_unit"),
                 *nr = in_data(nr_o, m, "norm"), *lo = in_data(lo_o, m, "lower"),
                 *hi = in_data(hi_o, m, "upper"), *band = in_data(band_o, m, "band");
    double *llo = out_data(llo_o, m, "lock_lo"), *lhi = out_data(lhi_o, m, "lock_hi");
    if (!w || !bl || !bu || !U || !nr || !lo || !hi || !band || !llo || !lhi) return NULL;
    PyArrayObject *v[2];
    const npy_intp sizes[2] = {n, m};
    if (!new_vectors(v, sizes, 2)) return NULL;
    double *qd = data_of(v[0]), *sd = data_of(v[1]);
    for (npy_intp j = 0; j < n; j++) qd[j] = np_min(np_max(w[j], bl[j]), bu[j]);
    for (npy_intp i = 0; i < m; i++) {
        double a = 0.0;
        for (npy_intp j = 0; j < n; j++) a += U[i * n + j] * qd[j];
        a *= nr[i];
        double s = w[n + i];
        sd[i] = s;
        double l, h;
        if (lo[i] == hi[i]) {
            l = h = a;
        } else {
            l = np_min(lo[i] + s, a);
            h = np_max(hi[i] + s, a);
        }
        llo[i] = l / nr[i] - band[i];
        lhi[i] = h / nr[i] + band[i];
    }
    return Py_BuildValue("(NN)", v[0], v[1]);
}

/* ---- the torque-limit level (ifc_spg.limits.torque_limits) --------------------------- */

PyDoc_STRVAR(torque_limit_doc,
"torque_limit(q, qdot, q_v, idx, K, gain, gain_tau, K_over, band, lower, upper)\n"
"    -> (beta_m, beta_M, s, lower', upper')\n\n"
"TorqueLimitLevel.apply on the joints idx (an intp array; None: all): the level's bounds\n"
"K (qdot - gain (q_v - q)) -+ gain_tau (unbounded where not finite), its closed-form\n"
"solution projected onto the box, the slack s (NaN -> 0) and the box narrowed by the lock.");

static PyObject *torque_limit(PyObject *self, PyObject *args) {
    PyObject *q_o, *qd_o, *qv_o, *idx_o, *K_o, *gt_o, *ko_o, *band_o, *lo_o, *hi_o;
    double gain;
    if (!PyArg_ParseTuple(args, "OOOOOdOOOOO", &q_o, &qd_o, &qv_o, &idx_o, &K_o, &gain, &gt_o,
                          &ko_o, &band_o, &lo_o, &hi_o))
        return NULL;
    if (!PyArray_Check(q_o) || !PyArray_Check(K_o)) {
        PyErr_SetString(PyExc_TypeError, "q and K must be numpy arrays");
        return NULL;
    }
    npy_intp n = PyArray_SIZE((PyArrayObject *)q_o), k = PyArray_SIZE((PyArrayObject *)K_o);
    const npy_intp *idx = NULL;
    if (idx_o != Py_None) {
        PyArrayObject *ia = (PyArrayObject *)idx_o;
        if (!PyArray_Check(idx_o) || PyArray_TYPE(ia) != NPY_INTP ||
            !PyArray_IS_C_CONTIGUOUS(ia) || PyArray_SIZE(ia) != k) {
            PyErr_SetString(PyExc_ValueError, "idx must be a contiguous intp array, one per K");
            return NULL;
        }
        idx = (const npy_intp *)PyArray_DATA(ia);
        for (npy_intp j = 0; j < k; j++) {
            if (idx[j] < 0 || idx[j] >= n) {
                PyErr_SetString(PyExc_ValueError, "idx out of range");
                return NULL;
            }
        }
    } else if (k != n) {
        PyErr_SetString(PyExc_ValueError, "K must have one entry per joint when idx is None");
        return NULL;
    }
    const double *q = in_data(q_o, n, "q"), *qd = in_data(qd_o, n, "qdot"),
                 *qv = in_data(qv_o, n, "q_v"), *K = in_data(K_o, k, "K"),
                 *gt = in_data(gt_o, k, "gain_tau"), *ko = in_data(ko_o, k, "K_over"),
                 *band = in_data(band_o, k, "band"), *lo = in_data(lo_o, n, "lower"),
                 *hi = in_data(hi_o, n, "upper");
    if (!q || !qd || !qv || !K || !gt || !ko || !band || !lo || !hi) return NULL;
    PyArrayObject *v[5];
    const npy_intp sizes[5] = {k, k, k, n, n};
    if (!new_vectors(v, sizes, 5)) return NULL;
    double *bl = data_of(v[0]), *bu = data_of(v[1]), *s = data_of(v[2]), *l = data_of(v[3]),
           *u = data_of(v[4]);
    for (npy_intp j = 0; j < n; j++) {
        l[j] = lo[j];
        u[j] = hi[j];
    }
    for (npy_intp t = 0; t < k; t++) {
        npy_intp j = idx ? idx[t] : t;
        double comp = (qd[j] - gain * (qv[j] - q[j])) * K[t];
        double b_lo = comp - gt[t], b_hi = comp + gt[t];
        if (!isfinite(comp)) {
            b_lo = -INFINITY;
            b_hi = INFINITY;
        }
        bl[t] = b_lo;
        bu[t] = b_hi;
        double x = np_min(np_max(0.0, b_lo), b_hi) * ko[t];
        x = np_min(np_max(x, lo[j]), hi[j]);
        double kx = K[t] * x;
        double st = kx - np_min(np_max(kx, b_lo), b_hi);
        if (isnan(st)) st = 0.0;
        s[t] = st;
        l[j] = np_max(lo[j], np_min((b_lo + st) / K[t], x) - band[t]);
        u[j] = np_min(hi[j], np_max((b_hi + st) / K[t], x) + band[t]);
    }
    return Py_BuildValue("(NNNNN)", v[0], v[1], v[2], v[3], v[4]);
}

/* ---- joint limits (ifc_spg.limits.joint_limits) ------------------------------------- */

PyDoc_STRVAR(limits_box_doc,
"limits_box(q_v, q_min, q_max, d_free, k_scale, half_c, inv_dt, v) -> (lower, upper) or None\n\n"
"JointVelocityLimits.box: None where every distance d = [q_v - q_min; q_max - q_v] is at\n"
"least d_free (the constant free box applies), else the stopping-velocity box (2n-vectors\n"
"d_free, k_scale, half_c, v).");

static PyObject *limits_box(PyObject *self, PyObject *args) {
    PyObject *qv_o, *mn_o, *mx_o, *df_o, *ks_o, *hc_o, *v_o;
    double inv_dt;
    if (!PyArg_ParseTuple(args, "OOOOOOdO", &qv_o, &mn_o, &mx_o, &df_o, &ks_o, &hc_o, &inv_dt,
                          &v_o))
        return NULL;
    npy_intp n = array_size(qv_o, "q_v");
    if (n < 0) return NULL;
    const double *qv = in_data(qv_o, n, "q_v"), *mn = in_data(mn_o, n, "q_min"),
                 *mx = in_data(mx_o, n, "q_max"), *df = in_data(df_o, 2 * n, "d_free"),
                 *ks = in_data(ks_o, 2 * n, "k_scale"), *hc = in_data(hc_o, 2 * n, "half_c"),
                 *vmax = in_data(v_o, 2 * n, "v");
    if (!qv || !mn || !mx || !df || !ks || !hc || !vmax) return NULL;
    int free = 1;
    for (npy_intp j = 0; j < n && free; j++)
        free = (qv[j] - mn[j] >= df[j]) && (mx[j] - qv[j] >= df[n + j]);
    if (free) Py_RETURN_NONE;
    PyArrayObject *out[2];
    const npy_intp sizes[2] = {n, n};
    if (!new_vectors(out, sizes, 2)) return NULL;
    double *l = data_of(out[0]), *h = data_of(out[1]);
    for (npy_intp i = 0; i < 2 * n; i++) {
        double d = i < n ? qv[i] - mn[i] : mx[i - n] - qv[i - n];
        d = np_max(d, 0.0);
        double k = floor(sqrt(d * ks[i] + 0.25) - 0.5);
        double k1 = k + 1.0;
        double stop = np_min((d * inv_dt + k * k1 * hc[i]) / k1, vmax[i]);
        if (i < n) l[i] = -stop; else h[i - n] = stop;
    }
    return Py_BuildValue("(NN)", out[0], out[1]);
}

PyDoc_STRVAR(velocity_box_doc,
"velocity_box(lower, upper, pb_lower, pb_upper, qdot_prev, accel) -> (lower, upper)\n\n"
"The tick's box on qdot_v: the joint-limit box intersected with the passivity box (None:\n"
"no PSPM; a NaN bound becomes 0, stopping that joint), then softly with the acceleration\n"
"box [qdot_prev - accel, qdot_prev + accel] (limits.intersect_soft).");

static PyObject *velocity_box(PyObject *self, PyObject *args) {
    PyObject *lo_o, *hi_o, *plo_o, *phi_o, *qp_o, *acc_o;
    if (!PyArg_ParseTuple(args, "OOOOOO", &lo_o, &hi_o, &plo_o, &phi_o, &qp_o, &acc_o))
        return NULL;
    npy_intp n = array_size(qp_o, "qdot_prev");
    if (n < 0) return NULL;
    const double *lo = in_data(lo_o, n, "lower"), *hi = in_data(hi_o, n, "upper"),
                 *qp = in_data(qp_o, n, "qdot_prev"), *acc = in_data(acc_o, n, "accel");
    const double *plo = NULL, *phi = NULL;
    if (!lo || !hi || !qp || !acc) return NULL;
    if (plo_o != Py_None) {
        plo = in_data(plo_o, n, "pb_lower");
        phi = plo ? in_data(phi_o, n, "pb_upper") : NULL;
        if (!phi) return NULL;
    }
    PyArrayObject *v[2];
    const npy_intp sizes[2] = {n, n};
    if (!new_vectors(v, sizes, 2)) return NULL;
    double *l = data_of(v[0]), *u = data_of(v[1]);
    for (npy_intp j = 0; j < n; j++) {
        double a = lo[j], b = hi[j];
        if (plo) {
            a = np_max(a, plo[j]);
            b = np_min(b, phi[j]);
            if (isnan(a)) a = 0.0;
            if (isnan(b)) b = 0.0;
        }
        l[j] = np_min(np_max(qp[j] - acc[j], a), b);
        u[j] = np_max(np_min(qp[j] + acc[j], b), a);
    }
    return Py_BuildValue("(NN)", v[0], v[1]);
}

PyDoc_STRVAR(integrate_doc,
"integrate(q_v, dt, qdot_v, q_min, q_max) -> q_v'\n\n"
"min(max(q_v + dt qdot_v, q_min), q_max) as a new array.");

static PyObject *integrate(PyObject *self, PyObject *args) {
    PyObject *qv_o, *qd_o, *mn_o, *mx_o;
    double dt;
    if (!PyArg_ParseTuple(args, "OdOOO", &qv_o, &dt, &qd_o, &mn_o, &mx_o)) return NULL;
    npy_intp n = array_size(qv_o, "q_v");
    if (n < 0) return NULL;
    const double *qv = in_data(qv_o, n, "q_v"), *qd = in_data(qd_o, n, "qdot_v"),
                 *mn = in_data(mn_o, n, "q_min"), *mx = in_data(mx_o, n, "q_max");
    if (!qv || !qd || !mn || !mx) return NULL;
    PyArrayObject *out;
    if (!new_vectors(&out, &n, 1)) return NULL;
    double *o = data_of(out);
    for (npy_intp j = 0; j < n; j++) o[j] = np_min(np_max(qv[j] + dt * qd[j], mn[j]), mx[j]);
    return (PyObject *)out;
}

/* ---- PSPM (ifc_spg.pspm.EnergyTanks) ------------------------------------------------- */

PyDoc_STRVAR(pspm_bounds_doc,
"pspm_bounds(q, q_v, q_prev, energy, shuffle, D_over_dt, two_over_K, inv_dt, modulated)\n"
"    -> (lower, upper, dissipated_min, avail)\n\n"
"EnergyTanks.bounds: E_Dmin = D/dT (q - q_prev)^2, E_avail = E_r + E_Dmin (+ shuffle unless\n"
"None), r = sqrt(2 E_avail / K + dq^2) with dq = q_v - q, upper = (r - dq)/dT,\n"
"lower = -(r + dq)/dT, unbounded where modulated is 0. modulated is a float array (1 or 0).\n"
"Writes nothing: the caller keeps q as the next tick's q_prev.");

static PyObject *pspm_bounds(PyObject *self, PyObject *args) {
    PyObject *q_o, *qv_o, *qp_o, *e_o, *sh_o, *dd_o, *tk_o, *mod_o;
    double inv_dt;
    if (!PyArg_ParseTuple(args, "OOOOOOOdO", &q_o, &qv_o, &qp_o, &e_o, &sh_o, &dd_o, &tk_o,
                          &inv_dt, &mod_o))
        return NULL;
    npy_intp n = array_size(q_o, "q");
    if (n < 0) return NULL;
    const double *q = in_data(q_o, n, "q"), *qv = in_data(qv_o, n, "q_v"),
                 *e = in_data(e_o, n, "energy"), *dd = in_data(dd_o, n, "D_over_dt"),
                 *tk = in_data(tk_o, n, "two_over_K"), *mod = in_data(mod_o, n, "modulated");
    const double *qp = in_data(qp_o, n, "q_prev");
    const double *sh = NULL;
    if (!q || !qv || !e || !dd || !tk || !mod || !qp) return NULL;
    if (sh_o != Py_None && !(sh = in_data(sh_o, n, "shuffle"))) return NULL;
    PyArrayObject *v[4];
    const npy_intp sizes[4] = {n, n, n, n};
    if (!new_vectors(v, sizes, 4)) return NULL;
    double *l = data_of(v[0]), *u = data_of(v[1]), *dm = data_of(v[2]), *av = data_of(v[3]);
    for (npy_intp j = 0; j < n; j++) {
        double step = q[j] - qp[j];
        step = step * step * dd[j];
        dm[j] = step;
        double avail = e[j] + step;
        if (sh) avail += sh[j];
        av[j] = avail;
        double dq = qv[j] - q[j];
        double r = sqrt(avail * tk[j] + dq * dq);
        if (mod[j] != 0.0) {
            u[j] = (r - dq) * inv_dt;
            l[j] = (r + dq) * -inv_dt;
        } else {
            u[j] = INFINITY;
            l[j] = -INFINITY;
        }
    }
    return Py_BuildValue("(NNNN)", v[0], v[1], v[2], v[3]);
}

PyDoc_STRVAR(pspm_update_doc,
"pspm_update(q, q_v, qdot_v, avail, half_K, dt, max_energy, modulated, energy)\n"
"    -> (energy', dEk, min(energy'))\n\n"
"EnergyTanks.update before its NaN / round-off repair: dEk = K/2 ((dq + dt qdot_v)^2 - dq^2),\n"
"energy' = min(avail - dEk, max_energy), the old energy where modulated is 0; the minimum\n"
"is NaN if any entry is.");

static PyObject *pspm_update(PyObject *self, PyObject *args) {
    PyObject *q_o, *qv_o, *qd_o, *av_o, *hk_o, *mod_o, *e_o;
    double dt, emax;
    if (!PyArg_ParseTuple(args, "OOOOOddOO", &q_o, &qv_o, &qd_o, &av_o, &hk_o, &dt, &emax,
                          &mod_o, &e_o))
        return NULL;
    npy_intp n = array_size(q_o, "q");
    if (n < 0) return NULL;
    const double *q = in_data(q_o, n, "q"), *qv = in_data(qv_o, n, "q_v"),
                 *qd = in_data(qd_o, n, "qdot_v"), *av = in_data(av_o, n, "avail"),
                 *hk = in_data(hk_o, n, "half_K"), *mod = in_data(mod_o, n, "modulated"),
                 *e0 = in_data(e_o, n, "energy");
    if (!q || !qv || !qd || !av || !hk || !mod || !e0) return NULL;
    PyArrayObject *v[2];
    const npy_intp sizes[2] = {n, n};
    if (!new_vectors(v, sizes, 2)) return NULL;
    double *e = data_of(v[0]), *dk = data_of(v[1]);
    double emin = INFINITY;
    for (npy_intp j = 0; j < n; j++) {
        double dq = qv[j] - q[j];
        double nw = qd[j] * dt + dq;
        double d = (nw * nw - dq * dq) * hk[j];
        dk[j] = d;
        e[j] = mod[j] != 0.0 ? np_min(av[j] - d, emax) : e0[j];
        emin = np_min(emin, e[j]);
    }
    return Py_BuildValue("(NNd)", v[0], v[1], emin);
}

/* ---- the tasks (ifc_spg.tasks.task.Task.level) ------------------------------------- */

PyDoc_STRVAR(task_bounds_doc,
"task_bounds(gain, alpha, lower, lower_ff, upper, upper_ff, gamma, kd, zero_gain)"
" -> (beta_lo, beta_hi)\n\n"
"A task's velocity bounds (4.25-4.28): beta_lo = gain (lower - alpha) + ff_lo with\n"
"ff_lo = lower_ff + gamma + kd (gamma, kd: None for none, added in that order), the same\n"
"for beta_hi with upper and upper_ff; upper None: beta_hi is beta_lo (an equality task).\n"
"zero_gain: where lower is -inf, beta_lo is -inf (where upper is +inf, beta_hi is +inf),\n"
"whatever 0 * inf gave. All vectors have m entries; beta_lo and beta_hi are new.");

/* beta = gain (bound - alpha) + ((ff + gamma) + kd), with unbounded sides kept if zero_gain */
static void bound_side(npy_intp m, const double *gain, const double *alpha, const double *b,
                       const double *ff, const double *g, const double *kd, int zero_gain,
                       double inf, double *out) {
    for (npy_intp i = 0; i < m; i++) {
        double f = ff[i];
        if (g) f = f + g[i];
        if (kd) f = f + kd[i];
        out[i] = gain[i] * (b[i] - alpha[i]) + f;
        if (zero_gain && b[i] == inf) out[i] = inf;
    }
}

/* A float64 C-contiguous view of obj (converted if needed) with exactly m entries, or
   NULL with an error; None gives NULL without one if allow_none. New reference. */
static PyArrayObject *in_vector(PyObject *obj, npy_intp m, const char *name) {
    PyArrayObject *a = in_array(obj, 1, name);
    if (a != NULL && PyArray_SIZE(a) != m) {
        PyErr_Format(PyExc_ValueError, "%s must have %zd entries", name, (Py_ssize_t)m);
        Py_DECREF(a);
        return NULL;
    }
    return a;
}

static PyObject *task_bounds(PyObject *self, PyObject *args) {
    PyObject *o[8];
    int zero_gain;
    if (!PyArg_ParseTuple(args, "OOOOOOOOp", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6],
                          &o[7], &zero_gain))
        return NULL;
    static const char *names[8] = {"gain", "alpha", "lower", "lower_ff", "upper", "upper_ff",
                                   "gamma", "kd"};
    PyArrayObject *a[8] = {NULL};
    PyObject *result = NULL;
    npy_intp m = array_size(o[1], "alpha");
    if (m < 0) return NULL;
    int equality = o[4] == Py_None;
    for (int k = 0; k < 8; k++) {
        if (o[k] == Py_None && (k == 6 || k == 7 || (equality && (k == 4 || k == 5)))) continue;
        a[k] = in_vector(o[k], m, names[k]);
        if (a[k] == NULL) goto done;
    }
    const double *v[8];
    for (int k = 0; k < 8; k++) v[k] = a[k] ? data_of(a[k]) : NULL;
    PyArrayObject *out[2];
    const npy_intp sizes[2] = {m, m};
    if (!new_vectors(out, sizes, equality ? 1 : 2)) goto done;
    bound_side(m, v[0], v[1], v[2], v[3], v[6], v[7], zero_gain, -INFINITY, data_of(out[0]));
    if (equality) {
        result = Py_BuildValue("(OO)", out[0], out[0]);
        Py_DECREF(out[0]);
    } else {
        bound_side(m, v[0], v[1], v[4], v[5], v[6], v[7], zero_gain, INFINITY,
                   data_of(out[1]));
        result = Py_BuildValue("(NN)", out[0], out[1]);
    }
done:
    for (int k = 0; k < 8; k++) Py_XDECREF(a[k]);
    return result;
}

/* ---- collision avoidance (ifc_spg.geometry.PairQuery) ---------------------------------- */

PyDoc_STRVAR(collision_rows_doc,
"collision_rows(J, within, found, point_a, point_b, distance, normal, mask_a, mask_b, eps, rows)"
"\n\n"
"Witness points and distance Jacobian rows of the pairs `within` (integer indices of the m\n"
"pairs). found: their witness points [p_a, p_b, p_a, p_b, ...] (2 k 3-vectors, coal's), written\n"
"to point_a[i], point_b[i] (m, 3) first (None: they hold them already). Then per pair i:\n"
"normal[i] = (point_b[i] - point_a[i]) / distance[i] where distance[i] > eps (else normal[i]\n"
"is kept: coal's), and\n"
"rows[i] = (n^T J_v) (mask_b[i] - mask_a[i]) + ((p_b x n)^T J_w) mask_b[i] - ((p_a x n)^T J_w)\n"
"mask_a[i] with J (6, n) the joint Jacobian in the world frame (J_v = J[:3], J_w = J[3:]).\n"
"normal (m, 3); masks and rows (m, n). Writes point_a, point_b, normal and rows (of the pairs\n"
"within only).");

static PyObject *collision_rows(PyObject *self, PyObject *args) {
    PyObject *J_o, *w_o, *f_o, *pa_o, *pb_o, *d_o, *nrm_o, *ma_o, *mb_o, *rows_o;
    double eps;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOdO", &J_o, &w_o, &f_o, &pa_o, &pb_o, &d_o, &nrm_o,
                          &ma_o, &mb_o, &eps, &rows_o))
        return NULL;
    PyArrayObject *J = in_array(J_o, 2, "J");
    if (!J) return NULL;
    PyArrayObject *w = (PyArrayObject *)PyArray_FROMANY(w_o, NPY_INTP, 1, 1,
                                                        NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED);
    if (!w) {
        Py_DECREF(J);
        PyErr_SetString(PyExc_TypeError, "within must be a 1-D integer array");
        return NULL;
    }
    PyObject *ret = NULL;
    npy_intp m = array_size(d_o, "distance"), n = PyArray_DIM(J, 1), k = PyArray_SIZE(w);
    if (m < 0) goto done;
    if (PyArray_DIM(J, 0) != 6) {
        PyErr_SetString(PyExc_ValueError, "J must have 6 rows");
        goto done;
    }
    const double *Jd = (const double *)PyArray_DATA(J), *d = in_data(d_o, m, "distance");
    double *pa = out_data(pa_o, 3 * m, "point_a"), *pb = out_data(pb_o, 3 * m, "point_b");
    const double *ma = in_data(ma_o, m * n, "mask_a"), *mb = in_data(mb_o, m * n, "mask_b");
    double *nrm = out_data(nrm_o, 3 * m, "normal"), *rows = out_data(rows_o, m * n, "rows");
    if (!d || !pa || !pb || !ma || !mb || !nrm || !rows) goto done;
    const npy_intp *idx = (const npy_intp *)PyArray_DATA(w);
    for (npy_intp t = 0; t < k; t++) {
        if (idx[t] < 0 || idx[t] >= m) {
            PyErr_SetString(PyExc_IndexError, "within holds an index outside the pairs");
            goto done;
        }
    }
    if (f_o != Py_None && (!PyList_Check(f_o) || PyList_GET_SIZE(f_o) != 2 * k)) {
        PyErr_SetString(PyExc_ValueError,
                        "found must be a list of 2 points per pair within, or None");
        goto done;
    }
    for (npy_intp t = 0; f_o != Py_None && t < 2 * k; t++) {
        PyArrayObject *v = (PyArrayObject *)PyArray_FROMANY(
            PyList_GET_ITEM(f_o, t), NPY_DOUBLE, 1, 1, NPY_ARRAY_ALIGNED);
        if (!v || PyArray_SIZE(v) != 3) {
            Py_XDECREF(v);
            PyErr_SetString(PyExc_ValueError, "found must hold 3-vectors");
            goto done;
        }
        double *dst = (t % 2 ? pb : pa) + 3 * idx[t / 2];
        for (int c = 0; c < 3; c++) dst[c] = *(const double *)PyArray_GETPTR1(v, c);
        Py_DECREF(v);
    }
    for (npy_intp t = 0; t < k; t++) {
        npy_intp i = idx[t];
        ifc_collision_row(n, Jd, pa + 3 * i, pb + 3 * i, d[i], eps, nrm + 3 * i, ma + n * i,
                          mb + n * i, rows + n * i);
    }
    ret = Py_None;
    Py_INCREF(ret);
done:
    Py_DECREF(J);
    Py_DECREF(w);
    return ret;
}

PyDoc_STRVAR(collision_cull_doc,
"collision_cull(last_bound, lever, q, last_q, influence, distance) -> near\n\n"
"The cull across calls: distance = last_bound - lever @ |q - last_q| (lever (m, n)), and\n"
"near, the indices (int array, ascending) where distance <= influence. Writes distance.");

static PyObject *collision_cull(PyObject *self, PyObject *args) {
    PyObject *lb_o, *lev_o, *q_o, *lq_o, *d_o;
    double influence;
    if (!PyArg_ParseTuple(args, "OOOOdO", &lb_o, &lev_o, &q_o, &lq_o, &influence, &d_o))
        return NULL;
    PyArrayObject *q = in_array(q_o, 1, "q");
    if (!q) return NULL;
    PyObject *ret = NULL;
    npy_intp m = array_size(lb_o, "last_bound"), n = PyArray_SIZE(q);
    if (m < 0) goto done;
    const double *lb = in_data(lb_o, m, "last_bound"), *lev = in_data(lev_o, m * n, "lever");
    const double *lq = in_data(lq_o, n, "last_q"), *qd = (const double *)PyArray_DATA(q);
    double *d = out_data(d_o, m, "distance");
    if (!lb || !lev || !lq || !d) goto done;
    npy_intp count = ifc_collision_cull(m, n, lb, lev, qd, lq, influence, d);
    PyArrayObject *near = (PyArrayObject *)PyArray_SimpleNew(1, &count, NPY_INTP);
    if (!near) goto done;
    npy_intp *out = (npy_intp *)PyArray_DATA(near);
    for (npy_intp i = 0, t = 0; i < m; i++)
        if (d[i] <= influence) out[t++] = i;
    ret = (PyObject *)near;
done:
    Py_DECREF(q);
    return ret;
}

PyDoc_STRVAR(collision_level_doc,
"collision_level(rows, distance, pairs, influence, gain, margin, A, lower) -> within\n\n"
"The velocity damper level of a collision-avoidance task: within, the pairs (int array, in\n"
"the order given) with distance < influence; the first R of them (R = lower's size) fill\n"
"A[t] = rows[p] and lower[t] = -gain (distance[p] - margin), the other rows of A (R, n)\n"
"are zero and their lower bounds -inf. rows (m, n). Writes A and lower.");

static PyObject *collision_level(PyObject *self, PyObject *args) {
    PyObject *rows_o, *d_o, *p_o, *A_o, *lo_o;
    double influence, gain, margin;
    if (!PyArg_ParseTuple(args, "OOOdddOO", &rows_o, &d_o, &p_o, &influence, &gain, &margin,
                          &A_o, &lo_o))
        return NULL;
    PyArrayObject *pairs = (PyArrayObject *)PyArray_FROMANY(
        p_o, NPY_INTP, 1, 1, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED);
    if (!pairs) {
        PyErr_SetString(PyExc_TypeError, "pairs must be a 1-D integer sequence");
        return NULL;
    }
    PyObject *ret = NULL;
    npy_intp m = array_size(d_o, "distance"), R = array_size(lo_o, "lower");
    npy_intp size = array_size(rows_o, "rows"), k = PyArray_SIZE(pairs);
    if (m < 0 || R < 0 || size < 0) goto done;
    npy_intp n = m > 0 ? size / m : 0;
    const double *rows = in_data(rows_o, m * n, "rows"), *d = in_data(d_o, m, "distance");
    double *A = out_data(A_o, R * n, "A"), *lo = out_data(lo_o, R, "lower");
    if (!rows || !d || !A || !lo) goto done;
    const npy_intp *p = (const npy_intp *)PyArray_DATA(pairs);
    npy_intp count = 0;
    for (npy_intp t = 0; t < k; t++) {
        if (p[t] < 0 || p[t] >= m) {
            PyErr_SetString(PyExc_IndexError, "pairs holds an index outside the pairs");
            goto done;
        }
        if (d[p[t]] < influence) count++;
    }
    PyArrayObject *within = (PyArrayObject *)PyArray_SimpleNew(1, &count, NPY_INTP);
    if (!within) goto done;
    ifc_collision_level(k, p, n, rows, d, influence, gain, margin, R, A, lo,
                        (npy_intp *)PyArray_DATA(within));
    ret = (PyObject *)within;
done:
    Py_DECREF(pairs);
    return ret;
}


/* ---- the Cartesian pose task (ifc_spg.tasks.CartesianPoseTask) ------------------------ */

/* pinocchio's TaylorSeriesExpansion<double>::precision<degree>(): eps^(1 / (degree + 1)) */
static double taylor_precision(int degree) {
    return pow(2.220446049250313e-16, 1.0 / (double)(degree + 1));
}

/* pinocchio::internal::compute_theta_axis<i0> (log.hxx), R row-major */
static void theta_axis(int i0, double val, const double *R, double *angle, double axis[3]) {
    const double eps = 2.220446049250313e-16;
    int i1 = (i0 + 1) % 3, i2 = (i0 + 2) % 3;
#define RC(i, j) R[3 * (i) + (j)]
    double s = sqrt(val + eps + eps * eps) * (RC(i2, i1) >= RC(i1, i2) ? 1.0 : -1.0);
    axis[i0] = s / 2.0;
    axis[i1] = 1.0 / (2.0 * s) * (RC(i1, i0) + RC(i0, i1));
    axis[i2] = 1.0 / (2.0 * s) * (RC(i2, i0) + RC(i0, i2));
    double w = 1.0 / (2.0 * s) * (RC(i2, i1) - RC(i1, i2));
#undef RC
    double norm = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    *angle = 2.0 * atan2(norm, w);
    axis[0] /= norm;
    axis[1] /= norm;
    axis[2] /= norm;
}

/* pinocchio::log3 (log3_impl::run, log.hxx) of the row-major rotation R: theta and w. */
static void log3_c(const double *Rin, double *theta, double w[3]) {
    const double eps = 2.220446049250313e-16;
    double c0[3], c1[3], c2[3], Rn[9];
    /* renormalize_rotation_matrix: columns 0 and 1 normalized, 2 = 0 x 1, 0 = 1 x 2 */
    double n0 = sqrt(Rin[0] * Rin[0] + Rin[3] * Rin[3] + Rin[6] * Rin[6]);
    double n1 = sqrt(Rin[1] * Rin[1] + Rin[4] * Rin[4] + Rin[7] * Rin[7]);
    for (int i = 0; i < 3; i++) {
        c0[i] = Rin[3 * i] / n0;
        c1[i] = Rin[3 * i + 1] / n1;
    }
    c2[0] = c0[1] * c1[2] - c0[2] * c1[1];
    c2[1] = c0[2] * c1[0] - c0[0] * c1[2];
    c2[2] = c0[0] * c1[1] - c0[1] * c1[0];
    c0[0] = c1[1] * c2[2] - c1[2] * c2[1];
    c0[1] = c1[2] * c2[0] - c1[0] * c2[2];
    c0[2] = c1[0] * c2[1] - c1[1] * c2[0];
    for (int i = 0; i < 3; i++) {
        Rn[3 * i] = c0[i];
        Rn[3 * i + 1] = c1[i];
        Rn[3 * i + 2] = c2[i];
    }
    const double tr = Rn[0] + Rn[4] + Rn[8];
    const double cos_value = (tr - 1.0) / 2.0;
    const double prec = taylor_precision(2);
    double val[3], ax[3][3], th[3];
    for (int k = 0; k < 3; k++) val[k] = 2.0 * Rn[4 * k] - tr + 1.0;
    for (int k = 0; k < 3; k++) theta_axis(k, val[k], Rn, &th[k], ax[k]);
    int pick = val[0] >= val[1] ? (val[0] >= val[2] ? 0 : 2) : (val[1] >= val[2] ? 1 : 2);
    const double theta_singular = th[pick];
    const double acos_expansion = sqrt(2.0 * (1.0 - cos_value) + eps * eps);
    const double theta_nominal = tr <= 3.0 - prec
        ? (tr >= -1.0 + prec ? acos(cos_value) : M_PI - acos_expansion)
        : acos_expansion;
    double a[3] = {0.5 * (Rn[7] - Rn[5]), 0.5 * (Rn[2] - Rn[6]), 0.5 * (Rn[3] - Rn[1])};
    const double a2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
    const double t = theta_nominal >= prec ? theta_nominal / sin(theta_nominal)
                                           : 1.0 + a2 / 6.0 + a2 * a2 * 3.0 / 40.0;
    int nominal = cos_value >= -1.0 + prec;
    *theta = nominal ? theta_nominal : theta_singular;
    for (int k = 0; k < 3; k++) w[k] = nominal ? t * a[k] : theta_singular * ax[pick][k];
}

/* pinocchio::Jlog3 (Jlog3_impl::run, log.hxx): the 3 x 3 row-major Jlog at theta, w. */
static void jlog3_c(double theta, const double w[3], double *Jl) {
    const double st = sin(theta), ct = cos(theta);
    const double st_1mct = st / (1.0 - ct);
    const double prec = taylor_precision(3);
    const double alpha = theta < prec ? 1.0 / 12.0 + theta * theta / 720.0
                                      : 1.0 / (theta * theta) - st_1mct / (2.0 * theta);
    const double diag = theta < prec ? 0.5 * (2.0 - theta * theta / 6.0)
                                     : 0.5 * (theta * st_1mct);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) Jl[3 * i + j] = alpha * w[i] * w[j] + (i == j ? diag : 0.0);
    Jl[1] -= 0.5 * w[2];
    Jl[2] += 0.5 * w[1];
    Jl[3] += 0.5 * w[2];
    Jl[5] -= 0.5 * w[0];
    Jl[6] -= 0.5 * w[1];
    Jl[7] += 0.5 * w[0];
}

PyDoc_STRVAR(pose_error_doc,
"pose_error(p, p_ref, R, R_ref, J) -> (x, Jx)\n\n"
"A pose task's error and Jacobian (docs/SPEC.md, Orientation): with R_e = R R_ref^T,\n"
"e = log3(R_e) and J_rot = Jlog3(R_e) R_e^T J[3:] (pinocchio's log3 and Jlog3),\n"
"x = (p - p_ref, e) (6,) and\n"
"Jx = (J[:3]; J_rot) (6, n); p and p_ref None: the rotation only, (e (3,), J_rot (3, n)).\n"
"R, R_ref (3, 3); J (6, n), any layout. Returns new arrays.");

static PyObject *pose_error(PyObject *self, PyObject *args) {
    PyObject *p_o, *pr_o, *R_o, *Rr_o, *J_o;
    if (!PyArg_ParseTuple(args, "OOOOO", &p_o, &pr_o, &R_o, &Rr_o, &J_o)) return NULL;
    int rot_only = p_o == Py_None;
    if (rot_only != (pr_o == Py_None)) {
        PyErr_SetString(PyExc_TypeError, "p and p_ref must both be arrays or both None");
        return NULL;
    }
    PyObject *ret = NULL;
    PyArrayObject *pa = NULL, *pra = NULL, *Ra = NULL, *Rra = NULL, *Ja = NULL;
    Ra = in_array(R_o, 2, "R");
    Rra = in_array(Rr_o, 2, "R_ref");
    Ja = (PyArrayObject *)PyArray_FROMANY(J_o, NPY_DOUBLE, 2, 2, NPY_ARRAY_ALIGNED);
    if (!Ra || !Rra || !Ja) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_TypeError, "J must be a 2-D float array");
        goto done;
    }
    if (PyArray_SIZE(Ra) != 9 || PyArray_SIZE(Rra) != 9 || PyArray_DIM(Ja, 0) != 6) {
        PyErr_SetString(PyExc_ValueError, "R and R_ref must be 3 x 3 and J 6 x n");
        goto done;
    }
    if (!rot_only) {
        pa = in_vector(p_o, 3, "p");
        pra = pa ? in_vector(pr_o, 3, "p_ref") : NULL;
        if (!pa || !pra) goto done;
    }
    const double *R = data_of(Ra), *Rr = data_of(Rra);
    double Re[9], Jl[9], M[9], theta, w[3];
    for (int i = 0; i < 3; i++)  /* R_e = R R_ref^T */
        for (int j = 0; j < 3; j++)
            Re[3 * i + j] = R[3 * i] * Rr[3 * j] + R[3 * i + 1] * Rr[3 * j + 1] +
                            R[3 * i + 2] * Rr[3 * j + 2];
    log3_c(Re, &theta, w);
    jlog3_c(theta, w, Jl);
    for (int i = 0; i < 3; i++)  /* M = Jlog3(R_e) R_e^T */
        for (int j = 0; j < 3; j++)
            M[3 * i + j] = Jl[3 * i] * Re[3 * j] + Jl[3 * i + 1] * Re[3 * j + 1] +
                           Jl[3 * i + 2] * Re[3 * j + 2];
    npy_intp n = PyArray_DIM(Ja, 1), rows = rot_only ? 3 : 6;
    npy_intp xdim = rows, Jdims[2] = {rows, n};
    PyArrayObject *x = (PyArrayObject *)PyArray_SimpleNew(1, &xdim, NPY_DOUBLE);
    PyArrayObject *Jx = x ? (PyArrayObject *)PyArray_SimpleNew(2, Jdims, NPY_DOUBLE) : NULL;
    if (!Jx) {
        Py_XDECREF(x);
        goto done;
    }
    const char *Jd = (const char *)PyArray_DATA(Ja);
    const npy_intp s0 = PyArray_STRIDE(Ja, 0), s1 = PyArray_STRIDE(Ja, 1);
#define JE(i, j) (*(const double *)(Jd + (i) * s0 + (j) * s1))
    double *xo = data_of(x), *Jo = data_of(Jx);
    npy_intp off = 0;
    if (!rot_only) {
        const double *p = data_of(pa), *pr = data_of(pra);
        for (int i = 0; i < 3; i++) {
            xo[i] = p[i] - pr[i];
            for (npy_intp j = 0; j < n; j++) Jo[i * n + j] = JE(i, j);
        }
        off = 3;
    }
    for (int i = 0; i < 3; i++) {
        xo[off + i] = w[i];
        for (npy_intp j = 0; j < n; j++)
            Jo[(off + i) * n + j] = M[3 * i] * JE(3, j) + M[3 * i + 1] * JE(4, j) +
                                    M[3 * i + 2] * JE(5, j);
    }
#undef JE
    ret = Py_BuildValue("(NN)", x, Jx);
done:
    Py_XDECREF(pa);
    Py_XDECREF(pra);
    Py_XDECREF(Ra);
    Py_XDECREF(Rra);
    Py_XDECREF(Ja);
    return ret;
}

static PyMethodDef methods[] = {
    {"stack_rows", stack_rows, METH_VARARGS, stack_rows_doc},
    {"normal_form", normal_form, METH_VARARGS, normal_form_doc},
    {"accept", accept, METH_VARARGS, accept_doc},
    {"lock_if_satisfied", lock_if_satisfied, METH_VARARGS, lock_if_satisfied_doc},
    {"slack_setup", slack_setup, METH_VARARGS, slack_setup_doc},
    {"accept_slack", accept_slack, METH_VARARGS, accept_slack_doc},
    {"torque_limit", torque_limit, METH_VARARGS, torque_limit_doc},
    {"limits_box", limits_box, METH_VARARGS, limits_box_doc},
    {"velocity_box", velocity_box, METH_VARARGS, velocity_box_doc},
    {"integrate", integrate, METH_VARARGS, integrate_doc},
    {"pspm_bounds", pspm_bounds, METH_VARARGS, pspm_bounds_doc},
    {"pspm_update", pspm_update, METH_VARARGS, pspm_update_doc},
    {"task_bounds", task_bounds, METH_VARARGS, task_bounds_doc},
    {"collision_rows", collision_rows, METH_VARARGS, collision_rows_doc},
    {"collision_cull", collision_cull, METH_VARARGS, collision_cull_doc},
    {"collision_level", collision_level, METH_VARARGS, collision_level_doc},
    {"pose_error", pose_error, METH_VARARGS, pose_error_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_native",
    "The SPG tick's per-joint and per-row arithmetic in C (numpy versions: the reference).",
    -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__native(void) {
    import_array();
    return PyModule_Create(&module);
}
