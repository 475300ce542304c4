/* The cascade's DAQP solves called from C (ifc_spg.cascade._daqp_native).
 *
 * A Model is a DAQP workspace over arrays the cascade owns and writes in place (H, f, the
 * stacked rows, the bounds, the level's working set, the solution): one method call per
 * level solve replaces the Python layer of the ``daqp`` module (daqp.Model's update and
 * solve, their argument checks, memoryviews, copies and info dict) and the cascade's
 * working-set bookkeeping (ifc_spg/cascade/daqp.py, _keep_working_set).
 *
 * The DAQP calls are those daqp.Model makes, in the same order: setup_daqp_main at
 * construction (all constraints inactive, DAQP's default settings; primal_tol is set after
 * the setup, as daqp.Model.settings does), then per solve daqp_update_ldp with the parts
 * the caller names (plus the working set) and daqp_solve.
 *
 * They are the functions of the installed ``daqp`` module's own binary (it exports DAQP's
 * C API), looked up at import: the same machine code as the Python path, so both give the
 * same numbers to the last bit. (DAQP's sources compiled here, even with the flags of its
 * setup.py, -O3 -fassociative-math, round differently: GCC 12 vectorizes its reductions
 * otherwise than the GCC 14 that built the wheel; single solves then differ by 1e-14, a
 * 300-tick closed loop by 3e-11.) The types are DAQP's headers from the pinned sdist of
 * that same version (setup.py fetches it; DAQP_VERSION says which).
 *
 * Arrays are C-contiguous float64 (the working set: int32), checked once at construction
 * and held (buffer views) for the model's lifetime.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <dlfcn.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "api.h"
#include "utils.h"

#ifndef IFC_SPG_DAQP_VERSION
#define IFC_SPG_DAQP_VERSION "unknown"
#endif

/* DAQP's functions, from the daqp module's binary (see bind). */
static struct {
    void (*allocate_settings)(DAQPWorkspace *);
    int (*setup_main)(DAQPProblem *, DAQPWorkspace *, c_float *, int);
    int (*update_ldp)(const int, DAQPWorkspace *, DAQPProblem *);
    void (*solve)(DAQPResult *, DAQPWorkspace *);
    void (*free_workspace)(DAQPWorkspace *);
    void (*free_ldp)(DAQPWorkspace *);
} daqp;

/* Why DAQP's functions could not be bound ("" once they are). */
static char unbound[512] = "not bound yet";

/* Look DAQP's functions up in the (imported) daqp module's binary. 0 on success. */
static int bind(void) {
    PyObject *mod = PyImport_ImportModule("daqp");
    if (mod == NULL) {
        PyErr_Clear();
        snprintf(unbound, sizeof unbound, "the daqp module cannot be imported");
        return -1;
    }
    PyObject *file = PyObject_GetAttrString(mod, "__file__");
    Py_DECREF(mod);
    const char *path = file != NULL && PyUnicode_Check(file) ? PyUnicode_AsUTF8(file) : NULL;
    if (path == NULL) {
        PyErr_Clear();
        Py_XDECREF(file);
        snprintf(unbound, sizeof unbound, "the daqp module has no file");
        return -1;
    }
    void *lib = dlopen(path, RTLD_NOW | RTLD_NOLOAD);
    if (lib == NULL) {
        snprintf(unbound, sizeof unbound, "dlopen(%s): %s", path, dlerror());
        Py_DECREF(file);
        return -1;
    }
    Py_DECREF(file);
    static const char *names[] = {"allocate_daqp_settings", "setup_daqp_main", "daqp_update_ldp",
                                  "daqp_solve", "free_daqp_workspace", "free_daqp_ldp"};
    void *fns[6];
    for (int i = 0; i < 6; i++) {
        fns[i] = dlsym(lib, names[i]);
        if (fns[i] == NULL) {
            snprintf(unbound, sizeof unbound, "the daqp module does not export %s", names[i]);
            return -1;  /* (the handle stays open: the module is loaded anyway) */
        }
    }
    *(void **)&daqp.allocate_settings = fns[0];
    *(void **)&daqp.setup_main = fns[1];
    *(void **)&daqp.update_ldp = fns[2];
    *(void **)&daqp.solve = fns[3];
    *(void **)&daqp.free_workspace = fns[4];
    *(void **)&daqp.free_ldp = fns[5];
    /* The binary must lay out DAQP's structs as the headers do (a build with other types,
     * say DAQP_SINGLE_PRECISION, would not): its default settings, read through them. */
    DAQPWorkspace *probe = calloc(1, sizeof(DAQPWorkspace));
    if (probe == NULL) {
        snprintf(unbound, sizeof unbound, "out of memory");
        return -1;
    }
    daqp.allocate_settings(probe);
    const DAQPSettings *st = probe->settings;
    const int same = st != NULL && st->primal_tol == DAQP_DEFAULT_PRIM_TOL &&
                     st->dual_tol == DAQP_DEFAULT_DUAL_TOL &&
                     st->iter_limit == DAQP_DEFAULT_ITER_LIMIT && st->time_limit == 0 &&
                     st->eq_reduction == DAQP_EQ_REDUCTION_AUTO && st->presolve == 1;
    free(probe->settings);
    free(probe);
    if (!same) {
        snprintf(unbound, sizeof unbound,
                 "the daqp module's DAQPSettings differ from DAQP %s's headers",
                 IFC_SPG_DAQP_VERSION);
        return -1;
    }
    unbound[0] = '\0';
    return 0;
}


