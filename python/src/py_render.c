/* SPDX-License-Identifier: MIT */
/* Volume rendering: one call, the library's entry point wvol_render, for dense volumes and
 * stores alike. Method and mode names, transfer-function names and files, the choice of
 * method for "auto" and every default are the library's: the options dict built by the
 * Python layer carries only what the caller gave. */
#include "pyutil.h"
#include "methods.h"
#include "py_store.h"
#include "wvol/render.h"
#include "wvol/progressive.h"
#include "wvol/lod.h"

#include <math.h>
#include <string.h>

static int opt_double(PyObject *opts, const char *key, double *out)
{
    PyObject *o = PyDict_GetItemString(opts, key); /* borrowed */
    if (!o || o == Py_None) return 0;
    *out = PyFloat_AsDouble(o);
    if (PyErr_Occurred()) return -1;
    if (!isfinite(*out)) {
        PyErr_Format(PyExc_ValueError, "%s must be finite", key);
        return -1;
    }
    return 0;
}

static int opt_int(PyObject *opts, const char *key, int *out)
{
    PyObject *o = PyDict_GetItemString(opts, key);
    long v;
    if (!o || o == Py_None) return 0;
    v = PyLong_AsLong(o);
    if (PyErr_Occurred()) return -1;
    if (v < -1000000000L || v > 1000000000L) {
        PyErr_Format(PyExc_ValueError, "%s out of range", key);
        return -1;
    }
    *out = (int)v;
    return 0;
}

static const char *opt_str(PyObject *opts, const char *key, const char *dflt)
{
    PyObject *o = PyDict_GetItemString(opts, key);
    if (!o || o == Py_None) return dflt;
    return wvolpy_utf8(o, key);
}

/* tf: a preset name or file path (str, wvol_tf_resolve), or a sequence of (value, r, g, b,
 * opacity) points in tf_units. */
static int parse_tf(PyObject *opts, wvol_tf *tf, double vmin, double vmax)
{
    PyObject *o = PyDict_GetItemString(opts, "tf");
    const char *units;
    wvol_error err;
    memset(tf, 0, sizeof *tf);
    if (!o || o == Py_None || PyUnicode_Check(o)) {
        const char *spec;
        wvol_status s;
        /* checked here too, though a preset or file carries its own units: 'diagonal' would be
         * ignored, and a misspelt value would pass unseen */
        if (!(units = opt_str(opts, "tf_units", "world"))) return -1;
        if (strcmp(units, "world") && strcmp(units, "diagonal")) {
            PyErr_Format(PyExc_ValueError, "tf_units '%s': expected 'world' or 'diagonal'", units);
            return -1;
        }
        if (!strcmp(units, "diagonal")) {
            PyErr_SetString(PyExc_ValueError, "tf_units='diagonal' applies to a list of points, not a preset or file");
            return -1;
        }
        spec = (!o || o == Py_None) ? "gaussian" : wvolpy_utf8(o, "tf");
        if (!spec) return -1;
        Py_BEGIN_ALLOW_THREADS
        s = wvol_tf_resolve(tf, spec, vmin, vmax, &err);
        Py_END_ALLOW_THREADS
        if (s != WVOL_OK) {
            wvolpy_raise(&err);
            return -1;
        }
        return 0;
    }
    {
        PyObject *seq = wvolpy_fast_snapshot(o, "tf must be a preset name, a file, or a list of (value, r, g, b, opacity)");
        Py_ssize_t n;
        if (!seq) return -1;
        n = PySequence_Fast_GET_SIZE(seq);
        if (n < 1 || n > WVOL_TF_MAX_POINTS) {
            Py_DECREF(seq);
            PyErr_Format(PyExc_ValueError, "tf: 1..%d points, got %zd", WVOL_TF_MAX_POINTS, n);
            return -1;
        }
        for (Py_ssize_t i = 0; i < n; i++) {
            wvol_tf_point *p = &tf->points[i];
            PyObject *item = PySequence_Fast_GET_ITEM(seq, i);
            /* any 5-sequence: a tuple, a list, a row of an (n, 5) array */
            PyObject *tup = PySequence_Check(item) ? PySequence_Tuple(item) : NULL;
            int ok = tup && PyArg_ParseTuple(tup, "ddddd;tf point must be (value, r, g, b, opacity)", &p->value,
                                             &p->rgb[0], &p->rgb[1], &p->rgb[2], &p->opacity);
            if (!tup && !PyErr_Occurred())
                PyErr_SetString(PyExc_TypeError, "tf point must be (value, r, g, b, opacity)");
            Py_XDECREF(tup);
            if (!ok) {
                Py_DECREF(seq);
                return -1;
            }
        }
        Py_DECREF(seq);
        tf->count = (int)n;
        /* read after the points: their conversions run Python code, which could replace the
         * string this pointer would lie in */
        if (!(units = opt_str(opts, "tf_units", "world"))) return -1;
        if (!strcmp(units, "diagonal")) tf->per_diagonal = 1;
        else if (strcmp(units, "world")) {
            PyErr_Format(PyExc_ValueError, "tf_units '%s': expected 'world' or 'diagonal'", units);
            return -1;
        }
        if (wvol_tf_check(tf, &err) != WVOL_OK) {
            wvolpy_raise(&err);
            return -1;
        }
    }
    return 0;
}

