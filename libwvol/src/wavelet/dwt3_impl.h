/* SPDX-License-Identifier: MIT */
/* Template body of the separable periodic 3D transform, included by dwt3.c once per
 * sample type with T (float or double) and SUF (f32 or f64) defined.
 *
 * Memory layout and speed (DESIGN.md section 4): the transform is memory-bound, so
 *  - along x, each contiguous row is split into its even and odd samples (periodically
 *    extended by a few samples), and a[k] = sum_j h[2j] e[k+j] + h[2j+1] o[k+j] runs
 *    with unit stride over k;
 *  - along y and z, a block of B x-adjacent columns is copied row by row into a
 *    periodically extended scratch (B floats per row: whole cache lines, <= 128 KiB in
 *    all), and each output row is summed over the taps 2 vectors of columns at a time,
 *    the sums held in registers (explicit vector code: GCC left the plain loops scalar);
 *  - the periodic wrap lives in the extension copy, never as % in an inner loop;
 *  - x and y run back to back on one z-slice while it sits in L2 (one trip to memory
 *    for both), z on (row, column-block) tasks;
 *  - OpenMP threads share the z-slices (x, y) or the tasks (z).
 * Accumulation is in T: float for the f32 path (the error bound in the tests allows
 * for it), double for f64. */

#define CAT2(a, b) a##_##b
#define CAT(a, b) CAT2(a, b)
#define FN(name) CAT(name, SUF)
/* GCC/Clang vector extensions: 32-byte vectors (AVX registers in the x86-64-v3 clone,
 * pairs of SSE registers in the baseline one), unaligned, two per accumulator so that
 * a chunk of 2*VL columns keeps its a/d (or even/odd) sums in registers over the taps. */
#define VL (32 / sizeof(T))
typedef T CAT(vec, SUF) __attribute__((vector_size(32), aligned(sizeof(T)), may_alias));
#define V CAT(vec, SUF)
#define VZERO ((V){0})
#define VLOAD(p) (*(const V *)(const void *)(p))
#define VSTORE(p, v) (*(V *)(void *)(p) = (v))

/* Forward, along x, one row of even length n: dst[0..n/2) = a, dst[n/2..n) = d, from the
 * samples src[0..n) (dst itself in place: src is read whole into e and o first). */
WVOL__KERNEL static void FN(fwd_row)(T *dst, const T *src, size_t n, const T *restrict h, const T *restrict g,
                                     int L, T *restrict e, T *restrict o)
{
    const T *row = src;
    size_t half = n / 2, J = (size_t)(L + 1) / 2, next = half + J - 1, i, k, k0;
    for (i = 0; i < half; i++) {
        e[i] = row[2 * i];
        o[i] = row[2 * i + 1];
    }
    for (; i < next; i++) { /* periodic extension: (2i) mod n, possibly several wraps */
        e[i] = row[(2 * i) % n];
        o[i] = row[(2 * i + 1) % n];
    }
    T *restrict a = dst, *restrict d = dst + half;
    for (k0 = 0; k0 + 2 * VL <= half; k0 += 2 * VL) {
        V a0 = VZERO, a1 = VZERO, d0 = VZERO, d1 = VZERO;
        for (size_t j = 0; j < J; j++) {
            T he = h[2 * j], ge = g[2 * j];
            /* odd L would have no last odd tap (all our filters have even L) */
            T ho = 2 * j + 1 < (size_t)L ? h[2 * j + 1] : 0, go = 2 * j + 1 < (size_t)L ? g[2 * j + 1] : 0;
            const T *ej = e + k0 + j, *oj = o + k0 + j;
            V p0 = VLOAD(ej), p1 = VLOAD(ej + VL), q0 = VLOAD(oj), q1 = VLOAD(oj + VL);
            a0 += he * p0 + ho * q0, a1 += he * p1 + ho * q1;
            d0 += ge * p0 + go * q0, d1 += ge * p1 + go * q1;
        }
        VSTORE(a + k0, a0), VSTORE(a + k0 + VL, a1);
        VSTORE(d + k0, d0), VSTORE(d + k0 + VL, d1);
    }
    for (k = k0; k < half; k++) {
        T sa = 0, sd = 0;
        for (size_t j = 0; j < J; j++) {
            sa += h[2 * j] * e[k + j];
            sd += g[2 * j] * e[k + j];
            if (2 * j + 1 < (size_t)L) sa += h[2 * j + 1] * o[k + j], sd += g[2 * j + 1] * o[k + j];
        }
        a[k] = sa, d[k] = sd;
    }
}

