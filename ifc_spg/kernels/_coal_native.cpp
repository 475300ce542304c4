// The narrowphase of ifc_spg.geometry.PairQuery in C++: coal distances and witness points of
// many shape pairs in one call (fallback: ifc_spg.geometry.narrowphase.PinocchioPairs).
//
// The shapes are the very coal objects of the pinocchio GeometryModel the Python path queries
// (their C++ pointers, taken from the Python objects through boost.python's converter
// registry, the one pinocchio's and coal's bindings register in), and each distance is coal's
// ComputeDistance with pinocchio's request and placement arithmetic (oMg = oMi * placement,
// pinocchio::updateGeometryPlacements; coal::Transform3s of it, pinocchio::computeDistance), so
// the numbers are the Python path's. What is saved is the Python binding calls: one call
// per tick for all the pairs instead of ~4 per pair.

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include <cmath>
#include <exception>
#include <memory>
#include <vector>

#include <boost/python/converter/from_python.hpp>
#include <boost/python/converter/registered.hpp>
#include <coal/collision_data.h>
#include <coal/config.hh>
#include <coal/distance.h>
#include <pinocchio/spatial.hpp>

#include "collision_core.h"

namespace {

namespace bpc = boost::python::converter;
using SE3 = pinocchio::SE3Tpl<double, 0>;
using SE3Vector = std::vector<SE3>;  // pinocchio::Data::oMi

// Bump when the Python-facing signatures change (ifc_spg.kernels refuses another value).
constexpr long kApi = 2;

struct PairsObject {
    PyObject_HEAD
    std::vector<PyObject *> *owners;  // the Python shapes (kept alive: we use their C++ objects)
    std::vector<const coal::CollisionGeometry *> *shapes;
    std::vector<long> *joint;  // parent joint per shape
    std::vector<SE3> *placement;  // per shape, in its joint's frame
    std::vector<double> *radius;  // bounding sphere about the shape's origin (inf: unbounded)
    std::vector<long> *ia, *ib;
    std::vector<std::unique_ptr<coal::ComputeDistance>> *functors;
    std::vector<SE3> *oMg;  // scratch: shape placements of this call
    std::vector<unsigned long> *placed;  // call stamp of each oMg entry
    unsigned long stamp;
    coal::DistanceRequest *request;
    coal::DistanceResult *result;
    PyObject *data;  // the pinocchio Data of the last call (a strong reference) ...
    const SE3Vector *oMi;  // ... and its joint placements
};

void pairs_free(PairsObject *self) {
    if (self->owners)
        for (PyObject *o : *self->owners) Py_DECREF(o);
    Py_XDECREF(self->data);
    delete self->owners;
    delete self->shapes;
    delete self->joint;
    delete self->placement;
    delete self->radius;
    delete self->ia;
    delete self->ib;
    delete self->functors;
    delete self->oMg;
    delete self->placed;
    delete self->request;
    delete self->result;
}

void pairs_dealloc(PyObject *obj) {
    pairs_free(reinterpret_cast<PairsObject *>(obj));
    Py_TYPE(obj)->tp_free(obj);
}

// A C-contiguous float64 array of `size` elements to read (new reference) or NULL.
PyArrayObject *doubles(PyObject *o, npy_intp size, const char *name) {
    PyArrayObject *a = reinterpret_cast<PyArrayObject *>(
        PyArray_FROMANY(o, NPY_DOUBLE, 0, 0, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED));
    if (!a) return nullptr;
    if (PyArray_SIZE(a) != size) {
        PyErr_Format(PyExc_ValueError, "%s must have %zd elements", name, (Py_ssize_t)size);
        Py_DECREF(a);
        return nullptr;
    }
    return a;
}

// The data pointer of an output array: float64, C-contiguous, writeable, `size` elements.
double *out_data(PyObject *o, npy_intp size, const char *name) {
    if (!PyArray_Check(o)) {
        PyErr_Format(PyExc_TypeError, "%s must be a numpy array", name);
        return nullptr;
    }
    PyArrayObject *a = reinterpret_cast<PyArrayObject *>(o);
    if (PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(a) ||
        !PyArray_ISWRITEABLE(a) || PyArray_SIZE(a) != size) {
        PyErr_Format(PyExc_ValueError,
                     "%s must be a writeable C-contiguous float64 array of %zd elements", name,
                     (Py_ssize_t)size);
        return nullptr;
    }
    return static_cast<double *>(PyArray_DATA(a));
}

SE3 se3_of(const double *R, const double *p) {
    Eigen::Matrix3d rot;
    rot << R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8];
    return SE3(rot, Eigen::Vector3d(p[0], p[1], p[2]));
}