/* colors: a (z, y, x, 3) array ((y, x, 3) for one slice) on the grid g; its float32 C-order
 * form goes to *holder and rp (finite and >= 0 is the library's check). */
static int parse_colors(PyObject *opts, const wvol_geometry *g, wvol_render_params *rp, PyArrayObject **holder)
{
    PyObject *o = PyDict_GetItemString(opts, "colors");
    PyArrayObject *a;
    npy_intp *d;
    int nd;
    if (!o || o == Py_None) return 0;
    if (!(a = wvolpy_real_f32(o))) return -1;
    nd = PyArray_NDIM(a);
    d = PyArray_DIMS(a);
    if (!((nd == 4 && (size_t)d[0] == g->dims[2] && (size_t)d[1] == g->dims[1] && (size_t)d[2] == g->dims[0] &&
           d[3] == 3) ||
          (nd == 3 && g->dims[2] == 1 && (size_t)d[0] == g->dims[1] && (size_t)d[1] == g->dims[0] && d[2] == 3))) {
        PyObject *shape = PyObject_GetAttrString((PyObject *)a, "shape");
        PyErr_Format(PyExc_ValueError, "colors must be a (z, y, x, 3) array on the volume's grid (%zu, %zu, %zu, 3), "
                     "got %S", g->dims[2], g->dims[1], g->dims[0], shape ? shape : Py_None);
        Py_XDECREF(shape);
        Py_DECREF(a);
        return -1;
    }
    rp->colors = PyArray_DATA(a);
    rp->colors_count = (size_t)PyArray_SIZE(a);
    *holder = a;
    return 0;
}

static PyObject *image_take(wvol_image *img)
{
    npy_intp dims[3] = {img->height, img->width, 4};
    float *data = img->rgba;
    img->rgba = NULL;
    wvol_image_destroy(img);
    return wvolpy_array_take(data, 3, dims); /* row 0 at the top: (h, w, 4) with no copy */
}

