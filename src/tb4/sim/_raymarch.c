/*
 * tb4.sim._raymarch: the lidar's beam marching through the step table (C kernel of tb4.sim.lidar).
 *
 * Why C: a 360-beam scan was the largest share of the simulator core's time when marched with NumPy (tens of
 * whole-array passes per scan, each reading 360 scattered cells). The kernel is deliberately tiny: plain C99 +
 * the Python C API, arrays read and written through the buffer protocol (no NumPy C API), no Python objects
 * touched while marching, the GIL released.
 *
 * It is the NumPy algorithm it replaces, operation for operation, so every range is bit for bit the same and
 * seeded runs replay exactly as before (float32 positions, the same rounding; compile without FMA contraction):
 *  1. sphere tracing: all beams step together by their cell's safe step (half cells; 0 in occupied cells, which
 *     freezes a beam on its hit), for at most `iterations` rounds, until at most `tail_beams` beams are still
 *     moving within range (checked every 4th round);
 *  2. the tail: those beams are sampled every half cell, a chunk at a time (chunks of about `tail_chunk` samples
 *     over all tail beams, 64 to `tail_max` per beam); a chunk without a hit is free up to its last sample plus
 *     that sample's safe step;
 *  3. `bisections` rounds of bisection over each hit's last half cell; hits outside `inside` (the map proper)
 *     and beams still free at `limit` cells see nothing (inf).
 * The table must be padded with occupied cells (Lidar.set_field) so no position leaves it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct {
    const uint8_t *tab;
    Py_ssize_t width, height;
} Table;

/* The step under (x, y) in table cells, as NumPy's tab[int(y), int(x)]; 0 (occupied) outside the table. */
static inline uint8_t step_at(const Table *t, double x, double y) {
    Py_ssize_t c = (Py_ssize_t)x, r = (Py_ssize_t)y;
    if (c < 0 || r < 0 || c >= t->width || r >= t->height) return 0;
    return t->tab[r * t->width + c];
}

/* |re + i im| of a complex64 as NumPy computes it (its SIMD complex absolute: larger * sqrt(ratio^2 + 1), the
 * ratio squared and added in one fused multiply-add), so distances round exactly as in the NumPy version. */
static inline float cabs32(float re, float im) {
    re = fabsf(re);
    im = fabsf(im);
    float larger = re > im ? re : im, smaller = re > im ? im : re;
    if (larger == 0.0f) return 0.0f;
    float ratio = smaller / larger;
    return sqrtf(fmaf(ratio, ratio, 1.0f)) * larger;
}

typedef struct {
    int iterations, tail_beams, tail_chunk, tail_max, bisections;
} Settings;

