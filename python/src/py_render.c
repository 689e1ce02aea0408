/* Volume rendering (wvol/render.h): the reference integrator on a dense volume, the
 * f^-sampling reference from coefficients, and (py_render_store.c) the spline-projected
 * integrator from a store. Options arrive as one dict built by the Python layer. */
#include "pyutil.h"
#include "methods.h"
#include "py_render.h"
#include "wvol/render.h"

#include <math.h>
#include <string.h>
#include <sys/stat.h>

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
    if (!PyUnicode_Check(o)) {
        PyErr_Format(PyExc_TypeError, "%s must be a string", key);
        return NULL;
    }
    return PyUnicode_AsUTF8(o);
}

/* tf: a preset name or file path (str), or a sequence of (value, r, g, b, opacity). */
static int parse_tf(PyObject *opts, wvol_tf *tf, double vmin, double vmax)
{
    PyObject *o = PyDict_GetItemString(opts, "tf");
    const char *units = opt_str(opts, "tf_units", "world");
    wvol_error err;
    if (!units) return -1;
    memset(tf, 0, sizeof *tf);
    if (!o || o == Py_None || PyUnicode_Check(o)) {
        const char *name = (!o || o == Py_None) ? "gaussian" : PyUnicode_AsUTF8(o);
        struct stat st;
        wvol_status s;
        if (!name) return -1;
        if (stat(name, &st) == 0 && S_ISREG(st.st_mode)) {
            Py_BEGIN_ALLOW_THREADS
            s = wvol_tf_load(tf, name, &err);
            Py_END_ALLOW_THREADS
        } else {
            s = wvol_tf_preset(tf, name, vmin, vmax, &err);
        }
        if (s != WVOL_OK) {
            wvolpy_raise(&err);
            return -1;
        }
        return 0;
    }
    {
        PyObject *seq = PySequence_Fast(o, "tf must be a preset name, a file, or a list of (value, r, g, b, opacity)");
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

int wvolpy_render_setup(PyObject *opts, const wvol_geometry *g, double vmin, double vmax, wvol_camera *cam,
                        wvol_tf *tf, wvol_render_params *rp, PyArrayObject **colors)
{
    *colors = NULL;
    const char *camspec, *mode;
    int width = 256, height = 256;
    wvol_error err;
    if (!PyDict_Check(opts)) {
        PyErr_SetString(PyExc_TypeError, "render options must be a dict");
        return -1;
    }
    wvol_render_params_default(rp);
    if (opt_int(opts, "width", &width) < 0 || opt_int(opts, "height", &height) < 0) return -1;
    if (!(camspec = opt_str(opts, "camera", "+z"))) return -1;
    if (wvol_camera_parse(cam, camspec, g, width, height, &err) != WVOL_OK) {
        wvolpy_raise(&err);
        return -1;
    }
    if (!(mode = opt_str(opts, "mode", "absorption"))) return -1;
    if (!strcmp(mode, "xray")) rp->mode = WVOL_MODE_XRAY;
    else if (!strcmp(mode, "absorption")) rp->mode = WVOL_MODE_ABSORPTION;
    else if (!strcmp(mode, "absorption-linear")) rp->mode = WVOL_MODE_ABSORPTION_LINEAR;
    else {
        PyErr_Format(PyExc_ValueError, "mode '%s': expected xray, absorption or absorption-linear", mode);
        return -1;
    }
    if (opt_double(opts, "step", &rp->step) < 0 || opt_double(opts, "termination", &rp->termination) < 0 ||
        opt_double(opts, "skip_tolerance", &rp->skip_tolerance) < 0 ||
        opt_double(opts, "ambient", &rp->ambient) < 0 || opt_int(opts, "shading", &rp->shading) < 0 ||
        opt_int(opts, "gauss_nodes", &rp->spline.gauss_nodes) < 0 || opt_int(opts, "threads", &rp->threads) < 0)
        return -1;
    if (rp->threads < 0 || rp->threads > WVOLPY_MAX_THREADS) {
        PyErr_Format(PyExc_ValueError, "threads must be in 0..%d (0: default)", WVOLPY_MAX_THREADS);
        return -1;
    }
    memset(tf, 0, sizeof *tf);
    if (rp->mode != WVOL_MODE_XRAY && parse_tf(opts, tf, vmin, vmax) < 0) return -1;
    return parse_colors(opts, g, rp, colors);
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
    return Py_BuildValue("{s:d,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:d,s:n,s:i,s:n}", "seconds", st->seconds, "rays",
                         (Py_ssize_t)st->rays, "rays_hit", (Py_ssize_t)st->rays_hit, "samples",
                         (Py_ssize_t)st->samples, "pieces", (Py_ssize_t)st->pieces, "functions",
                         (Py_ssize_t)st->functions, "skipped", (Py_ssize_t)st->skipped, "terminated",
                         (Py_ssize_t)st->terminated, "clamped", (Py_ssize_t)st->clamped, "skipped_tolerance",
                         (Py_ssize_t)st->skipped_tolerance, "skip_bound", st->skip_bound, "bricks_built",
                         (Py_ssize_t)st->bricks_built, "brick", st->brick, "bytes", (Py_ssize_t)st->bytes);
}

PyObject *wvolpy_render_finish(wvol_image *img, wvol_status s, const wvol_render_stats *st, const wvol_error *err,
                               PyArrayObject *colors)
{
    PyObject *a, *d;
    Py_XDECREF(colors);
    if (s != WVOL_OK) {
        wvol_image_destroy(img);
        return wvolpy_raise(err);
    }
    a = image_take(img);
    if (!a) return NULL;
    d = stats_dict(st);
    if (!d) {
        Py_DECREF(a);
        return NULL;
    }
    return Py_BuildValue("NN", a, d);
}

/* render_volume(array, spacing, origin, opts) -> (image, stats) */
static PyObject *py_render_volume(PyObject *self, PyObject *args)
{
    PyObject *arr_obj, *sp, *org, *opts;
    PyArrayObject *holder, *colors;
    wvol_volume v;
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_render_params rp;
    wvol_render_stats st;
    wvol_image *img = NULL;
    wvol_error err;
    wvol_status s;
    double vmin, vmax;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOO", &arr_obj, &sp, &org, &opts)) return NULL;
    if (wvolpy_as_placed_volume(arr_obj, sp, org, &v, &holder, 1) < 0) return NULL;
    if (wvol_volume_set_geometry(&v, v.spacing, v.origin, &err) != WVOL_OK) {
        wvolpy_raise(&err);
        goto fail;
    }
    wvol_volume_range(&v, &vmin, &vmax, NULL);
    wvol_geometry_of_volume(&g, &v);
    if (wvolpy_render_setup(opts, &g, vmin, vmax, &cam, &tf, &rp, &colors) < 0) goto fail;
    memset(&st, 0, sizeof st);
    Py_BEGIN_ALLOW_THREADS
    s = wvol_image_create(&img, cam.width, cam.height, &err);
    if (s == WVOL_OK) s = wvol_render_reference(img, &v, &cam, &tf, &rp, &st, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    return wvolpy_render_finish(img, s, &st, &err, colors);
fail:
    Py_DECREF(holder);
    return NULL;
}

/* render_fhat(coeffs, wavelet, levels, shape, spacing, origin, value_range, spline_j, opts) -> (image, stats) */
static PyObject *py_render_fhat(PyObject *self, PyObject *args)
{
    PyObject *arr_obj, *shape, *sp, *org, *opts;
    const char *name;
    int levels, J;
    double vmin, vmax;
    PyArrayObject *holder, *colors;
    wvol_coeffs c;
    wvol_geometry g;
    wvol_camera cam;
    wvol_tf tf;
    wvol_render_params rp;
    wvol_render_stats st;
    wvol_image *img = NULL;
    wvol_basis *b = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTuple(args, "OsiOOO(dd)iO", &arr_obj, &name, &levels, &shape, &sp, &org, &vmin, &vmax, &J, &opts))
        return NULL;
    if (wvolpy_as_coeffs(arr_obj, name, levels, shape, sp, org, &c, &holder) < 0) return NULL;
    wvol_geometry_of_coeffs(&g, &c);
    if (wvolpy_render_setup(opts, &g, vmin, vmax, &cam, &tf, &rp, &colors) < 0) {
        Py_DECREF(holder);
        return NULL;
    }
    memset(&st, 0, sizeof st);
    Py_BEGIN_ALLOW_THREADS
    s = wvol_basis_create(&b, c.filter, J, &err);
    if (s == WVOL_OK) s = wvol_image_create(&img, cam.width, cam.height, &err);
    if (s == WVOL_OK) s = wvol_render_reference_fhat(img, &c, b, &cam, &tf, &rp, &st, &err);
    Py_END_ALLOW_THREADS
    wvol_basis_destroy(b);
    Py_DECREF(holder);
    return wvolpy_render_finish(img, s, &st, &err, colors);
}

PyMethodDef wvolpy_render_methods[] = {
    {"render_volume", py_render_volume, METH_VARARGS, "render_volume(array, spacing, origin, opts) -> (image, stats)"},
    {"render_fhat", py_render_fhat, METH_VARARGS,
     "render_fhat(coeffs, wavelet, levels, shape, spacing, origin, value_range, spline_j, opts) -> (image, stats)"},
    {NULL, NULL, 0, NULL}};
