/* SPDX-License-Identifier: MIT
 * SPERR as a peer for bench/bench_sperr.py: file in, file out, one thread, so that its process
 * CPU seconds are measured the same way as `wvol compress` / `wvol decompress`'s (reading the
 * input and writing the output included).
 *
 *   sperr_driver c IN.raw NX NY NZ PSNR OUT.sperr   float32 little-endian in, fixed-PSNR mode
 *   sperr_driver d IN.sperr OUT.raw                 float32 out
 *
 * Built by the benchmark against a SPERR install named by $SPERR_DIR (not a Debian package);
 * the benchmark skips SPERR when it is absent. Chunks are SPERR's command-line default, 256^3. */
#include <stdio.h>
#include <stdlib.h>

#include "SPERR_C_API.h"

static void *read_all(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    void *buf = NULL;
    long len;
    if (!f) return NULL;
    if (fseek(f, 0, SEEK_END) == 0 && (len = ftell(f)) > 0 && fseek(f, 0, SEEK_SET) == 0) {
        buf = malloc((size_t)len);
        if (buf && fread(buf, 1, (size_t)len, f) != (size_t)len) {
            free(buf);
            buf = NULL;
        }
        *n = (size_t)len;
    }
    fclose(f);
    return buf;
}

static int write_all(const char *path, const void *buf, size_t n)
{
    FILE *f = fopen(path, "wb");
    int ok;
    if (!f) return 0;
    ok = fwrite(buf, 1, n, f) == n;
    return fclose(f) == 0 && ok;
}

int main(int argc, char **argv)
{
    size_t n = 0;
    void *in, *out = NULL;
    if (argc == 8 && argv[1][0] == 'c') {
        size_t nx = strtoul(argv[3], NULL, 10), ny = strtoul(argv[4], NULL, 10), nz = strtoul(argv[5], NULL, 10);
        size_t out_len = 0;
        in = read_all(argv[2], &n);
        if (!in || n != nx * ny * nz * sizeof(float)) {
            fprintf(stderr, "sperr_driver: %s: cannot read %zu float32 samples\n", argv[2], nx * ny * nz);
            return 1;
        }
        if (sperr_comp_3d(in, 1, nx, ny, nz, 256, 256, 256, 2, strtod(argv[6], NULL), 1, &out, &out_len) != 0) {
            fprintf(stderr, "sperr_driver: compression failed\n");
            return 1;
        }
        if (!write_all(argv[7], out, out_len)) {
            fprintf(stderr, "sperr_driver: cannot write %s\n", argv[7]);
            return 1;
        }
    } else if (argc == 4 && argv[1][0] == 'd') {
        size_t nx, ny, nz;
        in = read_all(argv[2], &n);
        if (!in || sperr_decomp_3d(in, n, 1, 1, &nx, &ny, &nz, &out) != 0) {
            fprintf(stderr, "sperr_driver: %s: cannot decompress\n", argv[2]);
            return 1;
        }
        if (!write_all(argv[3], out, nx * ny * nz * sizeof(float))) {
            fprintf(stderr, "sperr_driver: cannot write %s\n", argv[3]);
            return 1;
        }
    } else {
        fprintf(stderr, "usage: sperr_driver c IN.raw NX NY NZ PSNR OUT.sperr | d IN.sperr OUT.raw\n");
        return 2;
    }
    free(in);
    free(out);
    return 0;
}
