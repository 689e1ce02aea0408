/* Template body of the separable periodic 3D transform, included by dwt3.c once per
 * sample type with T (float or double) and SUF (f32 or f64) defined.
 *
 * Memory layout and speed (DESIGN.md section 4): the transform is memory-bound, so
 *  - along x, each contiguous row is split into its even and odd samples (periodically
 *    extended by a few samples), and a[k] = sum_j h[2j] e[k+j] + h[2j+1] o[k+j] runs
 *    with unit stride over k, which the compiler vectorises;
 *  - along y and z, a block of B x-adjacent columns is copied row by row into a
 *    periodically extended scratch (B floats per row: whole cache lines), and each
 *    output row is accumulated tap by tap over the B columns (vectorised, in L1);
 *  - the periodic wrap lives in the extension copy, never as % in an inner loop;
 *  - OpenMP threads share the rows (x) or (slab, column-block) pairs (y, z).
 * Accumulation is in T: float for the f32 path (the error bound in the tests allows
 * for it), double for f64. */

#define CAT2(a, b) a##_##b
#define CAT(a, b) CAT2(a, b)
#define FN(name) CAT(name, SUF)

/* Forward, along x, one row of even length n: row[0..n/2) = a, row[n/2..n) = d. */
static void FN(fwd_row)(T *restrict row, size_t n, const T *restrict h, const T *restrict g, int L,
                        T *restrict e, T *restrict o)
{
    size_t half = n / 2, J = (size_t)(L + 1) / 2, next = half + J - 1, i, k;
    for (i = 0; i < half; i++) {
        e[i] = row[2 * i];
        o[i] = row[2 * i + 1];
    }
    for (; i < next; i++) { /* periodic extension: (2i) mod n, possibly several wraps */
        e[i] = row[(2 * i) % n];
        o[i] = row[(2 * i + 1) % n];
    }
    T *restrict a = row, *restrict d = row + half;
    for (k = 0; k < half; k++) {
        a[k] = h[0] * e[k] + h[1] * o[k];
        d[k] = g[0] * e[k] + g[1] * o[k];
    }
    for (size_t j = 1; j < J; j++) {
        T he = h[2 * j], ge = g[2 * j];
        /* odd L (bl3): the last pair has no odd tap */
        T ho = 2 * j + 1 < (size_t)L ? h[2 * j + 1] : 0, go = 2 * j + 1 < (size_t)L ? g[2 * j + 1] : 0;
        const T *restrict ej = e + j, *restrict oj = o + j;
        for (k = 0; k < half; k++) {
            a[k] += he * ej[k] + ho * oj[k];
            d[k] += ge * ej[k] + go * oj[k];
        }
    }
}

/* Inverse, along x: row = [a | d] -> samples. ea, ed: half+J-1; ev, od: half. */
static void FN(inv_row)(T *restrict row, size_t n, const T *restrict h, const T *restrict g, int L,
                        T *restrict ea, T *restrict ed, T *restrict ev, T *restrict od)
{
    size_t half = n / 2, J = (size_t)(L + 1) / 2, pre = J - 1, i, t;
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
    for (t = 0; t < half; t++) {
        ev[t] = h[0] * ea[pre + t] + g[0] * ed[pre + t];
        od[t] = h[1] * ea[pre + t] + g[1] * ed[pre + t];
    }
    for (size_t j = 1; j < J; j++) {
        T he = h[2 * j], ge = g[2 * j];
        T ho = 2 * j + 1 < (size_t)L ? h[2 * j + 1] : 0, go = 2 * j + 1 < (size_t)L ? g[2 * j + 1] : 0;
        const T *restrict aj = ea + pre - j, *restrict dj = ed + pre - j;
        for (t = 0; t < half; t++) {
            ev[t] += he * aj[t] + ge * dj[t];
            od[t] += ho * aj[t] + go * dj[t];
        }
    }
    for (t = 0; t < half; t++) {
        row[2 * t] = ev[t];
        row[2 * t + 1] = od[t];
    }
}

/* Forward along a strided axis (y or z) for a block of w <= B adjacent columns:
 * base = first sample of the block, n samples along the axis at distance stride. */
