/*
 * tb4.nav._gridsearch: optimal A* over an 8-connected uint8 costmap (Nav2 cost values).
 *
 * Why C: the global planner must answer a cross-warehouse request (~420k cells) in a few milliseconds,
 * which a Python or NumPy search cannot do. The kernel is deliberately tiny: plain C99 + the Python C API,
 * the costmap read through the buffer protocol (no NumPy C API), all arrays allocated up front (and reused
 * by the next call), no Python objects touched while searching, and the GIL released during the search.
 *
 * Cost model (NavFn-like): entering a cell with cost c costs step * (neutral_cost + cost_factor * c),
 * step = 1 for the 4 straight and sqrt(2) for the 4 diagonal neighbours. Cells with c >= 253 (inscribed,
 * lethal) cannot be entered; NO_INFORMATION (255) costs `unknown_cost` when allow_unknown, else is blocked.
 * The heuristic min_weight * octile_distance is consistent, so the first time the goal is popped its cost
 * is optimal.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define SQRT2 1.4142135623730951

typedef struct {
    double f;     /* g + heuristic: the heap key */
    int32_t node; /* cell index */
    int32_t pad;
} Entry;

#define UNSEEN (-1)
#define CLOSED (-2)
#define STACKED (-3)

typedef struct {
    double *g;       /* best known cost from the start */
    int32_t *parent; /* predecessor on the best known path */
    int32_t *pos;    /* heap position, UNSEEN, STACKED or CLOSED (never reopened: the heuristic is consistent) */
    Entry *heap;     /* indexed 4-ary min-heap (decrease-key keeps one entry per cell: size <= cells) */
    size_t size;
    int32_t *stack;  /* cells reached with the minimum open f: expanded next, without heap work */
    size_t depth;
    size_t capacity; /* cells the arrays can hold */
} Search;

/* Smaller f first. No tie-breaking on g: reading g[] of both entries costs a cache miss per comparison,
 * which (measured) is slower than the extra expansions it saves; the optimum is the same. */
#define LESS(a, b) ((a).f < (b).f)

static inline void sift_up(Search *s, size_t i, Entry e) {
    Entry *h = s->heap;
    int32_t *pos = s->pos;
    while (i > 0) {
        size_t p = (i - 1) >> 2;
        if (!LESS(e, h[p])) break;
        h[i] = h[p];
        pos[h[i].node] = (int32_t)i;
        i = p;
    }
    h[i] = e;
    pos[e.node] = (int32_t)i;
}

static inline int32_t pop(Search *s) {
    Entry *h = s->heap;
    int32_t *pos = s->pos;
    int32_t top = h[0].node;
    Entry last = h[--s->size];
    size_t n = s->size, i = 0;
    if (n > 0) {
        for (;;) {
            size_t c = 4 * i + 1;
            if (c >= n) break;
            size_t best = c;
            size_t end = c + 4 < n ? c + 4 : n;
            for (size_t k = c + 1; k < end; k++)
                if (LESS(h[k], h[best])) best = k;
            if (!LESS(h[best], last)) break;
            h[i] = h[best];
            pos[h[i].node] = (int32_t)i;
            i = best;
        }
        h[i] = last;
        pos[last.node] = (int32_t)i;
    }
    return top;
}

static inline double octile(int32_t r0, int32_t c0, int32_t r1, int32_t c1) {
    int32_t dr = r0 > r1 ? r0 - r1 : r1 - r0;
    int32_t dc = c0 > c1 ? c0 - c1 : c1 - c0;
    int32_t lo = dr < dc ? dr : dc;
    int32_t hi = dr < dc ? dc : dr;
    return (double)hi + (SQRT2 - 1.0) * (double)lo;
}

