/* SPDX-License-Identifier: MIT */
/* wvol info FILE.wvc: header, sizes, ratio, predicted error, per-level counts and energies. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "cli.h"
#include "info_wvc.h"
#include "wvol/wvc.h"

/* A section's coder: version 1 codes each section with one coder; in version 2 a band is
 * spread over chunks, each coded in its own mode (the chunk_modes table). */
static const char *coder_name(const wvol_wvc_info *I, int c)
{
    if (c == WVOL_WVC_CODER_EMPTY) return "empty";
    if (I->version >= 2) return "chunks";
    return c == WVOL_WVC_CODER_CABAC ? "cabac" : c == WVOL_WVC_CODER_ZSTD ? "zstd" : "empty";
}

/* A version-2 file's chunks per level and mode (counts[m][k]); 0, or 1 with the error set. */
static int chunk_modes(const char *path, uint64_t counts[][WVOL_WVC_CHUNK_MODES], wvol_error *err)
{
    wvol_wvc_file *f = NULL;
    wvol_status st = wvol_wvc_open(&f, path, 0, err);
    if (st == WVOL_OK) st = wvol_wvc_file_chunk_modes(f, counts, err);
    wvol_wvc_close(f);
    return st != WVOL_OK;
}

/* What the sections of one level hold together. */
typedef struct level_totals {
    uint64_t count, nonzero, bytes;
    double energy, error;
} level_totals;

/* Row k of the level table: k = 0 the low-pass band, then the detail levels from the
 * coarsest (*m = levels) to the finest (*m = 1); *m = 0 for the low-pass row. */
static level_totals level_sum(const wvol_wvc_info *I, int k, int *m)
{
    level_totals t = {0, 0, 0, 0, 0};
    *m = k == 0 ? 0 : I->levels + 1 - k;
    for (int s = 0; s < I->nsections; s++) {
        const wvol_wvc_section *S = &I->sections[s];
        if ((*m == 0 && S->band == 0) || (*m > 0 && S->band != 0 && S->level == *m)) {
            t.count += S->count, t.nonzero += S->nonzero, t.bytes += S->bytes;
            t.energy += S->energy, t.error += S->error;
        }
    }
    return t;
}