static PyObject *stats_dict(const wvol_render_stats *st)
{
    return Py_BuildValue("{s:s,s:d,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:d,s:n,s:i,s:n,s:i,s:i,s:n,s:n,s:i,s:d}", "method",
                         wvol_render_method_name(st->method), "seconds", st->seconds, "rays",
                         (Py_ssize_t)st->rays, "rays_hit", (Py_ssize_t)st->rays_hit, "samples",
                         (Py_ssize_t)st->samples, "pieces", (Py_ssize_t)st->pieces, "functions",
                         (Py_ssize_t)st->functions, "skipped", (Py_ssize_t)st->skipped, "terminated",
                         (Py_ssize_t)st->terminated, "clamped", (Py_ssize_t)st->clamped, "skipped_tolerance",
                         (Py_ssize_t)st->skipped_tolerance, "skip_bound", st->skip_bound, "bricks_built",
                         (Py_ssize_t)st->bricks_built, "brick", st->brick, "bytes", (Py_ssize_t)st->bytes,
                         "context_frame", st->context_frame, "rates_reused", st->rates_reused, "bricks_reused",
                         (Py_ssize_t)st->bricks_reused, "cache_bytes", (Py_ssize_t)st->cache_bytes, "tiles_own",
                         st->tiles_own, "cpu_seconds", st->cpu_seconds);
}

static int dict_set_num(PyObject *d, const char *key, double v)
{
    PyObject *o = PyFloat_FromDouble(v);
    int r = o ? PyDict_SetItemString(d, key, o) : -1;
    Py_XDECREF(o);
    return r;
}

/* The level-of-detail figures into the stats dict: lod_level, lod_levels, lod_footprint,
 * lod_voxel, lod_energy, lod_rmse, lod_psnr (peak = the data range), lod_dims, lod_seconds. */
static int lod_stats(PyObject *d, const wvol_lod_stats *ls, const wvol_geometry *g, double vmin, double vmax)
{
    double n = (double)g->dims[0] * (double)g->dims[1] * (double)g->dims[2];
    PyObject *o = Py_BuildValue("(nnn)", (Py_ssize_t)ls->dims[2], (Py_ssize_t)ls->dims[1], (Py_ssize_t)ls->dims[0]);
    int r = o ? PyDict_SetItemString(d, "lod_dims", o) : -1;
    Py_XDECREF(o);
    if (r < 0) return -1;
    o = PyLong_FromLong(ls->level);
    r = o ? PyDict_SetItemString(d, "lod_level", o) : -1;
    Py_XDECREF(o);
    if (r < 0) return -1;
    o = PyLong_FromLong(ls->levels);
    r = o ? PyDict_SetItemString(d, "lod_levels", o) : -1;
    Py_XDECREF(o);
    if (r < 0) return -1;
    return dict_set_num(d, "lod_footprint", ls->footprint) < 0 || dict_set_num(d, "lod_voxel", ls->voxel) < 0 ||
                   dict_set_num(d, "lod_energy", ls->energy) < 0 || dict_set_num(d, "lod_rmse", ls->rmse) < 0 ||
                   dict_set_num(d, "lod_psnr", wvol_wvc_psnr(ls->energy, n, vmin, vmax)) < 0 ||
                   dict_set_num(d, "lod_seconds", ls->seconds) < 0
               ? -1
               : 0;
}

/* The render parameters from opts: only the keys given (not None) change the library's
 * defaults. *J: the spline_j asked for (0: the store's). */
static int parse_params(PyObject *opts, wvol_render_params *rp, int *J)
{
    const char *name;
    int brick = 0;
    wvol_error err;
    wvol_render_params_default(rp);
    if (!(name = opt_str(opts, "mode", NULL)) && PyErr_Occurred()) return -1;
    if (name && wvol_render_mode_parse(&rp->mode, name, &err) != WVOL_OK) goto raise;
    if (!(name = opt_str(opts, "method", NULL)) && PyErr_Occurred()) return -1;
    if (name && wvol_render_method_parse(&rp->method, name, &err) != WVOL_OK) goto raise;
    if (opt_double(opts, "step", &rp->step) < 0 || opt_double(opts, "termination", &rp->termination) < 0 ||
        opt_double(opts, "skip_tolerance", &rp->skip_tolerance) < 0 ||
        opt_double(opts, "ambient", &rp->ambient) < 0 || opt_int(opts, "shading", &rp->shading) < 0 ||
        opt_int(opts, "preintegrate", &rp->preintegrate) < 0 ||
        opt_int(opts, "gradient_levels", &rp->gradient_levels) < 0 ||
        opt_int(opts, "gauss_nodes", &rp->spline.gauss_nodes) < 0 || opt_int(opts, "threads", &rp->threads) < 0 ||
        opt_int(opts, "brick", &brick) < 0 || opt_int(opts, "spline_j", J) < 0)
        return -1;
    if (brick) rp->reference.brick = rp->bricks.brick = brick; /* as wvol render --brick */
    if (wvolpy_check_threads(rp->threads) < 0) return -1;
    return 0;
raise:
    wvolpy_raise(&err);
    return -1;
}