/* Returns 1 if the goal was reached, 0 if unreachable. Fills s->parent. */
static int run_search(Search *s, const uint8_t *costs, int32_t width, int32_t height, int32_t start, int32_t goal,
                      const double *weight, double hscale) {
    static const int32_t dr[8] = {0, 0, 1, -1, 1, 1, -1, -1};
    static const int32_t dc[8] = {1, -1, 0, 0, 1, -1, 1, -1};
    static const double step[8] = {1.0, 1.0, 1.0, 1.0, SQRT2, SQRT2, SQRT2, SQRT2};
    const int32_t gr = goal / width, gc = goal % width;
    const int32_t n = width * height;

    for (int32_t i = 0; i < n; i++) s->g[i] = INFINITY;
    memset(s->pos, 0xff, (size_t)n * sizeof(int32_t)); /* all UNSEEN (-1) */
    s->size = 0;

    s->g[start] = 0.0;
    s->parent[start] = -1;
    s->stack[0] = start;
    s->pos[start] = STACKED;
    s->depth = 1;
    double fmin = hscale * octile(start / width, start % width, gr, gc); /* f of the last heap pop */

    /*
     * A cell reached with f equal to the minimum f of the open cells (fmin, the f of the last heap pop, up to
     * rounding) may be expanded next in a valid A* order; its g is then final (every other path to it has
     * f >= that minimum). Such cells go on a stack instead of the heap: on open floor many steps towards the
     * goal keep f unchanged, so this skips part of the heap work.
     */
    while (s->depth > 0 || s->size > 0) {
        int32_t u;
        if (s->depth > 0) {
            u = s->stack[--s->depth];
        } else {
            fmin = s->heap[0].f;
            u = pop(s);
        }
        s->pos[u] = CLOSED;
        if (u == goal) return 1;
        int32_t ur = u / width, uc = u - ur * width;
        double gu = s->g[u];
        for (int k = 0; k < 8; k++) {
            int32_t nr = ur + dr[k], nc = uc + dc[k];
            if ((uint32_t)nr >= (uint32_t)height || (uint32_t)nc >= (uint32_t)width) continue;
            int32_t v = nr * width + nc;
            int32_t pv = s->pos[v];
            if (pv == CLOSED || pv == STACKED) continue;
            double wv = weight[costs[v]];
            if (wv < 0.0) continue;
            double ng = gu + step[k] * wv;
            if (ng < s->g[v]) {
                s->g[v] = ng;
                s->parent[v] = u;
                Entry e = {ng + hscale * octile(nr, nc, gr, gc), v, 0};
                if (pv == UNSEEN) {
                    if (e.f <= fmin + 1e-12 * fmin) { /* f is the minimum, up to rounding */
                        s->stack[s->depth++] = v;
                        s->pos[v] = STACKED;
                    } else {
                        sift_up(s, s->size++, e);
                    }
                } else {
                    sift_up(s, (size_t)pv, e);
                }
            }
        }
    }
    return 0;
}

static void free_search(Search *s) {
    if (!s) return;
    free(s->g);
    free(s->parent);
    free(s->pos);
    free(s->heap);
    free(s->stack);
    free(s);
}

/*
 * The arrays of the last search are kept for the next one: a fresh multi-megabyte allocation per call costs
 * page faults on first touch, about a quarter of a cross-warehouse search. The cache is only taken and given
 * back while holding the GIL, so concurrent searches (the GIL is released while searching) never share it;
 * a search that finds it taken allocates its own.
 */
static Search *cached = NULL;

static Search *take_search(size_t n) {
    if (cached && cached->capacity >= n) {
        Search *s = cached;
        cached = NULL;
        return s;
    }
    Search *s = (Search *)calloc(1, sizeof(Search));
    if (!s) return NULL;
    s->capacity = n;
    s->g = (double *)malloc(n * sizeof(double));
    s->parent = (int32_t *)malloc(n * sizeof(int32_t));
    s->pos = (int32_t *)malloc(n * sizeof(int32_t));
    s->heap = (Entry *)malloc(n * sizeof(Entry));
    s->stack = (int32_t *)malloc(n * sizeof(int32_t));
    if (!s->g || !s->parent || !s->pos || !s->heap || !s->stack) {
        free_search(s);
        return NULL;
    }
    return s;
}

static void give_back(Search *s) {
    if (!cached) {
        cached = s;
    } else if (cached->capacity < s->capacity) {
        free_search(cached);
        cached = s;
    } else {
        free_search(s);
    }
}

