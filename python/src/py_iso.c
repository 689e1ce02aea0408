/* SPDX-License-Identifier: MIT */
/* Isosurfaces (wvol/iso.h): marching cubes on a dense volume or brick by brick on the
 * reconstruction of a store's coefficients. Returns NumPy arrays over the mesh's memory. */
#include "pyutil.h"
#include "methods.h"
#include "py_store.h"
#include "wvol/iso.h"
#include "wvol/render.h"
#include <stdlib.h>

#include <math.h>
#include <string.h>

static int parse_normals(const char *name, wvol_iso_normals *out)
{
    if (!strcmp(name, "gradient")) *out = WVOL_ISO_NORMALS_GRADIENT;
    else if (!strcmp(name, "none")) *out = WVOL_ISO_NORMALS_NONE;
    else {
        PyErr_Format(PyExc_ValueError, "normals '%s': expected 'gradient' or 'none'", name);
        return -1;
    }
    return 0;
}

/* p shrunk to bytes (the brick path's arrays are large reservations filled in part, which a
 * program keeping many meshes should not hold); p itself when realloc declines. */
static void *fit(void *p, size_t bytes)
{
    void *q = p ? realloc(p, bytes ? bytes : 1) : NULL;
    return q ? q : p;
}

/* (vertices (n, 3) float32, faces (m, 3) uint32, normals (n, 3) float32, or None when not asked
 * for, stats); destroys m. */
static PyObject *mesh_take(wvol_mesh *m, const wvol_iso_stats *st, int want_normals)
{
    npy_intp vd[2] = {(npy_intp)m->nverts, 3}, td[2] = {(npy_intp)m->ntris, 3};
    PyObject *v, *t, *n, *d;
    m->verts = fit(m->verts, m->nverts * 3 * sizeof(float));
    m->normals = fit(m->normals, m->nverts * 3 * sizeof(float));
    m->tris = fit(m->tris, m->ntris * 3 * sizeof(uint32_t));
    v = wvolpy_array_take_type(m->verts, 2, vd, NPY_FLOAT32);
    m->verts = NULL;
    t = wvolpy_array_take_type(m->tris, 2, td, NPY_UINT32);
    m->tris = NULL;
    if (m->normals) {
        n = wvolpy_array_take_type(m->normals, 2, vd, NPY_FLOAT32);
        m->normals = NULL;
    } else if (want_normals) { /* an empty mesh: no array was made for no vertices */
        n = PyArray_SimpleNew(2, vd, NPY_FLOAT32);
    } else {
        n = Py_NewRef(Py_None);
    }
    wvol_mesh_destroy(m);
    /* the data's range is measured only to say why a mesh is empty (wvol_iso_stats) */
    d = Py_BuildValue("{s:O,s:s,s:N,s:n,s:n,s:n,s:n,s:d}", "empty", st->empty ? Py_True : Py_False, "message",
                      st->message, "data_range",
                      st->empty ? Py_BuildValue("(dd)", st->data_min, st->data_max) : Py_NewRef(Py_None),
                      "cells_active",
                      (Py_ssize_t)st->cells_active, "bricks_total", (Py_ssize_t)st->bricks_total, "bricks_skipped",
                      (Py_ssize_t)st->bricks_skipped, "bricks_meshed", (Py_ssize_t)st->bricks_meshed, "seconds",
                      st->seconds[3]);
    if (!v || !t || !n || !d) {
        Py_XDECREF(v);
        Py_XDECREF(t);
        Py_XDECREF(n);
        Py_XDECREF(d);
        return NULL;
    }
    return Py_BuildValue("NNNN", v, t, n, d);
}

/* Checks the arguments and fills *p; 0, or -1 with an exception. */
static int iso_setup(double iso, int threads, int brick, const char *normals, wvol_iso_params *p)
{
    if (!isfinite(iso)) {
        PyErr_SetString(PyExc_ValueError, "iso-value must be finite");
        return -1;
    }
    if (wvolpy_check_threads(threads) < 0) return -1;
    if (brick < 0) {
        PyErr_SetString(PyExc_ValueError, "brick must be >= 0 (0: default)");
        return -1;
    }
    wvol_iso_params_default(p);
    p->threads = threads;
    if (brick > 0) p->brick = brick;
    return parse_normals(normals, &p->normals);
}