/* What the library would refuse as unsupported but the Python API documents as a bad
 * argument (ValueError): a store's method on a dense volume, an X-ray-only method in an
 * absorption mode. */
static int check_method(const wvol_render_params *rp, int is_store)
{
    wvol_render_method m = rp->method;
    if (!is_store && m != WVOL_RENDER_METHOD_AUTO && m != WVOL_RENDER_METHOD_REFERENCE) {
        PyErr_Format(PyExc_ValueError, "method '%s' needs a Store (wvol.compress); volumes render with 'reference'",
                     wvol_render_method_name(m));
        return -1;
    }
    if ((m == WVOL_RENDER_METHOD_AXIS || m == WVOL_RENDER_METHOD_SPLAT) && rp->mode != WVOL_RENDER_MODE_XRAY) {
        PyErr_Format(PyExc_ValueError, "method '%s' renders X-ray only (mode='xray'), not mode '%s'",
                     wvol_render_method_name(m), wvol_render_mode_name(rp->mode));
        return -1;
    }
    return 0;
}

/* ---- render contexts (wvol_render_context) ---- */

/* A context and the Python object of the store it keeps state for (held so that the store
 * outlives it); busy while a frame renders without the GIL (a second thread is refused). */
typedef struct py_context {
    wvol_render_context *ctx;
    PyObject *store_obj;
    const wvol_store *store;
    int busy;
} py_context;

#define CONTEXT_CAPSULE "wvol.render_context"

static void context_free(PyObject *cap)
{
    py_context *pc = PyCapsule_GetPointer(cap, CONTEXT_CAPSULE);
    if (!pc) return;
    wvol_render_context_destroy(pc->ctx);
    Py_XDECREF(pc->store_obj);
    free(pc);
}

/* render_context_new(cache_bytes) -> capsule: a context with no source yet. */
static PyObject *py_render_context_new(PyObject *self, PyObject *args)
{
    long long cache = 0;
    py_context *pc;
    /* a placeholder source, never rendered: each frame sets its own (context_for) */
    static wvol_volume placeholder;
    wvol_render_source none = wvol_render_source_volume(&placeholder);
    wvol_error err;
    PyObject *cap;
    (void)self;
    if (!PyArg_ParseTuple(args, "L", &cache)) return NULL;
    if (cache < 0) return PyErr_Format(PyExc_ValueError, "cache_bytes must be >= 0 (0: the default)");
    pc = calloc(1, sizeof *pc);
    if (!pc) return PyErr_NoMemory();
    if (wvol_render_context_create(&pc->ctx, &none, NULL, (size_t)cache, &err) != WVOL_OK) {
        free(pc);
        return wvolpy_raise(&err);
    }
    cap = PyCapsule_New(pc, CONTEXT_CAPSULE, context_free);
    if (!cap) {
        wvol_render_context_destroy(pc->ctx);
        free(pc);
    }
    return cap;
}

/* The context of opts "context" (a capsule) set to render src: a store other than the one it
 * holds state for replaces it (everything kept dropped), a dense volume is set each frame (its
 * array is this call's; nothing is kept for it). NULL without a context; -1 on error. On
 * success with a context, *hold is a new reference to its capsule, which the caller releases
 * after the frame: without the GIL, another thread could drop the dict's reference and the
 * capsule's destructor would free the context under the render. */