int wvol_cli_info_wvc(const char *path, int json)
{
    wvol_error err;
    wvol_wvc_info *I = malloc(sizeof *I);
    double nvox, raw, ratio, bpv, sse, rmse, psnr;
    uint64_t count = 0, modes[WVOL_WVC_MAX_LEVELS + 1][WVOL_WVC_CHUNK_MODES];
    int s, m;
    if (!I) return cli_fail("info", "out of memory");
    wvol_error_clear(&err);
    if (wvol_wvc_read_info(I, path, &err) != WVOL_OK) {
        free(I);
        return cli_fail_err("info", &err);
    }
    if (I->version >= 2 && chunk_modes(path, modes, &err)) {
        free(I);
        return cli_fail_err("info", &err);
    }
    nvox = (double)I->nx * (double)I->ny * (double)I->nz;
    raw = nvox * 4.0;
    ratio = raw / (double)I->file_bytes;
    bpv = 8.0 * (double)I->file_bytes / nvox;
    sse = I->sse + I->dropped_energy;
    rmse = sqrt(sse / nvox);
    psnr = wvol_wvc_psnr(sse, nvox, I->value_min, I->value_max);
    for (s = 0; s < I->nsections; s++) count += I->sections[s].count;
    if (json) {
        cli_json_begin();
        cli_json_str("file", path);
        cli_json_str("format", "wvc");
        cli_json_int("version", I->version);
        cli_json_str("wavelet", I->filter);
        cli_json_int("levels", I->levels);
        cli_json_size3("dims", I->nx, I->ny, I->nz);
        cli_json_size3("padded", I->px, I->py, I->pz);
        cli_json_num3("spacing", I->spacing);
        cli_json_num3("origin", I->origin);
        cli_json_num("value_min", I->value_min);
        cli_json_num("value_max", I->value_max);
        cli_json_int("bytes", (long long)I->file_bytes);
        cli_json_int("header_bytes", (long long)I->header_bytes);
        if (I->version >= 2) {
            cli_json_int("chunks", (long long)I->chunks);
            cli_json_size3("tile", (size_t)I->tile, (size_t)I->tile, (size_t)I->tile_z);
        }
        cli_json_int("raw_bytes", (long long)raw);
        cli_json_num("ratio", ratio);
        cli_json_num("bits_per_voxel", bpv);
        cli_json_num("step", I->step);
        cli_json_num("rounding", I->rounding);
        cli_json_int("coefficients", (long long)count);
        cli_json_int("nonzero", (long long)I->nonzero);
        cli_json_num("energy", I->energy + I->dropped_energy);
        cli_json_num("dropped_energy", I->dropped_energy);
        cli_json_num("quantisation_sse", I->sse);
        cli_json_num("predicted_rmse", rmse);
        cli_json_num("predicted_psnr", psnr); /* null when infinite */
        cli_json_open("levels_detail", '[');
        for (int k = 0; k <= I->levels; k++) {
            level_totals t = level_sum(I, k, &m);
            cli_json_open(NULL, '{');
            cli_json_str("part", m == 0 ? "lowpass" : "detail");
            cli_json_int("level", m == 0 ? I->levels : m);
            cli_json_int("coefficients", (long long)t.count);
            cli_json_int("nonzero", (long long)t.nonzero);
            cli_json_int("bytes", (long long)t.bytes);
            cli_json_num("energy", t.energy);
            cli_json_num("error", t.error);
            cli_json_close('}');
        }
        cli_json_close(']');
        cli_json_open("sections", '[');
        for (s = 0; s < I->nsections; s++) {
            const wvol_wvc_section *S = &I->sections[s];
            cli_json_open(NULL, '{');
            cli_json_int("level", S->level);
            cli_json_int("band", S->band);
            cli_json_str("coder", coder_name(I, S->coder));
            cli_json_int("bytes", (long long)S->bytes);
            cli_json_int("coefficients", (long long)S->count);
            cli_json_int("nonzero", (long long)S->nonzero);
            cli_json_num("energy", S->energy);
            cli_json_num("error", S->error);
            cli_json_close('}');
        }
        cli_json_close(']');
        if (I->version >= 2) {
            cli_json_open("chunk_modes", '[');
            for (m = I->levels; m >= 1; m--) {
                cli_json_open(NULL, '{');
                cli_json_int("level", m);
                for (int k = 0; k < WVOL_WVC_CHUNK_MODES; k++) cli_json_int(wvol_wvc_chunk_mode_name(k), (long long)modes[m][k]);
                cli_json_close('}');
            }
            cli_json_close(']');
        }
        cli_json_end();
    } else {
        printf("file       %s (.wvc version %d)\n", path, I->version);
        printf("wavelet    %s, %d levels\n", I->filter, I->levels);
        printf("dims       %zu x %zu x %zu (padded %zu x %zu x %zu)\n", I->nx, I->ny, I->nz, I->px, I->py, I->pz);
        printf("spacing    %g %g %g\n", I->spacing[0], I->spacing[1], I->spacing[2]);
        printf("origin     %g %g %g\n", I->origin[0], I->origin[1], I->origin[2]);
        printf("range      %g .. %g\n", I->value_min, I->value_max);
        printf("size       %llu bytes (header %llu), ratio %.1f against float32, %.4f bits/voxel\n",
               (unsigned long long)I->file_bytes, (unsigned long long)I->header_bytes, ratio, bpv);
        if (I->version >= 2)
            printf("chunks     %llu of %d x %d x %d coefficients per level, index at byte %d (header %s)\n",
                   (unsigned long long)I->chunks, I->tile, I->tile, I->tile_z, 224 + 48 * I->nsections,
                   "+ band table + index");
        printf("quantiser  step %.6g, rounding %.3g, %llu of %llu coefficients non-zero\n", I->step, I->rounding,
               (unsigned long long)I->nonzero, (unsigned long long)count);
        printf("predicted  RMSE %.6g, PSNR %.3f dB (dropped energy %.6g + quantisation %.6g)\n", rmse, psnr,
               I->dropped_energy, I->sse);
        printf("%-9s %12s %12s %10s %14s %14s\n", "level", "coeffs", "non-zero", "bytes", "energy", "error");
        for (int k = 0; k <= I->levels; k++) {
            level_totals t = level_sum(I, k, &m);
            if (m == 0) printf("low-pass  ");
            else printf("%-9d ", m);
            printf("%12llu %12llu %10llu %14.6g %14.6g\n", (unsigned long long)t.count,
                   (unsigned long long)t.nonzero, (unsigned long long)t.bytes, t.energy, t.error);
        }
        if (I->version >= 2) {
            printf("chunk modes (0 bands apart, 1 cabac, 2 cabac with block flags, 3 rans, 4 rans with row contexts)\n");
            for (m = I->levels; m >= 1; m--) {
                const char *sep = "";
                printf("  level %d:", m);
                for (int k = 0; k < WVOL_WVC_CHUNK_MODES; k++)
                    if (modes[m][k]) {
                        if (k + 1 < WVOL_WVC_CHUNK_MODES) printf("%s %llu in mode %d", sep, (unsigned long long)modes[m][k], k);
                        else printf("%s %llu empty", sep, (unsigned long long)modes[m][k]);
                        sep = ",";
                    }
                printf("\n");
            }
        }
    }
    free(I);
    return CLI_OK;
}
