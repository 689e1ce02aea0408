/* SPDX-License-Identifier: MIT */
/* Random access to a .wvc file (wvol/wvc.h: wvol_wvc_open, wvol_wvc_read_region): an open
 * file as a capsule, its header, region reads at a level of detail, the chunk cache's
 * counters. The ParaView / VTK reader (python/wvol/vtk_wvc.py) is built on these: each
 * pipeline piece reads its own box and decodes only the chunks that box needs. */
#include "pyutil.h"
#include "methods.h"
#include "wvol/wvc.h"

#define CAPSULE_NAME "wvol.WvcFile"

static void capsule_close(PyObject *cap)
{
    wvol_wvc_close((wvol_wvc_file *)PyCapsule_GetPointer(cap, CAPSULE_NAME));
}

static wvol_wvc_file *file_of(PyObject *cap)
{
    return (wvol_wvc_file *)PyCapsule_GetPointer(cap, CAPSULE_NAME); /* NULL + TypeError/ValueError */
}

/* wvc_file_open(path, budget=0) -> capsule (closed when it dies). budget in bytes of
 * decoded chunks, 0 = the library's default. */
static PyObject *py_wvc_file_open(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "budget", NULL};
    PyObject *bytes = NULL, *cap;
    unsigned long long budget = 0;
    wvol_wvc_file *f = NULL;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&|O&", kwlist, PyUnicode_FSConverter, &bytes, wvolpy_conv_budget, &budget)) return NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_wvc_open(&f, PyBytes_AS_STRING(bytes), (size_t)budget, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(bytes);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    cap = PyCapsule_New(f, CAPSULE_NAME, capsule_close);
    if (!cap) wvol_wvc_close(f);
    return cap;
}

/* wvc_file_info(file) -> the header's dict (as wvc_info) plus "chunks", "tile" (x/y, z),
 * "level_shapes": the (z, y, x) grid of every level 0..levels (ceil(n / 2^s) along each
 * transformed axis, n along an axis the transform leaves alone) and "level_origins": the
 * (x, y, z) position of each level grid's first sample (origin + spacing (2^s - 1) c along a
 * transformed axis, c the filter's centre: wvol_idwt3_level's convention, which
 * wvol_wvc_read_region follows). A reader can describe every level without decoding. */
static PyObject *py_wvc_file_info(PyObject *self, PyObject *cap)
{
    wvol_wvc_file *f = file_of(cap);
    const wvol_wvc_info *in;
    wvol_error err;
    PyObject *d, *shapes = NULL, *origins = NULL, *v = NULL;
    (void)self;
    if (!f) return NULL;
    in = wvol_wvc_file_info(f);
    if (wvol_wvc_level_geometry(in, 0, NULL, NULL, NULL, &err) != WVOL_OK) return wvolpy_raise(&err);
    if (!(d = wvolpy_wvc_info_dict(in))) return NULL;
    shapes = PyList_New(in->levels + 1);
    origins = PyList_New(in->levels + 1);
    if (!shapes || !origins) goto fail;
    for (int s = 0; s <= in->levels; s++) {
        size_t g[3];
        double o[3];
        (void)wvol_wvc_level_geometry(in, s, g, NULL, o, NULL); /* checked above: the same filter, s in range */
        if (wvolpy_list_set(shapes, s, Py_BuildValue("(nnn)", (Py_ssize_t)g[2], (Py_ssize_t)g[1], (Py_ssize_t)g[0])) < 0 ||
            wvolpy_list_set(origins, s, Py_BuildValue("(ddd)", o[0], o[1], o[2])) < 0)
            goto fail;
    }
    if (PyDict_SetItemString(d, "level_shapes", shapes) < 0 || PyDict_SetItemString(d, "level_origins", origins) < 0)
        goto fail;
    if (!(v = Py_BuildValue("K", (unsigned long long)in->chunks)) || PyDict_SetItemString(d, "chunks", v) < 0) goto fail;
    Py_CLEAR(v);
    if (!(v = Py_BuildValue("(ii)", in->tile, in->tile_z)) || PyDict_SetItemString(d, "tile", v) < 0) goto fail;
    Py_DECREF(v);
    Py_DECREF(shapes);
    Py_DECREF(origins);
    return d;
fail:
    Py_XDECREF(v);
    Py_XDECREF(shapes);
    Py_XDECREF(origins);
    Py_DECREF(d);
    return NULL;
}

/* wvc_file_chunk_modes(file) -> per level 1..levels a dict of its chunks by coding mode
 * (wvol_wvc_file_chunk_modes: reads each chunk's first byte, so kept out of wvc_file_info,
 * which a reader calls at open); every count zero for a version-1 file. */
