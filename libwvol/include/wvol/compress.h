/* SPDX-License-Identifier: MIT */
/* One compression pipeline (DESIGN.md sections 4-6): volume -> forward transform ->
 * selection (fraction, count, energy, PSNR target, region-of-interest weights, dropped
 * levels) -> store, and for a .wvc file the quantiser's error-target rule and the coder.
 * Every command and the Python package build their stores and files through these calls,
 * so that defaults (family, levels, spline knots, quantiser share) are defined once, here
 * and in wvol_compress_params_default. docs/store.md describes the choices.
 *
 * Threading: the calls use OpenMP threads inside; a wvol_compressed is not shared between
 * threads while it is being filled or freed. */
#ifndef WVOL_COMPRESS_H
#define WVOL_COMPRESS_H

#include "wvol/export.h"
#include <stddef.h>
#include "wvol/status.h"
#include "wvol/source.h"
#include "wvol/store.h"
#include "wvol/volume.h"
#include "wvol/wavelet.h"
#include "wvol/wvc.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Levels when params.levels is 0, capped at what the volume allows (wvol_dwt_max_levels).
 * A store to render or mesh keeps 3: the bricked paths reconstruct a brick from a reach that
 * grows with the levels. A file keeps 5: each level shrinks the dense low-pass cube, the part
 * the coder does worst, by 8. */
#define WVOL_COMPRESS_LEVELS_STORE 3
#define WVOL_COMPRESS_LEVELS_FILE 5

/* How a .wvc file's quantiser step is chosen (wvol_compress_encode). */
typedef struct wvol_compress_quant {
    double psnr;          /* > 0: PSNR target of the whole file in dB (peak = data range): the
                             step makes selection error + quantisation error meet it. 0 (default):
                             the share rule below */
    double share;         /* quantisation error = share x the energy the selection dropped, never
                             below what 120 dB PSNR allows (default 0.02: RMSE +1%); in (0, 1] */
    double step;          /* > 0: this step, neither rule (default 0) */
    double rounding;      /* dead-zone rounding offset in [0, 0.5]; < 0 (default): the codec's */
    wvol_wvc_coder coder; /* default AUTO */
    int format_version;   /* .wvc format: 0 (default) = WVOL_WVC_FORMAT_VERSION (2), or 1 */
    int tile, tile_z;     /* version 2: chunk edge along x and y, depth along z, in coefficients
                             (0: the codec's defaults, 64 and 32) */
} wvol_compress_quant;

typedef struct wvol_compress_params {
    const char *wavelet;        /* family name for wvol_filter_get (default "db2"), or "auto"
                                   (WVOL_COMPRESS_WAVELET_AUTO): wvol_compress_choose_wavelet
                                   picks it from a trial on a sample of the volume */
    int levels;                 /* 0 (default): WVOL_COMPRESS_LEVELS_STORE, or _FILE when for_file */
    int for_file;               /* 1: the result will be coded into a .wvc (only the default levels
                                   depend on it); default 0 */
    wvol_select_params select;  /* what to keep (default: everything) */
    int build_store;            /* 1 (default): fill result->store */
    int build_residual;         /* 1: also fill result->residual, the store of the dropped
                                   coefficients (per-pixel error bounds); default 0 */
    wvol_store_params store;    /* the store's spline tables */
    wvol_compress_quant quant;  /* wvol_compress_encode only */
    size_t memory;              /* wvol_compress_stream only: bytes it may use to keep the
                                   transformed volume (4 bytes a padded voxel) between its
                                   passes instead of transforming the source twice; 0 (default):
                                   WVOL_WVC_DEFAULT_BUDGET (1 GiB) */
} wvol_compress_params;

/* Fills the defaults; NULL: does nothing. */
WVOL_API void wvol_compress_params_default(wvol_compress_params *p);