/* Inverse, along x: row = [a | d] -> samples. ea, ed: half+J-1; ev, od: half. */
WVOL__KERNEL static void FN(inv_row)(T *restrict row, size_t n, const T *restrict h, const T *restrict g,
                                     int L, T *restrict ea, T *restrict ed, T *restrict ev, T *restrict od)
{
    size_t half = n / 2, J = (size_t)(L + 1) / 2, pre = J - 1, i, t, t0;
    /* ea[u] = a[(u - pre) mod half]: x[2t+p] = sum_j h[2j+p] a[t-j] + g[2j+p] d[t-j] */
    for (i = 0; i < pre; i++) {
        size_t src = (half - (pre - i) % half) % half;
        ea[i] = row[src];
        ed[i] = row[half + src];
    }
    for (i = 0; i < half; i++) {
        ea[pre + i] = row[i];
        ed[pre + i] = row[half + i];
    }
    for (t0 = 0; t0 + 2 * VL <= half; t0 += 2 * VL) {
        V e0 = VZERO, e1 = VZERO, o0 = VZERO, o1 = VZERO;
        for (size_t j = 0; j < J; j++) {
            T he = h[2 * j], ge = g[2 * j];
            T ho = 2 * j + 1 < (size_t)L ? h[2 * j + 1] : 0, go = 2 * j + 1 < (size_t)L ? g[2 * j + 1] : 0;
            const T *aj = ea + pre + t0 - j, *dj = ed + pre + t0 - j;
            V p0 = VLOAD(aj), p1 = VLOAD(aj + VL), q0 = VLOAD(dj), q1 = VLOAD(dj + VL);
            e0 += he * p0 + ge * q0, e1 += he * p1 + ge * q1;
            o0 += ho * p0 + go * q0, o1 += ho * p1 + go * q1;
        }
        VSTORE(ev + t0, e0), VSTORE(ev + t0 + VL, e1);
        VSTORE(od + t0, o0), VSTORE(od + t0 + VL, o1);
    }
    for (t = t0; t < half; t++) {
        T se = 0, so = 0;
        for (size_t j = 0; j < J; j++) {
            T av = ea[pre + t - j], dv = ed[pre + t - j];
            se += h[2 * j] * av + g[2 * j] * dv;
            if (2 * j + 1 < (size_t)L) so += h[2 * j + 1] * av + g[2 * j + 1] * dv;
        }
        ev[t] = se, od[t] = so;
    }
    for (t = 0; t < half; t++) {
        row[2 * t] = ev[t];
        row[2 * t + 1] = od[t];
    }
}

/* One output row pair of the strided forward pass: a = sum_m h[m] r[m][x],
 * d = sum_m g[m] r[m][x] for x < w, r[m] the L input rows (of the scratch copy in the
 * in-memory pass; of the window itself in the streamed one, which needs no copy: its
 * rows are whole). Columns go in chunks of 4*VL (then 2*VL) with the accumulators in
 * registers across the taps: eight independent sums per tap, enough to keep the adds busy
 * with a product and a sum per tap and column (this file is built without contracted
 * multiply-adds, for the same bits on every CPU level: docs/wvc-format.md, "The same bytes
 * on every CPU"). Each column's sum runs over the taps in order whatever the chunk, so the
 * chunk width does not change a bit. The in-memory pass (fwd_cols) and the streamed one
 * (zrows) both call this one function on the same column blocks, so their coefficients are
 * computed by the same instructions: bit-identical whatever the compiler makes of the loops. */
