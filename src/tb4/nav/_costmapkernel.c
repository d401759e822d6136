/*
 * tb4.nav._costmapkernel: the costmaps' per-scan work (C kernel of tb4.nav.local_costmap, the rolling local
 * costmap, and of tb4.nav.obstacle_layer, the global costmap's lidar layer).
 *
 * Why C: raytrace clearing and re-inflation were the largest share of in-process navigation when done with NumPy
 * (every ray sampled into temporary arrays, a Euclidean distance transform per scan). The kernel is plain C99 +
 * the Python C API, arrays read and written through the buffer protocol (no NumPy C API), the GIL released while
 * it works.
 *
 * It is the NumPy code it replaces, operation for operation, so every cleared, marked and inflated cell is the
 * same (compile without FMA contraction):
 *  - raytrace_clear: a ray from the sensor to each end point is sampled every half cell (t = i * res/2, while
 *    t < reach), each sample's cell floor((p - origin) / res) is cleared when it is on the grid (mode 1: the
 *    local costmap's hits leave their end cell; mode 2: the global layer's hits stop half a cell short);
 *  - mark: end points within obstacle_max_range of the sensor mark their cell;
 *  - compose: the static map's LETHAL cells sampled at the window's cell centres (over the window grown by a
 *    margin), the obstacle marks, then inflation (below);
 *  - reinflate: a region of the global static layer with the obstacle marks made LETHAL, inflation (below), one
 *    box of it written out.
 * Inflation stamps a precomputed cost table (inflation_cost of each offset's distance, computed in Python as
 * scipy's distance transform computes it) around every LETHAL cell that borders a non-LETHAL one, then applies
 * inflate()'s rule: max(own cost, inflation cost), an unknown cell overwritten only from INSCRIBED up. The cost
 * is non-increasing in distance, so the largest stamp is the cost of the nearest LETHAL cell, which the distance
 * transform finds (offsets at the same distance have the same cost: tb4.nav.costmap.stamping_is_exact checks
 * both for the parameters in use), and the nearest LETHAL cell of a non-LETHAL cell always borders one.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define INSCRIBED 253
#define LETHAL 254
#define NO_INFORMATION 255

enum { RAY_PLAIN = 0, RAY_KEEP_END = 1, RAY_STOP_SHORT = 2 };

typedef struct {
    double ox, oy, res;
    Py_ssize_t rows, cols;
} Grid;

/* The cell of a coordinate as the NumPy code's floor((v - origin) / res); false when off the grid (NaN, or a
 * value NumPy's int64 conversion would have put off the grid). */
static inline int cell_of(const Grid *g, double x, double y, Py_ssize_t *r, Py_ssize_t *c) {
    /* floor(q) is on [0, n) exactly when q is (n an integer), and there truncation is floor: no floor() call */
    const double qr = (y - g->oy) / g->res, qc = (x - g->ox) / g->res;
    if (!(qr >= 0.0 && qr < (double)g->rows && qc >= 0.0 && qc < (double)g->cols)) return 0;
    *r = (Py_ssize_t)qr;
    *c = (Py_ssize_t)qc;
    return 1;
}

static void clear_rays(uint8_t *grid, const Grid *g, const double *ends, Py_ssize_t n, double sx, double sy,
                       double limit, double clip_range, int mode) {
    const double step = g->res / 2.0;
    for (Py_ssize_t k = 0; k < n; k++) {
        const double ex = ends[2 * k], ey = ends[2 * k + 1];
        const double vx = ex - sx, vy = ey - sy;
        const double length = hypot(vx, vy);
        if (!(length > 1e-9)) continue;
        double reach = length < limit ? length : limit;
        /* the global obstacle layer's hits: stop half a cell short of the end (np.maximum(reach - 0.5 res, 0)) */
        if (mode == RAY_STOP_SHORT && !(length > clip_range)) {
            reach = reach - 0.5 * g->res;
            if (reach < 0.0) reach = 0.0;
        }
        const double ux = vx / length, uy = vy / length;
        /* the end point's own cell, as floor values (an end off the grid matches no sample on it) */
        const double er = floor((ey - g->oy) / g->res), ec = floor((ex - g->ox) / g->res);
        const int keep_end = mode == RAY_KEEP_END && !(length > clip_range);
        for (Py_ssize_t i = 0;; i++) {
            const double t = (double)i * step;
            if (!(t < reach)) break;
            const double px = sx + ux * t, py = sy + uy * t;
            Py_ssize_t r, c;
            if (!cell_of(g, px, py, &r, &c)) continue;
            if (keep_end && (double)r == er && (double)c == ec) continue;
            grid[r * g->cols + c] = 0;
        }
    }
}

