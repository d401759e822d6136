/*
 * tb4.core._distance: the exact Euclidean distance transform of a grid (C kernel of tb4.core.distance).
 *
 * Why C: every simulator start computes three of them on warehouse-sized maps (the collision field, the AMCL
 * likelihood field, the global costmap's inflation), and SciPy's cost a noticeable share of a start each, plus the
 * import of scipy.ndimage, in every process and in every test that builds a Simulation.
 *
 * The algorithm is Felzenszwalb and Huttenlocher's (2012): the squared distance to the nearest feature cell is a
 * lower envelope of parabolas, found one dimension at a time, down the columns and then along the rows. All values
 * are whole numbers of squared cells, so the result is exact: the same squared distance as any exact transform,
 * whichever of several equally near features it picks. Plain C99 + the Python C API, the buffer protocol, the GIL
 * released while it runs.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

/* One row or column: d[q] = min over p of (q - p)^2 + f[p], with f[p] = `far` where there is no feature yet. */
static void envelope(const double *f, double *d, Py_ssize_t n, Py_ssize_t *v, double *z) {
    Py_ssize_t k = 0;
    v[0] = 0;
    z[0] = -INFINITY;
    z[1] = INFINITY;
    for (Py_ssize_t q = 1; q < n; q++) {
        double fq = f[q] + (double)q * (double)q, s;
        for (;;) { /* drop the parabolas q's hides; z[0] = -inf stops this at the first */
            Py_ssize_t p = v[k];
            s = (fq - (f[p] + (double)p * (double)p)) / (2.0 * (double)(q - p));
            if (s > z[k]) break;
            k--;
        }
        k++;
        v[k] = q;
        z[k] = s;
        z[k + 1] = INFINITY;
    }
    k = 0;
    for (Py_ssize_t q = 0; q < n; q++) {
        while (z[k + 1] < (double)q) k++;
        double dq = (double)(q - v[k]);
        d[q] = dq * dq + f[v[k]];
    }
}

/* squared(mask, height, width, out): out[r * width + c] = squared distance, in cells, from (r, c) to the nearest
 * cell whose mask byte is non-zero; inf when the mask has none. `out` is a writable float64 buffer. */
static PyObject *squared(PyObject *self, PyObject *args) {
    (void)self;
    Py_buffer mask, out;
    Py_ssize_t h, w;
    if (!PyArg_ParseTuple(args, "y*nnw*", &mask, &h, &w, &out)) return NULL;
    PyObject *result = NULL;
    if (h <= 0 || w <= 0 || mask.len != h * w || out.len != h * w * (Py_ssize_t)sizeof(double)) {
        PyErr_SetString(PyExc_ValueError, "mask must hold height*width bytes and out height*width float64");
        goto done;
    }
    Py_ssize_t n = h > w ? h : w;
    /* larger than any squared distance on the grid, and exact in a double */
    const double far = (double)h * (double)h + (double)w * (double)w + 1.0;
    double *f = malloc((size_t)n * sizeof(double)), *d = malloc((size_t)n * sizeof(double));
    double *z = malloc((size_t)(n + 1) * sizeof(double));
    Py_ssize_t *v = malloc((size_t)n * sizeof(Py_ssize_t));
    if (!f || !d || !z || !v) {
        free(f), free(d), free(z), free(v);
        PyErr_NoMemory();
        goto done;
    }
    const uint8_t *m = mask.buf;
    double *o = out.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t c = 0; c < w; c++) { /* down each column */
        for (Py_ssize_t r = 0; r < h; r++) f[r] = m[r * w + c] ? 0.0 : far;
        envelope(f, d, h, v, z);
        for (Py_ssize_t r = 0; r < h; r++) o[r * w + c] = d[r];
    }
    for (Py_ssize_t r = 0; r < h; r++) { /* then along each row, over the columns' results */
        double *row = o + r * w;
        for (Py_ssize_t c = 0; c < w; c++) f[c] = row[c];
        envelope(f, d, w, v, z);
        for (Py_ssize_t c = 0; c < w; c++) row[c] = d[c] >= far ? INFINITY : d[c];
    }
    Py_END_ALLOW_THREADS
    free(f), free(d), free(z), free(v);
    result = Py_NewRef(Py_None);
done:
    PyBuffer_Release(&mask);
    PyBuffer_Release(&out);
    return result;
}

static PyMethodDef methods[] = {
    {"squared", squared, METH_VARARGS, "squared(mask, height, width, out): squared distances to the nearest set cell"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_distance", NULL, -1, methods};

PyMODINIT_FUNC PyInit__distance(void) { return PyModule_Create(&module); }