// Pairs(shapes, joints, rotations, translations, radius, pairs, gjk_tolerance)
int pairs_init(PyObject *obj, PyObject *args, PyObject *kwds) {
    PairsObject *self = reinterpret_cast<PairsObject *>(obj);
    PyObject *shapes_o, *joint_o, *rot_o, *trans_o, *rad_o, *pairs_o;
    double tolerance;
    static const char *kwlist[] = {"shapes", "joints", "rotations", "translations", "radius",
                                   "pairs", "gjk_tolerance", nullptr};
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "OOOOOOd", const_cast<char **>(kwlist),
                                     &shapes_o, &joint_o, &rot_o, &trans_o, &rad_o, &pairs_o,
                                     &tolerance))
        return -1;
    pairs_free(self);
    self->owners = new std::vector<PyObject *>();
    self->shapes = new std::vector<const coal::CollisionGeometry *>();
    self->joint = new std::vector<long>();
    self->placement = new std::vector<SE3>();
    self->radius = new std::vector<double>();
    self->ia = new std::vector<long>();
    self->ib = new std::vector<long>();
    self->functors = new std::vector<std::unique_ptr<coal::ComputeDistance>>();
    self->oMg = new std::vector<SE3>();
    self->placed = new std::vector<unsigned long>();
    self->request = new coal::DistanceRequest(true);  // pinocchio::GeometryData's
    self->result = new coal::DistanceResult();
    self->data = nullptr;
    self->oMi = nullptr;
    self->stamp = 0;
    self->request->enable_signed_distance = true;
    self->request->gjk_tolerance = tolerance;
    self->request->enable_cached_gjk_guess = false;

    PyObject *seq = PySequence_Fast(shapes_o, "shapes must be a sequence of coal shapes");
    if (!seq) return -1;
    Py_ssize_t g = PySequence_Fast_GET_SIZE(seq);
    int ret = -1;
    PyArrayObject *joint = nullptr, *rot = nullptr, *trans = nullptr, *rad = nullptr,
                  *pairs = nullptr;
    for (Py_ssize_t i = 0; i < g; i++) {
        PyObject *s = PySequence_Fast_GET_ITEM(seq, i);
        void *p = bpc::get_lvalue_from_python(
            s, bpc::registered<coal::CollisionGeometry>::converters);
        if (!p) {
            PyErr_Format(PyExc_TypeError, "shape %zd is not a coal shape (%s)", i,
                         Py_TYPE(s)->tp_name);
            goto done;
        }
        Py_INCREF(s);
        self->owners->push_back(s);
        self->shapes->push_back(static_cast<const coal::CollisionGeometry *>(p));
    }
    joint = reinterpret_cast<PyArrayObject *>(
        PyArray_FROMANY(joint_o, NPY_LONG, 1, 1, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED));
    if (!joint) goto done;
    rot = doubles(rot_o, 9 * g, "rotations");
    trans = doubles(trans_o, 3 * g, "translations");
    rad = doubles(rad_o, g, "radius");
    pairs = reinterpret_cast<PyArrayObject *>(
        PyArray_FROMANY(pairs_o, NPY_LONG, 2, 2, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED));
    if (!rot || !trans || !rad || !pairs) goto done;
    if (PyArray_SIZE(joint) != g || PyArray_DIM(pairs, 1) != 2) {
        PyErr_SetString(PyExc_ValueError, "joints must have one entry per shape, pairs (m, 2)");
        goto done;
    }
    {
        const long *jd = static_cast<const long *>(PyArray_DATA(joint));
        const double *R = static_cast<const double *>(PyArray_DATA(rot));
        const double *t = static_cast<const double *>(PyArray_DATA(trans));
        const double *r = static_cast<const double *>(PyArray_DATA(rad));
        for (Py_ssize_t i = 0; i < g; i++) {
            if (jd[i] < 0) {
                PyErr_SetString(PyExc_ValueError, "joints must be >= 0");
                goto done;
            }
            self->joint->push_back(jd[i]);
            self->placement->push_back(se3_of(R + 9 * i, t + 3 * i));
            self->radius->push_back(r[i]);
        }
        const long *pd = static_cast<const long *>(PyArray_DATA(pairs));
        npy_intp m = PyArray_DIM(pairs, 0);
        for (npy_intp k = 0; k < m; k++) {
            long a = pd[2 * k], b = pd[2 * k + 1];
            if (a < 0 || b < 0 || a >= g || b >= g || a == b) {
                PyErr_Format(PyExc_ValueError, "pair %zd (%ld, %ld) is not two shapes", k, a,
                             b);
                goto done;
            }
            self->ia->push_back(a);
            self->ib->push_back(b);
            self->functors->emplace_back(
                new coal::ComputeDistance((*self->shapes)[a], (*self->shapes)[b]));
        }
    }
    self->oMg->resize(g);
    self->placed->assign(g, 0);
    ret = 0;
