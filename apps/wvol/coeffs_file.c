/* SPDX-License-Identifier: MIT */
/* Coefficient files of `wvol transform` / `wvol inverse`: raw float32 + JSON sidecar. */
#include "coeffs_file.h"

#include <ctype.h>
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "output_set.h"
#include "wvol/io.h"

char *coeffs_sidecar_path(const char *raw_path)
{
    size_t n = strlen(raw_path);
    char *s = malloc(n + 6);
    if (!s) return NULL;
    memcpy(s, raw_path, n + 1);
    if (wvol_path_has_ext(raw_path, ".raw")) s[n - 4] = '\0';
    strcat(s, ".json");
    return s;
}

static int host_is_big_endian(void)
{
    const uint16_t one = 1;
    return *(const uint8_t *)&one == 0;
}

static void swap4(float *v, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        uint8_t *b = (uint8_t *)&v[i], t;
        t = b[0], b[0] = b[3], b[3] = t;
        t = b[1], b[1] = b[2], b[2] = t;
    }
}

wvol_status coeffs_file_write(const wvol_coeffs *c, const char *raw_path, const char *pad,
                              const char *precision, wvol_error *err)
{
    wvol_atomic_file rf, jf;
    size_t n = c->px * c->py * c->pz;
    char *json_path = coeffs_sidecar_path(raw_path);
    if (!json_path) return wvol_error_set(err, WVOL_ERR_NOMEM, "out of memory");
    /* two files: the command's output set undoes the first committed if the second fails */
    wvol_status st = output_set_add(raw_path, err);
    if (st == WVOL_OK) st = output_set_add(json_path, err);
    if (st == WVOL_OK) st = wvol_atomic_open(&rf, raw_path, err);
    if (st != WVOL_OK) {
        free(json_path);
        return st;
    }
    if (host_is_big_endian()) swap4(c->data, n);
    size_t wrote = fwrite(c->data, sizeof(float), n, rf.fp);
    if (host_is_big_endian()) swap4(c->data, n);
    if (wrote != n) {
        st = wvol_atomic_fail(&rf, err);
        free(json_path);
        return st;
    }
    st = wvol_atomic_open(&jf, json_path, err);
    if (st != WVOL_OK) {
        wvol_atomic_abort(&rf);
        free(json_path);
        return st;
    }
    fprintf(jf.fp,
            "{\n  \"format\": \"wvol-coeffs\",\n  \"version\": 1,\n  \"wavelet\": \"%s\",\n  \"family\": \"%s\",\n"
            "  \"levels\": %d,\n  \"dims\": [%zu, %zu, %zu],\n  \"padded\": [%zu, %zu, %zu],\n"
            "  \"spacing\": [%.17g, %.17g, %.17g],\n  \"origin\": [%.17g, %.17g, %.17g],\n"
            "  \"pad\": \"%s\",\n  \"precision\": \"%s\",\n  \"sample_type\": \"float32\",\n"
            "  \"byte_order\": \"little\",\n  \"layout\": \"mallat\"\n}\n",
            c->filter->name, wvol_family_name(c->filter->family), c->levels, c->nx, c->ny, c->nz, c->px, c->py, c->pz,
            c->spacing[0], c->spacing[1], c->spacing[2], c->origin[0], c->origin[1], c->origin[2], pad,
            precision);
    st = wvol_atomic_commit(&jf, err);
    if (st != WVOL_OK) {
        wvol_atomic_abort(&rf);
        free(json_path);
        return st;
    }
    free(json_path);
    return wvol_atomic_commit(&rf, err);
}

/* ---- a minimal reader for the flat sidecar object (keys we wrote; others ignored) ---- */

static const char *find_key(const char *json, const char *key)
{
    size_t k = strlen(key);
    for (const char *p = strchr(json, '"'); p; p = strchr(p + 1, '"')) {
        if (!strncmp(p + 1, key, k) && p[1 + k] == '"') {
            p += k + 2;
            while (isspace((unsigned char)*p)) p++;
            if (*p != ':') continue;
            p++;
            while (isspace((unsigned char)*p)) p++;
            return p;
        }
    }
    return NULL;
}

static int get_string(const char *json, const char *key, char *out, size_t cap)
{
    const char *p = find_key(json, key), *q;
    if (!p || *p != '"') return 0;
    q = strchr(p + 1, '"');
    if (!q || (size_t)(q - p - 1) >= cap) return 0;
    memcpy(out, p + 1, (size_t)(q - p - 1));
    out[q - p - 1] = '\0';
    return 1;
}

static int get_numbers(const char *json, const char *key, double *out, int count)
{
    const char *p = find_key(json, key);
    char *end;
    if (!p) return 0;
    if (count > 1) {
        if (*p != '[') return 0;
        p++;
    }
    for (int i = 0; i < count; i++) {
        while (isspace((unsigned char)*p) || (i > 0 && *p == ',')) p++;
        errno = 0;
        out[i] = strtod(p, &end);
        if (end == p || errno) return 0;
        p = end;
    }
    return 1;
}