/* ABI of this module as ifc_spg/cascade/daqp.py expects it (bumped with the interface). */
#define IFC_SPG_DAQP_ABI 2

enum { B_H, B_F, B_A, B_BU, B_BL, B_WARM, B_X, B_COUNT };

typedef struct {
    PyObject_HEAD
    DAQPWorkspace *work;
    DAQPProblem qp;
    Py_buffer buf[B_COUNT];
    int held;          /* buffers acquired so far (released in dealloc) */
    int *cold;         /* the all-inactive sense of the setup */
    double *lam;       /* the multipliers of the last solve */
    int m;
    int iterations;    /* of the last solve */
} Model;

static void Model_dealloc(Model *self) {
    if (self->work != NULL) {
        daqp.free_workspace(self->work);
        daqp.free_ldp(self->work);
        free(self->work);
    }
    for (int i = 0; i < self->held; i++) PyBuffer_Release(&self->buf[i]);
    free(self->cold);
    free(self->lam);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* Acquire obj as a C-contiguous (writable) buffer of `format` with `size` items. */
static int hold(Model *self, int k, PyObject *obj, const char *format, Py_ssize_t size,
                const char *name) {
    Py_buffer *b = &self->buf[k];
    if (PyObject_GetBuffer(obj, b, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_WRITABLE) < 0) {
        PyErr_Format(PyExc_TypeError, "%s must be a writable C-contiguous array", name);
        return -1;
    }
    self->held++;
    if (b->format == NULL || strcmp(b->format, format) != 0 ||
        b->len != size * b->itemsize) {
        PyErr_Format(PyExc_ValueError, "%s must be a %s array of %zd items", name,
                     format[0] == 'd' ? "float64" : "int32", size);
        return -1;
    }
    return 0;
}

static int Model_init(Model *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"H", "f", "A", "bupper", "blower", "sense", "x", "primal_tol",
                             NULL};
    PyObject *H, *f, *A, *bu, *bl, *warm, *x;
    double primal_tol;
    if (self->work != NULL || self->held) {
        PyErr_SetString(PyExc_RuntimeError, "Model is initialized once");
        return -1;
    }
    if (unbound[0]) {
        PyErr_Format(PyExc_RuntimeError, "DAQP is not bound: %s", unbound);
        return -1;
    }
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "OOOOOOOd", kwlist, &H, &f, &A, &bu, &bl,
                                     &warm, &x, &primal_tol))
        return -1;
    /* sizes from f (n), A (rows) and bupper (m) */
    Py_buffer probe;
    if (PyObject_GetBuffer(A, &probe, PyBUF_ND) < 0) return -1;
    int ok = probe.ndim == 2;
    Py_ssize_t mA = ok ? probe.shape[0] : 0, nA = ok ? probe.shape[1] : 0;
    PyBuffer_Release(&probe);
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "A must be 2-D");
        return -1;
    }
    if (PyObject_GetBuffer(bu, &probe, PyBUF_ND) < 0) return -1;
    Py_ssize_t m = probe.ndim == 1 ? probe.shape[0] : -1;
    PyBuffer_Release(&probe);
    Py_ssize_t n = nA;
    if (m < mA || n <= 0 || m > INT32_MAX || n > INT32_MAX) {
        PyErr_SetString(PyExc_ValueError, "bupper must have at least A's rows; A n > 0 columns");
        return -1;
    }
    if (hold(self, B_H, H, "d", n * n, "H") || hold(self, B_F, f, "d", n, "f") ||
        hold(self, B_A, A, "d", mA * n, "A") || hold(self, B_BU, bu, "d", m, "bupper") ||
        hold(self, B_BL, bl, "d", m, "blower") || hold(self, B_WARM, warm, "i", m, "sense") ||
        hold(self, B_X, x, "d", n, "x"))
        return -1;
    self->m = (int)m;
    self->cold = calloc((size_t)(m > 0 ? m : 1), sizeof(int));
    self->lam = calloc((size_t)(m > 0 ? m : 1), sizeof(double));
    self->work = calloc(1, sizeof(DAQPWorkspace));
    if (self->cold == NULL || self->lam == NULL || self->work == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    daqp.allocate_settings(self->work);
    DAQPProblem qp = {(int)n, (int)m, (int)(m - mA), self->buf[B_H].buf, self->buf[B_F].buf,
                      mA ? self->buf[B_A].buf : NULL,
                      m ? self->buf[B_BU].buf : NULL, m ? self->buf[B_BL].buf : NULL,
                      m ? self->cold : NULL, NULL, 0, 0};
    self->qp = qp;
    c_float setup_time = 0.0;
    int flag = daqp.setup_main(&self->qp, self->work, &setup_time, 0);
    if (flag < 0) {
        /* setup_daqp_main freed the settings on failure */
        free(self->work);
        self->work = NULL;
        PyErr_Format(PyExc_ValueError, "DAQP setup failed (exit flag %d)", flag);
        return -1;
    }
    self->work->settings->primal_tol = primal_tol;
    return 0;
}

