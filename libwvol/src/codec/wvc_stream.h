/* SPDX-License-Identifier: MIT
 * Declared internal interface of the codec for a streamed encoder (not installed): the
 * statistics of a first pass over the coefficient rows (the magnitude histograms the
 * in-memory encoder takes of the whole pyramid, wvc_hist.c) and the quantiser step they
 * give. pipeline/compress_stream.c feeds it the rows of a streamed transform, then the
 * same rows again to the v2 slab writer (wvc2_writer.h) with that step. */
#ifndef WVOL_CODEC_WVC_STREAM_H
#define WVOL_CODEC_WVC_STREAM_H

#include <stddef.h>

#include "codec/wvc2_writer.h"
#include "wvol/status.h"
#include "wvol/wvc.h"

typedef struct wvc_stream_stats wvc_stream_stats;

/* For the pyramid of a px x py x pz padded grid with `levels` levels. */
wvol_status wvol__wvc_stream_stats_create(wvc_stream_stats **out, size_t px, size_t py, size_t pz, int levels,
                                          wvol_error *err);
/* Counts the rows y0 .. y1 - 1 of the two planes of one row of `level` as the streamed
 * transform makes them (its x fastest, cx x cy planes), every band of the level they hold:
 * planes as the writer's put() takes them for that row (band 0 only at level == levels),
 * pointing at the bands' first rows. Rows may come in any order, each once, and from
 * several threads at once (each counts into histograms of its own, for as many threads as
 * OpenMP allowed at create, up to 16; a further thread takes turns in the first's). */
void wvol__wvc_stream_stats_add_rows(wvc_stream_stats *s, int level, size_t y0, size_t y1,
                                     const wvc2_planes *planes);
/* The step for params p, as wvol_wvc_encode chooses it before its exact passes: p->step
 * when given (checked against the coefficients' range), else the largest step whose
 * error the histograms predict within target_scale x p->target_sse (the encoder's first
 * guess is 0.9925). Refuses NaN/Inf coefficients and a step whose dequantised values
 * would overflow float32, with the encoder's messages. *maxabs (may be NULL): max |c|. */
wvol_status wvol__wvc_stream_step(wvc_stream_stats *s, const wvol_wvc_params *p, double target_scale,
                                  double *step, double *maxabs, wvol_error *err);
/* The step for an error target refined by exact passes over the whole pyramid, as the
 * in-memory encoder refines it (wvol__wvc_refine_step), for a caller that holds every
 * coefficient (the streamed path's kept pyramid): planes[m] (1 <= m <= levels) level m's
 * rows as the writer's put() takes them, its bands' first rows with their z rows sz apart,
 * nz[m] of them. The file's error then lies within [0.985, 1] x p->target_sse where the
 * histograms' guess alone can miss by more (a piecewise-constant volume's few distinct
 * magnitudes). *step: the refined step (unchanged with a given step, an all-zero pyramid, or
 * a refined step past the float32 bounds wvol__wvc_stream_step checks); *passes: the exact
 * passes made. */
wvol_status wvol__wvc_stream_refine(wvc_stream_stats *s, const wvc2_planes *planes, const size_t *nz,
                                    const wvol_wvc_params *p, double *step, int *passes, wvol_error *err);
/* max |c| of level `level` (its detail bands; with the low-pass cube at the coarsest level),
 * as counted (NaN or Inf: a value above FLT_MAX); 0 for a level outside 1..levels. */
double wvol__wvc_stream_level_maxabs(wvc_stream_stats *s, int level);
/* The error the histograms predict for a step (sum over the pyramid). */
double wvol__wvc_stream_predict(wvc_stream_stats *s, double step, double rounding);
void wvol__wvc_stream_stats_free(wvc_stream_stats *s); /* NULL is fine */

#endif