/* The extraction's result as mesh_take's tuple, or its error raised. */
static PyObject *iso_finish(wvol_mesh *m, wvol_status s, const wvol_iso_stats *st, int want_normals,
                            const wvol_error *err)
{
    if (s != WVOL_OK) {
        wvol_mesh_destroy(m);
        return wvolpy_raise(err);
    }
    return mesh_take(m, st, want_normals);
}

/* isosurface(source, iso, spacing=None, origin=None, normals='gradient', threads=0, brick=None)
 * -> (vertices, faces, normals, stats). source: a StoreHandle (marching cubes brick by brick
 * from its coefficients, bricks of `brick` cells, None: the library's default; spacing/origin
 * are the store's) or an array (a dense volume placed by spacing/origin; no brick). */
static PyObject *py_isosurface(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"source", "iso", "spacing", "origin", "normals", "threads", "brick", "level", "wavelet",
                             NULL};
    PyObject *src, *sp = Py_None, *org = Py_None, *brick_obj = Py_None;
    const char *normals = "gradient", *wavelet = "db2";
    const wvol_filter *filter = NULL;
    wvol_volume *coarse = NULL;
    double iso, level_energy = 0.0;
    int threads = 0, brick = 0, level = 0;
    PyArrayObject *holder = NULL;
    const wvol_store *store = NULL; /* a Store's (every handle holds one), else NULL */
    wvol_volume v;
    wvol_iso_params p;
    wvol_iso_stats st;
    wvol_mesh *m = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "Od|OOsiOis", kwlist, &src, &iso, &sp, &org, &normals, &threads,
                                     &brick_obj, &level, &wavelet))
        return NULL;
    if (level < 0) return PyErr_Format(PyExc_ValueError, "level %d: must be >= 0 (0: full resolution)", level);
    if (wvol_filter_get(&filter, wavelet, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (brick_obj != Py_None) {
        long b = PyLong_AsLong(brick_obj);
        if (b == -1 && PyErr_Occurred()) return NULL;
        brick = b < -1 ? -1 : b > 65536 ? 65536 : (int)b; /* iso_setup refuses < 0, the library the too large */
    }
    if (iso_setup(iso, threads, brick, normals, &p) < 0) return NULL;
    if (WVOLPY_IS_STORE(src)) {
        store = ((wvolpy_store *)src)->c.store;
    } else {
        if (brick_obj != Py_None)
            return PyErr_Format(PyExc_ValueError, "brick applies to a Store (coefficient path), not to a dense volume");
        if (wvolpy_as_placed_volume(src, sp, org, &v, &holder, 1) < 0) return NULL;
    }
    memset(&st, 0, sizeof st);
    Py_BEGIN_ALLOW_THREADS
    s = WVOL_OK;
    if (!store) s = wvol_volume_set_geometry(&v, v.spacing, v.origin, &err);
    if (s == WVOL_OK && level > 0) { /* the level's coarser grid (wvol_idwt3_level's), then dense MC */
        s = store ? wvol_store_level_volume(&coarse, store, level, &err)
                  : wvol_volume_level(&coarse, &v, filter, level, &level_energy, &err);
        if (s == WVOL_OK && store) s = wvol_store_level_energy(store, level, &level_energy, &err);
        if (s == WVOL_OK) s = wvol_iso_extract(&m, coarse, iso, &p, &st, &err);
    } else if (s == WVOL_OK && store) { /* the bricks whose bound straddles iso, from the kept coefficients */
        s = wvol_iso_extract_store(&m, store, iso, &p, &st, &err);
    } else if (s == WVOL_OK) {
        s = wvol_iso_extract(&m, &v, iso, &p, &st, &err);
    }
    Py_END_ALLOW_THREADS
    Py_XDECREF(holder);
    {
        PyObject *r = iso_finish(m, s, &st, p.normals != WVOL_ISO_NORMALS_NONE, &err);
        if (r && coarse) {
            /* the stats dict is the last item: add the level's grid and dropped energy */
            PyObject *d = PyTuple_GET_ITEM(r, PyTuple_GET_SIZE(r) - 1), *o;
            o = Py_BuildValue("{s:i,s:(nnn),s:(ddd),s:(ddd),s:d}", "level", level, "dims", (Py_ssize_t)coarse->nz,
                              (Py_ssize_t)coarse->ny, (Py_ssize_t)coarse->nx, "spacing", coarse->spacing[2],
                              coarse->spacing[1], coarse->spacing[0], "origin", coarse->origin[2], coarse->origin[1],
                              coarse->origin[0], "energy", level_energy);
            if (!o || !PyDict_Check(d) || PyDict_SetItemString(d, "level", o) < 0) {
                Py_XDECREF(o);
                Py_DECREF(r);
                wvol_volume_destroy(coarse);
                return NULL;
            }
            Py_DECREF(o);
        }
        wvol_volume_destroy(coarse);
        return r;
    }
}

/* isoimage(source, iso, camera, width, height, method, threads, brick, tolerance, spacing, origin)
 * -> (rgba (h, w, 4) float32, depth (h, w) float32, stats). method "cast": the bricked caster of
 * the trilinear interpolant (a volume, or a store's reconstruction; brick, tolerance in voxels);
 * "exact": the f^ tracer (a store only; tolerance in voxels, brick ignored). */
static PyObject *py_isoimage(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"source", "iso", "camera", "width", "height", "method", "threads", "brick",
                             "tolerance", "spacing", "origin", "model_bound", NULL};
    PyObject *src_obj, *sp = Py_None, *org = Py_None;
    const char *camspec = "+z", *method = "cast";
    double iso, tol = 0.0;
    int width = 256, height = 256, threads = 0, brick = 0, exact, model_bound = 0;
    PyArrayObject *holder = NULL;
    const wvol_store *store = NULL;
    wvol_volume v;
    wvol_geometry g;
    wvol_camera cam;
    wvol_image *img = NULL;
    float *depth = NULL;
    wvol_error err;
    wvol_status s;
    PyObject *a, *z, *d;
    npy_intp zd[2];
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "Od|siisiidOOp", kwlist, &src_obj, &iso, &camspec, &width, &height,
                                     &method, &threads, &brick, &tol, &sp, &org, &model_bound))
        return NULL;
    if (!isfinite(iso)) return PyErr_Format(PyExc_ValueError, "iso-value must be finite");
    if (strcmp(method, "cast") && strcmp(method, "exact"))
        return PyErr_Format(PyExc_ValueError, "method '%s': expected 'cast' or 'exact'", method);
    exact = !strcmp(method, "exact");
    if (wvolpy_check_threads(threads) < 0) return NULL;
    if (!(tol >= 0) || !isfinite(tol)) return PyErr_Format(PyExc_ValueError, "tolerance must be >= 0 (0: default)");
    if (brick < 0) return PyErr_Format(PyExc_ValueError, "brick must be >= 0 (0: default)");
    if (WVOLPY_IS_STORE(src_obj)) {
        wvol_store_info info;
        int k;
        if (!(store = wvolpy_store_at((wvolpy_store *)src_obj, 0))) return NULL;
        wvol_store_get_info(store, &info);
        g.dims[0] = info.nx, g.dims[1] = info.ny, g.dims[2] = info.nz;
        for (k = 0; k < 3; k++) g.spacing[k] = info.spacing[k], g.origin[k] = info.origin[k];
    } else {
        if (exact)
            return PyErr_Format(PyExc_ValueError, "method 'exact' traces f^ of a Store (wvol.compress), not a volume");
        if (wvolpy_as_placed_volume(src_obj, sp, org, &v, &holder, 1) < 0) return NULL;
        if (wvol_volume_set_geometry(&v, v.spacing, v.origin, &err) != WVOL_OK) goto raise;
        wvol_geometry_of_volume(&g, &v);
    }
    if (wvol_camera_parse(&cam, camspec, &g, width, height, &err) != WVOL_OK) goto raise;
    depth = malloc((size_t)width * (size_t)height * sizeof *depth + 1);
    if (!depth) {
        Py_XDECREF(holder);
        return PyErr_NoMemory();
    }
    if (exact) {
        wvol_iso_trace_params tp;
        wvol_iso_trace_stats ts;
        double smin = fmin(g.spacing[0], fmin(g.spacing[1], g.spacing[2]));
        wvol_iso_trace_params_default(&tp);
        tp.threads = threads;
        if (tol > 0) tp.tolerance = tol * smin;
        memset(&ts, 0, sizeof ts);
        Py_BEGIN_ALLOW_THREADS
        s = wvol_image_create(&img, width, height, &err);
        if (s == WVOL_OK) s = wvol_iso_raytrace(img, depth, NULL, store, &cam, iso, &tp, &ts, &err);
        Py_END_ALLOW_THREADS
        d = s != WVOL_OK ? NULL
                         : Py_BuildValue("{s:s,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:d,s:d,s:d,s:s}", "method", "exact",
                                         "rays", (Py_ssize_t)ts.rays, "hits", (Py_ssize_t)ts.hits, "functions",
                                         (Py_ssize_t)ts.functions, "pieces", (Py_ssize_t)ts.pieces, "grazes",
                                         (Py_ssize_t)ts.grazes, "cells", (Py_ssize_t)ts.cells, "cells_undecided",
                                         (Py_ssize_t)ts.cells_undecided, "seconds", ts.seconds, "cpu_seconds",
                                         ts.cpu_seconds, "seconds_cells", ts.seconds_cells, "message", ts.message);
    } else {
        wvol_iso_cast_params cp;
        wvol_iso_cast_stats cs;
        wvol_render_source src = store ? wvol_render_source_store(store) : wvol_render_source_volume(&v);
        wvol_iso_cast_params_default(&cp);
        cp.threads = threads;
        if (brick > 0) cp.brick = brick;
        if (tol > 0) cp.tolerance = tol;
        cp.model_bound = model_bound;
        memset(&cs, 0, sizeof cs);
        Py_BEGIN_ALLOW_THREADS
        s = wvol_image_create(&img, width, height, &err);
        if (s == WVOL_OK) s = wvol_iso_cast(img, depth, NULL, &src, &cam, iso, &cp, &cs, &err);
        Py_END_ALLOW_THREADS
        d = s != WVOL_OK ? NULL
                         : Py_BuildValue("{s:s,s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:d,s:d,s:d,s:d,s:d,s:d,s:n,s:n,s:s}",
                                         "method", "cast", "rays", (Py_ssize_t)cs.rays, "hits", (Py_ssize_t)cs.hits,
                                         "bricks_total", (Py_ssize_t)cs.bricks_total, "bricks_bound",
                                         (Py_ssize_t)cs.bricks_bound, "bricks_built", (Py_ssize_t)cs.bricks_built,
                                         "cells_tested", (Py_ssize_t)cs.cells_tested, "bytes", (Py_ssize_t)cs.bytes,
                                         "seconds", cs.seconds, "seconds_bounds", cs.seconds_bounds,
                                         "thread_seconds_build", cs.seconds_build, "cpu_seconds", cs.cpu_seconds,
                                         "fhat_bound_max", cs.fhat_bound_max, "fhat_bound_mean", cs.fhat_bound_mean,
                                         "fhat_bound_bricks", (Py_ssize_t)cs.fhat_bound_bricks, "fhat_bound_faces",
                                         (Py_ssize_t)cs.fhat_bound_faces, "message", cs.message);
    }
    Py_XDECREF(holder);
    holder = NULL;
    if (s != WVOL_OK) {
        free(depth);
        wvol_image_destroy(img);
        return wvolpy_raise(&err);
    }
    if (!d) {
        free(depth);
        wvol_image_destroy(img);
        return NULL;
    }
    {
        npy_intp dims[3] = {height, width, 4};
        float *rgba = img->rgba;
        img->rgba = NULL;
        wvol_image_destroy(img);
        a = wvolpy_array_take(rgba, 3, dims);
    }
    zd[0] = height, zd[1] = width;
    z = wvolpy_array_take(depth, 2, zd);
    if (!a || !z) {
        Py_XDECREF(a);
        Py_XDECREF(z);
        Py_DECREF(d);
        return NULL;
    }
    return Py_BuildValue("NNN", a, z, d);