static int get_size3(const char *json, const char *key, size_t out[3])
{
    double d[3];
    if (!get_numbers(json, key, d, 3)) return 0;
    for (int a = 0; a < 3; a++) {
        if (!(d[a] >= 1 && d[a] <= 1e15) || d[a] != (double)(size_t)d[a]) return 0;
        out[a] = (size_t)d[a];
    }
    return 1;
}

/* path opened for reading when it is a regular file (links followed), so that fopen is never
 * asked to open a FIFO (which would wait for a writer) or a device; else NULL and *why says
 * what is wrong, in the readers' words ("not a regular file", or the system's reason). */
static FILE *open_regular(const char *path, const char **why)
{
    struct stat st;
    FILE *fp;
    if (stat(path, &st) != 0) {
        *why = strerror(errno);
        return NULL;
    }
    if (!S_ISREG(st.st_mode)) {
        *why = "not a regular file";
        return NULL;
    }
    if (!(fp = fopen(path, "rb"))) *why = strerror(errno);
    return fp;
}

wvol_status coeffs_file_read(wvol_coeffs **out, const char *raw_path, wvol_error *err)
{
    char *json_path = coeffs_sidecar_path(raw_path), *json = NULL, name[32], fmt[32];
    const char *why = "";
    FILE *fp = NULL;
    long len;
    double levels_d, spacing[3], origin[3];
    size_t dims[3], padded[3], n;
    const wvol_filter *f;
    wvol_coeffs *c = NULL;
    wvol_status st = WVOL_OK;
    *out = NULL;
    if (!json_path) return wvol_error_set(err, WVOL_ERR_NOMEM, "out of memory");
    if (!(fp = open_regular(json_path, &why))) {
        st = wvol_error_set(err, WVOL_ERR_IO, "%s: cannot open the sidecar of %s: %s", json_path, raw_path, why);
        goto done;
    }
    if (fseek(fp, 0, SEEK_END) != 0 || (len = ftell(fp)) < 0 || len > (1 << 20) || fseek(fp, 0, SEEK_SET)) {
        st = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: not a coefficient sidecar (size)", json_path);
        goto done;
    }
    json = malloc((size_t)len + 1);
    if (!json || fread(json, 1, (size_t)len, fp) != (size_t)len) {
        st = wvol_error_set(err, WVOL_ERR_IO, "%s: read failed", json_path);
        goto done;
    }
    json[len] = '\0';
    fclose(fp);
    fp = NULL;
    if (!get_string(json, "format", fmt, sizeof fmt) || strcmp(fmt, "wvol-coeffs") != 0) {
        st = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: \"format\" is not \"wvol-coeffs\"", json_path);
        goto done;
    }
    if (!get_string(json, "wavelet", name, sizeof name) || !get_numbers(json, "levels", &levels_d, 1) ||
        !get_size3(json, "dims", dims) || !get_size3(json, "padded", padded) ||
        levels_d != (double)(int)levels_d) {
        st = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: missing or malformed wavelet/levels/dims/padded",
                            json_path);
        goto done;
    }
    if (wvol_filter_get(&f, name, NULL) != WVOL_OK) {
        st = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: unknown wavelet '%s'", json_path, name);
        goto done;
    }
    if ((st = wvol_coeffs_create(&c, f, (int)levels_d, dims[0], dims[1], dims[2], err)) != WVOL_OK) {
        wvol_error_prefix(err, "%s: ", json_path);
        goto done;
    }
    if (c->px != padded[0] || c->py != padded[1] || c->pz != padded[2]) {
        st = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: padded size %zu x %zu x %zu does not follow from dims and levels (%zu x %zu x %zu)",
                            json_path, padded[0], padded[1], padded[2], c->px, c->py, c->pz);
        goto done;
    }
    if (get_numbers(json, "spacing", spacing, 3) && get_numbers(json, "origin", origin, 3)) {
        memcpy(c->spacing, spacing, sizeof spacing);
        memcpy(c->origin, origin, sizeof origin);
    }
    n = c->px * c->py * c->pz;
    if (!(fp = open_regular(raw_path, &why))) {
        st = wvol_error_set(err, WVOL_ERR_IO, "%s: cannot open: %s", raw_path, why);
        goto done;
    }
    if (fseek(fp, 0, SEEK_END) != 0 || (len = ftell(fp)) < 0 || (size_t)len != n * sizeof(float)) {
        st = wvol_error_set(err, WVOL_ERR_FORMAT, "%s: %ld bytes, the sidecar says %zu float32 values (%zu bytes)",
                            raw_path, len, n, n * sizeof(float));
        goto done;
    }
    fseek(fp, 0, SEEK_SET);
    if (fread(c->data, sizeof(float), n, fp) != n) {
        st = wvol_error_set(err, WVOL_ERR_IO, "%s: read failed", raw_path);
        goto done;
    }
    if (host_is_big_endian()) swap4(c->data, n);
    if ((st = wvol_check_finite(c->data, c->px, c->py, c->pz, raw_path, err)) != WVOL_OK) goto done;
    *out = c;
    c = NULL;
done:
    if (fp) fclose(fp);
    free(json);
    free(json_path);
    wvol_coeffs_destroy(c);
    return st;
}
