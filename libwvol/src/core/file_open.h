/* SPDX-License-Identifier: MIT
 * Opening an input file (not installed; the readers' shared first step), and naming the
 * temporaries written beside outputs (the writers' first step). A path may name a
 * FIFO, a device or a directory: open() of a FIFO for reading waits for a writer, forever
 * if none comes, and a device can be endless. The readers take only regular files: the path
 * (symbolic links followed) is opened without waiting (O_NONBLOCK), checked with fstat, and
 * made blocking again, so nothing is ever read from anything else. */
#ifndef WVOL_CORE_FILE_OPEN_H
#define WVOL_CORE_FILE_OPEN_H

#include <stdio.h>

#include "wvol/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* *fd: a descriptor open for reading on the regular file at path; else -1 and WVOL_ERR_IO
 * ("PATH: cannot open: REASON" or "PATH: not a regular file"). */
wvol_status wvol__open_regular(int *fd, const char *path, wvol_error *err);
/* The same as a stdio stream ("rb") in *fp (NULL on failure). */
wvol_status wvol__fopen_regular(FILE **fp, const char *path, wvol_error *err);
/* WVOL_OK when path names a regular file (links followed), else WVOL_ERR_IO as above, for
 * readers whose library opens the file itself (VTK, OpenVDB, OpenEXR, tinyobjloader). */
wvol_status wvol__check_regular(const char *path, wvol_error *err);

/* The template of a temporary beside final: "FINAL" tag "XXXXXX" ext (tag ".tmp-" for the
 * outputs' temporaries; ext may be ""), final's own name shortened (at a UTF-8 character's
 * start) when the whole would pass the 255 bytes a name may have, so that a name that fits
 * can always be written. malloc'ed; NULL when out of memory. */
char *wvol__temp_template(const char *final, const char *tag, const char *ext);

#ifdef __cplusplus
}
#endif
#endif
