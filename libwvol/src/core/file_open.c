/* SPDX-License-Identifier: MIT */
/* Input files: regular files only, opened without waiting (core/file_open.h). */
#include "core/file_open.h"
#include "core/status_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

wvol_status wvol__open_regular(int *fd, const char *path, wvol_error *err)
{
    struct stat st;
    int flags;
    *fd = -1;
    if (!path) return wvol_error_set(err, WVOL_ERR_ARG, "missing path");
    *fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (*fd < 0) return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (fstat(*fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        close(*fd);
        *fd = -1;
        return wvol_error_set(err, WVOL_ERR_IO, "%s: not a regular file", path);
    }
    flags = fcntl(*fd, F_GETFL);
    if (flags < 0 || fcntl(*fd, F_SETFL, flags & ~O_NONBLOCK) != 0) {
        int e = errno;
        close(*fd);
        *fd = -1;
        return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    return WVOL_OK;
}

wvol_status wvol__fopen_regular(FILE **fp, const char *path, wvol_error *err)
{
    int fd;
    *fp = NULL;
    WVOL_FORWARD(wvol__open_regular(&fd, path, err));
    *fp = fdopen(fd, "rb");
    if (!*fp) {
        int e = errno;
        close(fd);
        return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    return WVOL_OK;
}

wvol_status wvol__check_regular(const char *path, wvol_error *err)
{
    struct stat st;
    if (!path) return wvol_error_set(err, WVOL_ERR_ARG, "missing path");
    if (stat(path, &st) != 0) return wvol_error_set(err, WVOL_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (!S_ISREG(st.st_mode)) return wvol_error_set(err, WVOL_ERR_IO, "%s: not a regular file", path);
    return WVOL_OK;
}