WVOL__KERNEL static void FN(cols_row)(T *restrict a, T *restrict d, const T *const *r, size_t w,
                                      const T *restrict h, const T *restrict g, int L)
{
    size_t x, x0;
    for (x0 = 0; x0 + 4 * VL <= w; x0 += 4 * VL) {
        V a0 = VZERO, a1 = VZERO, a2 = VZERO, a3 = VZERO, d0 = VZERO, d1 = VZERO, d2 = VZERO, d3 = VZERO;
        for (int m = 0; m < L; m++) {
            const T *tm = r[m] + x0;
            V u0 = VLOAD(tm), u1 = VLOAD(tm + VL), u2 = VLOAD(tm + 2 * VL), u3 = VLOAD(tm + 3 * VL);
            T hm = h[m], gm = g[m];
            a0 += hm * u0, a1 += hm * u1, a2 += hm * u2, a3 += hm * u3;
            d0 += gm * u0, d1 += gm * u1, d2 += gm * u2, d3 += gm * u3;
        }
        VSTORE(a + x0, a0), VSTORE(a + x0 + VL, a1), VSTORE(a + x0 + 2 * VL, a2), VSTORE(a + x0 + 3 * VL, a3);
        VSTORE(d + x0, d0), VSTORE(d + x0 + VL, d1), VSTORE(d + x0 + 2 * VL, d2), VSTORE(d + x0 + 3 * VL, d3);
    }
    for (; x0 + 2 * VL <= w; x0 += 2 * VL) {
        V a0 = VZERO, a1 = VZERO, d0 = VZERO, d1 = VZERO;
        for (int m = 0; m < L; m++) {
            const T *tm = r[m] + x0;
            V u0 = VLOAD(tm), u1 = VLOAD(tm + VL);
            T hm = h[m], gm = g[m];
            a0 += hm * u0, a1 += hm * u1;
            d0 += gm * u0, d1 += gm * u1;
        }
        VSTORE(a + x0, a0), VSTORE(a + x0 + VL, a1);
        VSTORE(d + x0, d0), VSTORE(d + x0 + VL, d1);
    }
    for (x = x0; x < w; x++) {
        T sa = 0, sd = 0;
        for (int m = 0; m < L; m++) {
            T v = r[m][x];
            sa += h[m] * v;
            sd += g[m] * v;
        }
        a[x] = sa, d[x] = sd;
    }
}

/* Forward along a strided axis (y or z) for a block of w <= B adjacent columns:
 * base = first sample of the block, n samples along the axis at distance stride. */
WVOL__KERNEL static void FN(fwd_cols)(T *base, size_t n, size_t stride, size_t w, size_t B,
                                      const T *restrict h, const T *restrict g, int L, T *restrict tmp)
{
    size_t half = n / 2, next = n + (size_t)L - 2, i, k;
    const T *r[WVOL__MAX_TAPS];
    for (i = 0; i < next; i++) memcpy(tmp + i * B, base + (i < n ? i : i % n) * stride, w * sizeof(T));
    for (k = 0; k < half; k++) {
        for (int m = 0; m < L; m++) r[m] = tmp + (2 * k + (size_t)m) * B;
        FN(cols_row)(base + k * stride, base + (half + k) * stride, r, w, h, g, L);
    }
}

/* The streamed z pass (dwt3_stream.c): output rows a, d of planes cx x cy, rows y0 .. y1 - 1,
 * from the L input rows rows[m] (2k + m mod the depth), read in place, in the column blocks
 * of width B that fwd_cols uses on the same cube. */
__attribute__((unused)) static void FN(zrows)(T *a, T *d, const T *const *rows, size_t cx, size_t y0, size_t y1,
                                              size_t B, const T *h, const T *g, int L)
{
    const T *r[WVOL__MAX_TAPS];
    for (size_t y = y0; y < y1; y++)
        for (size_t xb = 0; xb < cx; xb += B) {
            size_t w = cx - xb < B ? cx - xb : B, off = y * cx + xb;
            for (int m = 0; m < L; m++) r[m] = rows[m] + off;
            FN(cols_row)(a + off, d + off, r, w, h, g, L);
        }
}

