/* SPDX-License-Identifier: MIT */
/* compress: the library's compression pipeline (wvol/compress.h: transform, selection, store)
 * in one call, its result held by a StoreHandle (py_store.h). */
#include "pyutil.h"
#include "methods.h"
#include "py_store.h"

#include <math.h>
#include <string.h>

static const struct {
    const char *name;
    wvol_select_mode mode;
} select_modes[] = {{"all", WVOL_SELECT_ALL},           {"count", WVOL_SELECT_COUNT},
                    {"fraction", WVOL_SELECT_FRACTION}, {"energy", WVOL_SELECT_ENERGY},
                    {"threshold", WVOL_SELECT_THRESHOLD}, {"psnr", WVOL_SELECT_PSNR}};

/* roi: a sequence of (center, radii[, power]) with center/radii in (x, y, z) world units. */
static int parse_roi(PyObject *roi, wvol_select_params *prm)
{
    PyObject *seq;
    Py_ssize_t n;
    if (roi == Py_None) return 0;
    seq = wvolpy_fast_snapshot(roi, "roi must be a sequence of (center, radii[, power]) tuples");
    if (!seq) return -1;
    n = PySequence_Fast_GET_SIZE(seq);
    if (n > WVOL_LOD_MAX_ELLIPSOIDS) {
        PyErr_Format(PyExc_ValueError, "roi: at most %d ellipsoids, got %zd", WVOL_LOD_MAX_ELLIPSOIDS, n);
        goto fail;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *c = NULL, *r = NULL;
        double power = 1.0;
        wvol_lod_ellipsoid *e = &prm->ellipsoids[i];
        PyObject *item = PySequence_Fast_GET_ITEM(seq, i), *entry;
        int ok;
        /* any sequence of two or three items, not only a tuple */
        if (PyUnicode_Check(item) || PyBytes_Check(item) || !PySequence_Check(item)) {
            PyErr_Format(PyExc_TypeError, "roi entry %zd must be (center, radii[, power]), got %R", i, item);
            goto fail;
        }
        if (!(entry = PySequence_Tuple(item))) goto fail;
        /* c and r are borrowed from entry, whose items may be its own (an array's rows are made
         * by the iteration): entry lives until they are read */
        ok = PyArg_ParseTuple(entry, "OO|d;roi entry must be (center, radii[, power])", &c, &r, &power) &&
             wvolpy_triple(c, e->center, "roi center") == 0 && wvolpy_triple(r, e->radii, "roi radii") == 0;
        Py_DECREF(entry);
        if (!ok) goto fail;
        e->power = power;
    }
    prm->n_ellipsoids = (int)n;
    Py_DECREF(seq);
    return 0;
fail:
    Py_DECREF(seq);
    return -1;
}

static PyObject *report_dict(const wvol_select_report *r)
{
    PyObject *lk = PyList_New(r->levels + 1), *lt = PyList_New(r->levels + 1);
    PyObject *le = PyList_New(r->levels + 1), *lek = PyList_New(r->levels + 1);
    if (!lk || !lt || !le || !lek) goto fail;
    for (int m = 0; m <= r->levels; m++)
        if (wvolpy_list_set(lk, m, PyLong_FromSize_t(r->level_kept[m])) < 0 ||
            wvolpy_list_set(lt, m, PyLong_FromSize_t(m == 0 ? r->kept_lowpass : r->level_total[m])) < 0 ||
            wvolpy_list_set(le, m, PyFloat_FromDouble(r->level_energy[m])) < 0 ||
            wvolpy_list_set(lek, m, PyFloat_FromDouble(r->level_energy_kept[m])) < 0)
            goto fail;
    return Py_BuildValue("{s:n,s:n,s:n,s:n,s:d,s:d,s:d,s:d,s:d,s:d,s:d,s:d,s:i,s:d,s:d,s:d,s:d,s:N,s:N,s:N,s:N}",
                         "total", (Py_ssize_t)r->total, "kept", (Py_ssize_t)r->kept, "kept_lowpass",
                         (Py_ssize_t)r->kept_lowpass, "candidates", (Py_ssize_t)r->candidates, "key_cut",
                         r->key_cut, "energy_total", r->energy_total, "energy_kept", r->energy_kept,
                         "energy_dropped", r->energy_dropped, "predicted_l2", r->predicted_l2, "predicted_rmse",
                         r->predicted_rmse, "predicted_psnr", r->predicted_psnr, "peak", r->peak, "measured",
                         r->measured, "measured_l2", r->measured_l2, "measured_rmse", r->measured_rmse,
                         "measured_psnr", r->measured_psnr, "measured_max", r->measured_max, "level_kept", lk,
                         "level_total", lt, "level_energy", le, "level_energy_kept", lek);
fail:
    Py_XDECREF(lk);
    Py_XDECREF(lt);
    Py_XDECREF(le);
    Py_XDECREF(lek);
    return NULL;
}

