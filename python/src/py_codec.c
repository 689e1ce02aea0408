/* .wvc files (wvol/wvc.h): quantise + entropy-code kept coefficients, read them back. */
#include "pyutil.h"
#include "methods.h"
#include "wvol/wvc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static PyObject *info_dict(const wvol_wvc_info *in)
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

/* wvc_save(coeffs, wavelet, levels, shape, path, spacing, origin, value_range, dropped_energy,
 *          target_sse=0, step=0) -> report dict */
static PyObject *py_wvc_save(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"coeffs", "wavelet", "levels", "shape", "path", "spacing", "origin", "value_range",
                             "dropped_energy", "target_sse", "step", NULL};
    PyObject *arr_obj, *shape, *path_obj, *sp = Py_None, *org = Py_None, *bytes = NULL;
    const char *name;
    int levels;
    double vmin = 0, vmax = 0, dropped = 0, target = 0, step = 0;
    PyArrayObject *holder;
    wvol_coeffs c;
    wvol_wvc_params wp;
    wvol_wvc_report rep;
    void *buf = NULL;
    size_t nbytes = 0;
    wvol_error err;
    wvol_status s;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OsiOOOO(dd)d|dd", kwlist, &arr_obj, &name, &levels, &shape,
                                     &path_obj, &sp, &org, &vmin, &vmax, &dropped, &target, &step))
        return NULL;
    if (!isfinite(vmin) || !isfinite(vmax) || vmax < vmin)
        return PyErr_Format(PyExc_ValueError, "value_range must be finite with min <= max");
    if (!(dropped >= 0) || !isfinite(dropped)) return PyErr_Format(PyExc_ValueError, "dropped_energy must be >= 0");
    if (!(target >= 0) || !isfinite(target)) return PyErr_Format(PyExc_ValueError, "target_sse must be >= 0");
    if (!(step >= 0) || !isfinite(step)) return PyErr_Format(PyExc_ValueError, "step must be finite and >= 0");
    if (step == 0 && target == 0) return PyErr_Format(PyExc_ValueError, "give a step or a target_sse > 0");
    if (!PyUnicode_FSConverter(path_obj, &bytes)) return NULL;
    if (wvolpy_as_coeffs(arr_obj, name, levels, shape, sp, org, &c, &holder) < 0) {
        Py_DECREF(bytes);
        return NULL;
    }
    wvol_wvc_params_default(&wp);
    wp.step = step;
    wp.target_sse = target;
    wp.value_min = vmin;
    wp.value_max = vmax;
    wp.dropped_energy = dropped;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_wvc_encode(&buf, &nbytes, &c, &wp, &rep, &err);
    if (s == WVOL_OK) s = wvol_wvc_save(PyBytes_AS_STRING(bytes), buf, nbytes, &err);
    Py_END_ALLOW_THREADS
    free(buf);
    Py_DECREF(holder);
    Py_DECREF(bytes);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    return Py_BuildValue("{s:d,s:d,s:K,s:K,s:n}", "step", rep.step, "sse_quant", rep.sse_quant, "nonzero",
                         (unsigned long long)rep.nonzero, "coefficients", (unsigned long long)rep.coefficients,
                         "bytes", (Py_ssize_t)rep.bytes);
}

/* wvc_open(path, stop_level=0) -> (coeffs array, info dict) */
static PyObject *py_wvc_open(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "stop_level", NULL};
    PyObject *path_obj, *bytes = NULL, *a, *d;
    int stop = 0;
    wvol_wvc_read_options opt;
    wvol_wvc_info *info;
    wvol_coeffs *c = NULL;
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
    Py_BEGIN_ALLOW_THREADS
    s = wvol_wvc_read(&c, PyBytes_AS_STRING(bytes), &opt, info, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(bytes);
    if (s != WVOL_OK) {
        PyMem_Free(info);
        return wvolpy_raise(&err);
    }
    d = info_dict(info);
    PyMem_Free(info);
    if (!d) {
        wvol_coeffs_destroy(c);
        return NULL;
    }
    {
        npy_intp dims[3] = {(npy_intp)c->pz, (npy_intp)c->py, (npy_intp)c->px};
        a = wvolpy_array_take(c->data, 3, dims);
        c->data = NULL;
    }
    wvol_coeffs_destroy(c);
    if (!a) {
        Py_DECREF(d);
        return NULL;
    }
    return Py_BuildValue("NN", a, d);
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
    d = s == WVOL_OK ? info_dict(info) : wvolpy_raise(&err);
    PyMem_Free(info);
    return d;
}

PyMethodDef wvolpy_codec_methods[] = {
    {"wvc_save", (PyCFunction)(void (*)(void))py_wvc_save, METH_VARARGS | METH_KEYWORDS,
     "wvc_save(coeffs, wavelet, levels, shape, path, spacing, origin, value_range, dropped_energy,\n"
     "         target_sse=0, step=0) -> report"},
    {"wvc_open", (PyCFunction)(void (*)(void))py_wvc_open, METH_VARARGS | METH_KEYWORDS,
     "wvc_open(path, stop_level=0) -> (coeffs, info)"},
    {"wvc_info", py_wvc_info, METH_O, "wvc_info(path) -> info"},
    {NULL, NULL, 0, NULL}};
