/* SPDX-License-Identifier: MIT */
/* The wavelet module's declared internal interface for the other modules (not installed):
 * local reconstruction of a box from any source of coefficients, and rigorous bounds of the
 * reconstructed samples of a box. The store's block view, the bricked renderer and the
 * bricked marching cubes use it; the wavelet module's own private declarations stay in
 * wavelet_internal.h. */
#ifndef WVOL_WAVELET_BRICKS_H
#define WVOL_WAVELET_BRICKS_H

#include <stddef.h>
#include "wvol/wavelet.h"

/* Validates a coefficient pyramid (sizes consistent with its levels). */
wvol_status wvol__coeffs_check(const wvol_coeffs *c, wvol_error *err);

/* Extent of axis a at level m (0 = the padded grid): 1 stays 1. */
static inline size_t wvol__extent(size_t p, int m) { return p == 1 ? 1 : p >> m; }

/* Level `level`'s grid (wvol_idwt3_level's) out of a whole period of its samples: dst, e[0] x
 * e[1] x e[2], x fastest, gets src's sample i - wvol_level_shift(f, level) per axis, read
 * periodically over P (1 on an untransformed axis), times scale. src's rows are `row` floats
 * apart and its slices `slice`: a whole padded pyramid's corner, or a period by itself. */
void wvol__level_crop(float *dst, const size_t e[3], const float *src, const size_t P[3], size_t row, size_t slice,
                      const wvol_filter *f, int level, double scale);

/* ---- DC offset (dc_offset.c) ----------------------------------------------------------
 * Data far from 0 against its spread goes through the float32 transforms without its offset:
 * the forward transform subtracts wvol__slice_offset of the first z-slice (0 unless its
 * midrange is more than 64 times its spread) from every sample and adds offset x
 * wvol__dc_gain_f32 (the float32 kernels' gain on a constant) to the coarsest low-pass band;
 * the inverse subtracts wvol__lowpass_offset (the same rule on that band) from it and adds
 * offset / gain to every sample. Both the in-memory and the streamed transform do it, the
 * same way. */
float wvol__slice_offset(const float *slice, size_t n);
double wvol__dc_gain_f32(const wvol_filter *f, int levels, const size_t pad[3]);
/* a added (in double, then rounded) to the coarsest low-pass block of a padded p[0] x p[1] x
 * p[2] Mallat pyramid of `levels` levels */
void wvol__lowpass_add(float *data, const size_t p[3], int levels, double a);
float wvol__lowpass_offset(const float *data, const size_t p[3], int levels);
/* wvol__lowpass_offset's rule on a band whose values span [lo, hi], found piece by piece */
float wvol__band_range_offset(double lo, double hi);
/* What float32 adds, as a squared error over `voxels` samples, to a reconstruction of data of
 * magnitude up to `mag` from a pyramid of that gain: the samples rounded at their magnitude
 * (variance spacing^2 / 12 each) and the coarsest low-pass coefficients at theirs (up to half a
 * spacing each). The compression's PSNR targets and the selection's predicted error count it
 * for data on a large offset. */
double wvol__f32_floor_sse(double mag, double voxels, const wvol_filter *f, int levels, const size_t pad[3]);

/* ---- local reconstruction (partial.c) ---------------------------------------------- */

/* Where a brick reconstruction reads coefficients: gather() fills dst with band `band`
 * of level m (band 0 of level `levels` is the low-pass cube; level 0 band 0: the
 * samples themselves, for levels == 0) on the region lo .. lo + n - 1 per axis, indices
 * taken modulo the band's extent, x fastest; it returns 0 when every value there is
 * zero (dst need not be written then), which lets the synthesis skip that band. */
typedef struct wvol__coef_source {
    int (*gather)(const void *ctx, float *dst, int m, int band, const ptrdiff_t lo[3], const ptrdiff_t n[3]);
    const void *ctx;
    const wvol_filter *filter;
    int levels;
    size_t dims[3], pad[3];
    /* the coarsest low-pass band's offset ("DC offset" above; 0: none): a reconstruction takes
     * it out of the gathered band and adds it over the gain to its samples, as the whole
     * inverse does. Set by the makers of sources over bands they hold; 0 keeps the plain
     * synthesis. */
    float dc;
} wvol__coef_source;