static void FN(fwd_cols)(T *base, size_t n, size_t stride, size_t w, size_t B, const T *restrict h,
                         const T *restrict g, int L, T *restrict tmp)
{
    size_t half = n / 2, next = n + (size_t)L - 2, i, k, x;
    for (i = 0; i < next; i++) memcpy(tmp + i * B, base + (i < n ? i : i % n) * stride, w * sizeof(T));
    for (k = 0; k < half; k++) {
        T *restrict a = base + k * stride, *restrict d = base + (half + k) * stride;
        const T *restrict t0 = tmp + 2 * k * B;
        for (x = 0; x < w; x++) {
            a[x] = h[0] * t0[x];
            d[x] = g[0] * t0[x];
        }
        for (int m = 1; m < L; m++) {
            const T *restrict tm = t0 + (size_t)m * B;
            T hm = h[m], gm = g[m];
            for (x = 0; x < w; x++) {
                a[x] += hm * tm[x];
                d[x] += gm * tm[x];
            }
        }
    }
}

/* Inverse along a strided axis for a block of w <= B columns. */
static void FN(inv_cols)(T *base, size_t n, size_t stride, size_t w, size_t B, const T *restrict h,
                         const T *restrict g, int L, T *restrict tmp)
{
    size_t half = n / 2, J = (size_t)(L + 1) / 2, pre = J - 1, rows = half + pre, i, t, x;
    T *restrict ta = tmp, *restrict td = tmp + rows * B;
    for (i = 0; i < rows; i++) {
        size_t src = i < pre ? (half - (pre - i) % half) % half : i - pre;
        memcpy(ta + i * B, base + src * stride, w * sizeof(T));
        memcpy(td + i * B, base + (half + src) * stride, w * sizeof(T));
    }
    for (t = 0; t < half; t++) {
        T *restrict xe = base + 2 * t * stride, *restrict xo = base + (2 * t + 1) * stride;
        const T *restrict a0 = ta + (pre + t) * B, *restrict d0 = td + (pre + t) * B;
        for (x = 0; x < w; x++) {
            xe[x] = h[0] * a0[x] + g[0] * d0[x];
            xo[x] = h[1] * a0[x] + g[1] * d0[x];
        }
        for (size_t j = 1; j < J; j++) {
            const T *restrict aj = a0 - j * B, *restrict dj = d0 - j * B;
            T he = h[2 * j], ge = g[2 * j];
            T ho = 2 * j + 1 < (size_t)L ? h[2 * j + 1] : 0, go = 2 * j + 1 < (size_t)L ? g[2 * j + 1] : 0;
            for (x = 0; x < w; x++) {
                xe[x] += he * aj[x] + ge * dj[x];
                xo[x] += ho * aj[x] + go * dj[x];
            }
        }
    }
}

/* One level, forward (inverse = 0) or inverse, on the cube c[3] at the corner of the
 * array of row length NX and slice size NXY. Axes of extent 1 are skipped. */
static void FN(level)(T *data, const size_t c[3], size_t NX, size_t NXY, const dwt_plan *pl,
                      const T *h, const T *g, T *scratch, int inverse)
{
    int L = pl->L;
    size_t cx = c[0], cy = c[1], cz = c[2];
    /* three passes; the inverse runs them in the opposite order */
    for (int s = 0; s < 3; s++) {
        int axis = inverse ? 2 - s : s;
        if (c[axis] < 2) continue;
        if (axis == 0) {
            long long rows = (long long)(cy * cz);
#pragma omp parallel for schedule(static) if (rows * (long long)cx > 32768)
            for (long long r = 0; r < rows; r++) {
                T *s0 = scratch + (size_t)wvol__thread_id() * pl->scratch;
                size_t j = (size_t)r % cy, k = (size_t)r / cy, ext = cx / 2 + (size_t)L;
                T *row = data + j * NX + k * NXY;
                if (!inverse) FN(fwd_row)(row, cx, h, g, L, s0, s0 + ext);
                else FN(inv_row)(row, cx, h, g, L, s0, s0 + ext, s0 + 2 * ext, s0 + 3 * ext);
            }
        } else {
            size_t n = c[axis], stride = axis == 1 ? NX : NXY, ostride = axis == 1 ? NXY : NX;
            size_t outer = axis == 1 ? cz : cy, B = wvol__block_width(cx, n, L, sizeof(T));
            size_t nb = (cx + B - 1) / B;
            long long tasks = (long long)(outer * nb);
#pragma omp parallel for schedule(static) if (tasks * (long long)(n * B) > 32768)
            for (long long tsk = 0; tsk < tasks; tsk++) {
                T *s0 = scratch + (size_t)wvol__thread_id() * pl->scratch;
                size_t b = (size_t)tsk % nb, o = (size_t)tsk / nb, x0 = b * B;
                size_t w = cx - x0 < B ? cx - x0 : B;
                T *base = data + o * ostride + x0;
                if (!inverse) FN(fwd_cols)(base, n, stride, w, B, h, g, L, s0);
                else FN(inv_cols)(base, n, stride, w, B, h, g, L, s0);
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
#undef CAT
#undef CAT2