/* Inverse along a strided axis for a block of w <= B columns. */
WVOL__KERNEL static void FN(inv_cols)(T *base, size_t n, size_t stride, size_t w, size_t B,
                                      const T *restrict h, const T *restrict g, int L, T *restrict tmp)
{
    size_t half = n / 2, J = (size_t)(L + 1) / 2, pre = J - 1, rows = half + pre, i, t, x, x0;
    T *restrict ta = tmp, *restrict td = tmp + rows * B;
    for (i = 0; i < rows; i++) {
        size_t src = i < pre ? (half - (pre - i) % half) % half : i - pre;
        memcpy(ta + i * B, base + src * stride, w * sizeof(T));
        memcpy(td + i * B, base + (half + src) * stride, w * sizeof(T));
    }
    for (t = 0; t < half; t++) {
        T *restrict xe = base + 2 * t * stride, *restrict xo = base + (2 * t + 1) * stride;
        const T *restrict a0 = ta + (pre + t) * B, *restrict d0 = td + (pre + t) * B;
        for (x0 = 0; x0 + 2 * VL <= w; x0 += 2 * VL) {
            V e0 = VZERO, e1 = VZERO, o0 = VZERO, o1 = VZERO;
            for (size_t j = 0; j < J; j++) {
                const T *aj = a0 - j * B + x0, *dj = d0 - j * B + x0;
                V p0 = VLOAD(aj), p1 = VLOAD(aj + VL), q0 = VLOAD(dj), q1 = VLOAD(dj + VL);
                T he = h[2 * j], ge = g[2 * j];
                T ho = 2 * j + 1 < (size_t)L ? h[2 * j + 1] : 0, go = 2 * j + 1 < (size_t)L ? g[2 * j + 1] : 0;
                e0 += he * p0 + ge * q0, e1 += he * p1 + ge * q1;
                o0 += ho * p0 + go * q0, o1 += ho * p1 + go * q1;
            }
            VSTORE(xe + x0, e0), VSTORE(xe + x0 + VL, e1);
            VSTORE(xo + x0, o0), VSTORE(xo + x0 + VL, o1);
        }
        for (x = x0; x < w; x++) {
            T se = 0, so = 0;
            for (size_t j = 0; j < J; j++) {
                T av = (a0 - j * B)[x], dv = (d0 - j * B)[x]; /* not a0[x - j B]: x - j B wraps */
                se += h[2 * j] * av + g[2 * j] * dv;
                if (2 * j + 1 < (size_t)L) so += h[2 * j + 1] * av + g[2 * j + 1] * dv;
            }
            xe[x] = se, xo[x] = so;
        }
    }
}

/* The y pass of one z-slice, forward or inverse, in column blocks. */
static void FN(slice_y)(T *slice, size_t cx, size_t cy, size_t NX, int L, const T *h, const T *g, T *s0,
                        int inverse)
{
    size_t B;
    if (cy < 2) return;
    B = wvol__block_width(cx, cy, L, sizeof(T));
    for (size_t x0 = 0; x0 < cx; x0 += B) {
        size_t w = cx - x0 < B ? cx - x0 : B;
        if (!inverse) FN(fwd_cols)(slice + x0, cy, NX, w, B, h, g, L, s0);
        else FN(inv_cols)(slice + x0, cy, NX, w, B, h, g, L, s0);
    }
}

/* x then y (forward) or y then x (inverse) on one z-slice of the cube: the slice
 * (<= 256 KiB at 256^2 floats) stays in L2 between the two passes, so they cost one
 * trip to memory instead of two. */
static void FN(slice_xy)(T *slice, size_t cx, size_t cy, size_t NX, const dwt_plan *pl, const T *h, const T *g,
                         T *s0, int inverse)
{
    int L = pl->L;
    size_t ext = cx / 2 + (size_t)L;
    for (int s = 0; s < 2; s++) {
        int axis = inverse ? 1 - s : s;
        if (axis == 0 && cx > 1) {
            for (size_t j = 0; j < cy; j++) {
                T *row = slice + j * NX;
                if (!inverse) FN(fwd_row)(row, row, cx, h, g, L, s0, s0 + ext);
                else FN(inv_row)(row, cx, h, g, L, s0, s0 + ext, s0 + 2 * ext, s0 + 3 * ext);
            }
        } else if (axis == 1) {
            FN(slice_y)(slice, cx, cy, NX, L, h, g, s0, inverse);
        }
    }
}

/* The forward x then y pass of slice_xy into the compact cx x cy slice dst, from rows of
 * cx samples at src, sstride apart (row j of the slice from src row min(j, ny - 1): the
 * edge padding along y), without copying them in first: the x pass reads each source row
 * into its even/odd scratch itself. The same kernels in the same order as slice_xy on the
 * copy: the same bits. cx >= 2 (an axis of one sample has no x pass). */
