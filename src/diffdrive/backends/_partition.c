/* The optimal partitioning of diffdrive.estimation.episodes.partition, in C: the same sums in
 * the same order, so the same episodes to the bit; the Python there is its twin. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

#include "_odometry.h"

/* _partition(along, weight, penalty, edge_cost, longest, start): along and weight (n, 2)
 * float64 (each interval's direction times its scaled innovation, and its direction
 * squared); start (n + 1,) float64 is filled with where the chosen episode ending at each
 * index begins (-1: none ends there). */
PyObject *dd_partition(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 6) {
        PyErr_SetString(PyExc_TypeError, "_partition takes 6 arguments");
        return NULL;
    }
    double penalty = PyFloat_AsDouble(args[2]), edge = PyFloat_AsDouble(args[3]);
    Py_ssize_t longest = PyLong_AsSsize_t(args[4]);
    if (PyErr_Occurred()) return NULL;
    Py_buffer views[3];
    int got = 0;
    PyObject *result = NULL;
    double *best = NULL;
    for (; got < 3; ++got) {
        int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (got == 2 ? PyBUF_WRITABLE : 0);
        PyObject *obj = args[got == 2 ? 5 : got];
        if (PyObject_GetBuffer(obj, &views[got], flags) < 0) goto done;
        if (views[got].format == NULL || strcmp(views[got].format, "d") != 0) {
            PyBuffer_Release(&views[got]);
            PyErr_SetString(PyExc_ValueError, "_partition: float64 arrays only");
            goto done;
        }
    }
    Py_ssize_t n = views[0].len / (Py_ssize_t)(2 * sizeof(double));
    if (views[1].len != views[0].len || views[2].len != (n + 1) * (Py_ssize_t)sizeof(double) ||
        longest < 1) {
        PyErr_SetString(PyExc_ValueError, "_partition: along, weight (n, 2), start (n + 1,)");
        goto done;
    }
    const double *along = views[0].buf, *weight = views[1].buf;
    double *start = views[2].buf;
    best = PyMem_Malloc((n + 1) * sizeof(double));
    if (best == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS;
    best[0] = 0.0;
    start[0] = -1.0;
    for (Py_ssize_t end = 1; end <= n; ++end) {
        Py_ssize_t first = end - longest > 0 ? end - longest : 0, pick = -1;
        double pooled[2] = {0.0, 0.0}, spread[2] = {0.0, 0.0}, top = 0.0;
        /* from the end back, as the reversed running sums: the earliest start wins a tie */
        for (Py_ssize_t s = end - 1; s >= first; --s) {
            double ratio[2];
            for (int w = 0; w < 2; ++w) {
                pooled[w] += along[2 * s + w];
                spread[w] += weight[2 * s + w];
                ratio[w] = spread[w] > 0.0 ? pooled[w] * pooled[w] / spread[w] : 0.0;
            }
            double gain = best[s] + (ratio[1] > ratio[0] ? ratio[1] : ratio[0]) - penalty - edge * (double)(end - s);
            if (pick < 0 || gain >= top) {
                top = gain;
                pick = s;
            }
        }
        if (top > best[end - 1]) {
            best[end] = top;
            start[end] = (double)pick;
        } else {
            best[end] = best[end - 1];
            start[end] = -1.0;
        }
    }
    /* back from the end: only the chosen episodes keep their start */
    for (Py_ssize_t end = n; end > 0;) {
        if (start[end] >= 0.0) {
            Py_ssize_t first = (Py_ssize_t)start[end];
            for (Py_ssize_t k = first + 1; k < end; ++k) start[k] = -1.0;
            end = first;
        } else {
            --end;
        }
    }
    Py_END_ALLOW_THREADS;
    result = Py_NewRef(Py_None);
done:
    for (int i = 0; i < got; ++i) PyBuffer_Release(&views[i]);
    PyMem_Free(best);
    return result;
}