raise:
    Py_XDECREF(holder);
    return wvolpy_raise(&err);
}

/* save_mesh(path, vertices (n, 3), faces (m, 3), normals (n, 3) or None): .ply .obj .stl .vtp */
static PyObject *py_save_mesh(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "vertices", "faces", "normals", NULL};
    PyObject *path_obj, *vo, *fo, *no = Py_None, *bytes = NULL, *res = NULL;
    PyArrayObject *va = NULL, *fa = NULL, *na = NULL;
    wvol_mesh m;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOO|O", kwlist, &path_obj, &vo, &fo, &no)) return NULL;
    va = wvolpy_real_f32(vo); /* complex, bool, object and strings refused, not cast */
    if (!va) goto done;
    if (PyArray_NDIM(va) != 2 || PyArray_DIM(va, 1) != 3) {
        PyErr_SetString(PyExc_ValueError, "vertices must be an (n, 3) array");
        goto done;
    }
    {
        PyArrayObject *fin = (PyArrayObject *)PyArray_FROM_O(fo), *f64;
        npy_intp nf, nv = PyArray_DIM(va, 0);
        if (!fin) goto done;
        if (!PyArray_ISINTEGER(fin)) {
            PyErr_Format(PyExc_TypeError, "faces must be an array of integer vertex indices, got dtype %S",
                         (PyObject *)PyArray_DESCR(fin));
            Py_DECREF(fin);
            goto done;
        }
        f64 = (PyArrayObject *)PyArray_FROM_OTF((PyObject *)fin, NPY_INT64, NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
        Py_DECREF(fin);
        if (!f64) goto done;
        if (PyArray_NDIM(f64) != 2 || PyArray_DIM(f64, 1) != 3) {
            Py_DECREF(f64);
            PyErr_SetString(PyExc_ValueError, "faces must be an (m, 3) array of vertex indices");
            goto done;
        }
        nf = PyArray_DIM(f64, 0);
        {
            const int64_t *f = PyArray_DATA(f64);
            for (npy_intp i = 0; i < 3 * nf; i++)
                if (f[i] < 0 || f[i] >= nv) {
                    /* the message reads f[i]: formatted before the array that holds it goes */
                    PyErr_Format(PyExc_ValueError, "faces: index %lld of face %zd is not a vertex (0..%zd)",
                                 (long long)f[i], (Py_ssize_t)(i / 3), (Py_ssize_t)nv - 1);
                    Py_DECREF(f64);
                    goto done;
                }
        }
        fa = (PyArrayObject *)PyArray_FROM_OTF((PyObject *)f64, NPY_UINT32, NPY_ARRAY_IN_ARRAY | NPY_ARRAY_FORCECAST);
        Py_DECREF(f64);
        if (!fa) goto done;
    }
    if (no != Py_None) {
        na = wvolpy_real_f32(no);
        if (!na) goto done;
        if (PyArray_NDIM(na) != 2 || PyArray_DIM(na, 1) != 3 || PyArray_DIM(na, 0) != PyArray_DIM(va, 0)) {
            PyErr_SetString(PyExc_ValueError, "normals must be an (n, 3) array, one per vertex");
            goto done;
        }
        {
            Py_ssize_t bad = wvolpy_first_nonfinite3(PyArray_DATA(na), 3 * PyArray_DIM(na, 0));
            if (bad >= 0) {
                PyErr_Format(PyExc_ValueError, "normals: non-finite value at vertex %zd", bad);
                goto done;
            }
        }
    }
    {
        Py_ssize_t bad = wvolpy_first_nonfinite3(PyArray_DATA(va), 3 * PyArray_DIM(va, 0));
        if (bad >= 0) {
            PyErr_Format(PyExc_ValueError, "vertices: non-finite coordinate at vertex %zd", bad);
            goto done;
        }
    }
    if (!PyUnicode_FSConverter(path_obj, &bytes)) goto done;
    m.nverts = (size_t)PyArray_DIM(va, 0);
    m.ntris = (size_t)PyArray_DIM(fa, 0);
    m.verts = PyArray_DATA(va);
    m.tris = PyArray_DATA(fa);
    m.normals = na ? PyArray_DATA(na) : NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_mesh_save(&m, PyBytes_AS_STRING(bytes), &err);
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) wvolpy_raise(&err);
    else res = Py_NewRef(Py_None);
done:
    Py_XDECREF(bytes);
    Py_XDECREF(va);
    Py_XDECREF(fa);
    Py_XDECREF(na);
    return res;
}

PyMethodDef wvolpy_iso_methods[] = {
    {"save_mesh", (PyCFunction)(void (*)(void))py_save_mesh, METH_VARARGS | METH_KEYWORDS,
     "save_mesh(path, vertices, faces, normals=None): .ply .obj .stl .vtp by extension"},
    {"isosurface", (PyCFunction)(void (*)(void))py_isosurface, METH_VARARGS | METH_KEYWORDS,
     "isosurface(source, iso, spacing=None, origin=None, normals='gradient', threads=0, brick=None, level=0,\n"
     "wavelet='db2')\n"
     "-> (vertices, faces, normals, stats); source: a StoreHandle or an array"},
    {"isoimage", (PyCFunction)(void (*)(void))py_isoimage, METH_VARARGS | METH_KEYWORDS,
     "isoimage(source, iso, camera='+z', width=256, height=256, method='cast', threads=0, brick=0,\n"
     "tolerance=0, spacing=None, origin=None, model_bound=False) -> (rgba, depth, stats)"},
    {NULL, NULL, 0, NULL}};