static PyObject *py_wvc_file_chunk_modes(PyObject *self, PyObject *cap)
{
    wvol_wvc_file *f = file_of(cap);
    uint64_t counts[WVOL_WVC_MAX_LEVELS + 1][WVOL_WVC_CHUNK_MODES];
    wvol_error err;
    PyObject *out;
    int levels;
    (void)self;
    if (!f) return NULL;
    if (wvol_wvc_file_chunk_modes(f, counts, &err) != WVOL_OK) return wvolpy_raise(&err);
    levels = wvol_wvc_file_info(f)->levels;
    if (!(out = PyList_New(levels))) return NULL;
    for (int m = 1; m <= levels; m++) {
        PyObject *e = PyDict_New();
        if (!e) goto fail;
        PyList_SET_ITEM(out, m - 1, e);
        for (int k = 0; k < WVOL_WVC_CHUNK_MODES; k++) {
            PyObject *n = PyLong_FromUnsignedLongLong((unsigned long long)counts[m][k]);
            if (!n || PyDict_SetItemString(e, wvol_wvc_chunk_mode_name(k), n) < 0) {
                Py_XDECREF(n);
                goto fail;
            }
            Py_DECREF(n);
        }
    }
    return out;
fail:
    Py_DECREF(out);
    return NULL;
}

static int size3(PyObject *o, size_t out[3], const char *what)
{
    PyObject *seq = wvolpy_fast_snapshot(o, what);
    if (!seq) return -1;
    if (PySequence_Fast_GET_SIZE(seq) != 3) {
        PyErr_Format(PyExc_ValueError, "%s must have 3 entries (x, y, z)", what);
        Py_DECREF(seq);
        return -1;
    }
    for (int a = 0; a < 3; a++) {
        long long v = PyLong_AsLongLong(PySequence_Fast_GET_ITEM(seq, a));
        if (v == -1 && PyErr_Occurred()) {
            Py_DECREF(seq);
            return -1;
        }
        if (v < 0) {
            PyErr_Format(PyExc_ValueError, "%s: negative index %lld", what, v);
            Py_DECREF(seq);
            return -1;
        }
        out[a] = (size_t)v;
    }
    Py_DECREF(seq);
    return 0;
}

/* wvc_file_region(file, lo, hi, level=0, out=None, threads=1) -> (array (z, y, x), spacing,
 * origin): the samples [lo, hi) (x, y, z order, in level `level`'s grid), decoding only the
 * chunks they need. With `out` (a writable C-contiguous float32 array of shape (z, y, x) of
 * the box) the samples are reconstructed in place and `out` is returned: a reader fills its
 * output slab by slab without a copy. `threads` reconstruct parts of the box along y at once
 * (0: all). */
static PyObject *py_wvc_file_region(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"file", "lo", "hi", "level", "out", "threads", NULL};
    PyObject *cap, *lo_o, *hi_o, *out_o = Py_None;
    PyArrayObject *o;
    int level = 0, threads = 1;
    size_t lo[3], hi[3], g[3];
    npy_intp want[3];
    double sp[3], org[3];
    const wvol_wvc_info *in;
    wvol_wvc_file *f;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOO|iOi", kwlist, &cap, &lo_o, &hi_o, &level, &out_o, &threads))
        return NULL;
    if (!(f = file_of(cap)) || size3(lo_o, lo, "lo") < 0 || size3(hi_o, hi, "hi") < 0) return NULL;
    if (wvolpy_check_threads(threads) < 0) return NULL;
    /* the box must lie in the level's grid before an array of its size is made; the
     * library refuses a level out of range itself, with its message */
    in = wvol_wvc_file_info(f);
    if (level >= 0 && level <= in->levels && wvol_wvc_level_geometry(in, level, g, NULL, NULL, NULL) == WVOL_OK) {
        for (int a = 0; a < 3; a++)
            if (lo[a] >= hi[a] || hi[a] > g[a]) {
                PyErr_Format(PyExc_ValueError, "wvc region: box %zu..%zu along axis %d is empty or outside 0..%zu "
                             "(level %d)", lo[a], hi[a], a, g[a], level);
                return NULL;
            }
    }
    for (int a = 0; a < 3; a++) want[2 - a] = hi[a] > lo[a] ? (npy_intp)(hi[a] - lo[a]) : 0;
    if (out_o == Py_None) {
        if (!(out_o = PyArray_SimpleNew(3, want, NPY_FLOAT32))) return NULL;
    } else if (!PyArray_Check(out_o)) {
        PyErr_SetString(PyExc_TypeError, "out must be a numpy array");
        return NULL;
    } else {
        o = (PyArrayObject *)out_o;
        /* the type number of '>f4' is float32's too: the byte order and alignment are checked */
        if (PyArray_TYPE(o) != NPY_FLOAT32 || PyArray_NDIM(o) != 3 || !PyArray_ISCARRAY(o) ||
            !PyArray_ISNOTSWAPPED(o) || PyArray_DIM(o, 0) != want[0] || PyArray_DIM(o, 1) != want[1] ||
            PyArray_DIM(o, 2) != want[2]) {
            PyErr_Format(PyExc_ValueError,
                         "out must be a writable, aligned, C-contiguous float32 array in the machine's byte "
                         "order of shape (%ld, %ld, %ld) (z, y, x)",
                         (long)want[0], (long)want[1], (long)want[2]);
            return NULL;
        }
        Py_INCREF(out_o);
    }
    o = (PyArrayObject *)out_o;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_wvc_read_region_into((float *)PyArray_DATA(o), f, lo, hi, level, threads, sp, org, &err);
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) {
        Py_DECREF(out_o);
        return wvolpy_raise(&err);
    }
    return Py_BuildValue("(N(ddd)(ddd))", out_o, sp[0], sp[1], sp[2], org[0], org[1], org[2]);
}

