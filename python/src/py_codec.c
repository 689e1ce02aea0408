/* SPDX-License-Identifier: MIT */
/* .wvc files (wvol/wvc.h): read one into a StoreHandle, read a header. Writing is the
 * handle's save (py_store.c). */
#include "pyutil.h"
#include "methods.h"
#include "py_store.h"
#include "wvol/wvc.h"

PyObject *wvolpy_wvc_info_dict(const wvol_wvc_info *in)
{
    return Py_BuildValue("{s:i,s:s,s:i,s:(nnn),s:(nnn),s:(ddd),s:(ddd),s:(dd),s:d,s:d,s:d,s:d,s:d,s:d,s:K,s:K,s:i}",
                         "version", in->version, "wavelet", in->filter, "levels", in->levels, "shape",
                         (Py_ssize_t)in->nz, (Py_ssize_t)in->ny, (Py_ssize_t)in->nx, "padded", (Py_ssize_t)in->pz,
                         (Py_ssize_t)in->py, (Py_ssize_t)in->px, "spacing", in->spacing[0], in->spacing[1],
                         in->spacing[2], "origin", in->origin[0], in->origin[1], in->origin[2], "value_range",
                         in->value_min, in->value_max, "step", in->step, "rounding", in->rounding, "sse_quant", in->sse, "sse",
                         in->sse + in->dropped_energy, /* the header's error field is quantisation only */
                         "energy", in->energy, "dropped_energy", in->dropped_energy, "nonzero",
                         (unsigned long long)in->nonzero, "file_bytes", (unsigned long long)in->file_bytes,
                         "sections", in->nsections);
}

/* store_open(path, stop_level=0) -> (StoreHandle, info dict): the file's coefficients through
 * the library's pipeline (wvol_compress_coeffs: every nonzero coefficient kept, the store
 * built), as `wvol render FILE.wvc` does. The handle's data range and dropped energy are the
 * header's (quantisation + dropped: what re-encoding it takes as dropped). */
static PyObject *py_store_open(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "stop_level", NULL};
    PyObject *path_obj, *bytes = NULL, *d;
    int stop = 0;
    wvol_wvc_read_options opt;
    wvol_wvc_info *info;
    wvol_coeffs *c = NULL;
    wvol_compress_params p;
    wvol_compressed out;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|i", kwlist, &path_obj, &stop)) return NULL;
    if (stop < 0) return PyErr_Format(PyExc_ValueError, "level must be >= 0, got %d", stop);
    if (!PyUnicode_FSConverter(path_obj, &bytes)) return NULL;
    info = PyMem_Malloc(sizeof *info); /* ~30 KB: not on the stack */
    if (!info) {
        Py_DECREF(bytes);
        return PyErr_NoMemory();
    }
    wvol_wvc_read_options_default(&opt);
    opt.stop_level = stop;
    wvol_compress_params_default(&p);
    Py_BEGIN_ALLOW_THREADS
    s = wvol_wvc_read(&c, PyBytes_AS_STRING(bytes), &opt, info, &err);
    if (s == WVOL_OK) s = wvol_compress_coeffs(&out, &c, &p, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(bytes);
    if (s != WVOL_OK) {
        PyMem_Free(info);
        return wvolpy_raise(&err);
    }
    out.value_min = info->value_min;
    out.value_max = info->value_max;
    out.report.energy_dropped = info->sse + info->dropped_energy;
    d = wvolpy_wvc_info_dict(info);
    PyMem_Free(info);
    return wvolpy_store_with(&out, d);
}

/* wvc_info(path) -> info dict (header and table only; checksums verified) */
static PyObject *py_wvc_info(PyObject *self, PyObject *path_obj)
{
    PyObject *bytes = NULL, *d;
    wvol_wvc_info *info;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyUnicode_FSConverter(path_obj, &bytes)) return NULL;
    info = PyMem_Malloc(sizeof *info);
    if (!info) {
        Py_DECREF(bytes);
        return PyErr_NoMemory();
    }
    Py_BEGIN_ALLOW_THREADS
    s = wvol_wvc_read_info(info, PyBytes_AS_STRING(bytes), &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(bytes);
    d = s == WVOL_OK ? wvolpy_wvc_info_dict(info) : wvolpy_raise(&err);
    PyMem_Free(info);
    return d;
}

/* wvc_region(path, lo, hi, level=0, memory=0) -> (array z,y,x, stats dict): the box [lo, hi)
 * (x, y, z, level-`level` grid) from a .wvc through its chunk cache (wvol_wvc_read_region). */
static PyObject *py_wvc_region(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "lo", "hi", "level", "memory", NULL};
    PyObject *path_obj, *bytes = NULL, *arr, *stats;
    Py_ssize_t lo_in[3], hi_in[3];
    unsigned long long memory = 0;
    int level = 0;
    size_t lo[3], hi[3];
    wvol_wvc_file *f = NULL;
    wvol_volume *v = NULL;
    wvol_wvc_cache_stats cs;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O(nnn)(nnn)|iO&", kwlist, &path_obj, &lo_in[0], &lo_in[1],
                                     &lo_in[2], &hi_in[0], &hi_in[1], &hi_in[2], &level, wvolpy_conv_budget, &memory))
        return NULL;
    for (int a = 0; a < 3; a++) {
        if (lo_in[a] < 0 || hi_in[a] < 0) return PyErr_Format(PyExc_ValueError, "region bounds must be >= 0");
        lo[a] = (size_t)lo_in[a], hi[a] = (size_t)hi_in[a];
    }
    if (!PyUnicode_FSConverter(path_obj, &bytes)) return NULL;
    memset(&cs, 0, sizeof cs);
    Py_BEGIN_ALLOW_THREADS
    s = wvol_wvc_open(&f, PyBytes_AS_STRING(bytes), (size_t)memory, &err);
    if (s == WVOL_OK) s = wvol_wvc_read_region(&v, f, lo, hi, level, &err);
    if (s == WVOL_OK) wvol_wvc_file_stats(f, &cs);
    wvol_wvc_close(f);
    Py_END_ALLOW_THREADS
    Py_DECREF(bytes);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    arr = wvolpy_volume_take(v, 0);
    if (!arr) return NULL;
    stats = Py_BuildValue("{s:K,s:K,s:K,s:K,s:n,s:n}", "chunks_decoded", (unsigned long long)cs.decoded,
                          "chunks_decoded_narrow", (unsigned long long)cs.decoded_narrow, "bytes_read",
                          (unsigned long long)cs.bytes_read, "cache_hits", (unsigned long long)cs.hits,
                          "cache_peak_bytes", (Py_ssize_t)cs.peak, "budget_bytes", (Py_ssize_t)cs.budget);
    if (!stats) {
        Py_DECREF(arr);
        return NULL;
    }
    return Py_BuildValue("(NN)", arr, stats);
}

PyMethodDef wvolpy_codec_methods[] = {
    {"wvc_region", (PyCFunction)(void (*)(void))py_wvc_region, METH_VARARGS | METH_KEYWORDS,
     "wvc_region(path, lo, hi, level=0, memory=0) -> (array, stats)"},
    {"store_open", (PyCFunction)(void (*)(void))py_store_open, METH_VARARGS | METH_KEYWORDS,
     "store_open(path, stop_level=0) -> (StoreHandle, info)"},
    {"wvc_info", py_wvc_info, METH_O, "wvc_info(path) -> info"},
    {NULL, NULL, 0, NULL}};