PyDoc_STRVAR(solve_doc,
"solve(mask) -> exitflag\n\n"
"Update the workspace with the parts ``mask`` names (DAQP_UPDATE_* bits: 1 H, 2 A, 4 f,\n"
"8 bounds; the working set is always taken from ``sense``), solve, and write the solution\n"
"into ``x``. Then ``sense`` is the working set the solve ended with, as\n"
"ifc_spg.cascade.daqp._keep_working_set leaves it: all 0 after a failure, unchanged after\n"
"one iteration, else 1 where the multiplier is not zero, 3 where it is negative.");

static PyObject *Model_solve(Model *self, PyObject *arg) {
    long mask = PyLong_AsLong(arg);
    if (mask == -1 && PyErr_Occurred()) return NULL;
    if (self->work == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "Model is not set up");
        return NULL;
    }
    const int m = self->m;
    int *sense = self->buf[B_WARM].buf;
    self->qp.sense = m ? sense : NULL;
    daqp.update_ldp((int)mask | DAQP_UPDATE_sense, self->work, &self->qp);
    DAQPResult res = {self->buf[B_X].buf, m ? self->lam : NULL, 0, 0, 0, 0, 0, 0, 0};
    daqp.solve(&res, self->work);
    self->iterations = res.iter;
    if (res.exitflag != 1) {
        memset(sense, 0, (size_t)m * sizeof(int));
    } else if (res.iter != 1) {
        const double *lam = self->lam;
        for (int i = 0; i < m; i++)
            sense[i] = lam[i] != 0.0 ? (lam[i] < 0.0 ? 3 : 1) : 0;
    }
    return PyLong_FromLong(res.exitflag);
}

PyDoc_STRVAR(finite_doc,
"finite() -> bool\n\n"
"Whether x @ f is finite: x and the cost finite (the cascade's check of a solution, without\n"
"numpy's call).");

static PyObject *Model_finite(Model *self, PyObject *unused) {
    (void)unused;
    const double *x = self->buf[B_X].buf, *f = self->buf[B_F].buf;
    const Py_ssize_t n = self->buf[B_X].len / (Py_ssize_t)sizeof(double);
    double sum = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) sum += x[i] * f[i];
    return PyBool_FromLong(isfinite(sum));
}

static PyObject *Model_iterations(Model *self, void *closure) {
    (void)closure;
    return PyLong_FromLong(self->iterations);
}

static PyMethodDef Model_methods[] = {
    {"solve", (PyCFunction)Model_solve, METH_O, solve_doc},
    {"finite", (PyCFunction)Model_finite, METH_NOARGS, finite_doc},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef Model_getset[] = {
    {"iterations", (getter)Model_iterations, NULL, "Iterations of the last solve.", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyTypeObject ModelType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "ifc_spg.cascade._daqp_native.Model",
    .tp_basicsize = sizeof(Model),
    .tp_dealloc = (destructor)Model_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Model(H, f, A, bupper, blower, sense, x, primal_tol): a DAQP workspace over "
              "these arrays (see the module docstring).",
    .tp_methods = Model_methods,
    .tp_getset = Model_getset,
    .tp_init = (initproc)Model_init,
    .tp_new = PyType_GenericNew,
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_daqp_native",
    "DAQP level solves from C for ifc_spg.cascade.daqp (see _daqp_native.c).", -1, NULL,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__daqp_native(void) {
    if (PyType_Ready(&ModelType) < 0) return NULL;
    bind();
    PyObject *mod = PyModule_Create(&module);
    if (mod == NULL) return NULL;
    Py_INCREF(&ModelType);
    if (PyModule_AddObject(mod, "Model", (PyObject *)&ModelType) < 0 ||
        PyModule_AddStringConstant(mod, "DAQP_VERSION", IFC_SPG_DAQP_VERSION) < 0 ||
        PyModule_AddStringConstant(mod, "UNBOUND", unbound) < 0 ||
        PyModule_AddIntConstant(mod, "ABI", IFC_SPG_DAQP_ABI) < 0 ||
        PyModule_AddIntConstant(mod, "UPDATE_H", DAQP_UPDATE_Rinv) < 0 ||
        PyModule_AddIntConstant(mod, "UPDATE_A", DAQP_UPDATE_M) < 0 ||
        PyModule_AddIntConstant(mod, "UPDATE_F", DAQP_UPDATE_v) < 0 ||
        PyModule_AddIntConstant(mod, "UPDATE_BOUNDS", DAQP_UPDATE_d) < 0) {
        Py_DECREF(mod);
        return NULL;
    }
    return mod;
}