/* Returns 0 on success, -1 when out of memory. */
static int march_all(const Table *tab, double z0x, double z0y, const double *cos_a, const double *sin_a,
                     Py_ssize_t n, double limit, const Settings *cfg, const Py_ssize_t inside[4], double *out) {
    float *zr = malloc((size_t)n * sizeof(float)), *zi = malloc((size_t)n * sizeof(float));
    float *hr = malloc((size_t)n * sizeof(float)), *hi = malloc((size_t)n * sizeof(float));
    uint8_t *s = malloc((size_t)n), *missed = calloc((size_t)n, 1);
    Py_ssize_t *beams = malloc((size_t)n * sizeof(Py_ssize_t));
    double *t0 = malloc((size_t)n * sizeof(double));
    float *offsets = malloc((size_t)(cfg->tail_max > 0 ? cfg->tail_max : 1) * sizeof(float));
    int ok = zr && zi && hr && hi && s && missed && beams && t0 && offsets;
    if (!ok) goto done;

    const float z0r = (float)z0x, z0i = (float)z0y, limf = (float)limit;
    for (Py_ssize_t i = 0; i < n; i++) {
        zr[i] = z0r;
        zi[i] = z0i;
        hr[i] = (float)(0.5 * cos_a[i]);
        hi[i] = (float)(0.5 * sin_a[i]);
    }
    /* 1. sphere tracing, all beams together */
    for (int it = 0; it < cfg->iterations; it++) {
        for (Py_ssize_t i = 0; i < n; i++) {
            s[i] = step_at(tab, (double)zr[i], (double)zi[i]);
            float step = (float)s[i];
            float dr = step * hr[i], di = step * hi[i];
            zr[i] = zr[i] + dr;
            zi[i] = zi[i] + di;
        }
        if ((it & 3) == 3) {
            Py_ssize_t moving = 0;
            for (Py_ssize_t i = 0; i < n; i++)
                if (s[i] > 0 && cabs32(zr[i] - z0r, zi[i] - z0i) < limf) moving++;
            if (moving <= cfg->tail_beams) break;
        }
    }
    Py_ssize_t nb = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        float dr = zr[i] - z0r, di = zi[i] - z0i;
        out[i] = (double)cabs32(dr, di);
        if (step_at(tab, (double)zr[i], (double)zi[i]) > 0) {
            if (out[i] < limit)
                beams[nb++] = i; /* still moving within range: the tail finishes it */
            else
                missed[i] = 1; /* still in free space beyond range_max */
        }
    }
    /* 2. the tail, a chunk of half-cell samples at a time */
    for (int k = 0; k < cfg->tail_max; k++) offsets[k] = 0.5f * (float)(k + 1);
    for (Py_ssize_t j = 0; j < nb; j++) t0[j] = out[beams[j]];
    while (nb > 0) {
        Py_ssize_t m = cfg->tail_chunk / nb;
        if (m < 64) m = 64;
        if (m > cfg->tail_max) m = cfg->tail_max;
        Py_ssize_t kept = 0;
        for (Py_ssize_t j = 0; j < nb; j++) {
            Py_ssize_t i = beams[j];
            float dkr = (float)cos_a[i], dki = (float)sin_a[i];
            float pr = (float)(z0x + t0[j] * (double)dkr), pi = (float)(z0y + t0[j] * (double)dki);
            Py_ssize_t k;
            uint8_t last = 0;
            for (k = 0; k < m; k++) {
                float ar = offsets[k] * dkr, ai = offsets[k] * dki;
                float qr = pr + ar, qi = pi + ai;
                last = step_at(tab, (double)qr, (double)qi);
                if (last == 0) break;
            }
            if (k < m) {
                out[i] = t0[j] + (double)offsets[k];
                continue;
            }
            double next = t0[j] + ((double)offsets[m - 1] + 0.5 * (double)last);
            if (next >= limit) {
                missed[i] = 1;
                out[i] = limit;
                continue;
            }
            beams[kept] = i;
            t0[kept] = next;
            kept++;
        }
        nb = kept;
    }
    /* 3. bisection over each hit's last half cell */
    for (Py_ssize_t i = 0; i < n; i++) {
        double lo = out[i] - 0.5, hi2 = out[i];
        for (int r = 0; r < cfg->bisections; r++) {
            double mid = 0.5 * (lo + hi2);
            if (step_at(tab, z0x + mid * cos_a[i], z0y + mid * sin_a[i]) == 0)
                hi2 = mid;
            else
                lo = mid;
        }
        double range = 0.5 * (lo + hi2);
        Py_ssize_t px = (Py_ssize_t)(z0x + hi2 * cos_a[i]), py = (Py_ssize_t)(z0y + hi2 * sin_a[i]);
        int off = px < inside[0] || py < inside[1] || px >= inside[2] || py >= inside[3];
        out[i] = (off || missed[i] || range > limit) ? INFINITY : range;
    }
done:
    free(zr);
    free(zi);
    free(hr);
    free(hi);
    free(s);
    free(missed);
    free(beams);
    free(t0);
    free(offsets);
    return ok ? 0 : -1;
}

PyDoc_STRVAR(march_doc,
             "march(table, width, height, x0, y0, cos_a, sin_a, limit, inside, settings, out) -> None\n\n"
             "Distance in cells from (x0, y0) (table cells) to the first occupied cell along each beam, written to\n"
             "`out` (float64, one per beam; inf for no hit within `limit` cells or a hit outside\n"
             "`inside` = (x0, y0, x1, y1), integer table cells). `table` is the row-major uint8 step table\n"
             "(width*height bytes, half cells, padded with occupied cells); cos_a and sin_a the float64 beam\n"
             "directions; settings = (iterations, tail_beams, tail_chunk, tail_max, bisections).");

static PyObject *march(PyObject *self, PyObject *args) {
    Py_buffer tab, cbuf, sbuf, obuf;
    Py_ssize_t width, height, inside[4];
    double x0, y0, limit;
    Settings cfg;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*nnddy*y*d(nnnn)(iiiii)w*", &tab, &width, &height, &x0, &y0, &cbuf, &sbuf, &limit,
                          &inside[0], &inside[1], &inside[2], &inside[3], &cfg.iterations, &cfg.tail_beams,
                          &cfg.tail_chunk, &cfg.tail_max, &cfg.bisections, &obuf))
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
    if (cfg.iterations < 0 || cfg.tail_beams < 0 || cfg.tail_chunk < 1 || cfg.tail_max < 1 || cfg.bisections < 0 ||
        cfg.bisections > 60 || !isfinite(limit) || !isfinite(x0) || !isfinite(y0)) {
        PyErr_SetString(PyExc_ValueError, "bad settings, limit or sensor position");
        goto done;
    }
    Table t = {(const uint8_t *)tab.buf, width, height};
    int status;
    Py_BEGIN_ALLOW_THREADS;
    status = march_all(&t, x0, y0, (const double *)cbuf.buf, (const double *)sbuf.buf, beams, limit, &cfg, inside,
                       (double *)obuf.buf);
    Py_END_ALLOW_THREADS;
    if (status != 0) {
        PyErr_NoMemory();
        goto done;
    }
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
