/*
 * tb4.sim._raymarch: the lidar's beam marching through the step table (C kernel of tb4.sim.lidar).
 *
 * Why C: a 360-beam scan is the largest share of the simulator core's time when marched with NumPy (about
 * 40 whole-array passes per scan, each reading 360 scattered cells). Marched beam by beam in C, a scan costs a
 * few microseconds. The kernel is deliberately tiny: plain C99 + the Python C API, arrays read and written
 * through the buffer protocol (no NumPy C API), no Python objects touched while marching, the GIL released.
 *
 * The step table (see Lidar.set_field) holds, per cell, the safe move in half cells: the largest move that
 * cannot enter an occupied cell from anywhere in the cell, at least half a cell, and 0 in occupied cells. A beam
 * moves by its cell's step until it stands in an occupied cell, so its hit lies within its last half-cell move;
 * `bisections` rounds of bisection over that half cell then put the hit near the cell boundary.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>

/* The table cell under (x, y) in cells, or 0 (occupied) outside the table. */
static inline uint8_t step_at(const uint8_t *tab, Py_ssize_t width, Py_ssize_t height, double x, double y) {
    if (!(x >= 0.0 && y >= 0.0)) return 0;
    Py_ssize_t c = (Py_ssize_t)x, r = (Py_ssize_t)y;
    if (c >= width || r >= height) return 0;
    return tab[r * width + c];
}

static void march_all(const uint8_t *tab, Py_ssize_t width, Py_ssize_t height, double x0, double y0,
                      const double *cos_a, const double *sin_a, Py_ssize_t beams, double limit, int bisections,
                      const double inside[4], double *out) {
    for (Py_ssize_t i = 0; i < beams; i++) {
        const double dx = cos_a[i], dy = sin_a[i];
        double t = 0.0;
        int missed = 0;
        for (;;) {
            uint8_t s = step_at(tab, width, height, x0 + t * dx, y0 + t * dy);
            if (s == 0) break;
            t += 0.5 * (double)s;
            if (t >= limit) {
                missed = 1; /* still in free space beyond range_max */
                break;
            }
        }
        if (missed) {
            out[i] = INFINITY;
            continue;
        }
        double lo = t - 0.5, hi = t;
        for (int k = 0; k < bisections; k++) {
            double mid = 0.5 * (lo + hi);
            if (step_at(tab, width, height, x0 + mid * dx, y0 + mid * dy) == 0)
                hi = mid;
            else
                lo = mid;
        }
        double px = x0 + hi * dx, py = y0 + hi * dy;
        double range = 0.5 * (lo + hi);
        /* a hit outside the map proper is a beam that left the map: it sees nothing */
        int off = !(px >= inside[0] && py >= inside[1] && px < inside[2] && py < inside[3]);
        out[i] = (off || range > limit) ? INFINITY : range;
    }
}

PyDoc_STRVAR(march_doc,
             "march(table, width, height, x0, y0, cos_a, sin_a, limit, bisections, inside, out) -> None\n\n"
             "Distance in cells from (x0, y0) (table cells) to the first occupied cell along each beam, written to\n"
             "`out` (float64, one per beam; inf for no hit within `limit` cells or a hit outside `inside` =\n"
             "(x0, y0, x1, y1)). `table` is the row-major uint8 step table (width*height bytes, half cells),\n"
             "cos_a and sin_a the float64 beam directions.");

static PyObject *march(PyObject *self, PyObject *args) {
    Py_buffer tab, cbuf, sbuf, obuf;
    Py_ssize_t width, height;
    double x0, y0, limit, inside[4];
    int bisections;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*nnddy*y*di(dddd)w*", &tab, &width, &height, &x0, &y0, &cbuf, &sbuf, &limit,
                          &bisections, &inside[0], &inside[1], &inside[2], &inside[3], &obuf))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t beams = obuf.len / (Py_ssize_t)sizeof(double);
    if (width <= 0 || height <= 0 || tab.len != width * height) {
        PyErr_Format(PyExc_ValueError, "table has %zd bytes, expected width*height = %zd", tab.len, width * height);
        goto done;
    }
    if (cbuf.len != obuf.len || sbuf.len != obuf.len || obuf.len % (Py_ssize_t)sizeof(double) != 0) {
        PyErr_SetString(PyExc_ValueError, "cos_a, sin_a and out must be float64 arrays of one length");
        goto done;
    }
    if (bisections < 0 || bisections > 60 || !isfinite(limit) || !isfinite(x0) || !isfinite(y0)) {
        PyErr_SetString(PyExc_ValueError, "bad bisections, limit or sensor position");
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS;
    march_all((const uint8_t *)tab.buf, width, height, x0, y0, (const double *)cbuf.buf, (const double *)sbuf.buf,
              beams, limit, bisections, inside, (double *)obuf.buf);
    Py_END_ALLOW_THREADS;
    result = Py_None;
    Py_INCREF(result);
done:
    PyBuffer_Release(&tab);
    PyBuffer_Release(&cbuf);
    PyBuffer_Release(&sbuf);
    PyBuffer_Release(&obuf);
    return result;
}

static PyMethodDef methods[] = {
    {"march", march, METH_VARARGS, march_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_raymarch", "Lidar beam marching through a step table (C kernel of tb4.sim.lidar).",
    -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__raymarch(void) { return PyModule_Create(&module); }