done:
    Py_DECREF(seq);
    Py_XDECREF(joint);
    Py_XDECREF(rot);
    Py_XDECREF(trans);
    Py_XDECREF(rad);
    Py_XDECREF(pairs);
    return ret;
}

// Joint placements of `data` (a pinocchio Data after forwardKinematics); a new call stamp.
bool use_data(PairsObject *self, PyObject *data) {
    if (data != self->data) {
        PyObject *o = PyObject_GetAttrString(data, "oMi");
        if (!o) return false;
        void *p = bpc::get_lvalue_from_python(o, bpc::registered<SE3Vector>::converters);
        Py_DECREF(o);  // the vector is a member of data, which we keep
        if (!p) {
            PyErr_SetString(PyExc_TypeError, "data must be a pinocchio Data (its oMi)");
            return false;
        }
        Py_INCREF(data);
        Py_XSETREF(self->data, data);
        self->oMi = static_cast<const SE3Vector *>(p);
    }
    for (long j : *self->joint)
        if (j >= (long)self->oMi->size()) {
            PyErr_SetString(PyExc_ValueError, "data has fewer joints than the shapes' model");
            return false;
        }
    self->stamp++;
    return true;
}

// pinocchio::updateGeometryPlacements for one shape (once per call).
const SE3 &place(PairsObject *self, long s) {
    SE3 &M = (*self->oMg)[s];
    if ((*self->placed)[s] != self->stamp) {
        long j = (*self->joint)[s];
        if (j > 0)
            M = (*self->oMi)[j] * (*self->placement)[s];
        else
            M = (*self->placement)[s];
        (*self->placed)[s] = self->stamp;
    }
    return M;
}

// pinocchio::computeDistance of pair k at this call's placements.
const coal::DistanceResult &distance(PairsObject *self, long k) {
    const SE3 &A = place(self, (*self->ia)[k]), &B = place(self, (*self->ib)[k]);
    coal::DistanceResult &res = *self->result;
    res.clear();
    coal::Transform3s oM1(A.rotation(), A.translation()), oM2(B.rotation(), B.translation());
    (*(*self->functors)[k])(oM1, oM2, *self->request, res);
    return res;
}

// The narrowphase of the pairs idx[0..k): distance[p] for each; for those within the
// influence distance (written to w, returned: their count) the witness points and, where
// distance <= eps, coal's normal. Throws what coal throws.
npy_intp narrow(PairsObject *self, const npy_intp *idx, npy_intp k, double influence, double eps,
                double *d, double *pa, double *pb, double *nrm, npy_intp *w) {
    npy_intp count = 0;
    for (npy_intp t = 0; t < k; t++) {
        npy_intp p = idx[t];
        const coal::DistanceResult &res = distance(self, p);
        d[p] = res.min_distance;
        if (!(res.min_distance <= influence)) continue;
        w[count++] = p;
        for (int c = 0; c < 3; c++) {
            pa[3 * p + c] = res.nearest_points[0][c];
            pb[3 * p + c] = res.nearest_points[1][c];
        }
        if (res.min_distance <= eps)
            for (int c = 0; c < 3; c++) nrm[3 * p + c] = res.normal[c];
    }
    return count;
}

#define COAL_TRY try {
#define COAL_CATCH                                                  \
    }                                                               \
    catch (const std::exception &e) {                               \
        PyErr_Format(PyExc_RuntimeError, "coal: %s", e.what());     \
        return nullptr;                                             \
    }

