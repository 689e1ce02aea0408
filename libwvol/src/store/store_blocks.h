/* SPDX-License-Identifier: MIT
 * The store's internal interface for a block-sparse view of its kept coefficients
 * (blocks.c): what a brick reconstruction (wvol__idwt3_brick_src) reads instead of a dense
 * pyramid, so that a brick costs what its coefficients cost, never the whole volume. Used by
 * the bricked renderer (render/bricks.c) and marching cubes from a store (iso/bricks.c).
 * Not installed. */
#ifndef WVOL_STORE_BLOCKS_H
#define WVOL_STORE_BLOCKS_H

#include <stddef.h>

#include "wavelet/wavelet_bricks.h"
#include "wvol/store.h"

typedef struct wvol__store_blocks wvol__store_blocks;

/* Builds the view of s's kept coefficients (on `threads`, 0: OpenMP's default; the view is the
 * same whatever the count). When bounds is not NULL, *bounds receives the
 * rigorous bounds of the reconstruction's boxes (wavelet/bounds.c), fed by the same pass
 * over the store and finished; it is NULL when the bound does not apply (an untransformed
 * axis, no levels: every brick must then be reconstructed). Free it with
 * wvol__bounds_free; it reads the store's low-pass cube, so the store must outlive it. */
wvol_status wvol__store_blocks_create(wvol__store_blocks **out, wvol__brick_bounds **bounds, const wvol_store *s,
                                      int threads, wvol_error *err);

/* Tests: below n nodes in a level (n blocks for the bounds' tables) the view is made on one
 * thread (the default suits real volumes; 0 sends every view through the threaded path).
 * Returns the setting it replaces. Not thread-safe: set it before any view is made. */
size_t wvol__store_blocks_parallel_min(size_t n);

/* The same, for a reader that will need most chunks anyway (marching cubes): a store opened
 * on a file gets its bounds from the decoded coefficients instead of the index's per-chunk
 * maxima, decoding every non-empty chunk (threads over chunks; 0 = OpenMP's default) into
 * the file's cache, when their decoded size fits in half the file's memory budget; *exact
 * says whether it did (else the index's bounds, as wvol__store_blocks_create). A chunk that
 * does not decode is an error naming it. */
wvol_status wvol__store_blocks_create_exact(wvol__store_blocks **out, wvol__brick_bounds **bounds,
                                            const wvol_store *s, int threads, int *exact, wvol_error *err);

/* A coefficient source reading through the view (the view and the store must outlive it):
 * the low-pass cube densely, a detail band through its blocks; a band with no kept position
 * in the region reads as absent, so the synthesis skips it. Safe to use from several
 * threads at once. */
void wvol__store_blocks_source(wvol__coef_source *src, const wvol__store_blocks *b);

/* Bytes the view allocated: its directories, blocks and values. */
size_t wvol__store_blocks_bytes(const wvol__store_blocks *b);

/* Tables a reader derives from the view and its bounds alone, kept with the view (a built
 * store's view lives as long as the store, so its first extraction makes the table and the
 * others read it): marching cubes' per-brick bounds, keyed by the brick size. _table: the
 * table kept under key, or NULL. _keep_table: offers *table (malloc'ed); returns 1 when the
 * view keeps it or already kept one under key (*table then points to the kept one, the
 * offered one freed: the same values), 0 when it cannot keep it (the caller still owns
 * *table). Safe from several threads at once; a kept table lives as long as the view. */
const double *wvol__store_blocks_table(wvol__store_blocks *b, int key);
int wvol__store_blocks_keep_table(wvol__store_blocks *b, int key, double **table);

/* For a store opened on a .wvc file: whether its memory budget leaves `bytes` more beside the
 * decoded chunks its cache holds now (a reader's dense copy of the whole pyramid, say). 0 for
 * a store in memory, which has no budget of its own. */
int wvol__store_file_room(const wvol_store *s, size_t bytes);

void wvol__store_blocks_destroy(wvol__store_blocks *b); /* NULL is fine */

#endif