void wvol__coef_source_of_coeffs(wvol__coef_source *src, const wvol_coeffs *c);

/* The pyramid of src above level `skip` (0 <= skip <= src->levels) as a source of its own:
 * levels - skip levels on the grid pad >> skip, whose samples are src's level-skip low-pass
 * coefficients (the scaling coefficients, not scaled to sample values). ctx holds the
 * mapping and must outlive dst; src's context must too. */
typedef struct wvol__coef_skip {
    wvol__coef_source inner;
    int skip;
} wvol__coef_skip;
void wvol__coef_source_skip(wvol__coef_source *dst, wvol__coef_skip *ctx, const wvol__coef_source *src, int skip);

/* Reusable scratch of one reconstruction (one per thread). Start zeroed. */
#define WVOL__BRICK_SCRATCH 16
typedef struct wvol__brick_scratch {
    float *buf[WVOL__BRICK_SCRATCH];
    size_t cap[WVOL__BRICK_SCRATCH];
} wvol__brick_scratch;

void wvol__brick_scratch_free(wvol__brick_scratch *s);
size_t wvol__brick_scratch_bytes(const wvol__brick_scratch *s);

/* The finest-level samples of the box [lo, hi) (lo < hi <= dims, unchecked) into out,
 * (hi - lo) sized, x fastest, synthesising only the coefficients whose support reaches
 * the box (wvol_idwt3_brick is this on a dense wvol_coeffs). */
wvol_status wvol__idwt3_brick_src(float *out, const wvol__coef_source *src, const size_t lo[3], const size_t hi[3],
                                  wvol__brick_scratch *scr, wvol_error *err);
/* The coefficient positions wvol__idwt3_brick_src gathers and synthesises for the box [lo, hi)
 * (every band of every level, whether it holds a non-zero or not): a measure of its work against
 * the whole inverse transform's, which takes each of the pyramid's positions once. */
size_t wvol__idwt3_brick_positions(const wvol__coef_source *src, const size_t lo[3], const size_t hi[3]);

/* ---- whole-slice inverse (dwt3.c) --------------------------------------------------- */

/* One level of the periodic inverse along y, then x, on the cx x cy corner (even sizes, or
 * 1) of one z-slice of row length NX, in place, with the in-place transform's kernels (h, g:
 * the filter's taps as float, L of them); scratch: wvol__idwt_slice_xy_scratch(cx, cy, L)
 * floats. For readers that synthesise z themselves (a slab of a file). */
size_t wvol__idwt_slice_xy_scratch(size_t cx, size_t cy, int L);
void wvol__idwt_slice_xy_f32(float *slice, size_t cx, size_t cy, size_t NX, const float *h, const float *g, int L,
                             float *scratch);

/* ---- brick bounds (bounds.c) --------------------------------------------------------- */

/* Rigorous [vmin, vmax] of the reconstructed samples of a box, from per-(level, band)
 * block maxima of the detail coefficients and a low-pass cube. Every axis must be
 * transformed (pad >= 2). Create from the coefficients' source: the bound works on the
 * pyramid of its finest WVOL__BOUNDS_LEVELS levels (fewer if the source has fewer; more while
 * that pyramid's low-pass cube would exceed WVOL__BOUNDS_LOW_BYTES), whose low-pass cube (the
 * coarser levels' exact synthesis, so their few large coefficients count at their real size
 * rather than each at its band's maximum times the filter's Lebesgue constant) it reconstructs
 * and owns; detail maxima added at coarser levels are ignored. Then fill the maxima (from
 * dense coefficients, or with the _add calls), finish, then query (concurrently). The maxima
 * are kept per block of 4, 2, 1 positions at levels 1, 2, >= 3 (about 8 samples wide); block
 * (NULL for that) asks for blocks of at least block[a] positions along axis a (rounded down
 * to a power of two), for maxima known only per larger box (a file's chunks), whose tables
 * would otherwise repeat one value per small block. */