const char narrowphase_doc[] =
    "narrowphase(data, near, influence, eps, distance, point_a, point_b, normal) -> within\n\n"
    "coal distances of the pairs `near` (int array, ascending) at the joint placements of the\n"
    "pinocchio Data `data`: distance[p] for each; for those with distance <= influence (within,\n"
    "the returned int array) the witness points point_a[p], point_b[p] (m, 3) in the base frame,\n"
    "and coal's normal[p] where distance <= eps. Nothing else is written.";

PyObject *pairs_narrowphase(PyObject *obj, PyObject *args) {
    PairsObject *self = reinterpret_cast<PairsObject *>(obj);
    PyObject *data, *near_o, *d_o, *pa_o, *pb_o, *n_o;
    double influence, eps;
    if (!PyArg_ParseTuple(args, "OOddOOOO", &data, &near_o, &influence, &eps, &d_o, &pa_o,
                          &pb_o, &n_o))
        return nullptr;
    npy_intp m = (npy_intp)self->ia->size();
    double *d = out_data(d_o, m, "distance"), *pa = out_data(pa_o, 3 * m, "point_a");
    double *pb = out_data(pb_o, 3 * m, "point_b"), *nrm = out_data(n_o, 3 * m, "normal");
    if (!d || !pa || !pb || !nrm) return nullptr;
    PyArrayObject *near = reinterpret_cast<PyArrayObject *>(
        PyArray_FROMANY(near_o, NPY_INTP, 1, 1, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED));
    if (!near) return nullptr;
    npy_intp k = PyArray_SIZE(near);
    const npy_intp *idx = static_cast<const npy_intp *>(PyArray_DATA(near));
    for (npy_intp t = 0; t < k; t++)
        if (idx[t] < 0 || idx[t] >= m) {
            Py_DECREF(near);
            PyErr_SetString(PyExc_IndexError, "near holds an index outside the pairs");
            return nullptr;
        }
    if (!use_data(self, data)) {
        Py_DECREF(near);
        return nullptr;
    }
    PyArrayObject *within =
        reinterpret_cast<PyArrayObject *>(PyArray_SimpleNew(1, &k, NPY_INTP));
    if (!within) {
        Py_DECREF(near);
        return nullptr;
    }
    npy_intp *w = static_cast<npy_intp *>(PyArray_DATA(within)), count = 0;
    try {
        count = narrow(self, idx, k, influence, eps, d, pa, pb, nrm, w);
    } catch (const std::exception &e) {
        Py_DECREF(near);
        Py_DECREF(within);
        PyErr_Format(PyExc_RuntimeError, "coal: %s", e.what());
        return nullptr;
    }
    Py_DECREF(near);
    PyArray_Dims shape = {&count, 1};  // shrink to the pairs within
    PyObject *out = PyArray_Resize(within, &shape, 0, NPY_CORDER);
    if (!out) {
        Py_DECREF(within);
        return nullptr;
    }
    Py_DECREF(out);  // PyArray_Resize returns None (a new reference)
    return reinterpret_cast<PyObject *>(within);
}

const char level_doc[] =
    "level(data, J, q, influence, eps, gain, margin, R, last_bound, lever, last_q, mask_a, mask_b,\n"
    "      normal) -> (distance, exact, rows, point_a, point_b, within, level_pairs, A, lower)\n\n"
    "A collision-avoidance level in one call, the steps of PairQuery.compute(q=...) after its\n"
    "first call and then the kernel collision_level, with the arithmetic of the C kernels\n"
    "(collision_core.h): the cull across calls (distance = last_bound - lever |q - last_q|),\n"
    "coal's distances of the pairs near (distance <= influence; exact there), witness points\n"
    "(NaN elsewhere) and normals of those within, their distance Jacobian rows from J (6, n:\n"
    "data.J; zero rows elsewhere), last_q = q, and the velocity damper rows A (R, n), lower (R,)\n"
    "of the pairs within closer than the influence (level_pairs, ascending; the first R of\n"
    "them). The arrays returned are new; last_q and normal (scratch) are written.";

// The data of an input array: float64, C-contiguous, `size` elements (read only) or NULL.
double *in_data(PyObject *o, npy_intp size, const char *name) {
    if (!PyArray_Check(o)) {
        PyErr_Format(PyExc_TypeError, "%s must be a numpy array", name);
        return nullptr;
    }
    PyArrayObject *a = reinterpret_cast<PyArrayObject *>(o);
    if (PyArray_TYPE(a) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(a) || PyArray_SIZE(a) != size) {
        PyErr_Format(PyExc_ValueError, "%s must be a C-contiguous float64 array of %zd elements",
                     name, (Py_ssize_t)size);
        return nullptr;
    }
    return static_cast<double *>(PyArray_DATA(a));
}