/* compress(array, wavelet=None, levels=None, mode='all', value=0, drop_levels=0, roi=None,
 *          roi_floor=0, spacing=None, origin=None, measure=False, value_range=None)
 * -> (StoreHandle, report): one wvol_compress (transform, selection, store); None leaves the
 * library's default (wavelet db2; levels WVOL_COMPRESS_LEVELS_STORE, fewer for a small volume);
 * wavelet "auto" is resolved by the library's trial (wvol_compress_choose_wavelet).
 * value_range (min, max) replaces the range of the float32 samples (the caller's data range
 * when it converted another dtype). */
static PyObject *py_compress(PyObject *self, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"array", "wavelet", "levels", "mode", "value", "drop_levels", "roi", "roi_floor",
                             "spacing", "origin", "measure", "value_range", "residual", NULL};
    PyObject *arr_obj, *roi = Py_None, *sp = Py_None, *org = Py_None, *lev_obj = Py_None, *range = Py_None;
    const char *name = NULL, *mode = "all";
    int drop = 0, measure = 0, residual = 0;
    double value = 0, floor_ = 0, vr[2] = {0, 0};
    PyArrayObject *holder;
    wvol_volume v;
    wvol_compress_params p;
    wvol_select_params *prm = &p.select;
    wvol_compressed out;
    wvol_error err;
    wvol_status s;
    size_t i;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O|zOsdiOdOOpOp", kwlist, &arr_obj, &name, &lev_obj, &mode, &value,
                                     &drop, &roi, &floor_, &sp, &org, &measure, &range, &residual))
        return NULL;
    wvol_compress_params_default(&p);
    if (name) p.wavelet = name;
    if (wvolpy_parse_levels(lev_obj, &p.levels) < 0) return NULL;
    if (range != Py_None && !PyArg_ParseTuple(range, "dd;value_range must be (min, max)", &vr[0], &vr[1])) return NULL;
    for (i = 0; i < sizeof select_modes / sizeof select_modes[0]; i++)
        if (strcmp(mode, select_modes[i].name) == 0) break;
    if (i == sizeof select_modes / sizeof select_modes[0])
        return PyErr_Format(PyExc_ValueError,
                            "unknown selection mode '%s' (all, count, fraction, energy, threshold, psnr)", mode);
    prm->mode = select_modes[i].mode;
    if (!isfinite(value)) return PyErr_Format(PyExc_ValueError, "selection value must be finite");
    switch (prm->mode) {
    case WVOL_SELECT_COUNT:
        if (value < 0 || value > 1.8e19) return PyErr_Format(PyExc_ValueError, "keep_count must be >= 0");
        prm->count = (size_t)value;
        break;
    case WVOL_SELECT_FRACTION: prm->fraction = value; break;
    case WVOL_SELECT_ENERGY: prm->energy = value; break;
    case WVOL_SELECT_THRESHOLD: prm->threshold = value; break;
    case WVOL_SELECT_PSNR: prm->psnr = value; break;
    default: break;
    }
    prm->drop_levels = drop;
    p.build_residual = residual;
    prm->lod_floor = floor_;
    prm->measure = measure;
    if (parse_roi(roi, prm) < 0) return NULL;
    if (wvolpy_as_placed_volume(arr_obj, sp, org, &v, &holder, 0) < 0) return NULL;
    Py_BEGIN_ALLOW_THREADS
    s = wvol_volume_set_geometry(&v, v.spacing, v.origin, &err);
    if (s == WVOL_OK) s = wvol_compress(&out, &v, &p, &err);
    Py_END_ALLOW_THREADS
    Py_DECREF(holder);
    if (s != WVOL_OK) return wvolpy_raise(&err);
    if (range != Py_None) {
        out.value_min = vr[0];
        out.value_max = vr[1];
    }
    return wvolpy_store_with(&out, report_dict(&out.report));
}

PyMethodDef wvolpy_compress_methods[] = {
    {"compress", (PyCFunction)(void (*)(void))py_compress, METH_VARARGS | METH_KEYWORDS,
     "compress(array, wavelet=None, levels=None, mode='all', value=0, drop_levels=0, roi=None, roi_floor=0,\n"
     "         spacing=None, origin=None, measure=False, value_range=None, residual=False) -> (StoreHandle, report)"},
    {NULL, NULL, 0, NULL}};
