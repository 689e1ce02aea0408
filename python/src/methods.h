/* SPDX-License-Identifier: MIT */
/* Method tables of the extension, one per area (py_<area>.c). Add new ones here. */
#ifndef WVOL_PY_METHODS_H
#define WVOL_PY_METHODS_H
#include "wvol/version.h"
#include <Python.h>

extern PyMethodDef wvolpy_io_methods[];
extern PyMethodDef wvolpy_wavelet_methods[];
extern PyMethodDef wvolpy_compress_methods[];
extern PyMethodDef wvolpy_synth_methods[];
extern PyMethodDef wvolpy_analysis_methods[];
extern PyMethodDef wvolpy_codec_methods[];
extern PyMethodDef wvolpy_iso_methods[];
extern PyMethodDef wvolpy_render_methods[];
extern PyMethodDef wvolpy_radiosity_methods[];
extern PyMethodDef wvolpy_transport_methods[];
extern PyMethodDef wvolpy_wvc_region_methods[];
/* The StoreHandle type (py_store.c), added to the module at import: 0 or -1. */
int wvolpy_store_ready(PyObject *module);
/* A .wvc header as a dict (py_codec.c; also the open file's info in py_wvc_region.c). */
struct wvol_wvc_info;
PyObject *wvolpy_wvc_info_dict(const struct wvol_wvc_info *in);

#define WVOLPY_METHOD_TABLES                                                                             \
    wvolpy_io_methods, wvolpy_wavelet_methods, wvolpy_compress_methods, wvolpy_synth_methods,             \
    wvolpy_analysis_methods, wvolpy_codec_methods, wvolpy_iso_methods, wvolpy_render_methods,            \
    wvolpy_radiosity_methods, wvolpy_transport_methods, wvolpy_wvc_region_methods
#endif
