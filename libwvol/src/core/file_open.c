/* SPDX-License-Identifier: MIT */
/* Input files: regular files only, opened without waiting; and the names of the temporaries
 * beside outputs (core/file_open.h). */
#include "core/file_open.h"
#include "core/status_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
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

char *wvol__temp_template(const char *final, const char *tag, const char *ext)
{
    const char *slash = strrchr(final, '/'), *base = slash ? slash + 1 : final;
    const size_t dir = (size_t)(base - final), g = strlen(tag) + 6, e = strlen(ext);
    size_t keep = strlen(base);
    char *t;
    if (g + e > 128) return NULL; /* no writer's tag and extension are that long */
    if (keep > 255 - g - e) {
        keep = 255 - g - e;
        while (keep > 0 && ((unsigned char)base[keep] & 0xC0) == 0x80) keep--; /* not inside a character */
    }
    if (!(t = malloc(dir + keep + g + e + 1))) return NULL;
    memcpy(t, final, dir + keep);
    memcpy(t + dir + keep, tag, g - 6);
    memcpy(t + dir + keep + g - 6, "XXXXXX", 6);
    memcpy(t + dir + keep + g, ext, e + 1);
    return t;
}