__attribute__((unused)) static void FN(slice_xy_from)(T *dst, const T *src, size_t sstride, size_t ny, size_t cx,
                                                      size_t cy, int L, const T *h, const T *g, T *s0)
{
    size_t ext = cx / 2 + (size_t)L;
    for (size_t j = 0; j < cy; j++)
        FN(fwd_row)(dst + j * cx, src + sstride * (j < ny ? j : ny - 1), cx, h, g, L, s0, s0 + ext);
    FN(slice_y)(dst, cx, cy, cx, L, h, g, s0, 0);
}

/* One level, forward (inverse = 0) or inverse, on the cube c[3] at the corner of the
 * array of row length NX and slice size NXY. Axes of extent 1 are skipped. */
static void FN(level)(T *data, const size_t c[3], size_t NX, size_t NXY, const dwt_plan *pl,
                      const T *h, const T *g, T *scratch, int inverse)
{
    int L = pl->L;
    size_t cx = c[0], cy = c[1], cz = c[2];
    for (int s = 0; s < 2; s++) {
        int zpass = inverse ? s == 0 : s == 1;
        if (!zpass) {
            if (cx < 2 && cy < 2) continue;
            long long slices = (long long)cz;
#pragma omp parallel for schedule(static) if (slices > 1 && (long long)(cx * cy * cz) > 32768)
            for (long long k = 0; k < slices; k++)
                FN(slice_xy)(data + (size_t)k * NXY, cx, cy, NX, pl, h, g,
                             scratch + (size_t)wvol__thread_id() * pl->scratch, inverse);
        } else {
            if (cz < 2) continue;
            size_t B = wvol__block_width(cx, cz, L, sizeof(T)), nb = (cx + B - 1) / B;
            long long tasks = (long long)(cy * nb);
#pragma omp parallel for schedule(static) if (tasks > 1 && (long long)(cx * cy * cz) > 32768)
            for (long long tsk = 0; tsk < tasks; tsk++) {
                T *s0 = scratch + (size_t)wvol__thread_id() * pl->scratch;
                size_t b = (size_t)tsk % nb, j = (size_t)tsk / nb, x0 = b * B;
                size_t w = cx - x0 < B ? cx - x0 : B;
                T *base = data + j * NX + x0;
                if (!inverse) FN(fwd_cols)(base, cz, NXY, w, B, h, g, L, s0);
                else FN(inv_cols)(base, cz, NXY, w, B, h, g, L, s0);
            }
        }
    }
}

/* Forward: levels 1..levels. Inverse: undoes levels..stop+1 (stop 0 = all). */
static wvol_status FN(transform)(T *data, size_t nx, size_t ny, size_t nz, const wvol_filter *f,
                                 int levels, int inverse, int stop, wvol_error *err)
{
    dwt_plan pl;
    T h[WVOL__MAX_TAPS], g[WVOL__MAX_TAPS], *scratch;
    size_t c[3], n[3] = {nx, ny, nz};
    WVOL_FORWARD(wvol__dwt_plan(&pl, data, n, f, levels, sizeof(T), err));
    for (int i = 0; i < f->length; i++) {
        h[i] = (T)f->h[i];
        g[i] = (T)f->g[i];
    }
    scratch = malloc(pl.scratch * (size_t)pl.threads * sizeof(T));
    WVOL_RETURN_IF(!scratch, err, WVOL_ERR_NOMEM, "wavelet transform: no memory for %zu scratch values",
                   pl.scratch * (size_t)pl.threads);
    for (int s = 0; s < levels - (inverse ? stop : 0); s++) {
        int m = inverse ? levels - s : s + 1; /* level being made (forward) or undone */
        for (int a = 0; a < 3; a++) c[a] = n[a] == 1 ? 1 : n[a] >> (m - 1);
        FN(level)(data, c, nx, nx * ny, &pl, h, g, scratch, inverse);
    }
    free(scratch);
    return WVOL_OK;
}

#undef FN
#undef VL
#undef V
#undef VZERO
#undef VLOAD
#undef VSTORE
#undef CAT
#undef CAT2