/* What wvol_compress made; free with wvol_compressed_free. */
typedef struct wvol_compressed {
    wvol_coeffs *coeffs;        /* the coefficients with the dropped ones zeroed */
    wvol_selection *selection;  /* the kept set */
    wvol_store *store;          /* the store of the kept set (NULL unless build_store); when the
                                   selection keeps everything, of the nonzero coefficients only */
    wvol_store *residual;       /* what the selection dropped, as a majorant store (|c| on the
                                   majorants of |B|, wvol_store_params.majorant; NULL unless
                                   build_residual): wvol_render_bound's input */
    wvol_select_report report;  /* predicted (and with select.measure, measured) error */
    int levels;                 /* levels used */
    double value_min, value_max;/* range of the volume's samples */
    double seconds_transform, seconds_select, seconds_store;
} wvol_compressed;

/* The levels wvol_compress would use for v with p (the default resolved, capped at what the
 * volume allows); 0 when v cannot be transformed. For messages that name a caller's options. */
WVOL_API int wvol_compress_levels(const wvol_volume *v, const wvol_compress_params *p);

/* Transform, select, (store). On failure nothing is left allocated in *out. Refuses bad
 * parameters with WVOL_ERR_ARG naming them (unknown family, levels beyond what the volume
 * allows, drop_levels >= levels, and what wvol_select refuses). */
WVOL_API wvol_status wvol_compress(wvol_compressed *out, const wvol_volume *v, const wvol_compress_params *p,
                          wvol_error *err);

/* The pipeline from coefficients (a decoded .wvc): selection and store, no transform. Takes
 * ownership of *c (set to NULL, freed on failure too). Without an original volume the PSNR
 * peak comes from a full reconstruction and value_min/max stay 0. */
WVOL_API wvol_status wvol_compress_coeffs(wvol_compressed *out, wvol_coeffs **c, const wvol_compress_params *p,
                                 wvol_error *err);

WVOL_API void wvol_compressed_free(wvol_compressed *c); /* NULL is fine; leaves *c zeroed */

/* The wvc parameters of the pipeline's quantiser rule for coefficients whose selection
 * dropped `dropped` energy, over `voxels` samples of range [vmin, vmax]: the PSNR target (the
 * step meets budget - dropped; refused with WVOL_ERR_ARG when the volume is constant, or
 * when dropping alone already loses more than the target allows) or the share rule, or the
 * given step. Fills *wp completely (wvol_wvc_params_default first). */
WVOL_API wvol_status wvol_compress_wvc_params(wvol_wvc_params *wp, const wvol_compress_quant *q, double dropped,
                                     double voxels, double vmin, double vmax, wvol_error *err);

/* Quantises and codes c->coeffs into a heap buffer (free with free()) with the rule above. */
WVOL_API wvol_status wvol_compress_encode(void **buf, size_t *size, const wvol_compressed *c, const wvol_compress_params *p,
                                 wvol_wvc_report *report, wvol_error *err);

/* ---- the automatic filter choice (wavelet "auto") ----------------------------------
 * A trial on a sample of the volume (the whole volume when it is no larger than two 64^3
 * cubes, else 2 to 8 64^3 cubes spread through it, read slice by slice in increasing z)
 * transforms it with each candidate (db2, db4, coif2, haar), finds the quantiser step that
 * meets the target on the sample (quant.step if given, else quant.psnr, else a PSNR
 * selection's target, else 50 dB; PSNR over the sample's range) and estimates the bits (zeroth-order entropy of the quantised
 * magnitudes per band, plus signs). db2, the project's default, is kept unless another
 * candidate's estimate is smaller by more than WVOL_WAVELET_CHOICE_MARGIN: a wider filter
 * makes rendering, marching cubes and the tracers slower (docs/wvc-format.md, "Choosing the
 * filter"). Deterministic: the same volume and parameters give the same choice, whether the
 * source streams or holds a volume in memory. wvol_compress and wvol_compress_stream run it
 * when params.wavelet is "auto". */