typedef struct wvol__brick_bounds wvol__brick_bounds;
#define WVOL__BOUNDS_LEVELS 2
#define WVOL__BOUNDS_LOW_BYTES ((size_t)64 << 20)
wvol_status wvol__bounds_create_src(wvol__brick_bounds **out, const wvol__coef_source *src, const size_t block[3],
                                    wvol_error *err);
/* The number of levels the bound works on (detail maxima of levels above it are folded into
 * its low-pass cube); _for: the number a source of these padded sizes and levels gets. */
int wvol__bounds_levels(const wvol__brick_bounds *b);
int wvol__bounds_levels_for(const size_t pad[3], int levels);
/* The least edge over the axes of the maxima's blocks at level m (coefficient positions); 0
 * outside the bound's levels. A maximum added over an aligned box at least this wide along
 * every axis loses nothing. */
size_t wvol__bounds_block(const wvol__brick_bounds *b, int m);
void wvol__bounds_fill_coeffs(wvol__brick_bounds *b, const wvol_coeffs *c);
void wvol__bounds_add(wvol__brick_bounds *b, int m, int band, size_t p, size_t q, size_t r, float value);
/* The same for every position of the box [lo, hi) of a band at once (a bound of the box's
 * coefficients, e.g. a file chunk's maximum). */
void wvol__bounds_add_box(wvol__brick_bounds *b, int m, int band, const size_t lo[3], const size_t hi[3], float value);
/* The block maxima of band (m, band) for a filler that writes them itself (as the _add calls
 * do: a slot takes max(slot, |value|), NaN as +inf): the maximum over block (x, y, z), the
 * positions [x, y, z] << shift, at table[x + nb[0] (y + nb[1] z)]; NULL outside the bound's
 * levels. Before wvol__bounds_finish. */
float *wvol__bounds_table(wvol__brick_bounds *b, int m, int band, size_t nb[3], int shift[3]);
/* The same for a dense box of one band: positions lo .. lo + n - 1 (inside the band's
 * extent, unwrapped), value (x, y, z) at v[x + sy y + sz z]. Calls on boxes that share no
 * block may run concurrently (boxes whose corners are multiples of 4 share none). */
void wvol__bounds_add_dense(wvol__brick_bounds *b, int m, int band, const size_t lo[3], const size_t n[3],
                            const float *v, size_t sy, size_t sz);
/* (Re)computes the bands' global maxima from the block maxima: after filling, before queries. */
void wvol__bounds_finish(wvol__brick_bounds *b);
/* Bound of the samples in the box [s0, s1] (inclusive voxel indices). */
void wvol__bounds_box(const wvol__brick_bounds *b, const long s0[3], const long s1[3], double *vmin, double *vmax);
/* wvol__bounds_box of every box of a tensor grid at once, the same values bit for bit: box
 * (i, j, k) is [s0[0][i], s1[0][i]] x [s0[1][j], s1[1][j]] x [s0[2][k], s1[2][k]], its bound
 * at range[2 t], range[2 t + 1], t = i + n[0] (j + n[1] k). The block maxima over each box's
 * reach are taken axis by axis (separable), shared by the boxes of a row, instead of box by
 * box. 0 when out of memory (range then unwritten). */
int wvol__bounds_grid(const wvol__brick_bounds *b, const long *const s0[3], const long *const s1[3],
                      const size_t n[3], double *range);
size_t wvol__bounds_bytes(const wvol__brick_bounds *b);
/* kept = 1: b is shared by its maker (a store's cached bounds, read-only once finished), and
 * wvol__bounds_free leaves it; the maker sets 0 again before freeing it. */
void wvol__bounds_keep(wvol__brick_bounds *b, int kept);
void wvol__bounds_free(wvol__brick_bounds *b);

#endif