static int context_for(PyObject *opts, PyObject *src_obj, const wvol_render_source *src, py_context **out,
                       PyObject **hold)
{
    PyObject *cap = PyDict_GetItemString(opts, "context");
    py_context *pc;
    wvol_error err;
    *out = NULL;
    *hold = NULL;
    if (!cap || cap == Py_None) return 0;
    if (!(pc = PyCapsule_GetPointer(cap, CONTEXT_CAPSULE))) return -1;
    if (pc->busy) {
        PyErr_SetString(PyExc_RuntimeError, "render context: in use by another thread");
        return -1;
    }
    if (src->kind == WVOL_RENDER_SOURCE_VOLUME || src->store != pc->store) {
        if (wvol_render_context_set_source(pc->ctx, src, &err) != WVOL_OK) {
            wvolpy_raise(&err);
            return -1;
        }
        Py_XDECREF(pc->store_obj);
        pc->store_obj = NULL;
        pc->store = NULL;
        if (src->kind == WVOL_RENDER_SOURCE_STORE) {
            Py_INCREF(src_obj);
            pc->store_obj = src_obj;
            pc->store = src->store;
        }
    }
    Py_INCREF(cap);
    *hold = cap;
    *out = pc;
    return 0;
}

/* render(source, spacing, origin, opts) -> (image (h, w, 4) float32 over the image's pixels,
 * stats, bound image or None (opts "bound": wvol_render_bound from the store's residual)). source: a StoreHandle, or an array (a dense volume placed by spacing/origin, which
 * a store ignores). opts: camera, width, height, mode, method, tf, tf_units, step, termination,
 * skip_tolerance, ambient, shading, gauss_nodes, spline_j, brick, threads, colors. */