PyDoc_STRVAR(astar_doc,
             "astar(costs, width, height, start, goal, neutral_cost=50.0, cost_factor=0.8, allow_unknown=True,\n"
             "      unknown_cost=253.0) -> list[int] | None\n\n"
             "Optimal 8-connected A* over a row-major uint8 costmap (bytes-like, width*height bytes).\n"
             "Entering a cell of cost c costs step*(neutral_cost + cost_factor*c) (step 1 or sqrt(2)); cells\n"
             ">= 253 are blocked; 255 costs step*unknown_cost if allow_unknown else is blocked. The start cell's\n"
             "own cost is ignored. Returns the cell indices from start to goal, or None if the goal is unreachable.");

static PyObject *astar(PyObject *self, PyObject *args, PyObject *kwargs) {
    static char *kwlist[] = {"costs",        "width",         "height",       "start", "goal", "neutral_cost",
                             "cost_factor", "allow_unknown", "unknown_cost", NULL};
    Py_buffer buf;
    Py_ssize_t width, height, start, goal;
    double neutral = 50.0, factor = 0.8, unknown_cost = 253.0;
    int allow_unknown = 1;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "y*nnnn|ddpd", kwlist, &buf, &width, &height, &start, &goal,
                                     &neutral, &factor, &allow_unknown, &unknown_cost))
        return NULL;

    PyObject *result = NULL;
    if (width <= 0 || height <= 0 || width > INT32_MAX / height) {
        PyErr_Format(PyExc_ValueError, "bad grid size %zd x %zd", width, height);
        goto done;
    }
    if (buf.len != width * height) {
        PyErr_Format(PyExc_ValueError, "costs has %zd bytes, expected width*height = %zd", buf.len, width * height);
        goto done;
    }
    const Py_ssize_t n = width * height;
    if (start < 0 || start >= n || goal < 0 || goal >= n) {
        PyErr_Format(PyExc_IndexError, "start %zd or goal %zd outside the grid of %zd cells", start, goal, n);
        goto done;
    }
    if (!(isfinite(neutral) && isfinite(factor) && isfinite(unknown_cost)) || neutral <= 0.0 || factor < 0.0 ||
        unknown_cost <= 0.0) {
        PyErr_SetString(PyExc_ValueError, "neutral_cost and unknown_cost must be > 0 and cost_factor >= 0");
        goto done;
    }

    double weight[256];
    double hscale = INFINITY;
    for (int c = 0; c < 256; c++) {
        if (c < 253)
            weight[c] = neutral + factor * (double)c;
        else if (c == 255 && allow_unknown)
            weight[c] = unknown_cost;
        else
            weight[c] = -1.0;
        if (weight[c] >= 0.0 && weight[c] < hscale) hscale = weight[c];
    }

    Search *s = take_search((size_t)n);
    if (!s) {
        PyErr_NoMemory();
        goto done;
    }

    int found;
    const uint8_t *costs = (const uint8_t *)buf.buf;
    Py_BEGIN_ALLOW_THREADS;
    found = run_search(s, costs, (int32_t)width, (int32_t)height, (int32_t)start, (int32_t)goal, weight, hscale);
    Py_END_ALLOW_THREADS;

    if (!found) {
        give_back(s);
        result = Py_None;
        Py_INCREF(result);
        goto done;
    }
    Py_ssize_t length = 0;
    for (int32_t v = (int32_t)goal; v != -1; v = s->parent[v]) length++;
    result = PyList_New(length);
    if (result) {
        Py_ssize_t i = length - 1;
        for (int32_t v = (int32_t)goal; v != -1; v = s->parent[v], i--) {
            PyObject *item = PyLong_FromLong((long)v);
            if (!item) {
                Py_CLEAR(result);
                break;
            }
            PyList_SET_ITEM(result, i, item);
        }
    }
    give_back(s);

done:
    PyBuffer_Release(&buf);
    return result;
}

static PyMethodDef methods[] = {
    {"astar", (PyCFunction)(void (*)(void))astar, METH_VARARGS | METH_KEYWORDS, astar_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_gridsearch", "Optimal A* grid search over Nav2 costmaps (C kernel of tb4.nav.planner).",
    -1, methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__gridsearch(void) { return PyModule_Create(&module); }