// A new C-contiguous array of `nd` dimensions `dims` and type `type`, filled with `fill`
// (zeros for a bool array) or NULL.
PyArrayObject *filled(int nd, npy_intp *dims, int type, double fill) {
    PyArrayObject *a = reinterpret_cast<PyArrayObject *>(
        type == NPY_DOUBLE && fill != 0.0 ? PyArray_SimpleNew(nd, dims, type)
                                          : PyArray_ZEROS(nd, dims, type, 0));
    if (a && type == NPY_DOUBLE && fill != 0.0) {
        double *p = static_cast<double *>(PyArray_DATA(a));
        for (npy_intp i = 0, size = PyArray_SIZE(a); i < size; i++) p[i] = fill;
    }
    return a;
}

PyObject *pairs_level(PyObject *obj, PyObject *args) {
    PairsObject *self = reinterpret_cast<PairsObject *>(obj);
    PyObject *data, *J_o, *q_o, *lb_o, *lev_o, *lq_o, *ma_o, *mb_o, *nrm_o;
    double influence, eps, gain, margin;
    Py_ssize_t R;
    if (!PyArg_ParseTuple(args, "OOOddddnOOOOOO", &data, &J_o, &q_o, &influence, &eps, &gain,
                          &margin, &R, &lb_o, &lev_o, &lq_o, &ma_o, &mb_o, &nrm_o))
        return nullptr;
    if (R < 0) {
        PyErr_SetString(PyExc_ValueError, "R must be >= 0");
        return nullptr;
    }
    npy_intp m = (npy_intp)self->ia->size();
    PyArrayObject *J = reinterpret_cast<PyArrayObject *>(
        PyArray_FROMANY(J_o, NPY_DOUBLE, 2, 2, NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED));
    if (!J) return nullptr;
    PyArrayObject *q = nullptr, *out[9] = {nullptr};  // d, exact, rows, pa, pb, within, pairs, A, lo
    PyObject *ret = nullptr;
    npy_intp n = PyArray_DIM(J, 1), count = 0, below = 0;
    double *lb, *lev, *lq, *ma, *mb, *nrm, *d, *rows, *pa, *pb, *A, *lo;
    npy_bool *exact;
    npy_intp *w;
    const double *Jd, *qd;
    npy_intp near_count;
    std::vector<npy_intp> near;
    npy_intp d1[1] = {m}, dmn[2] = {m, n}, dm3[2] = {m, 3}, dR[1] = {(npy_intp)R},
             dRn[2] = {(npy_intp)R, n};
    if (PyArray_DIM(J, 0) != 6) {
        PyErr_SetString(PyExc_ValueError, "J must have 6 rows");
        goto done;
    }
    q = doubles(q_o, n, "q");
    if (!q) goto done;
    lb = in_data(lb_o, m, "last_bound");
    lev = lb ? in_data(lev_o, m * n, "lever") : nullptr;
    lq = lev ? out_data(lq_o, n, "last_q") : nullptr;
    ma = lq ? in_data(ma_o, m * n, "mask_a") : nullptr;
    mb = ma ? in_data(mb_o, m * n, "mask_b") : nullptr;
    nrm = mb ? out_data(nrm_o, 3 * m, "normal") : nullptr;
    if (!nrm || !use_data(self, data)) goto done;
    out[0] = reinterpret_cast<PyArrayObject *>(PyArray_SimpleNew(1, d1, NPY_DOUBLE));
    out[1] = filled(1, d1, NPY_BOOL, 0.0);
    out[2] = filled(2, dmn, NPY_DOUBLE, 0.0);
    out[3] = filled(2, dm3, NPY_DOUBLE, NAN);
    out[4] = filled(2, dm3, NPY_DOUBLE, NAN);
    out[7] = reinterpret_cast<PyArrayObject *>(PyArray_SimpleNew(2, dRn, NPY_DOUBLE));
    out[8] = reinterpret_cast<PyArrayObject *>(PyArray_SimpleNew(1, dR, NPY_DOUBLE));
    if (!out[0] || !out[1] || !out[2] || !out[3] || !out[4] || !out[7] || !out[8]) goto done;
    d = static_cast<double *>(PyArray_DATA(out[0]));
    exact = static_cast<npy_bool *>(PyArray_DATA(out[1]));
    rows = static_cast<double *>(PyArray_DATA(out[2]));
    pa = static_cast<double *>(PyArray_DATA(out[3]));
    pb = static_cast<double *>(PyArray_DATA(out[4]));
    A = static_cast<double *>(PyArray_DATA(out[7]));
    lo = static_cast<double *>(PyArray_DATA(out[8]));
    Jd = static_cast<const double *>(PyArray_DATA(J));
    qd = static_cast<const double *>(PyArray_DATA(q));
    near_count = ifc_collision_cull(m, n, lb, lev, qd, lq, influence, d);
    near.reserve(near_count);
    for (npy_intp i = 0; i < m; i++)
        if (d[i] <= influence) near.push_back(i);
    out[5] = reinterpret_cast<PyArrayObject *>(PyArray_SimpleNew(1, &near_count, NPY_INTP));
    if (!out[5]) goto done;
    w = static_cast<npy_intp *>(PyArray_DATA(out[5]));
    try {
        count = narrow(self, near.data(), near_count, influence, eps, d, pa, pb, nrm, w);
    } catch (const std::exception &e) {
        PyErr_Format(PyExc_RuntimeError, "coal: %s", e.what());
        goto done;
    }
    for (npy_intp t = 0; t < count; t++) {
        npy_intp i = w[t];
        ifc_collision_row(n, Jd, pa + 3 * i, pb + 3 * i, d[i], eps, nrm + 3 * i, ma + n * i,
                          mb + n * i, rows + n * i);
    }
    for (npy_intp p : near) exact[p] = 1;
    for (npy_intp j = 0; j < n; j++) lq[j] = qd[j];
    for (npy_intp t = 0; t < count; t++) below += d[w[t]] < influence;
    out[6] = reinterpret_cast<PyArrayObject *>(PyArray_SimpleNew(1, &below, NPY_INTP));
    if (!out[6]) goto done;
    ifc_collision_level(count, w, n, rows, d, influence, gain, margin, R, A, lo,
                        static_cast<npy_intp *>(PyArray_DATA(out[6])));
    {
        PyArray_Dims shape = {&count, 1};  // shrink to the pairs within
        PyObject *none = PyArray_Resize(out[5], &shape, 0, NPY_CORDER);
        if (!none) goto done;
        Py_DECREF(none);  // PyArray_Resize returns None (a new reference)
    }
    ret = PyTuple_New(9);
    if (ret)
        for (int i = 0; i < 9; i++) {
            PyTuple_SET_ITEM(ret, i, reinterpret_cast<PyObject *>(out[i]));  // (steals)
            out[i] = nullptr;
        }
done:
    Py_DECREF(J);
    Py_XDECREF(q);
    for (PyArrayObject *a : out) Py_XDECREF(a);
    return ret;
}