static void capsule_free_samples(PyObject *cap) { free(PyCapsule_GetPointer(cap, "wvol.samples")); }

/* wvc_file_piece(file, lo, hi, level=0, threads=0) -> (array (z, y, x), spacing, origin), or None
 * when the box is not a piece wvol_wvc_read_piece_into reads (it must span the level's grid
 * along x and y): the box decoded into a work array of wvol_wvc_piece_samples floats, which
 * then shrinks to the box's samples and becomes the array's memory (no copy). */
static PyObject *py_wvc_file_piece(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"file", "lo", "hi", "level", "threads", NULL};
    PyObject *cap, *lo_o, *hi_o, *arr, *owner;
    int level = 0, threads = 0;
    size_t lo[3], hi[3], cap_n, box;
    npy_intp dims[3];
    double sp[3], org[3];
    float *work, *shrunk;
    wvol_wvc_file *f;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOO|ii", kwlist, &cap, &lo_o, &hi_o, &level, &threads)) return NULL;
    if (!(f = file_of(cap)) || size3(lo_o, lo, "lo") < 0 || size3(hi_o, hi, "hi") < 0) return NULL;
    if (wvolpy_check_threads(threads) < 0) return NULL;
    if (!(cap_n = wvol_wvc_piece_samples(f, level, lo, hi))) Py_RETURN_NONE;
    box = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    if (!(work = malloc(cap_n * sizeof *work))) return PyErr_NoMemory();
    Py_BEGIN_ALLOW_THREADS
    s = wvol_wvc_read_piece_into(work, cap_n, f, lo, hi, level, threads, sp, org, &err);
    Py_END_ALLOW_THREADS
    if (s != WVOL_OK) {
        free(work);
        return wvolpy_raise(&err);
    }
    /* the margins' planes go back to the system (glibc shrinks a large block in place) */
    shrunk = realloc(work, box * sizeof *work);
    if (shrunk) work = shrunk;
    for (int a = 0; a < 3; a++) dims[2 - a] = (npy_intp)(hi[a] - lo[a]);
    owner = PyCapsule_New(work, "wvol.samples", capsule_free_samples);
    if (!owner) {
        free(work);
        return NULL;
    }
    arr = PyArray_SimpleNewFromData(3, dims, NPY_FLOAT32, work);
    if (!arr || PyArray_SetBaseObject((PyArrayObject *)arr, owner) < 0) { /* SetBaseObject steals owner */
        Py_XDECREF(arr);
        if (!arr) Py_DECREF(owner);
        return NULL;
    }
    return Py_BuildValue("(N(ddd)(ddd))", arr, sp[0], sp[1], sp[2], org[0], org[1], org[2]);
}

/* wvc_file_piece_budget(file, threads=1) -> bytes of decoded chunks a piece read pins at once
 * (wvol_wvc_piece_budget; 0 for a version-1 file). */
static PyObject *py_wvc_file_piece_budget(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"file", "threads", NULL};
    PyObject *cap;
    int threads = 1;
    wvol_wvc_file *f;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|i", kwlist, &cap, &threads)) return NULL;
    if (wvolpy_check_threads(threads) < 0) return NULL;
    if (!(f = file_of(cap))) return NULL;
    return PyLong_FromSize_t(wvol_wvc_piece_budget(f, threads));
}

/* wvc_file_stats(file) -> the chunk cache's counters (wvol_wvc_cache_stats). */
static PyObject *py_wvc_file_stats(PyObject *self, PyObject *cap)
{
    wvol_wvc_file *f = file_of(cap);
    wvol_wvc_cache_stats st;
    (void)self;
    if (!f) return NULL;
    wvol_wvc_file_stats(f, &st);
    return Py_BuildValue("{s:K,s:K,s:K,s:K,s:K,s:K,s:K,s:K}", "budget", (unsigned long long)st.budget, "held",
                         (unsigned long long)st.held, "peak", (unsigned long long)st.peak, "chunk_bytes",
                         (unsigned long long)st.chunk_bytes, "decoded", (unsigned long long)st.decoded,
                         "decoded_narrow", (unsigned long long)st.decoded_narrow, "hits",
                         (unsigned long long)st.hits, "bytes_read", (unsigned long long)st.bytes_read);
}