static int parse_grid(Py_buffer *buf, Py_ssize_t rows, Py_ssize_t cols, double ox, double oy, double res, Grid *g,
                      const char *what) {
    if (rows <= 0 || cols <= 0 || cols > PY_SSIZE_T_MAX / rows || buf->len != rows * cols) {
        PyErr_Format(PyExc_ValueError, "%s has %zd bytes, expected rows*cols = %zd*%zd", what, buf->len, rows, cols);
        return -1;
    }
    if (!(isfinite(ox) && isfinite(oy) && isfinite(res) && res > 0.0)) {
        PyErr_Format(PyExc_ValueError, "%s: origin must be finite and resolution > 0", what);
        return -1;
    }
    g->ox = ox;
    g->oy = oy;
    g->res = res;
    g->rows = rows;
    g->cols = cols;
    return 0;
}

static int points_len(Py_buffer *buf, Py_ssize_t *n) {
    if (buf->len % (Py_ssize_t)(2 * sizeof(double)) != 0) {
        PyErr_SetString(PyExc_ValueError, "points must be a C-contiguous float64 array of shape (N, 2)");
        return -1;
    }
    *n = buf->len / (Py_ssize_t)(2 * sizeof(double));
    return 0;
}

PyDoc_STRVAR(raytrace_clear_doc,
             "raytrace_clear(grid, rows, cols, origin_x, origin_y, resolution, ends, sensor_x, sensor_y, limit,\n"
             "               clip_range, mode) -> None\n\n"
             "Clear (set to 0) the cells of the row-major uint8/bool `grid` crossed by each ray from the sensor to\n"
             "an end point of `ends` (float64, shape (N, 2), C-contiguous), sampled every half cell up to\n"
             "min(length, limit); rays no longer than 1e-9 are skipped. mode 0: nothing more; mode 1: a ray no\n"
             "longer than clip_range leaves its end point's cell (the local costmap's hits); mode 2: a ray no longer\n"
             "than clip_range stops half a cell short, max(reach - res/2, 0) (the global obstacle layer's hits).");