const char distances_doc[] =
    "distances(data, out)\n\n"
    "coal distances of every pair at the joint placements of `data` into out (m,).";

PyObject *pairs_distances(PyObject *obj, PyObject *args) {
    PairsObject *self = reinterpret_cast<PairsObject *>(obj);
    PyObject *data, *out_o;
    if (!PyArg_ParseTuple(args, "OO", &data, &out_o)) return nullptr;
    npy_intp m = (npy_intp)self->ia->size();
    double *out = out_data(out_o, m, "out");
    if (!out || !use_data(self, data)) return nullptr;
    COAL_TRY
    for (npy_intp k = 0; k < m; k++) out[k] = distance(self, k).min_distance;
    COAL_CATCH
    Py_RETURN_NONE;
}

const char gaps_doc[] =
    "gaps(data, out)\n\n"
    "The bounding spheres' gaps of every pair (|c_a - c_b| - r_a - r_b, -inf where a radius is\n"
    "inf) at the joint placements of `data` into out (m,).";

PyObject *pairs_gaps(PyObject *obj, PyObject *args) {
    PairsObject *self = reinterpret_cast<PairsObject *>(obj);
    PyObject *data, *out_o;
    if (!PyArg_ParseTuple(args, "OO", &data, &out_o)) return nullptr;
    npy_intp m = (npy_intp)self->ia->size();
    double *out = out_data(out_o, m, "out");
    if (!out || !use_data(self, data)) return nullptr;
    const std::vector<double> &r = *self->radius;
    for (npy_intp k = 0; k < m; k++) {
        long a = (*self->ia)[k], b = (*self->ib)[k];
        double rsum = r[a] + r[b];
        if (!std::isfinite(rsum)) {
            out[k] = -INFINITY;
            continue;
        }
        Eigen::Vector3d diff = place(self, a).translation() - place(self, b).translation();
        out[k] = std::sqrt(diff.dot(diff)) - rsum;
    }
    Py_RETURN_NONE;
}