/* wvc_file_slab_budget(file, lo, hi, level=0) -> bytes of decoded chunks that reading the box
 * [lo, hi) (x, y, z, level `level`'s grid) in z slabs needs cached to decode each chunk about
 * once (wvol_wvc_slab_budget; 0 for a version-1 file). */
static PyObject *py_wvc_file_slab_budget(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"file", "lo", "hi", "level", NULL};
    PyObject *cap, *lo_o, *hi_o;
    int level = 0;
    size_t lo[3], hi[3];
    wvol_wvc_file *f;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOO|i", kwlist, &cap, &lo_o, &hi_o, &level)) return NULL;
    if (!(f = file_of(cap)) || size3(lo_o, lo, "lo") < 0 || size3(hi_o, hi, "hi") < 0) return NULL;
    if (level < 0 || level > wvol_wvc_file_info(f)->levels)
        return PyErr_Format(PyExc_ValueError, "level %d outside 0..%d", level, wvol_wvc_file_info(f)->levels);
    for (int a = 0; a < 3; a++)
        if (lo[a] >= hi[a]) return PyErr_Format(PyExc_ValueError, "box %zu..%zu along axis %d is empty", lo[a], hi[a], a);
    return PyLong_FromSize_t(wvol_wvc_slab_budget(f, level, lo, hi));
}

/* wvc_file_set_budget(file, budget) -> None: the open file's chunk cache budget in bytes (0: the
 * default), refused below one chain of decoded chunks (wvol_wvc_set_budget). */
static PyObject *py_wvc_file_set_budget(PyObject *self, PyObject *args)
{
    PyObject *cap;
    unsigned long long budget;
    wvol_wvc_file *f;
    wvol_error err;
    (void)self;
    if (!PyArg_ParseTuple(args, "OO&", &cap, wvolpy_conv_budget, &budget)) return NULL;
    if (!(f = file_of(cap))) return NULL;
    if (wvol_wvc_set_budget(f, (size_t)budget, &err) != WVOL_OK) return wvolpy_raise(&err);
    Py_RETURN_NONE;
}

/* built_with_vtk() -> True when this build links VTK (the VTK adapter): such a module must not
 * be imported into ParaView, which carries a VTK of its own (docs/paraview.md). */
static PyObject *py_built_with_vtk(PyObject *self, PyObject *unused)
{
    (void)self;
    (void)unused;
    return PyBool_FromLong(wvol_has_feature(WVOL_FEATURE_VTK));
}

PyMethodDef wvolpy_wvc_region_methods[] = {
    {"built_with_vtk", py_built_with_vtk, METH_NOARGS, "built_with_vtk() -> bool"},
    {"wvc_file_open", (PyCFunction)(void (*)(void))py_wvc_file_open, METH_VARARGS | METH_KEYWORDS,
     "wvc_file_open(path, budget=0) -> file"},
    {"wvc_file_info", py_wvc_file_info, METH_O, "wvc_file_info(file) -> info"},
    {"wvc_file_chunk_modes", py_wvc_file_chunk_modes, METH_O, "wvc_file_chunk_modes(file) -> [per level {mode: chunks}]"},
    {"wvc_file_region", (PyCFunction)(void (*)(void))py_wvc_file_region, METH_VARARGS | METH_KEYWORDS,
     "wvc_file_region(file, lo, hi, level=0, out=None, threads=1) -> (array, spacing, origin)"},
    {"wvc_file_piece", (PyCFunction)(void (*)(void))py_wvc_file_piece, METH_VARARGS | METH_KEYWORDS,
     "wvc_file_piece(file, lo, hi, level=0, threads=0) -> (array, spacing, origin) or None"},
    {"wvc_file_piece_budget", (PyCFunction)(void (*)(void))py_wvc_file_piece_budget, METH_VARARGS | METH_KEYWORDS,
     "wvc_file_piece_budget(file, threads=1) -> bytes"},
    {"wvc_file_stats", py_wvc_file_stats, METH_O, "wvc_file_stats(file) -> counters"},
    {"wvc_file_slab_budget", (PyCFunction)(void (*)(void))py_wvc_file_slab_budget, METH_VARARGS | METH_KEYWORDS,
     "wvc_file_slab_budget(file, lo, hi, level=0) -> bytes"},
    {"wvc_file_set_budget", py_wvc_file_set_budget, METH_VARARGS, "wvc_file_set_budget(file, budget) -> None"},
    {NULL, NULL, 0, NULL}};