static PyObject *raytrace_clear(PyObject *self, PyObject *args) {
    Py_buffer gbuf, ebuf;
    Py_ssize_t rows, cols, n;
    double ox, oy, res, sx, sy, limit, clip_range;
    int mode;
    Grid g;
    (void)self;
    if (!PyArg_ParseTuple(args, "w*nndddy*ddddi", &gbuf, &rows, &cols, &ox, &oy, &res, &ebuf, &sx, &sy, &limit,
                          &clip_range, &mode))
        return NULL;
    PyObject *result = NULL;
    if (parse_grid(&gbuf, rows, cols, ox, oy, res, &g, "grid") < 0 || points_len(&ebuf, &n) < 0) goto done;
    if (!(isfinite(sx) && isfinite(sy) && isfinite(limit) && !isnan(clip_range)) || mode < 0 || mode > 2) {
        PyErr_SetString(PyExc_ValueError, "raytrace_clear: bad sensor position, limit, clip_range or mode");
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS;
    clear_rays((uint8_t *)gbuf.buf, &g, (const double *)ebuf.buf, n, sx, sy, limit, clip_range, mode);
    Py_END_ALLOW_THREADS;
    result = Py_None;
    Py_INCREF(result);
done:
    PyBuffer_Release(&gbuf);
    PyBuffer_Release(&ebuf);
    return result;
}

PyDoc_STRVAR(mark_doc,
             "mark(grid, rows, cols, origin_x, origin_y, resolution, points, sensor_x, sensor_y, max_range) -> None\n\n"
             "Set to 1 the cell of every point of `points` (float64, (N, 2)) no farther than max_range from the\n"
             "sensor (hypot) and on the grid.");

static PyObject *mark(PyObject *self, PyObject *args) {
    Py_buffer gbuf, pbuf;
    Py_ssize_t rows, cols, n;
    double ox, oy, res, sx, sy, max_range;
    Grid g;
    (void)self;
    if (!PyArg_ParseTuple(args, "w*nndddy*ddd", &gbuf, &rows, &cols, &ox, &oy, &res, &pbuf, &sx, &sy, &max_range))
        return NULL;
    PyObject *result = NULL;
    if (parse_grid(&gbuf, rows, cols, ox, oy, res, &g, "grid") < 0 || points_len(&pbuf, &n) < 0) goto done;
    uint8_t *grid = (uint8_t *)gbuf.buf;
    const double *p = (const double *)pbuf.buf;
    for (Py_ssize_t k = 0; k < n; k++) {
        const double x = p[2 * k], y = p[2 * k + 1];
        if (!(hypot(x - sx, y - sy) <= max_range)) continue;
        Py_ssize_t r, c;
        if (cell_of(&g, x, y, &r, &c)) grid[r * g.cols + c] = 1;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    PyBuffer_Release(&gbuf);
    PyBuffer_Release(&pbuf);
    return result;
}

/* Inflate the LETHAL cells of `big` (brows x bcols) into out (rows x cols = big[mr:mr+rows, mc:mc+cols]) with
 * the (2k+1)^2 cost table; k < 0: no inflation. As inflate(): each cell gets max(own cost, inflation cost), and a
 * NO_INFORMATION cell keeps NO_INFORMATION unless the inflation cost is INSCRIBED or more. Returns -1 when out
 * of memory. */
static int inflate_window(const uint8_t *big, Py_ssize_t brows, Py_ssize_t bcols, Py_ssize_t mr, Py_ssize_t mc,
                          uint8_t *out, Py_ssize_t rows, Py_ssize_t cols, const uint8_t *table, Py_ssize_t k) {
    for (Py_ssize_t r = 0; r < rows; r++) memcpy(out + r * cols, big + (r + mr) * bcols + mc, (size_t)cols);
    if (k < 0) return 0;
    uint8_t *cost = calloc((size_t)(rows * cols), 1);
    if (!cost) return -1;
    const Py_ssize_t width = 2 * k + 1;
    for (Py_ssize_t br = 0; br < brows; br++) {
        /* rows of the window this cell's stamp reaches */
        const Py_ssize_t r_lo = br - mr - k < 0 ? 0 : br - mr - k;
        const Py_ssize_t r_hi = br - mr + k >= rows ? rows - 1 : br - mr + k;
        if (r_lo > r_hi) continue;
        for (Py_ssize_t bc = 0; bc < bcols; bc++) {
            const Py_ssize_t i = br * bcols + bc;
            if (big[i] != LETHAL) continue;
            /* a LETHAL cell with only LETHAL 4-neighbours (on the grid) is nobody's nearest LETHAL cell */
            if ((br == 0 || big[i - bcols] == LETHAL) && (br == brows - 1 || big[i + bcols] == LETHAL) &&
                (bc == 0 || big[i - 1] == LETHAL) && (bc == bcols - 1 || big[i + 1] == LETHAL))
                continue;
            const Py_ssize_t c_lo = bc - mc - k < 0 ? 0 : bc - mc - k;
            const Py_ssize_t c_hi = bc - mc + k >= cols ? cols - 1 : bc - mc + k;
            if (c_lo > c_hi) continue;
            for (Py_ssize_t r = r_lo; r <= r_hi; r++) {
                const uint8_t *trow = table + (r - (br - mr) + k) * width + k - (bc - mc);
                uint8_t *crow = cost + r * cols;
                for (Py_ssize_t c = c_lo; c <= c_hi; c++)
                    if (trow[c] > crow[c]) crow[c] = trow[c];
            }
        }
    }
    for (Py_ssize_t i = 0; i < rows * cols; i++) {
        if (out[i] == NO_INFORMATION) {
            if (cost[i] >= INSCRIBED) out[i] = cost[i];
        } else if (cost[i] > out[i]) {
            out[i] = cost[i];
        }
    }
    free(cost);
    return 0;
}

PyDoc_STRVAR(compose_doc,
             "compose(out, rows, cols, origin_x, origin_y, resolution, obstacles, static, static_rows,\n"
             "        static_cols, static_origin_x, static_origin_y, static_resolution, margin, table, k) -> None\n\n"
             "The local costmap's window into `out` (uint8, rows x cols): the window grown by `margin` cells gets\n"
             "LETHAL where the `static` costmap (uint8, static_rows x static_cols; static_rows 0 for none) is\n"
             "LETHAL at the cell centre, and the window proper where `obstacles` (bool, rows x cols) is set; that\n"
             "grid is inflated with `table` ((2k+1)^2 uint8 costs by offset; k < 0: no inflation) and its window\n"
             "part written to `out`.");

static PyObject *compose(PyObject *self, PyObject *args) {
    Py_buffer obuf, mbuf, sbuf, tbuf;
    Py_ssize_t rows, cols, srows, scols, margin, k;
    double ox, oy, res, sox, soy, sres;
    Grid win, st = {0.0, 0.0, 1.0, 0, 0};
    (void)self;
    if (!PyArg_ParseTuple(args, "w*nndddy*y*nndddny*n", &obuf, &rows, &cols, &ox, &oy, &res, &mbuf, &sbuf, &srows,
                          &scols, &sox, &soy, &sres, &margin, &tbuf, &k))
        return NULL;
    PyObject *result = NULL;
    uint8_t *big = NULL;
    if (parse_grid(&obuf, rows, cols, ox, oy, res, &win, "out") < 0) goto done;
    if (mbuf.len != obuf.len) {
        PyErr_SetString(PyExc_ValueError, "obstacles must have rows*cols cells");
        goto done;
    }
    if (srows != 0 && parse_grid(&sbuf, srows, scols, sox, soy, sres, &st, "static") < 0) goto done;
    if (margin < 0 || margin > 1 << 20 || k > 1 << 20 || (k >= 0 && tbuf.len != (2 * k + 1) * (2 * k + 1))) {
        PyErr_SetString(PyExc_ValueError, "compose: bad margin, or a table that is not (2k+1)^2 bytes");
        goto done;
    }
    const Py_ssize_t brows = rows + 2 * margin, bcols = cols + 2 * margin;
    big = calloc((size_t)(brows * bcols), 1);
    Py_ssize_t *srow = malloc((size_t)(brows + bcols) * sizeof(Py_ssize_t));
    if (!big || !srow) {
        free(srow);
        PyErr_NoMemory();
        goto done;
    }
    int status = 0;
    Py_BEGIN_ALLOW_THREADS;
    if (srows != 0) {
        /* cell centres of the grown window, as oy + (arange(-margin, rows + margin) + 0.5) * res */
        Py_ssize_t *scol = srow + brows;
        for (Py_ssize_t i = 0; i < brows; i++) {
            const double y = oy + ((double)(i - margin) + 0.5) * res;
            const double f = floor((y - soy) / sres);
            srow[i] = (isfinite(y) && f >= 0.0 && f < (double)srows) ? (Py_ssize_t)f : -1;
        }
        for (Py_ssize_t j = 0; j < bcols; j++) {
            const double x = ox + ((double)(j - margin) + 0.5) * res;
            const double f = floor((x - sox) / sres);
            scol[j] = (isfinite(x) && f >= 0.0 && f < (double)scols) ? (Py_ssize_t)f : -1;
        }
        const uint8_t *s = (const uint8_t *)sbuf.buf;
        for (Py_ssize_t i = 0; i < brows; i++) {
            if (srow[i] < 0) continue;
            const uint8_t *line = s + srow[i] * scols;
            for (Py_ssize_t j = 0; j < bcols; j++)
                if (scol[j] >= 0 && line[scol[j]] == LETHAL) big[i * bcols + j] = LETHAL;
        }
    }
    const uint8_t *marks = (const uint8_t *)mbuf.buf;
    for (Py_ssize_t r = 0; r < rows; r++)
        for (Py_ssize_t c = 0; c < cols; c++)
            if (marks[r * cols + c]) big[(r + margin) * bcols + c + margin] = LETHAL;
    status = inflate_window(big, brows, bcols, margin, margin, (uint8_t *)obuf.buf, rows, cols, (const uint8_t *)tbuf.buf,
                            k);
    Py_END_ALLOW_THREADS;
    free(srow);
    if (status != 0) {
        PyErr_NoMemory();
        goto done;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    free(big);
    PyBuffer_Release(&obuf);
    PyBuffer_Release(&mbuf);
    PyBuffer_Release(&sbuf);
    PyBuffer_Release(&tbuf);
    return result;
}

PyDoc_STRVAR(reinflate_doc,
             "reinflate(out, static, marks, rows, cols, r_lo, r_hi, c_lo, c_hi, box_r_lo, box_r_hi, box_c_lo,\n"
             "          box_c_hi, table, k) -> None\n\n"
             "The global obstacle layer's re-inflation: the region [r_lo, r_hi) x [c_lo, c_hi) of the `static` costmap\n"
             "(uint8, rows x cols) with LETHAL where `marks` (bool, rows x cols) is set, inflated as inflate() does\n"
             "(max of own cost and the `table` cost, (2k+1)^2 uint8 by offset, k < 0: no inflation; a NO_INFORMATION\n"
             "cell only becomes INSCRIBED or LETHAL); the box [box_r_lo, box_r_hi) x [box_c_lo, box_c_hi) of that\n"
             "region (grid coordinates) is written to `out` (uint8, row-major, the box's size).");

static PyObject *reinflate(PyObject *self, PyObject *args) {
    Py_buffer obuf, sbuf, mbuf, tbuf;
    Py_ssize_t rows, cols, rl, rh, cl, ch, br0, br1, bc0, bc1, k;
    (void)self;
    if (!PyArg_ParseTuple(args, "w*y*y*nnnnnnnnnny*n", &obuf, &sbuf, &mbuf, &rows, &cols, &rl, &rh, &cl, &ch, &br0,
                          &br1, &bc0, &bc1, &tbuf, &k))
        return NULL;
    PyObject *result = NULL;
    uint8_t *big = NULL;
    if (rows <= 0 || cols <= 0 || cols > PY_SSIZE_T_MAX / rows || sbuf.len != rows * cols || mbuf.len != sbuf.len) {
        PyErr_SetString(PyExc_ValueError, "reinflate: static and marks must both have rows*cols cells");
        goto done;
    }
    if (!(0 <= rl && rl <= br0 && br0 < br1 && br1 <= rh && rh <= rows && 0 <= cl && cl <= bc0 && bc0 < bc1 &&
          bc1 <= ch && ch <= cols) ||
        obuf.len != (br1 - br0) * (bc1 - bc0)) {
        PyErr_SetString(PyExc_ValueError, "reinflate: the box must lie in the region, the region in the grid, and "
                                          "out must have the box's size");
        goto done;
    }
    if (k > 1 << 20 || (k >= 0 && tbuf.len != (2 * k + 1) * (2 * k + 1))) {
        PyErr_SetString(PyExc_ValueError, "reinflate: a table that is not (2k+1)^2 bytes");
        goto done;
    }
    const Py_ssize_t brows = rh - rl, bcols = ch - cl;
    big = malloc((size_t)(brows * bcols));
    if (!big) {
        PyErr_NoMemory();
        goto done;
    }
    int status = 0;
    const uint8_t *st = (const uint8_t *)sbuf.buf, *marks = (const uint8_t *)mbuf.buf;
    Py_BEGIN_ALLOW_THREADS;
    for (Py_ssize_t r = 0; r < brows; r++) {
        const uint8_t *srow = st + (r + rl) * cols + cl, *mrow = marks + (r + rl) * cols + cl;
        uint8_t *brow = big + r * bcols;
        for (Py_ssize_t c = 0; c < bcols; c++) brow[c] = mrow[c] ? LETHAL : srow[c];
    }
    status = inflate_window(big, brows, bcols, br0 - rl, bc0 - cl, (uint8_t *)obuf.buf, br1 - br0, bc1 - bc0,
                            (const uint8_t *)tbuf.buf, k);
    Py_END_ALLOW_THREADS;
    if (status != 0) {
        PyErr_NoMemory();
        goto done;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    free(big);
    PyBuffer_Release(&obuf);
    PyBuffer_Release(&sbuf);
    PyBuffer_Release(&mbuf);
    PyBuffer_Release(&tbuf);
    return result;
}

static PyMethodDef methods[] = {
    {"raytrace_clear", raytrace_clear, METH_VARARGS, raytrace_clear_doc},
    {"mark", mark, METH_VARARGS, mark_doc},
    {"compose", compose, METH_VARARGS, compose_doc},
    {"reinflate", reinflate, METH_VARARGS, reinflate_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_costmapkernel",
    "Raytrace clearing, marking and inflation of the local costmap and the global obstacle layer (C kernel of\n"
    "tb4.nav.local_costmap and tb4.nav.obstacle_layer).",
    -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__costmapkernel(void) { return PyModule_Create(&module); }