const char move_shape_doc[] =
    "move_shape(shape, rotation, translation)\n\n"
    "Place shape `shape` at (rotation (3, 3), translation (3,)) in its joint's frame.";

PyObject *pairs_move_shape(PyObject *obj, PyObject *args) {
    PairsObject *self = reinterpret_cast<PairsObject *>(obj);
    long s;
    PyObject *rot_o, *trans_o;
    if (!PyArg_ParseTuple(args, "lOO", &s, &rot_o, &trans_o)) return nullptr;
    if (s < 0 || s >= (long)self->shapes->size()) {
        PyErr_SetString(PyExc_IndexError, "no such shape");
        return nullptr;
    }
    PyArrayObject *rot = doubles(rot_o, 9, "rotation");
    if (!rot) return nullptr;
    PyArrayObject *trans = doubles(trans_o, 3, "translation");
    if (!trans) {
        Py_DECREF(rot);
        return nullptr;
    }
    (*self->placement)[s] = se3_of(static_cast<const double *>(PyArray_DATA(rot)),
                                   static_cast<const double *>(PyArray_DATA(trans)));
    (*self->placed)[s] = 0;
    Py_DECREF(rot);
    Py_DECREF(trans);
    Py_RETURN_NONE;
}

PyMethodDef pairs_methods[] = {
    {"narrowphase", pairs_narrowphase, METH_VARARGS, narrowphase_doc},
    {"distances", pairs_distances, METH_VARARGS, distances_doc},
    {"level", pairs_level, METH_VARARGS, level_doc},
    {"gaps", pairs_gaps, METH_VARARGS, gaps_doc},
    {"move_shape", pairs_move_shape, METH_VARARGS, move_shape_doc},
    {nullptr, nullptr, 0, nullptr},
};

PyObject *pairs_new(PyTypeObject *type, PyObject *, PyObject *) {
    PyObject *obj = type->tp_alloc(type, 0);  // zeroed: every pointer NULL
    return obj;
}

PyTypeObject PairsType = {PyVarObject_HEAD_INIT(nullptr, 0)};

PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_coal_native",
    "coal distances and witness points of many shape pairs in one call (C++).", -1, nullptr,
    nullptr, nullptr, nullptr, nullptr,
};

}  // namespace

PyMODINIT_FUNC PyInit__coal_native(void) {
    import_array();
    PairsType.tp_name = "ifc_spg.kernels._coal_native.Pairs";
    PairsType.tp_basicsize = sizeof(PairsObject);
    PairsType.tp_flags = Py_TPFLAGS_DEFAULT;
    PairsType.tp_doc =
        "Pairs(shapes, joints, rotations, translations, radius, pairs, gjk_tolerance)\n\n"
        "coal shapes (the Python objects of a pinocchio GeometryModel), their parent joints\n"
        "and placements in them (rotations (g, 3, 3), translations (g, 3)), bounding radii\n"
        "(g,), the pairs (m, 2) of shape indices and GJK's tolerance [m].";
    PairsType.tp_methods = pairs_methods;
    PairsType.tp_new = pairs_new;
    PairsType.tp_init = pairs_init;
    PairsType.tp_dealloc = pairs_dealloc;
    if (PyType_Ready(&PairsType) < 0) return nullptr;
    PyObject *m = PyModule_Create(&module);
    if (!m) return nullptr;
    Py_INCREF(&PairsType);
    if (PyModule_AddObject(m, "Pairs", reinterpret_cast<PyObject *>(&PairsType)) < 0 ||
        PyModule_AddStringConstant(m, "COAL_VERSION", COAL_VERSION) < 0 ||
        PyModule_AddStringConstant(m, "PINOCCHIO_VERSION", PINOCCHIO_VERSION) < 0 ||
        PyModule_AddIntConstant(m, "API", kApi) < 0) {
        Py_DECREF(m);
        return nullptr;
    }
    return m;
}
