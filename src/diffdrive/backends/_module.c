/* The extension diffdrive.backends._odometry: its two types, each from its own source
 * (_odometry.c: OdometryCore; _estimator.c: EstimatorCore, built on the first), and the slip
 * episodes' partitioning (_partition.c). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "_odometry.h"

static PyMethodDef functions[] = {
    {"_partition", (PyCFunction)(void (*)(void))dd_partition, METH_FASTCALL, NULL},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT,
    .m_name = "diffdrive.backends._odometry",
    .m_doc = "The compiled cores of diffdrive.Odometry and diffdrive.estimation.PoseEstimator.",
    .m_size = -1,
    .m_methods = functions,
};

PyMODINIT_FUNC PyInit__odometry(void) {
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    if (odometry_add_type(m) < 0 || estimator_add_type(m) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