static PyObject *py_render(PyObject *self, PyObject *args)
{
    PyObject *src_obj, *sp, *org, *opts;
    PyArrayObject *holder = NULL, *colors = NULL;
    const char *camspec;
    int width = 256, height = 256, J = 0, is_store;
    wvol_volume v;
    wvol_render_source src;
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_render_params rp;
    wvol_render_stats st;
    wvol_render_bound_stats bs;
    wvol_lod_params lp;
    wvol_lod_stats ls;
    const char *lod_wavelet;
    wvol_image *img = NULL, *bimg = NULL;
    const wvol_store *residual = NULL;
    wvol_error err;
    wvol_status s;
    double vmin, vmax;
    int want_bound = 0;
    py_context *pc = NULL;
    PyObject *pc_hold = NULL;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOO!", &src_obj, &sp, &org, &PyDict_Type, &opts)) return NULL;
    if (parse_params(opts, &rp, &J) < 0) return NULL;
    is_store = WVOLPY_IS_STORE(src_obj);
    if (check_method(&rp, is_store) < 0) return NULL;
    if (opt_int(opts, "bound", &want_bound) < 0) return NULL;
    if (want_bound < WVOL_BOUND_NONE || want_bound > WVOL_BOUND_COARSE)
        return PyErr_Format(PyExc_ValueError, "bound: unknown method %d", want_bound);
    /* level of detail (wvol/lod.h): on unless opts "lod" is 0; a bound is the full grid's */
    wvol_lod_params_default(&lp);
    if (opt_int(opts, "lod", &lp.enabled) < 0 || opt_int(opts, "lod_level", &lp.level) < 0) return NULL;
    if (want_bound) lp.enabled = 0;
    if (!(lod_wavelet = opt_str(opts, "lod_wavelet", NULL)) && PyErr_Occurred()) return NULL;
    if (lod_wavelet && wvol_filter_get(&lp.filter, lod_wavelet, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (is_store) {
        wvolpy_store *h = (wvolpy_store *)src_obj;
        const wvol_store *store = wvolpy_store_at(h, J);
        if (!store) return NULL;
        if (want_bound) {
            residual = h->c.residual;
            if (!residual)
                return PyErr_Format(PyExc_ValueError, "bound=True needs a Store made with "
                                                      "wvol.compress(..., residual=True)");
            if (wvol_store_basis(residual)->J != wvol_store_basis(store)->J)
                return PyErr_Format(PyExc_ValueError, "bound=True: spline_j must be the store's (%d)",
                                    wvol_store_basis(residual)->J);
        }
        src = wvol_render_source_store(store);
        wvol_geometry_of_coeffs(&g, h->c.coeffs);
        vmin = h->c.value_min;
        vmax = h->c.value_max;
    } else {
        if (wvolpy_as_placed_volume(src_obj, sp, org, &v, &holder, 1) < 0) return NULL;
        if (wvol_volume_set_geometry(&v, v.spacing, v.origin, &err) != WVOL_OK) {
            wvolpy_raise(&err);
            goto done;
        }
        src = wvol_render_source_volume(&v);
        wvol_volume_range(&v, &vmin, &vmax, NULL);
        wvol_geometry_of_volume(&g, &v);
    }
    if (opt_int(opts, "width", &width) < 0 || opt_int(opts, "height", &height) < 0) goto done;
    if (!(camspec = opt_str(opts, "camera", "+z"))) goto done;
    if (wvol_camera_parse(&cam, camspec, &g, width, height, &err) != WVOL_OK) {
        wvolpy_raise(&err);
        goto done;
    }
    memset(&tf, 0, sizeof tf);
    if (rp.mode != WVOL_RENDER_MODE_XRAY && parse_tf(opts, &tf, vmin, vmax) < 0) goto done;
    if (parse_colors(opts, &g, &rp, &colors) < 0) goto done;
    memset(&st, 0, sizeof st);
    memset(&bs, 0, sizeof bs);
    if (context_for(opts, src_obj, &src, &pc, &pc_hold) < 0) goto done;
    if (pc) pc->busy = 1;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_image_create(&img, cam.width, cam.height, &err);
    if (s == WVOL_OK)
        s = pc ? wvol_render_lod_context(pc->ctx, img, &cam, &tf, &rp, &lp, &st, &ls, &err)
               : wvol_render_lod(img, &src, &cam, &tf, &rp, &lp, &st, &ls, &err);
    /* a dense volume dropped nothing: its bound image stays 0 */
    if (s == WVOL_OK && want_bound) s = wvol_image_create(&bimg, cam.width, cam.height, &err);
    if (s == WVOL_OK && residual)
        s = (want_bound == WVOL_BOUND_COARSE ? wvol_render_bound_coarse : wvol_render_bound)(bimg, residual, 0.0, &cam,
                                                                                          &tf, &rp, &bs, &err);
    Py_END_ALLOW_THREADS
    if (pc) pc->busy = 0;
    Py_XDECREF(pc_hold);
    Py_XDECREF(holder);
    Py_XDECREF(colors);
    if (s != WVOL_OK) {
        wvol_image_destroy(img);
        wvol_image_destroy(bimg);
        return wvolpy_raise(&err);
    }
    {
        PyObject *a = image_take(img), *d, *b = Py_None;
        if (!a) {
            wvol_image_destroy(bimg);
            return NULL;
        }
        if (bimg && !(b = image_take(bimg))) {
            Py_DECREF(a);
            return NULL;
        }
        if (!(d = stats_dict(&st)) || lod_stats(d, &ls, &g, vmin, vmax) < 0 ||
            (bimg && (dict_set_num(d, "bound_max", bs.max) < 0 || dict_set_num(d, "bound_mean", bs.mean) < 0))) {
            Py_XDECREF(d);
            Py_DECREF(a);
            if (bimg) Py_DECREF(b);
            return NULL;
        }
        if (!bimg) Py_INCREF(Py_None);
        return Py_BuildValue("NNN", a, d, b);
    }
done:
    Py_XDECREF(holder);
    Py_XDECREF(colors);
    return NULL;
}

/* ---- progressive passes (wvol/progressive.h) ---- */

typedef struct prog_state {
    wvol_progressive *pr;
    wvol_geometry g;
    double vmin, vmax;
    int bound;
    int busy; /* a pass runs without the GIL: a second thread's pass is refused (progressive.h) */
} prog_state;

#define PROG_CAPSULE "wvol.progressive"

static void prog_free(PyObject *cap)
{
    prog_state *ps = PyCapsule_GetPointer(cap, PROG_CAPSULE);
    if (!ps) return;
    wvol_progressive_end(ps->pr);
    free(ps);
}

/* progressive_begin(array, spacing, origin, wavelet, levels, max_error, seconds, growth, bound)
 * -> capsule: the volume transformed once (wvol_progressive_begin). */
static PyObject *py_progressive_begin(PyObject *self, PyObject *args)
{
    PyObject *arr, *sp, *org, *lev_obj;
    PyArrayObject *holder = NULL;
    const char *wavelet;
    wvol_volume v;
    wvol_compress_params cp;
    wvol_progressive_params pp;
    prog_state *ps;
    wvol_error err;
    wvol_status s;
    PyObject *cap;
    (void)self;
    wvol_progressive_params_default(&pp);
    int bound = 1;
    if (!PyArg_ParseTuple(args, "OOOzOdddi", &arr, &sp, &org, &wavelet, &lev_obj, &pp.max_error, &pp.seconds,
                          &pp.growth, &bound))
        return NULL;
    pp.bound = (wvol_bound_method)bound;
    wvol_compress_params_default(&cp);
    if (wavelet) cp.wavelet = wavelet;
    if (wvolpy_parse_levels(lev_obj, &cp.levels) < 0) return NULL;
    if (!(ps = calloc(1, sizeof *ps))) return PyErr_NoMemory();
    if (wvolpy_as_placed_volume(arr, sp, org, &v, &holder, 1) < 0) {
        free(ps);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    s = wvol_volume_set_geometry(&v, v.spacing, v.origin, &err);
    if (s == WVOL_OK) s = wvol_progressive_begin(&ps->pr, &v, &cp, &pp, &err);
    Py_END_ALLOW_THREADS
    if (s == WVOL_OK) {
        wvol_volume_range(&v, &ps->vmin, &ps->vmax, NULL);
        wvol_geometry_of_volume(&ps->g, &v);
        ps->bound = pp.bound;
    }
    Py_DECREF(holder);
    if (s != WVOL_OK) {
        free(ps);
        return wvolpy_raise(&err);
    }
    if (!(cap = PyCapsule_New(ps, PROG_CAPSULE, prog_free))) {
        wvol_progressive_end(ps->pr);
        free(ps);
    }
    return cap;
}

/* A progressive pass's options (as render's): 0, or -1 with an exception. */
static int progressive_opts(const prog_state *ps, PyObject *opts, wvol_render_params *rp, wvol_camera *cam,
                            wvol_tf *tf)
{
    const char *camspec;
    int width = 256, height = 256, J = 0;
    wvol_error err;
    if (parse_params(opts, rp, &J) < 0) return -1;
    if (opt_int(opts, "width", &width) < 0 || opt_int(opts, "height", &height) < 0) return -1;
    if (!(camspec = opt_str(opts, "camera", "+z"))) return -1;
    if (wvol_camera_parse(cam, camspec, &ps->g, width, height, &err) != WVOL_OK) {
        wvolpy_raise(&err);
        return -1;
    }
    memset(tf, 0, sizeof *tf);
    if (rp->mode != WVOL_RENDER_MODE_XRAY && parse_tf(opts, tf, ps->vmin, ps->vmax) < 0) return -1;
    return 0;
}

/* progressive_check(capsule, opts) -> None: the options checked as progressive_next checks
 * them, nothing rendered (render_progressive refuses bad ones at its call). */
static PyObject *py_progressive_check(PyObject *self, PyObject *args)
{
    PyObject *cap, *opts;
    prog_state *ps;
    wvol_camera cam;
    wvol_tf tf;
    wvol_render_params rp;
    (void)self;
    if (!PyArg_ParseTuple(args, "OO!", &cap, &PyDict_Type, &opts)) return NULL;
    if (!(ps = PyCapsule_GetPointer(cap, PROG_CAPSULE))) return NULL;
    if (progressive_opts(ps, opts, &rp, &cam, &tf) < 0) return NULL;
    Py_RETURN_NONE;
}

/* progressive_next(capsule, opts) -> (image, bound or None, pass dict); opts as render's. */
static PyObject *py_progressive_next(PyObject *self, PyObject *args)
{
    PyObject *cap, *opts, *a, *b = Py_None, *d;
    prog_state *ps;
    wvol_camera cam;
    wvol_tf tf;
    wvol_render_params rp;
    wvol_progressive_pass pass;
    wvol_image *img = NULL, *bimg = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTuple(args, "OO!", &cap, &PyDict_Type, &opts)) return NULL;
    if (!(ps = PyCapsule_GetPointer(cap, PROG_CAPSULE))) return NULL;
    if (progressive_opts(ps, opts, &rp, &cam, &tf) < 0) return NULL;
    if (ps->busy) {
        PyErr_SetString(PyExc_RuntimeError,
                        "progressive render: a pass of this render is running in another thread (one at a time)");
        return NULL;
    }
    ps->busy = 1; /* set and cleared with the GIL held */
    Py_BEGIN_ALLOW_THREADS
    s = wvol_image_create(&img, cam.width, cam.height, &err);
    if (s == WVOL_OK && ps->bound) s = wvol_image_create(&bimg, cam.width, cam.height, &err);
    if (s == WVOL_OK) s = wvol_progressive_next(ps->pr, img, bimg, &cam, &tf, &rp, &pass, &err);
    Py_END_ALLOW_THREADS
    ps->busy = 0;
    if (s != WVOL_OK) {
        wvol_image_destroy(img);
        wvol_image_destroy(bimg);
        return wvolpy_raise(&err);
    }
    if (!(a = image_take(img))) {
        wvol_image_destroy(bimg);
        return NULL;
    }
    if (bimg && !(b = image_take(bimg))) {
        Py_DECREF(a);
        return NULL;
    }
    if (!bimg) Py_INCREF(Py_None);
    d = Py_BuildValue("{s:i,s:n,s:n,s:d,s:d,s:d,s:d,s:s,s:O,s:s}", "index", pass.index, "kept",
                      (Py_ssize_t)pass.kept, "total", (Py_ssize_t)pass.total, "bound_max", pass.bound_max,
                      "bound_mean", pass.bound_mean, "seconds", pass.seconds, "elapsed", pass.elapsed, "method",
                      wvol_render_method_name(pass.method), "last", pass.last ? Py_True : Py_False, "stop",
                      pass.stop);
    if (!d) {
        Py_DECREF(a);
        Py_DECREF(b);
        return NULL;
    }
    return Py_BuildValue("NNN", a, b, d);
}

PyMethodDef wvolpy_render_methods[] = {
    {"render", py_render, METH_VARARGS,
     "render(source, spacing, origin, opts) -> (image, stats, bound or None); source: a StoreHandle or an array"},
    {"render_context_new", py_render_context_new, METH_VARARGS,
     "render_context_new(cache_bytes) -> context (opts['context'] of render: its set-up kept across frames)"},
    {"progressive_begin", py_progressive_begin, METH_VARARGS,
     "progressive_begin(array, spacing, origin, wavelet, levels, max_error, seconds, growth, bound) -> state"},
    {"progressive_next", py_progressive_next, METH_VARARGS,
     "progressive_next(state, opts) -> (image, bound or None, pass)"},
    {"progressive_check", py_progressive_check, METH_VARARGS,
     "progressive_check(state, opts) -> None: the options checked, nothing rendered"},
    {NULL, NULL, 0, NULL}};
