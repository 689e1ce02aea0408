/* SPDX-License-Identifier: MIT */
/* Shared helpers of the extension: errors as exceptions, arrays as volumes, result buffers. */
#ifndef WVOL_PY_UTIL_H
#define WVOL_PY_UTIL_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NO_IMPORT_ARRAY
#define PY_ARRAY_UNIQUE_SYMBOL wvol_ARRAY_API
#include <numpy/arrayobject.h>

#include <stdint.h>

#include "wvol/wvol.h"

/* Raises the Python exception matching err's status (ValueError for arguments and
 * data, OSError for files, MemoryError, NotImplementedError for missing features,
 * RuntimeError for internal errors) with the library's message; returns NULL. */
PyObject *wvolpy_raise(const wvol_error *err);

/* Any real-valued array (float or integer dtype) as a float32 C-contiguous array: a new
 * reference, the same memory when it already is one, else a converted copy. NULL with
 * TypeError naming the dtype for anything else (complex, object, strings). */
PyArrayObject *wvolpy_real_f32(PyObject *obj);

/* Views a NumPy array (3D (z, y, x) or 2D (y, x) => nz = 1) as a float32 volume.
 * Float32 C-contiguous arrays are used without a copy; other real dtypes or layouts
 * are converted (a copy). *holder receives the array that owns the memory (DECREF it
 * after use). Refuses empty arrays, wrong ndim, non-real dtypes; checks NaN/Inf
 * when check_finite. spacing/origin may be NULL (1 and 0). Returns 0 on success,
 * -1 with an exception set. */
int wvolpy_as_volume(PyObject *obj, wvol_volume *out, PyArrayObject **holder, int check_finite);
/* wvolpy_as_volume, then spacing and origin (x, y, z; None keeps 1 / 0) from Python
 * sequences into out (not yet checked: wvol_volume_set_geometry does that). On failure
 * *holder is released and NULL. */
int wvolpy_as_placed_volume(PyObject *obj, PyObject *spacing, PyObject *origin, wvol_volume *out,
                            PyArrayObject **holder, int check_finite);

/* A levels argument: None keeps *levels (the library's default, 0), else an int in 1..30.
 * 0 on success, -1 with ValueError/TypeError set. */
int wvolpy_parse_levels(PyObject *obj, int *levels);

/* New float32 array (nz, ny, nx) copying v's samples (2D (ny, nx) when squeeze2d and nz == 1). */
PyObject *wvolpy_volume_to_array(const wvol_volume *v, int squeeze2d);

/* Float32 array of nd dims (C order) over malloc'ed memory, taking ownership: the array
 * frees it with free() when it dies (no copy). On failure frees data and returns NULL. */
PyObject *wvolpy_array_take(float *data, int nd, const npy_intp *dims);
/* Same for any NumPy type number (NPY_UINT32, ...). */
PyObject *wvolpy_array_take_type(void *data, int nd, const npy_intp *dims, int typenum);

/* Array (nz, ny, nx) (2D when squeeze2d and nz == 1) of a library volume, then destroys v:
 * the samples are handed over without a copy when v owns them, copied otherwise. */
PyObject *wvolpy_volume_take(wvol_volume *v, int squeeze2d);

/* Maps a padded Mallat coefficient array (z, y, x) onto *c (no copy for float32
 * C-contiguous input): wavelet by name, levels, the original shape (nz, ny, nx) as a
 * Python sequence, spacing/origin (x, y, z; None = 1 / 0). Checks that the array's
 * shape is the padded size of `shape` for `levels` and refuses NaN/Inf. *holder owns
 * the memory (DECREF after use). Returns 0, or -1 with an exception set. */
int wvolpy_as_coeffs(PyObject *arr, const char *wavelet, int levels, PyObject *shape, PyObject *spacing,
                     PyObject *origin, wvol_coeffs *c, PyArrayObject **holder, int check_finite);

/* Result buffers: the transforms' outputs, handed to NumPy without a copy. A fresh large
 * buffer costs a page fault per 4 KiB page when first written, about as much as a copy of it
 * (more than a third of a 256^3 transform's time): so the last two freed buffers of 4 MiB and
 * more (512 MiB in all at most) are kept for the next request of the same size, as NumPy's
 * allocator keeps small blocks; a loop of transforms then reuses its memory. Call these with
 * the GIL held (it guards the cache). */
typedef struct wvolpy_buffer {
    float *data;
    size_t bytes;   /* capacity */
} wvolpy_buffer;
/* count floats; 0, or -1 with MemoryError. */
int wvolpy_buffer_alloc(wvolpy_buffer *b, size_t count);
/* An nd-dim float32 array over b, which it owns from now on (b is emptied; on failure b is
 * released and NULL returned). */
PyObject *wvolpy_buffer_array(wvolpy_buffer *b, int nd, const npy_intp *dims);
void wvolpy_buffer_free(wvolpy_buffer *b); /* an empty b is fine */

/* Most OpenMP threads a call may ask for (as the command line): libgomp aborts the
 * process when it cannot create the threads asked for, so absurd counts are refused. */
#define WVOLPY_MAX_THREADS 4096
/* 0 when threads is in 0..WVOLPY_MAX_THREADS (0: the default), else -1 with a ValueError. */
int wvolpy_check_threads(int threads);
/* The row (of 3 values) of the first non-finite value among n3 floats, or -1 when all are finite. */
Py_ssize_t wvolpy_first_nonfinite3(const float *p, Py_ssize_t n3);

/* PyArg "O&" converter for a memory budget in bytes: an int >= 0 into *(unsigned long long *)out
 * (negative numbers and non-integers refused with a ValueError / TypeError naming the budget). */
int wvolpy_conv_budget(PyObject *obj, void *out);

/* PyList_SET_ITEM of a new reference that may be NULL (a failed allocation, its error set):
 * -1 then, and the list's slot stays empty (a list frees with its NULL slots). */
int wvolpy_list_set(PyObject *list, Py_ssize_t i, PyObject *item);

/* A seed: an int in 0..2^64-1 into *out (None or NULL leaves it); 0, or -1 with a ValueError
 * (out of range) or TypeError (not an int). */
int wvolpy_seed(PyObject *obj, uint64_t *out);

/* PySequence_Fast whose items stay put while they are read: a list the caller passed (which an
 * item's __float__ or __index__ could shrink or clear mid-loop) comes back as a tuple copy. */
PyObject *wvolpy_fast_snapshot(PyObject *o, const char *msg);

/* Parses an optional 3-sequence of floats (x, y, z order); returns 0 or -1 with exception. */
int wvolpy_triple(PyObject *obj, double out[3], const char *what);

/* The UTF-8 text of str o (owned by o), or NULL with an exception: a TypeError when o is not a
 * str, a ValueError when it holds a NUL ("'xray\0junk'" would be read as "xray"); what names
 * the argument. */
const char *wvolpy_utf8(PyObject *o, const char *what);

/* Sets a ValueError formatted as printf does (PyErr_Format knows no %g) and returns NULL. */
PyObject *wvolpy_value_error(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

#endif
