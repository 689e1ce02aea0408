/* Shared by py_render.c and py_render_store.c. */
#ifndef WVOL_PY_RENDER_H
#define WVOL_PY_RENDER_H
#include "pyutil.h"
#include "wvol/render.h"

/* Camera, transfer function and parameters from the options dict (keys: camera, width,
 * height, mode, tf, tf_units, step, termination, ambient, shading, gauss_nodes, threads,
 * colors); vmin/vmax: the data range for TF presets. *colors receives the colour volume's
 * array (NULL when none; pass it to wvolpy_render_finish, which releases it). 0, or -1
 * with an exception (and nothing to release). */
int wvolpy_render_setup(PyObject *opts, const wvol_geometry *g, double vmin, double vmax, wvol_camera *cam,
                        wvol_tf *tf, wvol_render_params *rp, PyArrayObject **colors);
/* (image (h, w, 4) float32 over the image's pixels, no copy; stats dict) when s is
 * WVOL_OK, else err raised; destroys img and releases colors either way. */
PyObject *wvolpy_render_finish(wvol_image *img, wvol_status s, const wvol_render_stats *st, const wvol_error *err,
                               PyArrayObject *colors);
#endif
