/* SPDX-License-Identifier: MIT
 * The codec module's declared internal interface for other modules (not installed): an
 * open .wvc file (wvol_wvc_open) as a coefficient source for local reconstructions
 * (wavelet/wavelet_bricks.h), decoding chunks on demand into the file's cache. The
 * store's file-backed view and the region reader use it. */
#ifndef WVOL_CODEC_WVC_SOURCE_H
#define WVOL_CODEC_WVC_SOURCE_H

#include "wavelet/wavelet_bricks.h"
#include "wvol/wvc.h"

/* A source over f's coefficients; with skip = s > 0 the pyramid seen is the one whose
 * finest level is s (levels - s levels, grid ceil(n / 2^s), padded p >> s): a brick
 * reconstruction then gives the level-s low-pass samples (unscaled: 2^{d s / 2} times
 * wvol_idwt3_level's values). Safe from several threads at once; f must outlive it.
 * A gather that cannot decode (a damaged chunk, the budget exceeded by pinned chunks)
 * fills zeros and leaves an error in the file's own slot, which wvol__wvc_file_error returns:
 * the slot of the stores opened on the file. The file's region, piece and offset reads keep
 * an error slot per call instead (wvc2_read.h), so that reads from several threads neither
 * take nor clear each other's. */
void wvol__wvc_file_source(wvol__coef_source *src, wvol_wvc_file *f, int skip);

/* The path the file was opened from. */
const char *wvol__wvc_file_path(const wvol_wvc_file *f);

/* The first error a store's gather met since the last call (WVOL_OK if none), copied to err,
 * and cleared. */
wvol_status wvol__wvc_file_error(wvol_wvc_file *f, wvol_error *err);

/* The low-pass cube of the coarsest level (dims px >> levels etc.), dequantised, into
 * dst; it also finds the band's offset (below). */
wvol_status wvol__wvc_file_lowpass(wvol_wvc_file *f, float *dst, wvol_error *err);

/* The coarsest low-pass band's offset (wavelet_bricks.h, "DC offset") into *dc (dc may be
 * NULL), found once (decoding that band, a chunk at a time) and kept: the sources made after
 * carry it as their dc, so that every reconstruction from the file takes it out and adds it
 * back as the whole inverse does. A source made before carries none (dc 0). Opening a file
 * decodes nothing; the first reconstruction calls this. */
wvol_status wvol__wvc_file_dc(wvol_wvc_file *f, float *dc, wvol_error *err);

/* max |c| over the chunks of level m that cover band positions [lo, hi] (inclusive,
 * taken periodically) of any band, from the index (no decoding); for bounds. Fills
 * the per-chunk maxima of level m into max[] (g.lv[m].count values, chunk order) when
 * max is not NULL and returns the tile sizes. */
void wvol__wvc_file_level_max(const wvol_wvc_file *f, int m, float *max, size_t nt[3], size_t tile[3]);

#endif
