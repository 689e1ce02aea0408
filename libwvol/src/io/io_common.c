/* SPDX-License-Identifier: MIT
 * Helpers the image readers share (io_internal.h): the axis-flipping geometry and
 * the number syntax of text headers. */
#include "io/io_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static void reverse_floats(float *a, float *b) /* [a, b) */
{
    while (a < --b) {
        float t = *a;
        *a++ = *b;
        *b = t;
    }
}

static void swap_floats(float *a, float *b, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        float t = a[i];
        a[i] = b[i];
        b[i] = t;
    }
}

static void flip_axis(wvol_volume *v, int axis)
{
    const size_t nx = v->nx, ny = v->ny, nz = v->nz;
    float *d = v->data;
    if (axis == 0) {
        for (size_t r = 0; r < ny * nz; r++) reverse_floats(d + r * nx, d + (r + 1) * nx);
    } else if (axis == 1) {
        for (size_t k = 0; k < nz; k++)
            for (size_t j = 0; j < ny / 2; j++) swap_floats(d + (k * ny + j) * nx, d + (k * ny + ny - 1 - j) * nx, nx);
    } else {
        for (size_t k = 0; k < nz / 2; k++) swap_floats(d + k * nx * ny, d + (nz - 1 - k) * nx * ny, nx * ny);
    }
}

int wvol__io_reversed_axes(const double spacing[3], const double dir[3][3])
{
    int axes = 0;
    for (int a = 0; a < 3; a++) {
        /* axis a keeps its direction's sign when the rotation leaves it on world axis a (its
         * column and row zero elsewhere): a rotation in x-y with z reversed still reverses z */
        int aligned = 1;
        for (int o = 0; o < 3; o++)
            if (o != a && (fabs(dir[o][a]) > 1e-6 || fabs(dir[a][o]) > 1e-6)) aligned = 0;
        if (spacing[a] * (aligned && dir[a][a] < 0 ? -1.0 : 1.0) < 0) axes |= 1 << a;
    }
    return axes;
}

wvol_status wvol__io_apply_geometry(wvol_volume *v, const double origin_in[3], const double spacing_in[3],
                                    const double dir[3][3], wvol_error *err)
{
    const size_t n[3] = {v->nx, v->ny, v->nz};
    const int reversed = wvol__io_reversed_axes(spacing_in, dir);
    double spacing[3], origin[3];
    for (int a = 0; a < 3; a++) {
        origin[a] = origin_in[a];
        spacing[a] = fabs(spacing_in[a]);
        if (reversed >> a & 1) {
            flip_axis(v, a);
            origin[a] = origin_in[a] - (double)(n[a] - 1) * spacing[a];
        }
    }
    return wvol_volume_set_geometry(v, spacing, origin, err);
}

static int is_space(char c)
{
    return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r';
}

/* One number the way libstdc++'s num_get reads a double in the C locale: the longest
 * run of [+-] digits [.] digits [e [+-] digits] (an exponent only after a digit),
 * converted by strtod, which must use all of it; +-inf (overflow) fails. */
size_t wvol__io_parse_numbers(const char *s, double *out, size_t cap)
{
    size_t count = 0, len = strlen(s);
    char *tok = malloc(len + 2);
    const char *p = s;
    if (!tok) return 0;
    for (;;) {
        size_t k = 0;
        int mantissa = 0, dec = 0, sci = 0;
        char *end;
        double x;
        while (is_space(*p)) p++;
        if (*p == '+' || *p == '-') tok[k++] = *p++;
        for (; *p; p++) {
            if (*p >= '0' && *p <= '9') {
                tok[k++] = *p;
                mantissa = 1;
            } else if (*p == '.' && !dec && !sci) {
                tok[k++] = '.';
                dec = 1;
            } else if ((*p == 'e' || *p == 'E') && !sci && mantissa) {
                tok[k++] = 'e';
                sci = 1;
                if (p[1] == '+' || p[1] == '-') tok[k++] = *++p;
            } else {
                break;
            }
        }
        tok[k] = '\0';
        if (k == 0) break;
        x = strtod(tok, &end);
        if (end == tok || *end != '\0' || isinf(x)) break;
        if (count < cap) out[count] = x;
        count++;
    }
    free(tok);
    return count;
}

char *wvol__io_data_path_of(const char *header_path, const char *data_file)
{
    const char *slash = strrchr(header_path, '/');
    size_t dir = slash ? (size_t)(slash - header_path) + 1 : 0, n = strlen(data_file);
    char *p;
    if (data_file[0] == '/' || dir == 0) return strdup(data_file);
    p = malloc(dir + n + 1);
    if (!p) return NULL;
    memcpy(p, header_path, dir);
    memcpy(p + dir, data_file, n + 1);
    return p;
}