#define WVOL_COMPRESS_WAVELET_AUTO "auto"
#define WVOL_WAVELET_CHOICE_CANDIDATES 4
#define WVOL_WAVELET_CHOICE_MARGIN 0.10
typedef struct wvol_wavelet_choice {
    const char *wavelet;      /* the filter chosen (a static name for wvol_filter_get) */
    int candidates;
    const char *name[WVOL_WAVELET_CHOICE_CANDIDATES]; /* db2 first */
    double bits[WVOL_WAVELET_CHOICE_CANDIDATES];      /* estimated bits per sampled coefficient */
    double step[WVOL_WAVELET_CHOICE_CANDIDATES];      /* the step each met the target with */
    double psnr;              /* the target the trial used (0 with a given step) */
    double margin;            /* WVOL_WAVELET_CHOICE_MARGIN */
    int blocks;               /* cubes read (1: the whole volume) */
    size_t sample_voxels, sample_coefficients;
    double seconds;           /* wall time of the trial, reading included */
} wvol_wavelet_choice;
/* 1 if name asks for the automatic choice ("auto"). */
WVOL_API int wvol_compress_wavelet_is_auto(const char *name);
/* Runs the trial on src (slices read forward; a streamed source is left wherever the last
 * sampled slice was) with p's levels, for_file and quant (NULL: the defaults). A constant
 * sample gives db2 with zero estimates. */
WVOL_API wvol_status wvol_compress_choose_wavelet(wvol_wavelet_choice *out, wvol_source *src,
                                                  const wvol_compress_params *p, wvol_error *err);

/* ---- streamed compression: volumes larger than memory ------------------------------
 * A volume source (wvol/source.h: raw, NRRD, a generator) into a .wvc version-2 file with
 * memory for the transform's window (about 2 L + 8 slices per level, L taps) and the
 * writer's rows, whatever the number of slices. Two passes over the source (no spill):
 * the streamed transform into the quantiser's magnitude histograms, which give the step
 * (the in-memory encoder's first guess, from the same histograms), then the transform
 * again into the chunk writer, which reports the exact quantisation error. Should that
 * miss the error target, another pass writes with a smaller step (so a target is met, as
 * in memory). When the padded volume's coefficients fit p->memory, the first pass keeps
 * them and the later passes write from that copy (one read and transform of the source;
 * the same bytes). With a given step (quant.step) the file holds the same bytes as
 * wvol_compress + wvol_compress_encode of the same volume; with an error target the
 * in-memory encoder may refine the step and spend the unused budget with exact passes
 * over the whole pyramid, so the files can differ while both meet the target
 * (docs/store.md). Only what needs no ranking streams: select.mode ALL, no dropped
 * levels, no regions of interest, format version 2 (wvol_compress_streams). */
typedef struct wvol_compress_stream_report {
    int levels;
    double value_min, value_max; /* of the source's samples */
    double step;                 /* the step written */
    double target_sse;           /* the quantiser's error target (0 with a given step) */
    double sse_quant;            /* exact sum (c - c_hat)^2 over the padded grid (Parseval: the
                                    volume's squared error, the padding's included, so an upper
                                    bound of the error over the original voxels) */
    size_t bytes;                /* the file */
    int passes;                  /* passes over the coefficients: 2 (statistics, writing), more
                                    when the error missed */
    int source_reads;            /* reads and transforms of the source: 1 when its coefficients
                                    were kept (they are quantised in place by the first write,
                                    so a further pass reads the source again: passes - 1), else
                                    passes */
    size_t kept_bytes;           /* the coefficients kept between the passes (0: none) */
    size_t window_bytes;         /* the transform's window and slab buffer */
    size_t writer_bytes;         /* the writer's bound for its rows (wvc2_writer_memory) */
    double seconds_stats, seconds_write;
    wvol_wvc_report wvc;         /* the writer's report of the last pass */
} wvol_compress_stream_report;
/* 1 if p can be compressed streamed (see above); NULL: the defaults, 1. */
WVOL_API int wvol_compress_streams(const wvol_compress_params *p);
/* Compresses src into the .wvc file at path (atomic: no file on failure). p: levels (0:
 * WVOL_COMPRESS_LEVELS_FILE capped by the size), wavelet, quant (psnr / share / step,
 * rounding, coder, tile); NULL: the defaults. rep may be NULL. Refuses with
 * WVOL_ERR_UNSUPPORTED what wvol_compress_streams refuses. */
WVOL_API wvol_status wvol_compress_stream(const char *path, wvol_source *src, const wvol_compress_params *p,
                                          wvol_compress_stream_report *rep, wvol_error *err);
#ifdef __cplusplus
}
#endif
#endif
