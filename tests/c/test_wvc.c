/* SPDX-License-Identifier: MIT */
/* .wvc files: round trips in every coder and step mode, the error target met,
 * early stop at each level, and refusal of damaged files (truncation at every
 * byte, a flipped bit anywhere, crafted headers with valid checksums). */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "check.h"
#include "fixtures.h"
#include "wvc_fixtures.h"
#include "codec/wvc2_writer.h"
#include "codec/wvc_dequant.h"
#include "codec/wvc_format.h"
#include "codec/wvc_quant.h"
#include "wvol/io.h"
#include "wvol/wvc.h"

/* A small volume with smooth parts, a sharp sphere and a little texture. */
static double make_volume_at(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    double x = (i + 0.5) / v->nx - 0.5, y = (j + 0.5) / v->ny - 0.5, z = (k + 0.5) / v->nz - 0.5;
    double r2 = x * x + y * y + z * z, f = 100.0 * exp(-8 * r2);
    (void)ctx;
    if (r2 < 0.09) f += 40.0;
    f += 3.0 * sin(13.0 * x + 7.0 * y) * cos(5.0 * z);
    return f;
}

static wvol_volume *make_volume(size_t nx, size_t ny, size_t nz)
{
    return fixture_volume(nx, ny, nz, make_volume_at, NULL);
}

typedef struct fixture {
    wvol_volume *v;
    wvol_coeffs *c;
    double vmin, vmax;
} fixture;

static int fixture_make(fixture *F, size_t nx, size_t ny, size_t nz, const char *wavelet, int levels)
{
    const wvol_filter *f;
    wvol_error err;
    memset(F, 0, sizeof *F);
    F->v = make_volume(nx, ny, nz);
    if (!F->v || wvol_filter_get(&f, wavelet, &err) != WVOL_OK) return 0;
    if (wvol_dwt3(&F->c, F->v, f, levels, &err) != WVOL_OK) {
        fprintf(stderr, "dwt3: %s\n", err.message);
        return 0;
    }
    wvol_volume_range(F->v, &F->vmin, &F->vmax, NULL);
    return 1;
}

static void fixture_free(fixture *F)
{
    wvol_coeffs_destroy(F->c);
    wvol_volume_destroy(F->v);
}

/* The format version encode() writes (0: the default, version 2), and its tile (0: default);
 * g_coder, when not AUTO, replaces AUTO in encode() (the tests run again with chunk modes 3
 * and 4, and --coder compact). */
static int g_version, p_tile;
static wvol_wvc_coder g_coder = WVOL_WVC_CODER_AUTO;

static int encode(void **buf, size_t *n, const fixture *F, double psnr, double step, wvol_wvc_coder coder,
                  wvol_wvc_report *rep)
{
    wvol_wvc_params p;
    wvol_error err;
    size_t nv = wvol_volume_count(F->v);
    wvol_wvc_params_default(&p);
    p.value_min = F->vmin;
    p.value_max = F->vmax;
    p.coder = coder == WVOL_WVC_CODER_AUTO ? g_coder : coder;
    p.step = step;
    p.version = g_version;
    p.tile = p.tile_z = p_tile;
    if (step == 0) p.target_sse = wvol_wvc_sse_for_psnr(psnr, (double)nv, F->vmin, F->vmax);
    if (wvol_wvc_encode(buf, n, F->c, &p, rep, &err) != WVOL_OK) {
        fprintf(stderr, "encode: %s\n", err.message);
        return 0;
    }
    return 1;
}

static double coeff_sse(const wvol_coeffs *a, const wvol_coeffs *b, double *maxabs)
{
    size_t i, n = a->px * a->py * a->pz;
    double s = 0, m = 0;
    for (i = 0; i < n; i++) {
        double d = (double)a->data[i] - b->data[i];
        s += d * d;
        if (fabs(d) > m) m = fabs(d);
    }
    if (maxabs) *maxabs = m;
    return s;
}

static void wvc_round_trip_meets_psnr_target(const char *wavelet, size_t nx, size_t ny, size_t nz, int levels)
{
    fixture F;
    double targets[3] = {35, 50, 70};
    int t;
    CHECK(fixture_make(&F, nx, ny, nz, wavelet, levels), "fixture %s", wavelet);
    if (!F.c) return;
    for (t = 0; t < 3; t++) {
        void *buf = NULL;
        size_t n = 0;
        wvol_wvc_report rep;
        wvol_coeffs *d = NULL;
        wvol_volume *r = NULL;
        wvol_wvc_info info;
        wvol_error err;
        double sse, maxabs, vsse, vmax, psnr;
        if (!encode(&buf, &n, &F, targets[t], 0, WVOL_WVC_CODER_AUTO, &rep)) {
            CHECK(0, "encode %s psnr %g", wavelet, targets[t]);
            continue;
        }
        CHECK(wvol_wvc_decode(&d, buf, n, NULL, &info, &err) == WVOL_OK, "decode: %s", err.message);
        if (d) {
            sse = coeff_sse(F.c, d, &maxabs);
            /* dead-zone quantiser: every coefficient within one step */
            CHECK(maxabs <= rep.step * 1.0001, "%s: max coefficient error %g > step %g", wavelet, maxabs, rep.step);
            /* the encoder's predicted error is the coefficient error (Parseval), up to the
             * rounding of each reconstructed coefficient to float32 (half an ulp) */
            {
                double ulp = 0, cmax = 0;
                size_t i, nc = F.c->px * F.c->py * F.c->pz;
                for (i = 0; i < nc; i++)
                    if (fabs(F.c->data[i]) > cmax) cmax = fabs(F.c->data[i]);
                ulp = (double)nc * pow(cmax * ldexp(1.0, -24), 2) + 2 * sqrt(rep.sse_quant * (double)nc) * cmax * ldexp(1.0, -24);
                CHECK(fabs(sse - rep.sse_quant) <= 1e-5 * rep.sse_quant + ulp + 1e-12, "%s: sse %g vs predicted %g",
                      wavelet, sse, rep.sse_quant);
            }
            CHECK(fabs(info.sse - rep.sse_quant) <= 1e-12 * rep.sse_quant, "header sse");
            CHECK(wvol_idwt3(&r, d, &err) == WVOL_OK, "idwt3: %s", err.message);
            if (r) {
                wvol_wvc_compare(&vsse, &vmax, F.v, r, NULL);
                psnr = wvol_wvc_psnr(vsse, (double)wvol_volume_count(F.v), F.vmin, F.vmax);
                CHECK(psnr >= targets[t] - 0.01, "%s %zux%zux%zu: measured PSNR %.3f below target %g", wavelet,
                      nx, ny, nz, psnr, targets[t]);
                /* padding can only add error outside the original grid */
                CHECK(vsse <= rep.sse_quant * 1.001 + 1e-6, "%s: volume sse %g > coefficient sse %g", wavelet,
                      vsse, rep.sse_quant);
            }
        }
        wvol_volume_destroy(r);
        wvol_coeffs_destroy(d);
        free(buf);
    }
    fixture_free(&F);
}

static void wvc_coders_decode_to_the_same_coefficients(void)
{
    fixture F;
    void *b1 = NULL, *b2 = NULL, *b3 = NULL;
    size_t n1, n2, n3;
    wvol_wvc_report r1, r2, r3;
    wvol_coeffs *d1 = NULL, *d2 = NULL, *d3 = NULL;
    CHECK(fixture_make(&F, 16, 16, 16, "db2", 2), "fixture");
    if (!F.c) return;
    CHECK(encode(&b1, &n1, &F, 0, 0.05, WVOL_WVC_CODER_CABAC, &r1), "cabac");
    CHECK(encode(&b2, &n2, &F, 0, 0.05, WVOL_WVC_CODER_ZSTD, &r2), "zstd");
    CHECK(encode(&b3, &n3, &F, 0, 0.05, WVOL_WVC_CODER_COMPACT, &r3), "compact");
    CHECK(r1.step == 0.05 && r2.step == 0.05, "fixed step kept: %g", r1.step);
    CHECK(r1.bytes_zstd == 0 && r2.bytes_cabac == 0 && r3.bytes_cabac > 0 && r3.bytes_zstd > 0, "alternatives");
    CHECK(n3 <= n1 && n3 <= n2, "compact keeps the smaller per section: %zu %zu %zu", n1, n2, n3);
    CHECK(wvol_wvc_decode(&d1, b1, n1, NULL, NULL, NULL) == WVOL_OK, "decode cabac");
    CHECK(wvol_wvc_decode(&d2, b2, n2, NULL, NULL, NULL) == WVOL_OK, "decode zstd");
    CHECK(wvol_wvc_decode(&d3, b3, n3, NULL, NULL, NULL) == WVOL_OK, "decode auto");
    if (d1 && d2 && d3) {
        size_t n = F.c->px * F.c->py * F.c->pz;
        CHECK(!memcmp(d1->data, d2->data, n * sizeof(float)), "cabac and zstd differ");
        CHECK(!memcmp(d1->data, d3->data, n * sizeof(float)), "cabac and auto differ");
    }
    wvol_coeffs_destroy(d1);
    wvol_coeffs_destroy(d2);
    wvol_coeffs_destroy(d3);
    free(b1);
    free(b2);
    free(b3);
    fixture_free(&F);
}

/* The low-pass cube of level m depends only on levels > m: stopping early must give it exactly. */
static void wvc_early_stop_gives_the_coarser_volume(void)
{
    fixture F;
    void *buf = NULL;
    size_t n;
    int m, levels = 3;
    wvol_coeffs *full = NULL;
    CHECK(fixture_make(&F, 32, 24, 16, "coif1", levels), "fixture");
    if (!F.c) return;
    CHECK(encode(&buf, &n, &F, 45, 0, WVOL_WVC_CODER_AUTO, NULL), "encode");
    CHECK(wvol_wvc_decode(&full, buf, n, NULL, NULL, NULL) == WVOL_OK, "full decode");
    for (m = 0; m <= levels && full; m++) {
        wvol_wvc_read_options o;
        wvol_coeffs *part = NULL;
        wvol_volume *a = NULL, *b = NULL;
        wvol_error err;
        wvol_wvc_read_options_default(&o);
        o.stop_level = m;
        CHECK(wvol_wvc_decode(&part, buf, n, &o, NULL, &err) == WVOL_OK, "stop %d: %s", m, err.message);
        if (!part) continue;
        CHECK(wvol_idwt3_level(&a, part, m, &err) == WVOL_OK, "idwt3_level part %d: %s", m, err.message);
        CHECK(wvol_idwt3_level(&b, full, m, &err) == WVOL_OK, "idwt3_level full %d: %s", m, err.message);
        if (a && b) {
            double sse = 0, mx = 0;
            CHECK(a->nx == b->nx && a->ny == b->ny && a->nz == b->nz, "sizes at level %d", m);
            wvol_wvc_compare(&sse, &mx, a, b, NULL);
            CHECK(mx <= 1e-3, "level %d: early stop differs by %g", m, mx);
        }
        if (m > 0) {
            /* the finer levels really were not decoded */
            size_t i, nz = 0;
            for (i = 0; i < part->px * part->py * part->pz; i++) {
                int lev, band;
                size_t p, q, r;
                wvol_coeffs_locate(part, i, &lev, &band, &p, &q, &r);
                if (lev <= m && band != 0 && part->data[i] != 0) nz++;
            }
            CHECK(nz == 0, "stop %d: %zu finer coefficients are set", m, nz);
        }
        wvol_volume_destroy(a);
        wvol_volume_destroy(b);
        wvol_coeffs_destroy(part);
    }
    {
        wvol_wvc_read_options o;
        wvol_coeffs *part = NULL;
        wvol_wvc_read_options_default(&o);
        o.stop_level = levels + 1;
        CHECK(wvol_wvc_decode(&part, buf, n, &o, NULL, NULL) == WVOL_ERR_ARG, "stop level beyond levels");
    }
    wvol_coeffs_destroy(full);
    free(buf);
    fixture_free(&F);
}

/* The dequantised value of q as the format defines it, written out independently of the
 * codec: sign(q) o1 for |q| = 1, sign(q) (|q| + d2) step beyond, each rounded once from
 * double; +0 for 0. */
static float dequant_reference(int32_t q, double o1, double d2, double step)
{
    double a = fabs((double)q), v = a == 0 ? 0.0 : a == 1 ? o1 : (a + d2) * step;
    float f = (float)v;
    return q < 0 ? -f : f;
}

/* The vector dequantiser (eight values, the selects on the float bits) gives the reference's
 * bits and counts the non-zeros, on zeros, +-1, +-2, large |q| and random values, for
 * constants at the edges wvc_dequant_fits allows (d2 = -1 and near 1, a step near the
 * float32 bound, a tiny step). */
static void wvc_dequant_vector_form_matches_reference(void)
{
    const double steps[] = {1e-30, 0.0508673, 3.0, 7.3e28};
    const double d2s[] = {-1.0, -0.25, 0.0, 0.37, 0.999};
    const double d1s[] = {-0.5, 0.0, 0.42};
    uint32_t rng = 12345;
    long bad = 0, checked = 0, badnz = 0;
    for (size_t si = 0; si < sizeof steps / sizeof *steps; si++)
        for (size_t di = 0; di < sizeof d2s / sizeof *d2s; di++)
            for (size_t oi = 0; oi < sizeof d1s / sizeof *d1s; oi++) {
                const double step = steps[si], d2 = d2s[di], o1 = (1.0 + d1s[oi]) * step;
                CHECK(wvc_dequant_fits(o1, d2, step), "constants step %g d2 %g o1 %g should fit", step, d2, o1);
                for (int round = 0; round < 64; round++) {
                    int32_t q[8], nzref = 0;
                    float out[8];
                    wvc_dq_i8 nz = {0, 0, 0, 0, 0, 0, 0, 0};
                    for (int k = 0; k < 8; k++) {
                        int32_t v;
                        rng = rng * 1664525u + 1013904223u;
                        switch ((rng >> 8) % 6) {
                        case 0: v = 0; break;
                        case 1: v = 1; break;
                        case 2: v = 2; break;
                        case 3: v = (int32_t)((rng >> 12) % 1000); break;
                        case 4: v = (int32_t)(rng >> 2); break; /* up to 2^30 */
                        default: v = (int32_t)((rng >> 16) & 0xff); break;
                        }
                        q[k] = (rng & 1) ? -v : v;
                        nzref += q[k] != 0;
                    }
                    wvc_dequant8(out, q, (float)o1, d2, step, &nz);
                    for (int k = 0; k < 8; k++) {
                        float r = dequant_reference(q[k], o1, d2, step), w = wvc_dequant1(q[k], (float)o1, d2, step);
                        uint32_t rb, ob, wb;
                        memcpy(&rb, &r, 4);
                        memcpy(&ob, &out[k], 4);
                        memcpy(&wb, &w, 4);
                        bad += rb != ob || rb != wb;
                        checked++;
                    }
                    badnz += nz[0] + nz[1] + nz[2] + nz[3] + nz[4] + nz[5] + nz[6] + nz[7] != nzref;
                }
            }
    CHECK(bad == 0, "%ld of %ld dequantised values differ from the reference's bits", bad, checked);
    CHECK(badnz == 0, "%ld groups counted their non-zeros wrong", badnz);
    CHECK(!wvc_dequant_fits(1.0, 0.0, 1e30), "a step whose largest value passes float32 must not fit");
    CHECK(!wvc_dequant_fits(1.0, -1.5, 1.0), "d2 below -1 must not fit");
    CHECK(!wvc_dequant_fits(NAN, 0.0, 1.0) && !wvc_dequant_fits(1.0, 0.0, 0.0), "NaN o1 or a zero step must not fit");
}

/* Every decoded coefficient of a version-2 file lies on its section's quantiser lattice with
 * the reference's bits, at every stop level: the finest decoded level is dequantised chunk by
 * chunk as the chunks are decoded, the others in a pass of their own, and a tile missed or
 * dequantised twice would leave values off the lattice (an int32's bits read as a float, or a
 * value scaled twice). Several chunks per level (96 x 80 x 72, tiles 32 x 32 x 16), 45 and
 * 60 dB. */
static void wvc2_decoded_values_on_the_quantiser_lattice(void)
{
    fixture F;
    const int levels = 3, save_tile = p_tile;
    CHECK(fixture_make(&F, 96, 80, 72, "db2", levels), "fixture");
    p_tile = 32;
    for (int t = 0; t < 2 && F.c; t++) {
        void *buf = NULL;
        size_t n;
        wvol_wvc_info info;
        CHECK(encode(&buf, &n, &F, t ? 60 : 45, 0, WVOL_WVC_CODER_AUTO, NULL), "encode");
        if (!buf) continue;
        CHECK(wvol_wvc_parse_info(&info, buf, n, NULL) == WVOL_OK && info.version == 2 && info.chunks > 8,
              "a version-2 file of several chunks per level");
        for (int m = 0; m < levels; m++) {
            wvol_wvc_read_options o;
            wvol_coeffs *c = NULL;
            wvol_error err;
            long off = 0, nonzero = 0;
            wvol_wvc_read_options_default(&o);
            o.stop_level = m;
            CHECK(wvol_wvc_decode(&c, buf, n, &o, NULL, &err) == WVOL_OK, "stop %d: %s", m, err.message);
            for (size_t i = 0; c && i < c->px * c->py * c->pz; i++) {
                int lev, band, s;
                size_t a, b, d;
                double o1, d2, mag;
                int32_t q;
                float r, v = c->data[i];
                wvol_coeffs_locate(c, i, &lev, &band, &a, &b, &d);
                if (band != 0 && lev <= m) continue; /* not decoded */
                for (s = 0; s < info.nsections; s++)
                    if (info.sections[s].level == lev && info.sections[s].band == band) break;
                if (s == info.nsections) {
                    off++;
                    continue;
                }
                o1 = (1.0 + (double)info.sections[s].delta1) * info.step;
                d2 = info.sections[s].delta2;
                mag = fabs((double)v);
                q = mag == 0 ? 0 : (float)mag == (float)o1 ? 1 : (int32_t)llround(mag / info.step - d2);
                if (v < 0) q = -q;
                r = dequant_reference(q, o1, d2, info.step);
                off += memcmp(&r, &v, sizeof r) != 0;
                nonzero += q != 0;
            }
            CHECK(c && off == 0, "%s dB, stop %d: %ld coefficients off the quantiser's lattice", t ? "60" : "45", m,
                  off);
            CHECK(nonzero > 0, "stop %d: some coefficients are non-zero", m);
            wvol_coeffs_destroy(c);
        }
        free(buf);
    }
    p_tile = save_tile;
    fixture_free(&F);
}

static void wvc_odd_sizes_and_flat_axes_round_trip(void)
{
    wvc_round_trip_meets_psnr_target("db2", 13, 10, 7, 2);  /* padded */
    wvc_round_trip_meets_psnr_target("haar", 16, 16, 1, 3); /* one axis not transformed */
    wvc_round_trip_meets_psnr_target("coif1", 9, 1, 1, 3);  /* a line */
}

/* Every byte of the file is covered: a refusal must name what is damaged. */
static int names_the_damage(const char *msg)
{
    return strstr(msg, "chunk") || strstr(msg, "index") || strstr(msg, "header") || strstr(msg, "magic") ||
           strstr(msg, "truncated") || strstr(msg, "version") || strstr(msg, "short") || strstr(msg, "section");
}

/* buf is refused with one of the statuses in the mask `allowed` (bit s for status s) and a
 * message naming the damaged part. */
#define ST(s) (1u << (s))
static int refused(const void *buf, size_t n, unsigned allowed, const char *what, size_t pos)
{
    wvol_coeffs *d = NULL;
    wvol_error err;
    wvol_status s;
    memset(&err, 0, sizeof err);
    s = wvol_wvc_decode(&d, buf, n, NULL, NULL, &err);
    wvol_coeffs_destroy(d);
    if (s == WVOL_OK) {
        fprintf(stderr, "%s at %zu: accepted\n", what, pos);
        return 0;
    }
    if (!(allowed & ST(s))) {
        fprintf(stderr, "%s at %zu: status %d (%s)\n", what, pos, (int)s, err.message);
        return 0;
    }
    if (!err.message[0] || !names_the_damage(err.message)) {
        fprintf(stderr, "%s at %zu: message '%s' does not name the damaged part\n", what, pos, err.message);
        return 0;
    }
    return 1;
}

static void wvc_refuses_truncation_and_bit_flips_everywhere(int version)
{
    fixture F;
    void *buf = NULL;
    uint8_t *copy;
    size_t n, pos, bad_trunc = 0, bad_flip = 0, header_bytes;
    int bit;
    CHECK(fixture_make(&F, 16, 16, 16, "db2", 2), "fixture");
    if (!F.c) return;
    g_version = version;
    CHECK(encode(&buf, &n, &F, 40, 0, WVOL_WVC_CODER_AUTO, NULL), "encode");
    g_version = 0;
    if (!buf) return;
    copy = malloc(n);
    {
        wvol_wvc_info info;
        header_bytes = wvol_wvc_parse_info(&info, buf, n, NULL) == WVOL_OK ? (size_t)info.header_bytes : n;
    }
    for (pos = 0; pos < n; pos++) {
        /* an exact-size copy so ASan sees any read past the end */
        uint8_t *t = malloc(pos ? pos : 1);
        memcpy(t, buf, pos);
        if (!refused(t, pos, ST(WVOL_ERR_FORMAT), "truncation", pos)) bad_trunc++;
        free(t);
    }
    /* one flipped bit at every byte (the bit rotates with the position), and all
     * eight bits of every header and table byte */
    for (pos = 0; pos < n; pos++)
        for (bit = 0; bit < 8; bit++) {
            if (pos >= header_bytes && bit != (int)(pos % 8)) continue;
            memcpy(copy, buf, n);
            copy[pos] ^= (uint8_t)(1u << bit);
            /* a flip in the version or flags field reads as a newer format: UNSUPPORTED */
            if (!refused(copy, n, ST(WVOL_ERR_FORMAT) | ST(WVOL_ERR_UNSUPPORTED), "bit flip", pos * 8 + bit)) bad_flip++;
        }
    CHECK(bad_trunc == 0, "%zu truncations accepted", bad_trunc);
    CHECK(bad_flip == 0, "%zu bit flips accepted", bad_flip);
    {
        /* one byte more is refused too */
        uint8_t *t = malloc(n + 1);
        memcpy(t, buf, n);
        t[n] = 0;
        CHECK(refused(t, n + 1, ST(WVOL_ERR_FORMAT), "extension", n), "trailing byte accepted");
        free(t);
    }
    free(copy);
    free(buf);
    fixture_free(&F);
}

/* Decodes t (n bytes) after `mutate`; the status must be want and the message name needle.
 * Uses t, buf, n, d and err of the calling test. */
#define TRY(label, mutate, want, needle)                                                     \
    do {                                                                                     \
        memcpy(t, buf, n);                                                                   \
        mutate;                                                                              \
        memset(&err, 0, sizeof err);                                                         \
        CHECK(wvol_wvc_decode(&d, t, n, NULL, NULL, &err) == (want), "%s: %s", label, err.message); \
        CHECK(strstr(err.message, needle) != NULL, "%s: message '%s' lacks '%s'", label, err.message, needle); \
        wvol_coeffs_destroy(d);                                                              \
        d = NULL;                                                                            \
    } while (0)

/* Rewrites the header checksum so that only the field checks can refuse. */
static void reseal(uint8_t *b)
{
    uint32_t nsec = b[12] | (b[13] << 8) | (b[14] << 16) | ((uint32_t)b[15] << 24);
    size_t h;
    uint32_t c;
    if (nsec > WVOL_WVC_MAX_SECTIONS) return;
    h = WVC_HEADER_SIZE + (size_t)nsec * WVC_SECTION_SIZE;
    c = (uint32_t)crc32(0L, b, (uInt)h);
    for (int i = 0; i < 4; i++) b[h + i] = (uint8_t)(c >> (8 * i));
}

static void put64(uint8_t *d, uint64_t v)
{
    for (int i = 0; i < 8; i++) d[i] = (uint8_t)(v >> (8 * i));
}

static void wvc_refuses_crafted_headers(void)
{
    fixture F;
    void *buf = NULL;
    uint8_t *t;
    size_t n;
    wvol_error err;
    wvol_coeffs *d = NULL;
    CHECK(fixture_make(&F, 16, 16, 16, "haar", 2), "fixture");
    if (!F.c) return;
    g_version = 1; /* the version-1 layout; version 2's own fields are crafted below */
    CHECK(encode(&buf, &n, &F, 40, 0, WVOL_WVC_CODER_CABAC, NULL), "encode");
    if (!buf) return;
    t = malloc(n);


    TRY("magic", t[1] = 'X', WVOL_ERR_FORMAT, "magic");
    TRY("newer version", (t[8] = 3, reseal(t)), WVOL_ERR_UNSUPPORTED, "newer");
    TRY("version 0", (t[8] = 0, reseal(t)), WVOL_ERR_FORMAT, "version");
    TRY("header checksum", t[40] ^= 1, WVOL_ERR_FORMAT, "checksum");
    TRY("flags", (t[10] = 1, reseal(t)), WVOL_ERR_UNSUPPORTED, "flags");
    TRY("huge nx", (put64(t + 40, (uint64_t)1 << 62), reseal(t)), WVOL_ERR_DIMS, "size");
    TRY("overflowing padded size",
        (put64(t + 40, (uint64_t)1 << 40), put64(t + 48, (uint64_t)1 << 40), put64(t + 56, (uint64_t)1 << 40),
         put64(t + 64, (uint64_t)1 << 40), put64(t + 72, (uint64_t)1 << 40), put64(t + 80, (uint64_t)1 << 40),
         reseal(t)),
        WVOL_ERR_DIMS, "overflow");
    TRY("padded smaller than size", (put64(t + 64, 8), reseal(t)), WVOL_ERR_DIMS, "padded");
    TRY("zero size", (put64(t + 40, 0), reseal(t)), WVOL_ERR_DIMS, "size");
    TRY("levels beyond size", (t[32] = 6, reseal(t)), WVOL_ERR_FORMAT, "sections");
    TRY("too many levels", (t[32] = 200, reseal(t)), WVOL_ERR_FORMAT, "levels");
    TRY("section count", (t[12] = 250, reseal(t)), WVOL_ERR_FORMAT, "sections");
    TRY("unknown wavelet", (memcpy(t + 16, "db99", 5), reseal(t)), WVOL_ERR_UNSUPPORTED, "wavelet");
    TRY("negative step", (t[152 + 7] ^= 0x80, reseal(t)), WVOL_ERR_FORMAT, "step");
    TRY("nan spacing", (put64(t + 88, 0x7ff8000000000000ull), reseal(t)), WVOL_ERR_FORMAT, "spacing");
    TRY("section order", (t[WVC_HEADER_SIZE + WVC_SECTION_SIZE + 1] = 5, reseal(t)), WVOL_ERR_FORMAT, "expected");
    TRY("section length", (t[WVC_HEADER_SIZE + 8] += 1, reseal(t)), WVOL_ERR_FORMAT, "");
    TRY("unknown coder", (t[WVC_HEADER_SIZE + 2] = 9, reseal(t)), WVOL_ERR_UNSUPPORTED, "coder");
    {
        /* levels beyond what the size allows, with a consistent section count and table:
         * a 16^3 file of 4 levels relabelled as 9^3 (still padded to 16, but 2^4 > 9) */
        fixture G;
        void *b4 = NULL;
        size_t n4;
        CHECK(fixture_make(&G, 16, 16, 16, "haar", 4), "fixture 4 levels");
        if (G.c && encode(&b4, &n4, &G, 40, 0, WVOL_WVC_CODER_AUTO, NULL)) {
            uint8_t *u = b4;
            for (int a = 0; a < 3; a++) put64(u + 40 + 8 * a, 9);
            reseal(u);
            CHECK(wvol_wvc_decode(&d, u, n4, NULL, NULL, &err) == WVOL_ERR_DIMS, "levels beyond size: %s",
                  err.message);
            CHECK(strstr(err.message, "allows") != NULL, "message: %s", err.message);
            wvol_coeffs_destroy(d);
            d = NULL;
        }
        free(b4);
        fixture_free(&G);
    }
    g_version = 0;
    free(t);
    free(buf);
    fixture_free(&F);
}

/* Version 2: the header, band table and chunk index share one CRC; reseal recomputes it. */
static size_t v2_prefix(const uint8_t *b)
{
    uint32_t nsec = b[12] | (b[13] << 8) | (b[14] << 16) | ((uint32_t)b[15] << 24);
    uint64_t nchunks = 0;
    for (int i = 7; i >= 0; i--) nchunks = (nchunks << 8) | b[208 + i];
    return 224 + (size_t)nsec * 48 + (size_t)nchunks * 32;
}

static void reseal2(uint8_t *b)
{
    size_t h = v2_prefix(b);
    uint32_t c = (uint32_t)crc32(0L, b, (uInt)h);
    for (int i = 0; i < 4; i++) b[h + i] = (uint8_t)(c >> (8 * i));
}

static void wvc2_refuses_crafted_headers_and_indexes(void)
{
    fixture F;
    void *buf = NULL;
    uint8_t *t;
    size_t n, idx, first_coded = 0;
    wvol_error err;
    wvol_coeffs *d = NULL;
    wvol_wvc_info info;
    CHECK(fixture_make(&F, 24, 20, 16, "db2", 2), "fixture");
    if (!F.c) return;
    CHECK(encode(&buf, &n, &F, 50, 0, WVOL_WVC_CODER_AUTO, NULL), "encode");
    if (!buf) return;
    CHECK(wvol_wvc_parse_info(&info, buf, n, &err) == WVOL_OK && info.version == 2 && info.chunks > 1,
          "a version-2 file with several chunks: %s", err.message);
    t = malloc(n);
    idx = 224 + (size_t)info.nsections * 48;
    /* the first chunk with a payload */
    for (size_t k = 0; k < info.chunks; k++) {
        const uint8_t *e = (const uint8_t *)buf + idx + 32 * k;
        if (e[8] | e[9] | e[10] | e[11]) {
            first_coded = k;
            break;
        }
    }
    TRY("index checksum", t[idx + 17] ^= 4, WVOL_ERR_FORMAT, "index checksum");
    TRY("tile too small", (t[33] = 2, reseal2(t)), WVOL_ERR_FORMAT, "tile");
    TRY("tile depth too large", (t[34] = 9, reseal2(t)), WVOL_ERR_FORMAT, "tile");
    TRY("tile changed", (t[33] = 3, reseal2(t)), WVOL_ERR_FORMAT, "chunks");
    TRY("reserved", (t[35] = 1, reseal2(t)), WVOL_ERR_FORMAT, "reserved");
    TRY("chunk offset", (t[idx + 32 * first_coded] += 1, reseal2(t)), WVOL_ERR_FORMAT, "index: chunk");
    TRY("chunk size", (t[idx + 32 * first_coded + 8] += 1, reseal2(t)), WVOL_ERR_FORMAT, "");
    TRY("chunk non-zeros", (t[idx + 32 * first_coded + 20] += 1, reseal2(t)), WVOL_ERR_FORMAT, "non-zero");
    TRY("chunk max is NaN", (t[idx + 32 * first_coded + 19] = 0x7f, t[idx + 32 * first_coded + 18] = 0xc0, reseal2(t)),
         WVOL_ERR_FORMAT, "index: chunk");
    TRY("band table level", (t[224 + 48 + 0] = 7, reseal2(t)), WVOL_ERR_FORMAT, "band table");
    TRY("band offset", (t[224 + 48 + 19] = 0x7f, reseal2(t)), WVOL_ERR_FORMAT, "band table");
    {
        /* a chunk's payload with a valid CRC but an unknown mode: named by the chunk */
        const uint8_t *e = (const uint8_t *)buf + idx + 32 * first_coded;
        uint64_t off = 0;
        uint32_t len = e[8] | (e[9] << 8) | (e[10] << 16) | ((uint32_t)e[11] << 24), c;
        for (int i = 7; i >= 0; i--) off = (off << 8) | e[i];
        memcpy(t, buf, n);
        t[off] = 5; /* the first mode after the known ones */
        c = (uint32_t)crc32(0L, t + off, len);
        for (int i = 0; i < 4; i++) t[idx + 32 * first_coded + 12 + i] = (uint8_t)(c >> (8 * i));
        reseal2(t);
        CHECK(wvol_wvc_decode(&d, t, n, NULL, NULL, &err) == WVOL_ERR_FORMAT && strstr(err.message, "chunk") &&
                  strstr(err.message, "mode"),
              "unknown chunk mode: %s", err.message);
        wvol_coeffs_destroy(d);
        d = NULL;
    }
    free(t);
    free(buf);
    fixture_free(&F);
}

/* Payload bytes replaced with noise and the section checksums recomputed: the
 * coders themselves must refuse or decode something, never read out of bounds. */
static void wvc_survives_garbage_payloads_with_valid_checksums(int version)
{
    fixture F;
    void *buf = NULL;
    size_t n;
    wvol_wvc_info info;
    uint8_t *t;
    int trial, ok = 0, refused_n = 0;
    uint32_t seed = 12345;
    CHECK(fixture_make(&F, 16, 16, 16, "db2", 2), "fixture");
    if (!F.c) return;
    g_version = version;
    p_tile = 8; /* version 2: several chunks */
    CHECK(encode(&buf, &n, &F, 50, 0, WVOL_WVC_CODER_AUTO, NULL), "encode");
    g_version = 0;
    p_tile = 0;
    if (!buf || wvol_wvc_parse_info(&info, buf, n, NULL) != WVOL_OK) return;
    t = malloc(n);
    for (trial = 0; trial < 400; trial++) {
        int s;
        wvol_coeffs *d = NULL;
        memcpy(t, buf, n);
        if (version == 2) {
            /* every chunk's payload: noise, then its CRC recomputed in the index */
            size_t idx = 224 + (size_t)info.nsections * 48;
            for (uint64_t k = 0; k < info.chunks; k++) {
                uint8_t *e = t + idx + 32 * k;
                uint64_t off = 0;
                uint32_t len = e[8] | (e[9] << 8) | (e[10] << 16) | ((uint32_t)e[11] << 24), c;
                for (int i = 7; i >= 0; i--) off = (off << 8) | e[i];
                for (uint32_t q = 0; q < len; q++) {
                    seed = seed * 1664525u + 1013904223u;
                    if ((seed >> 24) < (uint32_t)(trial % 64) || trial % 3 == 0) t[off + q] = (uint8_t)(seed >> 16);
                }
                c = (uint32_t)crc32(0L, t + off, len);
                for (int i = 0; i < 4; i++) e[12 + i] = (uint8_t)(c >> (8 * i));
            }
            reseal2(t);
        }
        for (s = 0; s < info.nsections && version == 1; s++) {
            wvol_wvc_section *S = &info.sections[s];
            uint64_t k;
            uint32_t c;
            uint8_t *e = t + WVC_HEADER_SIZE + (size_t)s * WVC_SECTION_SIZE;
            for (k = 0; k < S->bytes; k++) {
                seed = seed * 1664525u + 1013904223u;
                if ((seed >> 24) < (uint32_t)(trial % 64) || trial % 3 == 0) t[S->offset + k] = (uint8_t)(seed >> 16);
            }
            c = (uint32_t)crc32(0L, t + S->offset, (uInt)S->bytes);
            for (int i = 0; i < 4; i++) e[4 + i] = (uint8_t)(c >> (8 * i));
        }
        if (version == 1) reseal(t);
        if (wvol_wvc_decode(&d, t, n, NULL, NULL, NULL) == WVOL_OK) {
            ok++;
            for (size_t i = 0; i < d->px * d->py * d->pz; i++)
                if (!isfinite(d->data[i])) {
                    CHECK(0, "non-finite coefficient decoded");
                    break;
                }
        } else {
            refused_n++;
        }
        wvol_coeffs_destroy(d);
    }
    CHECK(refused_n > 0, "garbage was never refused (%d decoded)", ok);
    free(t);
    free(buf);
    fixture_free(&F);
}

static void wvc_files_are_atomic_and_checked(void)
{
    fixture F;
    void *buf = NULL;
    size_t n;
    char dir[] = "/tmp/wvc_test_XXXXXX", path[256], bad[256];
    wvol_error err;
    wvol_wvc_info info;
    wvol_coeffs *d = NULL;
    wvol_wvc_read_options o;
    FILE *fp;
    CHECK(mkdtemp(dir) != NULL, "mkdtemp");
    snprintf(path, sizeof path, "%s/a.wvc", dir);
    snprintf(bad, sizeof bad, "%s/no/such/dir/a.wvc", dir);
    CHECK(fixture_make(&F, 16, 16, 16, "db2", 3), "fixture");
    if (!F.c) return;
    CHECK(encode(&buf, &n, &F, 45, 0, WVOL_WVC_CODER_AUTO, NULL), "encode");
    CHECK(wvol_wvc_save(path, buf, n, &err) == WVOL_OK, "save: %s", err.message);
    CHECK(wvol_wvc_save(bad, buf, n, &err) == WVOL_ERR_IO, "save into a missing folder");
    CHECK(wvol_wvc_read_info(&info, path, &err) == WVOL_OK, "read_info: %s", err.message);
    CHECK(info.file_bytes == n && info.levels == 3 && info.nx == 16 && !strcmp(info.filter, "db2"), "info");
    wvol_wvc_read_options_default(&o);
    o.stop_level = 2;
    CHECK(wvol_wvc_read(&d, path, &o, &info, &err) == WVOL_OK, "read stop 2: %s", err.message);
    wvol_coeffs_destroy(d);
    d = NULL;
    CHECK(wvol_wvc_read(&d, path, NULL, NULL, &err) == WVOL_OK, "read: %s", err.message);
    wvol_coeffs_destroy(d);
    d = NULL;
    /* truncated on disk: refused even when only coarse levels are asked for */
    CHECK(truncate(path, (off_t)n - 1) == 0, "truncate");
    CHECK(wvol_wvc_read(&d, path, &o, NULL, &err) == WVOL_ERR_FORMAT, "truncated file read");
    CHECK(strstr(err.message, "a.wvc") != NULL, "message names the file: %s", err.message);
    CHECK(wvol_wvc_read(&d, "/nonexistent/x.wvc", NULL, NULL, &err) == WVOL_ERR_IO, "missing file");
    /* nothing but the one file in the folder: no temporary left behind */
    snprintf(bad, sizeof bad, "ls %s | wc -l", dir);
    fp = popen(bad, "r");
    if (fp) {
        int count = -1;
        CHECK(fscanf(fp, "%d", &count) == 1 && count == 1, "files in the folder: %d", count);
        pclose(fp);
    }
    remove(path);
    rmdir(dir);
    free(buf);
    fixture_free(&F);
}

static void wvc_refuses_bad_parameters(void)
{
    fixture F;
    wvol_wvc_params p;
    void *buf = NULL;
    size_t n;
    wvol_error err;
    CHECK(fixture_make(&F, 16, 16, 16, "haar", 2), "fixture");
    if (!F.c) return;
    wvol_wvc_params_default(&p);
    p.value_max = 1;
    CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_ERR_ARG, "no step, no target");
    p.step = NAN;
    CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_ERR_ARG, "nan step");
    p.step = 0.1;
    p.rounding = 0.7;
    CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_ERR_ARG, "rounding");
    p.rounding = 0.38;
    p.step = 1e-30;
    CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_ERR_ARG, "step too small for the range");
    {
        /* all-zero coefficients: any target is met, the file holds empty sections */
        wvol_coeffs *z = NULL, *d = NULL;
        void *zb = NULL;
        size_t zn = 0;
        wvol_wvc_params q = p;
        CHECK(wvol_coeffs_clone(&z, F.c, NULL) == WVOL_OK, "clone");
        if (z) {
            memset(z->data, 0, z->px * z->py * z->pz * sizeof(float));
            q.step = 0;
            q.target_sse = 1;
            CHECK(wvol_wvc_encode(&zb, &zn, z, &q, NULL, &err) == WVOL_OK, "zeros: %s", err.message);
            CHECK(zb && wvol_wvc_decode(&d, zb, zn, NULL, NULL, &err) == WVOL_OK, "zeros decode");
            if (d) {
                size_t i, bad = 0;
                for (i = 0; i < d->px * d->py * d->pz; i++) bad += d->data[i] != 0;
                CHECK(bad == 0, "zeros decoded as %zu non-zeros", bad);
            }
        }
        wvol_coeffs_destroy(d);
        wvol_coeffs_destroy(z);
        free(zb);
    }
    p.step = 1e39; /* the limit is FLT_MAX: a larger step would zero every float32 coefficient */
    CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_ERR_ARG, "step above the format's limit");
    p.step = 0.1;
    F.c->spacing[1] = 0;
    CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_ERR_ARG, "zero spacing");
    F.c->spacing[1] = 1;
    F.c->data[5] = NAN;
    p.step = 0.1;
    CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_ERR_NONFINITE, "nan coefficient");
    CHECK(buf == NULL, "no output on failure");
    F.c->data[5] = 0;
    CHECK(wvol_wvc_encode(NULL, &n, F.c, &p, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "output pointer"),
          "NULL buffer pointer: %s", err.message);
    CHECK(wvol_wvc_encode(&buf, NULL, F.c, &p, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "output pointer"),
          "NULL size pointer: %s", err.message);
    {
        /* only versions 1 and 2 (0: the default) are written: another would be mislabelled */
        const int bad_versions[] = {3, 99, -1};
        for (int i = 0; i < 3; i++) {
            p.version = bad_versions[i];
            CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_ERR_ARG &&
                      strstr(err.message, "format version"),
                  "version %d refused: %s", bad_versions[i], err.message);
            CHECK(buf == NULL, "no output for version %d", bad_versions[i]);
        }
        p.version = 0;
    }
    {
        wvol_wvc_cache_stats st;
        memset(&st, 0xff, sizeof st);
        wvol_wvc_file_stats(NULL, &st);
        CHECK(st.budget == 0 && st.hits == 0, "stats of no file are zero");
        wvol_wvc_file_stats(NULL, NULL); /* does nothing */
    }
    fixture_free(&F);
}

/* The fuzz corpus doubles as golden files: valid_* decode, damaged_* are refused.
 * A change of the coder that breaks them needs a new format version (and a new corpus). */
/* The corpus's small mode-4 file fits the fuzzer's 4096-byte inputs (scripts/fuzz.sh): `wvol
 * synth skull --size 16 --noise 20`, `--step 100 --levels 2 --tile 8 --coder rans4`. */
static void wvc_corpus_files_decode_or_are_refused(void)
{
    const char *root = getenv("WVOL_SOURCE_DIR");
    const char *names[] = {"valid_haar_8_cabac.wvc", "valid_db2_8x8x4_zstd.wvc", "valid_coif1_4x4x1_auto.wvc",
                           "valid_db2_8x6x5_padded.wvc", "valid_bl3_8_3levels.wvc", "damaged_truncated.wvc",
                           "damaged_bitflip_payload.wvc", "damaged_magic.wvc", "damaged_version.wvc",
                           "valid_v2_db2_8.wvc", "valid_v2_haar_12x10x9_tiles.wvc",
                           "valid_v2_coif1_16x16x1_zstd.wvc", "damaged_v2_bitflip_chunk.wvc",
                           "damaged_v2_bitflip_index.wvc", "valid_v2_mode1_skull32_step600.wvc",
                           "valid_v2_mode2_skull32_step600.wvc", "valid_v2_mode3_skull32_step600.wvc",
                           "valid_v2_mode4_skull32_step600.wvc", "valid_v2_mode4_skull16_step100.wvc",
                           "valid_v2_mode4_packed_skull16_step100.wvc"};
    char path[1024];
    size_t i;
    if (!root) {
        printf("test_wvc: WVOL_SOURCE_DIR not set, corpus check skipped\n");
        return;
    }
    for (i = 0; i < sizeof names / sizeof names[0]; i++) {
        wvol_coeffs *c = NULL;
        wvol_error err;
        wvol_status st;
        snprintf(path, sizeof path, "%s/tests/fuzz/corpus/%s", root, names[i]);
        st = wvol_wvc_read(&c, path, NULL, NULL, &err);
        if (names[i][0] == 'v')
            CHECK(st == WVOL_OK, "%s: %s", names[i], err.message);
        else
            /* malformed content (damaged_version says 2 over a version-1 body, made before
             * version 2 existed: read as a version-2 header, refused as malformed) */
            CHECK(st == WVOL_ERR_FORMAT, "%s: status %d", names[i], (int)st);
        wvol_coeffs_destroy(c);
    }
}

/* CRC-32 of the float coefficients the mode-1 corpus file decodes to (see below). */
#define MODE1_DECODED_CRC 0xc9516f29UL

/* Files written before the block flags (chunk mode 1) still decode, to the values the
 * current coders (modes 2 and 3) give for the same quantised coefficients. The corpus files
 * are `wvol synth skull --size 32 --noise 20` compressed with `--step 600 --tile 8
 * --levels 2 --coder cabac`, by the encoder before mode 2 and by a current one, and with
 * `--coder rans` (mode 3 but for the low-pass cube's level, mode 2) and `--coder rans4` (mode 4
 * likewise) (the same quantised
 * values: the same transform and step). Decoding involves no transform,
 * only integers and one double rounding per value, so the values do not depend on the
 * build: the CRC-32 of the mode-1 file's decoded coefficients is pinned (computed when
 * the file was made). */
static void wvc2_mode1_files_decode_to_the_same_values(void)
{
    const char *root = getenv("WVOL_SOURCE_DIR");
    const char *names[4] = {"valid_v2_mode1_skull32_step600.wvc", "valid_v2_mode2_skull32_step600.wvc",
                            "valid_v2_mode3_skull32_step600.wvc", "valid_v2_mode4_skull32_step600.wvc"};
    wvol_coeffs *d[4] = {NULL, NULL, NULL, NULL};
    wvol_error err;
    if (!root) {
        printf("test_wvc: WVOL_SOURCE_DIR not set, mode-1 file check skipped\n");
        return;
    }
    for (int k = 0; k < 4; k++) {
        char path[1024];
        uint8_t raw[16384];
        size_t got;
        int modes[5];
        FILE *fp;
        snprintf(path, sizeof path, "%s/tests/fuzz/corpus/%s", root, names[k]);
        fp = fopen(path, "rb");
        got = fp ? fread(raw, 1, sizeof raw, fp) : 0;
        if (fp) fclose(fp);
        /* mode 1 or 2 alone; mode 3 or 4 with mode 2 for the low-pass cube's level, no mode 1 */
        CHECK(got > 0 && got < sizeof raw && wvc_chunk_modes(raw, got, modes) && modes[1 + k] > 0 &&
                  modes[k == 0 ? 2 : 1] == 0 && (k == 2 || modes[3] == 0) && (k == 3 || modes[4] == 0),
              "%s holds mode-%d chunks", names[k], 1 + k);
        CHECK(wvol_wvc_read(&d[k], path, NULL, NULL, &err) == WVOL_OK, "%s: %s", names[k], err.message);
    }
    if (d[0] && d[1]) {
        size_t count = d[0]->px * d[0]->py * d[0]->pz, nz = 0;
        uLong crc = crc32(0L, (const Bytef *)d[0]->data, (uInt)(count * sizeof(float)));
        CHECK(d[1]->px == d[0]->px && d[1]->py == d[0]->py && d[1]->pz == d[0]->pz, "grids");
        CHECK(!memcmp(d[0]->data, d[1]->data, count * sizeof(float)), "mode 1 and mode 2 decode differently");
        CHECK(d[2] && d[2]->px == d[0]->px && d[2]->py == d[0]->py && d[2]->pz == d[0]->pz &&
                  !memcmp(d[0]->data, d[2]->data, count * sizeof(float)),
              "mode 1 and mode 3 decode differently");
        CHECK(d[3] && d[3]->px == d[0]->px && d[3]->py == d[0]->py && d[3]->pz == d[0]->pz &&
                  !memcmp(d[0]->data, d[3]->data, count * sizeof(float)),
              "mode 1 and mode 4 decode differently");
        for (size_t i = 0; i < count; i++) nz += d[0]->data[i] != 0;
        CHECK(nz > 100 && nz < count / 2, "a meaningful file: %zu of %zu non-zero", nz, count);
        CHECK(crc == MODE1_DECODED_CRC, "mode-1 file decodes to other values: CRC-32 %08lx", (unsigned long)crc);
    }
    for (int k = 0; k < 4; k++) wvol_coeffs_destroy(d[k]);
}

/* Nearly empty pyramids: all-zero chunks, a chunk with one non-zero coefficient (at a
 * block's or a band's far corner too, where the block and group flags are implied), and
 * two or three in one chunk. Integer multiples of the step round-trip exactly (the
 * reconstruction offsets are then 0), every other coefficient decodes to 0, and the
 * index counts what is there. Odd band extents (10 x 9 x 7 at level 1) leave partial
 * groups and blocks at the far edges. */
/* --coder compact codes a chunk's bands apart (chunk mode 0, each band CABAC with its own model
 * or zstd) where that is smaller than one shared stream: here band 1 of level 1 holds rows that
 * repeat (zstd's matches take them almost for free) and band 7 scattered values (CABAC's
 * ground), so the level's chunk is mode 0 with one band of each kind; the coefficients, all
 * multiples of the step, decode exactly. */
/* One value of the quantiser kernels' test rows: zeros (both signs), values below the dead
 * zone, values a hair either side of a decision (|c| / step + f at an integer), large ones
 * beyond the clamp of |q|, subnormals, a coarse noise. */
static float quant_value(unsigned *rng, double step, double f)
{
    unsigned r = (*rng = *rng * 1103515245u + 12345u) >> 8;
    double u = (double)(r & 0xFFFF) / 65536.0, k = (double)((r >> 16) & 7);
    float s = (r & 0x10000) ? -1.0f : 1.0f;
    switch (r % 9) {
    case 0: return (r & 2) ? 0.0f : -0.0f;
    case 1: return s * (float)(u * (1.0 - f) * step);                     /* dead zone */
    case 2: return s * nextafterf((float)((k + 1 - f) * step), 0.0f);       /* just below a decision */
    case 3: return s * nextafterf((float)((k + 1 - f) * step), INFINITY);   /* just above */
    case 4: return s * (float)(u * 2e9 * step);                             /* |q| clamped */
    case 5: return s * 1e-40f * (float)u;                                   /* subnormal */
    default: return s * (float)(u * u * 40.0 * step);
    }
}

/* The x86-64-v4 kernel of the quantiser's sums (where the CPU has it) against row_kernel as
 * the compiler builds it for the same CPU: the same sums bit for bit, the same largest |c|,
 * the same quantised values, and in the sparse form the same values written and nothing else;
 * rows of every length from 0 to 70 and a few longer ones, zero runs, both writers. On a CPU
 * without x86-64-v4 both are row_kernel and the check holds trivially. */
static void wvc_quant_kernels_agree(void)
{
    const double steps[3] = {8.484323856428156, 0.37, 269.34};
    const double fs[3] = {0.38, 0.5, 0.0};
    unsigned rng = 12345u;
    float row[1100];
    int32_t q1[1100], q2[1100];
    int bad = 0;
    for (int si = 0; si < 3; si++)
        for (int fi = 0; fi < 3; fi++)
            for (size_t n = 0; n < 1100; n = n < 70 ? n + 1 : n * 2 + 37) {
                double t1[8], t2[8];
                float a1, a2;
                /* a few rows with long zero runs (the dead zone's fast path) */
                int runs = (int)(n % 3);
                for (size_t x = 0; x < n; x++) {
                    row[x] = quant_value(&rng, steps[si], fs[fi]);
                    if (runs && (x / 8) % (size_t)(runs + 1)) row[x] = 0.25f * (float)((1.0 - fs[fi]) * steps[si]);
                }
                memset(q1, 0x5a, sizeof q1);
                memset(q2, 0x5a, sizeof q2);
                a1 = wvol__wvc_row_stats(t1, row, q1, n, steps[si], fs[fi]);
                a2 = wvol__wvc_row_stats_generic(t2, row, q2, n, steps[si], fs[fi]);
                bad += memcmp(t1, t2, sizeof t1) != 0 || memcmp(&a1, &a2, sizeof a1) != 0 ||
                       memcmp(q1, q2, sizeof q1) != 0;
                for (int sparse = 0; sparse < 2; sparse++) {
                    sec_stats s1, s2;
                    const size_t ex = n / 3 + 1, ey = 2, nz = 2, sy = ex + 3, sz = 3 * sy;
                    if (nz * sz > 1100) continue;
                    memset(q1, 0, sizeof q1);
                    memset(q2, 0, sizeof q2);
                    wvol__wvc_rows_stats(&s1, row, q1, ex, ey, nz, sy, sz, steps[si], fs[fi], sparse);
                    wvol__wvc_rows_stats_generic(&s2, row, q2, ex, ey, nz, sy, sz, steps[si], fs[fi], sparse);
                    bad += memcmp(&s1, &s2, sizeof s1) != 0 || memcmp(q1, q2, sizeof q1) != 0;
                }
            }
    CHECK(bad == 0, "quantiser kernels: %d rows differ between the x86-64-v4 kernel and the generic one", bad);
}

static void wvc2_bands_coded_apart_round_trip(void)
{
    const wvol_filter *f;
    wvol_error err;
    wvol_coeffs *c = NULL, *d = NULL;
    wvol_wvc_params p;
    wvol_wvc_info info;
    void *buf = NULL;
    size_t n = 0, count, h, x, y, z, bad = 0, mixed = 0;
    uint64_t rng = 777;
    CHECK(wvol_filter_get(&f, "haar", &err) == WVOL_OK, "haar");
    if (wvol_coeffs_create(&c, f, 2, 32, 32, 32, &err) != WVOL_OK) {
        CHECK(0, "coeffs: %s", err.message);
        return;
    }
    count = c->px * c->py * c->pz;
    h = c->px / 2;
    c->data[0] = 400;
    for (z = 0; z < h; z++)
        for (y = 0; y < h; y++)
            for (x = 0; x < h; x++) {
                /* band 1 (x odd half): the same row again and again */
                c->data[(h + x) + c->px * (y + c->py * z)] = (float)(8 * (1 + (int)((x * 7) % 5)));
                /* band 7 (all odd halves): a few scattered values */
                if (fixture_urand(&rng) < 0.06)
                    c->data[(h + x) + c->px * ((h + y) + c->py * (h + z))] =
                        (float)((fixture_urand(&rng) < 0.5 ? -8 : 8) * (1 + (int)(fixture_urand(&rng) * 30)));
            }
    wvol_wvc_params_default(&p);
    p.value_min = -500;
    p.value_max = 500;
    p.step = 8;
    p.coder = WVOL_WVC_CODER_COMPACT;
    p.tile = p.tile_z = 16; /* one chunk for level 1's bands */
    CHECK(wvol_wvc_encode(&buf, &n, c, &p, NULL, &err) == WVOL_OK, "encode: %s", err.message);
    if (buf) { /* the level-1 chunk: mode 0 with a CABAC band and a zstd band */
        const uint8_t *b = buf;
        uint32_t nsec;
        uint64_t nchunks;
        memcpy(&nsec, b + 12, 4);
        memcpy(&nchunks, b + 208, 8);
        for (uint64_t i = 0; i < nchunks && 224 + (size_t)nsec * 48 + (i + 1) * 32 <= n; i++) {
            const uint8_t *e = b + 224 + (size_t)nsec * 48 + i * 32;
            uint64_t off;
            uint32_t bytes;
            int cabac = 0, zstd = 0;
            memcpy(&off, e, 8);
            memcpy(&bytes, e + 8, 4);
            if (!bytes || off + 8 > n || b[off] != 0) continue;
            for (int k = 1; k <= 7; k++) {
                cabac += b[off + k] == WVOL_WVC_CODER_CABAC;
                zstd += b[off + k] == WVOL_WVC_CODER_ZSTD;
            }
            mixed += cabac > 0 && zstd > 0;
        }
    }
    CHECK(mixed == 1, "%zu mode-0 chunks with both CABAC and zstd bands (1 expected)", mixed);
    CHECK(buf && wvol_wvc_decode(&d, buf, n, NULL, &info, &err) == WVOL_OK, "decode: %s", err.message);
    if (d) {
        for (size_t i = 0; i < count; i++) bad += d->data[i] != c->data[i];
        CHECK(bad == 0, "%zu coefficients differ", bad);
    }
    free(buf);
    wvol_coeffs_destroy(c);
    wvol_coeffs_destroy(d);
}

static void wvc2_sparse_chunks_round_trip(void)
{
    const wvol_filter *f;
    wvol_error err;
    uint64_t rng = 12345;
    CHECK(wvol_filter_get(&f, "haar", &err) == WVOL_OK, "haar");
    for (int trial = 0; trial < 60; trial++) {
        wvol_coeffs *c = NULL, *d = NULL;
        wvol_wvc_params p;
        wvol_wvc_info info;
        void *buf = NULL;
        size_t n = 0, count, pos[3];
        int k = 1 + trial % 3;
        if (wvol_coeffs_create(&c, f, 2, 20, 18, 14, &err) != WVOL_OK) {
            CHECK(0, "coeffs: %s", err.message);
            return;
        }
        count = c->px * c->py * c->pz;
        c->data[0] = 64; /* the low-pass cube's corner: a range for the header */
        for (int j = 0; j < k; j++) {
            size_t i;
            if (trial < 8 && j == 0) {
                /* the far corner of each band of level 1: the last coefficient of a partial block */
                int band = trial % 8 ? trial % 8 : 7;
                pos[0] = (band & 1 ? c->px / 2 : 0) + c->px / 2 - 1;
                pos[1] = (band & 2 ? c->py / 2 : 0) + c->py / 2 - 1;
                pos[2] = (band & 4 ? c->pz / 2 : 0) + c->pz / 2 - 1;
            } else {
                for (int a = 0; a < 3; a++) pos[a] = (size_t)(fixture_urand(&rng) * (a == 0 ? c->px : a == 1 ? c->py : c->pz));
                if (j > 0) /* near the first: the same chunk, often the same block */
                    for (int a = 0; a < 3; a++) pos[a] = pos[a] < 2 ? pos[a] + 1 : pos[a] - 1;
            }
            i = pos[0] + c->px * (pos[1] + c->py * pos[2]);
            c->data[i] = (float)((fixture_urand(&rng) < 0.5 ? -1 : 1) * (1 + (int)(fixture_urand(&rng) * 40)) * 8);
        }
        wvol_wvc_params_default(&p);
        p.value_min = -500;
        p.value_max = 500;
        p.step = 8;
        p.coder = trial % 2 ? WVOL_WVC_CODER_CABAC : WVOL_WVC_CODER_AUTO;
        p.tile = p.tile_z = 8;
        CHECK(wvol_wvc_encode(&buf, &n, c, &p, NULL, &err) == WVOL_OK, "trial %d encode: %s", trial, err.message);
        CHECK(buf && wvol_wvc_decode(&d, buf, n, NULL, &info, &err) == WVOL_OK, "trial %d decode: %s", trial,
              err.message);
        if (d) {
            size_t nz = 0, bad = 0;
            for (size_t i = 0; i < count; i++) {
                nz += c->data[i] != 0;
                bad += d->data[i] != c->data[i];
            }
            CHECK(bad == 0, "trial %d: %zu coefficients differ", trial, bad);
            CHECK(info.nonzero == nz, "trial %d: %llu non-zero in the file, %zu given", trial,
                  (unsigned long long)info.nonzero, nz);
        }
        free(buf);
        wvol_coeffs_destroy(c);
        wvol_coeffs_destroy(d);
    }
}


/* The slab writer fed as a streamed transform would feed it (finest level first, a
 * few rows at a time, each coarser level lagging behind the finer one) writes the
 * same bytes as wvol_wvc_encode from the whole pyramid, and every put out of order is
 * refused. in_place: the writer quantises the rows where they lie (a copy of the
 * pyramid, which it overwrites), the same bytes; rows put where the first rows' layout
 * does not put them are refused. */
/* The writer's planes of level 1's rows from 0, in the pyramid `room` laid out as c's. */
static void level1_planes(wvc2_planes *pl, const wvol_coeffs *c, float *room, int levels)
{
    memset(pl, 0, sizeof *pl);
    for (int b = levels == 1 ? 0 : 1; b < 8; b++) {
        size_t o[3];
        for (int a = 0; a < 3; a++) {
            size_t pa = a == 0 ? c->px : a == 1 ? c->py : c->pz;
            o[a] = ((b >> a) & 1) && pa > 1 ? pa >> 1 : 0;
        }
        pl->band[b] = room + o[0] + c->px * (o[1] + c->py * o[2]);
        pl->sy[b] = c->px;
        pl->sz[b] = c->px * c->py;
    }
}

/* rows: 0 the writer's own int32 rows, 1 quantised in place, 2 the writer's own int16 rows
 * (wvc2_header.narrow, every level: the values here fit) */
static void wvc2_streamed_rows_give_the_same_bytes(const char *wavelet, size_t nx, size_t ny, size_t nz, int levels,
                                                   int tile, int tile_z, int rows_kind)
{
    const int in_place = rows_kind == 1;
    fixture F;
    void *dense = NULL, *streamed = NULL;
    size_t nd = 0, ns = 0, next[WVOL_WVC_MAX_LEVELS + 1] = {0}, ez[WVOL_WVC_MAX_LEVELS + 1];
    wvol_wvc_params p;
    wvol_wvc_report rep;
    wvol_error err;
    wvc2_header h;
    wvc2_writer *w = NULL;
    uint64_t rng = 12345;
    int done = 0;
    float *room;
    CHECK(fixture_make(&F, nx, ny, nz, wavelet, levels), "fixture");
    if (!F.c) return;
    room = F.c->data;
    if (in_place) {
        room = malloc(F.c->px * F.c->py * F.c->pz * sizeof *room);
        CHECK(room != NULL, "out of memory");
        if (!room) {
            fixture_free(&F);
            return;
        }
        memcpy(room, F.c->data, F.c->px * F.c->py * F.c->pz * sizeof *room);
    }
    wvol_wvc_params_default(&p);
    p.value_min = F.vmin;
    p.value_max = F.vmax;
    p.target_sse = wvol_wvc_sse_for_psnr(45, (double)(nx * ny * nz), F.vmin, F.vmax);
    p.tile = tile;
    p.tile_z = tile_z;
    CHECK(wvol_wvc_encode(&dense, &nd, F.c, &p, &rep, &err) == WVOL_OK, "dense: %s", err.message);
    /* the same step without the slack spending (a streamed encoder sees no second pass) */
    p.step = rep.step;
    p.target_sse = 0;
    free(dense);
    CHECK(wvol_wvc_encode(&dense, &nd, F.c, &p, &rep, &err) == WVOL_OK, "dense, fixed step: %s", err.message);
    wvol__wvc2_header_default(&h);
    strcpy(h.filter, F.c->filter->name);
    h.levels = levels;
    h.nx = F.c->nx, h.ny = F.c->ny, h.nz = F.c->nz;
    h.px = F.c->px, h.py = F.c->py, h.pz = F.c->pz;
    memcpy(h.spacing, F.c->spacing, sizeof h.spacing);
    memcpy(h.origin, F.c->origin, sizeof h.origin);
    h.value_min = F.vmin, h.value_max = F.vmax;
    h.step = rep.step;
    h.tile = tile, h.tile_z = tile_z;
    h.in_place = in_place;
    if (rows_kind == 2) {
        double mx = 0;
        for (size_t i = 0; i < F.c->px * F.c->py * F.c->pz; i++) mx = fmax(mx, fabs((double)F.c->data[i]));
        CHECK(mx / rep.step < 30000, "the values fit 16 bits (max |c| / step %g)", mx / rep.step);
        h.narrow = ~0u << 1;
    }
    if (in_place && F.c->pz > 2) {
        /* level 1's second row put one float off its place */
        wvc2_planes pl;
        CHECK(wvol__wvc2_writer_open_mem(&w, &h, &err) == WVOL_OK, "open: %s", err.message);
        level1_planes(&pl, F.c, room, levels);
        CHECK(w && wvol__wvc2_writer_put(w, 1, 0, 1, &pl, &err) == WVOL_OK, "first row in place: %s", err.message);
        for (int b = 0; b < 8; b++)
            if (pl.band[b]) pl.band[b] += pl.sz[b] + 1;
        CHECK(w && wvol__wvc2_writer_put(w, 1, 1, 1, &pl, &err) == WVOL_ERR_ARG && strstr(err.message, "in place"),
              "a row off its place is refused: %s", err.message);
        wvol__wvc2_writer_abort(w);
        memcpy(room, F.c->data, F.c->px * F.c->py * F.c->pz * sizeof *room);
    }
    CHECK(wvol__wvc2_writer_open_mem(&w, &h, &err) == WVOL_OK, "open: %s", err.message);
    for (int m = 1; m <= levels; m++) ez[m] = F.c->pz > 1 ? F.c->pz >> m : 1;
    while (w && !done) {
        done = 1;
        for (int m = 1; m <= levels; m++) {
            size_t want, rows;
            wvc2_planes pl;
            if (next[m] >= ez[m]) continue;
            done = 0;
            /* a coarser row z needs the finer rows up to about 2z + filter length */
            if (m > 1 && next[m - 1] < ez[m - 1] && next[m - 1] < 2 * next[m] + 4) continue;
            rng = rng * 6364136223846793005ull + 1442695040888963407ull;
            rows = 1 + (size_t)(rng >> 62);
            want = next[m] + rows < ez[m] ? rows : ez[m] - next[m];
            memset(&pl, 0, sizeof pl);
            for (int b = m == levels ? 0 : 1; b < 8; b++) {
                size_t o[3];
                for (int a = 0; a < 3; a++) {
                    size_t pa = a == 0 ? F.c->px : a == 1 ? F.c->py : F.c->pz;
                    o[a] = ((b >> a) & 1) && pa > 1 ? pa >> m : 0;
                }
                o[2] += next[m];
                pl.band[b] = room + o[0] + F.c->px * (o[1] + F.c->py * o[2]);
                pl.sy[b] = F.c->px;
                pl.sz[b] = F.c->px * F.c->py;
            }
            if (wvol__wvc2_writer_put(w, m, next[m], want, &pl, &err) != WVOL_OK) {
                CHECK(0, "put level %d rows %zu+%zu: %s", m, next[m], want, err.message);
                wvol__wvc2_writer_abort(w);
                w = NULL;
                break;
            }
            next[m] += want;
        }
    }
    if (w) {
        wvc2_planes pl;
        memset(&pl, 0, sizeof pl);
        CHECK(wvol__wvc2_writer_put(w, 1, 0, 1, &pl, &err) == WVOL_ERR_ARG, "a row again is refused");
        CHECK(wvol__wvc2_writer_close(w, &streamed, &ns, NULL, &err) == WVOL_OK, "close: %s", err.message);
    }
    CHECK(ns == nd && streamed && dense && memcmp(streamed, dense, nd) == 0,
          "%s %zux%zux%zu, %d levels, tile %d,%d%s: streamed %zu bytes, dense %zu, %s", wavelet, nx, ny, nz, levels,
          tile, tile_z, in_place ? ", in place" : rows_kind == 2 ? ", 16-bit rows" : "", ns, nd,
          ns == nd ? "contents differ" : "sizes differ");
    if (rows_kind == 2) {
        /* a value beyond 16 bits in narrow rows (a caller's wrong bound) is refused, not wrapped */
        wvc2_planes pl;
        h.step = rep.step / 1e4;
        CHECK(wvol__wvc2_writer_open_mem(&w, &h, &err) == WVOL_OK, "open: %s", err.message);
        level1_planes(&pl, F.c, room, levels);
        CHECK(w && wvol__wvc2_writer_put(w, 1, 0, F.c->pz > 1 ? F.c->pz / 2 : 1, &pl, &err) == WVOL_ERR_INTERNAL &&
                  strstr(err.message, "16-bit"),
              "a value beyond the 16-bit rows is refused: %s", err.message);
        wvol__wvc2_writer_abort(w);
        h.step = rep.step;
    }
    {
        /* a level left incomplete is refused at close, and nothing is handed out */
        void *o = NULL;
        size_t on = 0;
        CHECK(wvol__wvc2_writer_open_mem(&w, &h, &err) == WVOL_OK, "open");
        CHECK(wvol__wvc2_writer_close(w, &o, &on, NULL, &err) == WVOL_ERR_ARG && !o && strstr(err.message, "rows"),
              "incomplete levels: %s", err.message);
    }
    free(streamed);
    free(dense);
    if (in_place) free(room);
    fixture_free(&F);
}


/* A fixture volume coded as a version-2 file at path (the given PSNR and tiles), its whole
 * decode and the file opened (default budget): what the random-access tests read. */
typedef struct wvc2_file_fixture {
    fixture F;
    void *buf;
    size_t n;
    wvol_coeffs *dec;
    wvol_wvc_file *wf;
} wvc2_file_fixture;

static int wvc2_file_fixture_make(wvc2_file_fixture *X, const char *path, const char *wavelet, size_t nx, size_t ny,
                                  size_t nz, int levels, int tile, int tile_z, double psnr)
{
    wvol_error err;
    wvol_wvc_params p;
    memset(X, 0, sizeof *X);
    CHECK(fixture_make(&X->F, nx, ny, nz, wavelet, levels), "fixture");
    if (!X->F.c) return 0;
    wvol_wvc_params_default(&p);
    p.value_min = X->F.vmin, p.value_max = X->F.vmax;
    p.target_sse = wvol_wvc_sse_for_psnr(psnr, (double)(nx * ny * nz), X->F.vmin, X->F.vmax);
    p.tile = tile, p.tile_z = tile_z;
    CHECK(wvol_wvc_encode(&X->buf, &X->n, X->F.c, &p, NULL, &err) == WVOL_OK, "encode: %s", err.message);
    CHECK(wvol_wvc_save(path, X->buf, X->n, &err) == WVOL_OK, "save: %s", err.message);
    CHECK(wvol_wvc_decode(&X->dec, X->buf, X->n, NULL, NULL, &err) == WVOL_OK, "decode: %s", err.message);
    CHECK(wvol_wvc_open(&X->wf, path, 0, &err) == WVOL_OK, "open: %s", err.message);
    return 1;
}

/* The whole decode's level volume (wvol_idwt3_level) and its peak magnitude. */
static wvol_volume *level_volume(const wvol_coeffs *dec, int level, double *peak)
{
    wvol_volume *full = NULL;
    wvol_error err;
    CHECK(wvol_idwt3_level(&full, dec, level, &err) == WVOL_OK, "level %d: %s", level, err.message);
    *peak = 0;
    for (size_t i = 0; full && i < full->nx * full->ny * full->nz; i++)
        if (fabs(full->data[i]) > *peak) *peak = fabs(full->data[i]);
    return full;
}

static void wvc2_file_fixture_free(wvc2_file_fixture *X, const char *path)
{
    wvol_wvc_close(X->wf);
    wvol_coeffs_destroy(X->dec);
    remove(path);
    free(X->buf);
    fixture_free(&X->F);
}

/* A copy of the file at path with chunk k's maximum in the index set to 0 (resealed): its
 * values then claim to fit 16 bits. */
static void wvc2_understate_chunk_max(const char *path, const char *out, size_t k)
{
    FILE *fp = fopen(path, "rb");
    uint8_t *b = NULL;
    long n = -1;
    wvol_wvc_info info;
    wvol_error err;
    if (fp && fseek(fp, 0, SEEK_END) == 0) n = ftell(fp);
    if (n > 0 && (b = malloc((size_t)n)) && fseek(fp, 0, SEEK_SET) == 0 && fread(b, 1, (size_t)n, fp) == (size_t)n &&
        wvol_wvc_parse_info(&info, b, (size_t)n, &err) == WVOL_OK) {
        memset(b + 224 + (size_t)info.nsections * 48 + 32 * k + 16, 0, 4);
        reseal2(b);
        CHECK(wvol_wvc_save(out, b, (size_t)n, &err) == WVOL_OK, "save: %s", err.message);
    } else {
        CHECK(0, "reading %s back", path);
    }
    if (fp) fclose(fp);
    free(b);
}

/* Region reads: random boxes (edges included, where the periodic basis wraps) at every
 * level equal the same box of the whole decoded file's level volume. Tolerance: both
 * sum the same float coefficients through the synthesis in a different order (a local
 * brick against the whole pyramid), so they differ by float rounding: 1e-5 of the
 * volume's peak magnitude is ~100 ulps of it. The cache holds a chunk as 16-bit values
 * where the index's maximum allows: at 50 dB every chunk of these volumes, at 100 dB the
 * coarse low-pass's need 32 bits (|q| in the hundred thousands) and the details still fit,
 * so both kinds are read; a file whose index understates a wide chunk's maximum is refused
 * when that chunk decodes, not wrapped. */
static void wvc2_regions_equal_the_full_decode(const char *wavelet, size_t nx, size_t ny, size_t nz, int levels,
                                               int tile, int tile_z, double psnr)
{
    wvc2_file_fixture X;
    const char *path = "test_wvc_region.wvc";
    wvol_error err;
    wvol_wvc_file *wf;
    wvol_coeffs *dec;
    uint64_t rng = 99;
    int bad = 0, tried = 0;
    if (!wvc2_file_fixture_make(&X, path, wavelet, nx, ny, nz, levels, tile, tile_z, psnr)) return;
    wf = X.wf, dec = X.dec;
    for (int level = 0; wf && dec && level <= levels; level++) {
        double peak = 0;
        wvol_volume *full = level_volume(dec, level, &peak);
        if (!full) break;
        {
            /* the level's grid without decoding: the whole decode's level volume's (its
             * spacing exact, its origin to the rounding of one product and sum) */
            size_t g[3];
            double sp[3], org[3];
            int same = wvol_wvc_level_geometry(wvol_wvc_file_info(wf), level, g, sp, org, &err) == WVOL_OK;
            for (int a = 0; same && a < 3; a++) {
                const size_t n = a == 0 ? full->nx : a == 1 ? full->ny : full->nz;
                same = g[a] == n && sp[a] == full->spacing[a] && fabs(org[a] - full->origin[a]) < 1e-9;
            }
            CHECK(same, "level geometry at level %d equals the decoded level volume's", level);
        }
        for (int trial = 0; trial < 12; trial++) {
            size_t lo[3], hi[3], dims[3] = {full->nx, full->ny, full->nz};
            wvol_volume *r = NULL;
            for (int a = 0; a < 3; a++) {
                rng = rng * 6364136223846793005ull + 1442695040888963407ull;
                lo[a] = (size_t)(rng >> 33) % dims[a];
                rng = rng * 6364136223846793005ull + 1442695040888963407ull;
                hi[a] = lo[a] + 1 + (size_t)(rng >> 33) % (dims[a] - lo[a]);
                if (trial == 0) lo[a] = 0, hi[a] = dims[a] < 3 ? dims[a] : 3;           /* a corner */
                if (trial == 1) lo[a] = dims[a] - 1, hi[a] = dims[a];                      /* the far edge */
            }
            tried++;
            if (wvol_wvc_read_region(&r, wf, lo, hi, level, &err) != WVOL_OK) {
                CHECK(0, "region at level %d: %s", level, err.message);
                bad++;
                continue;
            }
            for (size_t k = 0; k < r->nz; k++)
                for (size_t j = 0; j < r->ny; j++)
                    for (size_t i = 0; i < r->nx; i++) {
                        float a = r->data[i + r->nx * (j + r->ny * k)];
                        float b = full->data[(lo[0] + i) + full->nx * ((lo[1] + j) + full->ny * (lo[2] + k))];
                        if (!(fabs((double)a - (double)b) <= 1e-5 * peak)) {
                            if (bad++ < 3)
                                fprintf(stderr, "level %d voxel %zu,%zu,%zu: region %g full %g\n", level, lo[0] + i,
                                        lo[1] + j, lo[2] + k, a, b);
                        }
                    }
            CHECK(fabs(r->spacing[0] - full->spacing[0]) < 1e-12 &&
                      fabs(r->origin[0] - (full->origin[0] + full->spacing[0] * (double)lo[0])) < 1e-9,
                  "region geometry at level %d", level);
            {
                /* in place, in parts along y on 3 threads: the same samples bit for bit
                 * (each sample is synthesised from the same coefficients in the same order) */
                size_t nv = r->nx * r->ny * r->nz;
                float *into = malloc(nv * sizeof *into);
                double sp[3], org[3];
                CHECK(into && wvol_wvc_read_region_into(into, wf, lo, hi, level, 3, sp, org, &err) == WVOL_OK,
                      "region into at level %d: %s", level, err.message);
                CHECK(into && memcmp(into, r->data, nv * sizeof *into) == 0 && sp[1] == r->spacing[1] &&
                          org[2] == r->origin[2],
                      "threaded in-place region equals the region at level %d", level);
                free(into);
            }
            wvol_volume_destroy(r);
        }
        wvol_volume_destroy(full);
    }
    CHECK(bad == 0 && tried > 0, "%s %zux%zux%zu at %g dB: %d region voxels differ from the full decode", wavelet, nx,
          ny, nz, psnr, bad);
    if (wf) {
        wvol_wvc_cache_stats cs;
        wvol_wvc_file_stats(wf, &cs);
        if (psnr <= 50)
            CHECK(cs.decoded > 0 && cs.decoded_narrow == cs.decoded, "%g dB: %llu of %llu chunks held as 16 bits", psnr,
                  (unsigned long long)cs.decoded_narrow, (unsigned long long)cs.decoded);
        else
            CHECK(cs.decoded_narrow > 0 && cs.decoded_narrow < cs.decoded, "%g dB: %llu of %llu chunks held as 16 bits",
                  psnr, (unsigned long long)cs.decoded_narrow, (unsigned long long)cs.decoded);
    }
    if (wf && psnr > 50) {
        /* the first chunk (the coarsest level's, with the low-pass cube) is wide here */
        const char *lie = "test_wvc_region_lie.wvc";
        wvol_wvc_file *lf = NULL;
        wvol_volume *r = NULL;
        const size_t lo[3] = {0, 0, 0}, hi[3] = {nx, ny, nz};
        wvc2_understate_chunk_max(path, lie, 0);
        CHECK(wvol_wvc_open(&lf, lie, 0, &err) == WVOL_OK, "open: %s", err.message);
        CHECK(lf && wvol_wvc_read_region(&r, lf, lo, hi, 0, &err) == WVOL_ERR_FORMAT && strstr(err.message, "chunk") &&
                  strstr(err.message, "maximum"),
              "a chunk whose values exceed its index maximum is refused: %s", err.message);
        wvol_volume_destroy(r);
        wvol_wvc_close(lf);
        remove(lie);
    }
    CHECK(!wf || (wvol_wvc_level_geometry(wvol_wvc_file_info(wf), levels + 1, NULL, NULL, NULL, &err) == WVOL_ERR_ARG &&
                  strstr(err.message, "level") && wvol_wvc_level_geometry(NULL, 0, NULL, NULL, NULL, &err) == WVOL_ERR_ARG),
          "level geometry refuses a level past the last and a missing info");
    wvc2_file_fixture_free(&X, path);
}

/* Piece reads (boxes spanning the level's grid along x and y, decoded into the work array and
 * inverted in place): random z ranges and both edges (the periodic wrap) at every level below
 * the last equal the whole decode's level volume (float rounding, as the region reads: 1e-5 of
 * the peak), bit for bit on 1 and 3 threads, each chunk decoded once within the budget the read
 * asks for; a box narrower along x or y, a padded grid or the last level are not pieces. */
static void wvc2_pieces_equal_the_full_decode(const char *wavelet, size_t nx, size_t ny, size_t nz, int levels,
                                              int tile, int tile_z)
{
    wvc2_file_fixture X;
    const char *path = "test_wvc_piece.wvc";
    wvol_error err;
    wvol_wvc_file *wf;
    wvol_coeffs *dec;
    uint64_t rng = 7;
    int bad = 0, tried = 0;
    if (!wvc2_file_fixture_make(&X, path, wavelet, nx, ny, nz, levels, tile, tile_z, 50)) return;
    wf = X.wf, dec = X.dec;
    for (int level = 0; wf && dec && level < levels; level++) {
        double peak = 0;
        wvol_volume *full = level_volume(dec, level, &peak);
        if (!full) break;
        for (int trial = 0; trial < 8; trial++) {
            size_t lo[3] = {0, 0, 0}, hi[3] = {full->nx, full->ny, 0}, cap, nv;
            float *got[2] = {NULL, NULL};
            rng = rng * 6364136223846793005ull + 1442695040888963407ull;
            lo[2] = (size_t)(rng >> 33) % full->nz;
            rng = rng * 6364136223846793005ull + 1442695040888963407ull;
            hi[2] = lo[2] + 1 + (size_t)(rng >> 33) % (full->nz - lo[2]);
            if (trial == 0) lo[2] = 0, hi[2] = full->nz; /* the whole volume: every window the period */
            if (trial == 1) lo[2] = 0, hi[2] = 1;         /* the first plane: the wrap below it */
            if (trial == 2) lo[2] = full->nz - 1, hi[2] = full->nz;
            cap = wvol_wvc_piece_samples(wf, level, lo, hi);
            nv = full->nx * full->ny * (hi[2] - lo[2]);
            {
                /* a level whose samples are rolled into place (wvol_level_shift) is read as a region */
                const wvol_filter *flt = NULL;
                if (wvol_filter_get(&flt, wavelet, NULL) == WVOL_OK && level > 0 && wvol_level_shift(flt, level)) {
                    CHECK(cap == 0, "%s level %d: a shifted level is not a piece", wavelet, level);
                    continue;
                }
            }
            CHECK(cap >= nv, "level %d z %zu..%zu is a piece (%zu samples of work for %zu)", level, lo[2], hi[2], cap,
                  nv);
            if (cap < nv) continue;
            tried++;
            for (int t = 0; t < 2; t++) {
                int threads = t ? 3 : 1;
                wvol_wvc_file *pf = NULL;
                wvol_wvc_cache_stats cs;
                double sp[3], org[3];
                got[t] = malloc(cap * sizeof(float));
                CHECK(wvol_wvc_open(&pf, path, 0, &err) == WVOL_OK, "open: %s", err.message);
                if (!pf || !got[t]) continue;
                CHECK(wvol_wvc_set_budget(pf, wvol_wvc_piece_budget(pf, threads), &err) == WVOL_OK, "budget: %s",
                      err.message);
                CHECK(wvol_wvc_read_piece_into(got[t], cap, pf, lo, hi, level, threads, sp, org, &err) == WVOL_OK,
                      "piece at level %d z %zu..%zu: %s", level, lo[2], hi[2], err.message);
                wvol_wvc_file_stats(pf, &cs);
                CHECK(cs.decoded <= wvol_wvc_file_info(pf)->chunks && cs.peak <= cs.budget,
                      "each chunk once (%llu of %llu), within the budget", (unsigned long long)cs.decoded,
                      (unsigned long long)wvol_wvc_file_info(pf)->chunks);
                CHECK(fabs(sp[2] - full->spacing[2]) < 1e-12 &&
                          fabs(org[2] - (full->origin[2] + full->spacing[2] * (double)lo[2])) < 1e-9,
                      "piece geometry at level %d", level);
                wvol_wvc_close(pf);
            }
            for (size_t i = 0; got[0] && i < nv; i++) {
                float b = full->data[i + full->nx * full->ny * lo[2]];
                if (!(fabs((double)got[0][i] - (double)b) <= 1e-5 * peak) && bad++ < 3)
                    fprintf(stderr, "%s level %d z %zu..%zu sample %zu: piece %g full %g\n", wavelet, level, lo[2],
                            hi[2], i, got[0][i], b);
            }
            CHECK(got[0] && got[1] && memcmp(got[0], got[1], nv * sizeof(float)) == 0,
                  "1 and 3 threads give the same samples (level %d)", level);
            free(got[0]);
            free(got[1]);
        }
        {
            size_t lo[3] = {1, 0, 0}, hi[3] = {full->nx, full->ny, 1}, lo2[3] = {0, 0, 0}, hi2[3] = {2, 2, 2};
            CHECK(wvol_wvc_piece_samples(wf, level, lo, hi) == 0, "a box narrower along x is not a piece");
            CHECK(wvol_wvc_read_piece_into(full->data, full->nx * full->ny, wf, lo, hi, level, 1, NULL, NULL, &err) ==
                          WVOL_ERR_ARG && strstr(err.message, "span"),
                  "reading it as one is refused: %s", err.message);
            CHECK(wvol_wvc_piece_samples(wf, levels, lo2, hi2) == 0, "the last level is not a piece");
        }
        wvol_volume_destroy(full);
    }
    CHECK(bad == 0 && tried > 0, "%s %zux%zux%zu: %d piece samples differ from the full decode", wavelet, nx, ny, nz,
          bad);
    wvc2_file_fixture_free(&X, path);
}

/* A budget is respected: with a tiny budget the cache's peak stays within it (measured by
 * the cache, the only thing that grows with the file) and the region is still right; a
 * budget below one chain of chunks is refused; a damaged chunk fails only the regions
 * that need it, naming it. */
static void wvc2_budget_and_damage(void)
{
    fixture F;
    void *buf = NULL;
    uint8_t *b;
    size_t n, lo[3] = {0, 0, 0}, hi[3] = {8, 8, 8}, far_lo[3] = {40, 40, 40}, far_hi[3] = {48, 48, 48};
    wvol_error err;
    wvol_wvc_params p;
    wvol_wvc_file *wf = NULL;
    wvol_wvc_cache_stats cs;
    wvol_wvc_info info;
    wvol_volume *r = NULL, *r2 = NULL;
    const char *path = "test_wvc_budget.wvc";
    size_t budget;
    CHECK(fixture_make(&F, 64, 64, 64, "haar", 2), "fixture");
    if (!F.c) return;
    wvol_wvc_params_default(&p);
    p.value_min = F.vmin, p.value_max = F.vmax;
    p.target_sse = wvol_wvc_sse_for_psnr(50, 64.0 * 64 * 64, F.vmin, F.vmax);
    p.tile = 8, p.tile_z = 8;
    CHECK(wvol_wvc_encode(&buf, &n, F.c, &p, NULL, &err) == WVOL_OK, "encode: %s", err.message);
    if (!buf) return;
    CHECK(wvol_wvc_save(path, buf, n, &err) == WVOL_OK, "save");
    CHECK(wvol_wvc_open(&wf, path, 100, &err) == WVOL_ERR_NOMEM && strstr(err.message, "budget"),
          "a budget below one chain is refused: %s", err.message);
    /* a chunk of this file is 7 (or 8) x 8^3 int32 = 14-16 KiB: 24 of them */
    budget = 24 * 17000;
    CHECK(wvol_wvc_open(&wf, path, budget, &err) == WVOL_OK, "open: %s", err.message);
    if (wf) {
        wvol_volume *full = NULL;
        size_t all_lo[3] = {0, 0, 0}, all_hi[3] = {64, 64, 64};
        CHECK(wvol_wvc_read_region(&full, wf, all_lo, all_hi, 0, &err) == WVOL_OK, "whole volume within %zu bytes: %s",
              budget, err.message);
        wvol_wvc_file_stats(wf, &cs);
        CHECK(cs.peak <= budget && cs.peak > 0, "cache peak %zu within the budget %zu", cs.peak, budget);
        CHECK(cs.decoded > wvol_wvc_file_info(wf)->chunks / 2, "chunks were decoded (%llu)",
              (unsigned long long)cs.decoded);
        if (full) {
            wvol_coeffs *dec = NULL;
            wvol_volume *ref = NULL;
            double sse = 0, mx = 0;
            if (wvol_wvc_decode(&dec, buf, n, NULL, NULL, &err) == WVOL_OK && wvol_idwt3(&ref, dec, &err) == WVOL_OK)
                wvol_wvc_compare(&sse, &mx, full, ref, &err);
            CHECK(ref && mx <= 1e-5 * F.vmax, "budgeted whole read equals the decode (max %g)", mx);
            {
                /* in place on 2 threads (parts along y sharing the cache) within the same budget */
                float *into = malloc(64 * 64 * 64 * sizeof *into);
                CHECK(into && wvol_wvc_read_region_into(into, wf, all_lo, all_hi, 0, 2, NULL, NULL, &err) == WVOL_OK,
                      "threaded whole read within %zu bytes: %s", budget, err.message);
                CHECK(into && memcmp(into, full->data, 64 * 64 * 64 * sizeof *into) == 0,
                      "threaded whole read equals the one-thread read");
                wvol_wvc_file_stats(wf, &cs);
                CHECK(cs.peak <= budget, "threaded: cache peak %zu within the budget %zu", cs.peak, budget);
                CHECK(wvol_wvc_read_region_into(NULL, wf, all_lo, all_hi, 0, 2, NULL, NULL, &err) == WVOL_ERR_ARG,
                      "no destination is refused: %s", err.message);
                CHECK(into && wvol_wvc_read_region_into(into, wf, all_lo, all_hi, -1, 2, NULL, NULL, &err) ==
                              WVOL_ERR_ARG && strstr(err.message, "level"),
                      "a negative level is refused: %s", err.message);
                free(into);
            }
            wvol_volume_destroy(ref);
            wvol_coeffs_destroy(dec);
        }
        wvol_volume_destroy(full);
        /* the budget of the open file: below one chain refused and unchanged; lowered, the
         * cache evicts down to it at once; raised, a later read holds more */
        CHECK(wvol_wvc_set_budget(wf, 100, &err) == WVOL_ERR_NOMEM && strstr(err.message, "chain"),
              "set_budget below one chain is refused: %s", err.message);
        wvol_wvc_file_stats(wf, &cs);
        CHECK(cs.budget == budget, "a refused budget leaves it at %zu (%zu)", budget, cs.budget);
        CHECK(wvol_wvc_set_budget(wf, budget / 3, &err) == WVOL_OK, "lower budget: %s", err.message);
        wvol_wvc_file_stats(wf, &cs);
        CHECK(cs.budget == budget / 3 && cs.held <= budget / 3, "lowered: %zu held within %zu", cs.held, cs.budget);
        CHECK(wvol_wvc_set_budget(wf, 0, &err) == WVOL_OK, "the default budget: %s", err.message);
        {
            wvol_volume *again = NULL;
            size_t all_lo[3] = {0, 0, 0}, all_hi[3] = {64, 64, 64};
            CHECK(wvol_wvc_read_region(&again, wf, all_lo, all_hi, 0, &err) == WVOL_OK, "read: %s", err.message);
            wvol_wvc_file_stats(wf, &cs);
            CHECK(cs.budget == WVOL_WVC_DEFAULT_BUDGET && cs.held > budget,
                  "raised to the default: %zu held (more than the old %zu)", cs.held, budget);
            wvol_volume_destroy(again);
        }
        CHECK(wvol_wvc_set_budget(NULL, 0, &err) == WVOL_ERR_ARG, "a NULL file is refused");
        wvol_wvc_close(wf);
        wf = NULL;
    }
    /* damage one level-1 chunk near the origin: regions far from it still decode */
    CHECK(wvol_wvc_parse_info(&info, buf, n, &err) == WVOL_OK, "info");
    b = buf;
    {
        size_t idx = 224 + (size_t)info.nsections * 48, k, first1 = 0;
        /* level-1 chunks are the last ones; the first of them covers the origin */
        k = (size_t)info.chunks - 4 * 4 * 4;
        first1 = k;
        {
            const uint8_t *e = b + idx + 32 * first1;
            uint64_t off = 0;
            for (int i = 7; i >= 0; i--) off = (off << 8) | e[i];
            CHECK(off > 0, "the chunk at the origin holds data");
            if (off) b[off + 2] ^= 0x10;
        }
    }
    CHECK(wvol_wvc_save(path, buf, n, &err) == WVOL_OK, "save damaged");
    CHECK(wvol_wvc_open(&wf, path, 0, &err) == WVOL_OK, "the index is intact: %s", err.message);
    if (wf) {
        CHECK(wvol_wvc_read_region(&r, wf, lo, hi, 0, &err) == WVOL_ERR_FORMAT && strstr(err.message, "chunk") &&
                  strstr(err.message, "level 1"),
              "the damaged chunk is named: %s", err.message);
        {
            /* the same through two threads: the error of the part that met the chunk is the call's */
            size_t big_lo[3] = {0, 0, 0}, big_hi[3] = {32, 32, 16};
            float *into = malloc(32 * 32 * 16 * sizeof *into);
            CHECK(into && wvol_wvc_read_region_into(into, wf, big_lo, big_hi, 0, 2, NULL, NULL, &err) ==
                              WVOL_ERR_FORMAT && strstr(err.message, "level 1"),
                  "threaded: the damaged chunk is named: %s", err.message);
            free(into);
        }
        {
            /* a piece that needs it fails naming it; a piece far from it (z 40..48 of the
             * 64-plane volume: its windows stay clear of the first tile layer) decodes */
            size_t p_lo[3] = {0, 0, 0}, p_hi[3] = {64, 64, 64}, q_lo[3] = {0, 0, 40}, q_hi[3] = {64, 64, 48};
            size_t cap = wvol_wvc_piece_samples(wf, 0, p_lo, p_hi);
            float *into = cap ? malloc(cap * sizeof *into) : NULL;
            CHECK(into && wvol_wvc_read_piece_into(into, cap, wf, p_lo, p_hi, 0, 2, NULL, NULL, &err) ==
                              WVOL_ERR_FORMAT && strstr(err.message, "level 1"),
                  "piece: the damaged chunk is named: %s", err.message);
            CHECK(into && wvol_wvc_piece_samples(wf, 0, q_lo, q_hi) <= cap &&
                      wvol_wvc_read_piece_into(into, cap, wf, q_lo, q_hi, 0, 2, NULL, NULL, &err) == WVOL_OK,
                  "a piece elsewhere decodes: %s", err.message);
            free(into);
        }
        CHECK(wvol_wvc_read_region(&r2, wf, far_lo, far_hi, 0, &err) == WVOL_OK, "a region elsewhere decodes: %s",
              err.message);
        CHECK(wvol_wvc_read_region(&r, wf, lo, hi, 1, &err) == WVOL_OK, "the coarser level there decodes: %s",
              err.message);
        {
            /* two threads reading at once, one the damaged box and one the far box, each
             * call its own error: the far reads all succeed with the samples read alone, the
             * near ones all fail (a shared slot handed one's error to the other, or cleared it
             * and returned zeros as success) */
            int near_ok = 0, far_bad = 0;
#pragma omp parallel num_threads(2)
            {
#ifdef _OPENMP
                const int near = omp_get_thread_num() == 0;
#else
                const int near = 0; /* one thread: the far reads alone */
#endif
                float *box = malloc(8 * 8 * 8 * sizeof *box);
                wvol_error e;
                for (int it = 0; box && it < 200; it++) {
                    const wvol_status st =
                        wvol_wvc_read_region_into(box, wf, near ? lo : far_lo, near ? hi : far_hi, 0, 1, NULL, NULL, &e);
                    if (near && st == WVOL_OK) {
#pragma omp atomic
                        near_ok++;
                    }
                    if (!near && (st != WVOL_OK || (r2 && memcmp(box, r2->data, 8 * 8 * 8 * sizeof *box)))) {
#pragma omp atomic
                        far_bad++;
                    }
                }
                free(box);
            }
            CHECK(near_ok == 0 && far_bad == 0,
                  "concurrent reads keep their own errors: %d near reads succeeded, %d far reads failed or differed",
                  near_ok, far_bad);
        }
        {
            /* the budget changed while two threads read (the Python module lets one thread do
             * that while others read): a read either gives the samples read alone or fails as
             * over a budget too small for it, never another error or other samples. Regions
             * and pieces (a z slab clear of the damage) alternate: a piece read checks the
             * budget before it starts. */
            const size_t low = wvol_wvc_piece_budget(wf, 1), q_lo[3] = {0, 0, 40}, q_hi[3] = {64, 64, 48};
            const size_t cap = wvol_wvc_piece_samples(wf, 0, q_lo, q_hi), slab = 64 * 64 * 8;
            float *piece_ref = cap >= slab ? malloc(cap * sizeof *piece_ref) : NULL;
            int read_bad = 0, set_bad = 0, readers_done = 0;
            CHECK(low > 0 && piece_ref && r2 &&
                      wvol_wvc_read_piece_into(piece_ref, cap, wf, q_lo, q_hi, 0, 1, NULL, NULL, &err) == WVOL_OK,
                  "a slab read alone: %s", err.message);
#pragma omp parallel num_threads(3) if (piece_ref && r2)
            {
#ifdef _OPENMP
                /* a setter only beside two readers: it waits for both */
                const int setter = omp_get_num_threads() == 3 && omp_get_thread_num() == 0;
#else
                const int setter = 0;
#endif
                wvol_error e;
                if (setter) {
                    for (int it = 0, d = 0; d < 2; it++) {
                        if (wvol_wvc_set_budget(wf, (it & 1) ? low : 0, &e) != WVOL_OK) {
#pragma omp atomic
                            set_bad++;
                        }
#pragma omp atomic read
                        d = readers_done;
                    }
                } else if (piece_ref && r2) {
                    float *work = malloc(cap * sizeof *work);
                    for (int it = 0; work && it < 100; it++) {
                        const int piece = it & 1;
                        const wvol_status st =
                            piece ? wvol_wvc_read_piece_into(work, cap, wf, q_lo, q_hi, 0, 1, NULL, NULL, &e)
                                  : wvol_wvc_read_region_into(work, wf, far_lo, far_hi, 0, 1, NULL, NULL, &e);
                        if (st == WVOL_ERR_NOMEM) continue;
                        if (st != WVOL_OK || memcmp(work, piece ? piece_ref : r2->data,
                                                    (piece ? slab : 8 * 8 * 8) * sizeof *work)) {
#pragma omp atomic
                            read_bad++;
                        }
                    }
                    if (!work) {
#pragma omp atomic
                        read_bad++;
                    }
                    free(work);
                }
                if (!setter) {
#pragma omp atomic
                    readers_done++;
                }
            }
            CHECK(set_bad == 0 && read_bad == 0,
                  "budget set during reads: %d settings refused, %d reads failed otherwise or differed", set_bad,
                  read_bad);
            CHECK(piece_ref && wvol_wvc_set_budget(wf, 0, &err) == WVOL_OK &&
                      wvol_wvc_read_region_into(piece_ref, wf, far_lo, far_hi, 0, 1, NULL, NULL, &err) == WVOL_OK,
                  "a read after: %s", err.message);
            free(piece_ref);
        }
        wvol_wvc_close(wf);
    }
    wvol_volume_destroy(r);
    wvol_volume_destroy(r2);
    remove(path);
    free(buf);
    fixture_free(&F);
}

/* 1e4 + a signal of range about 1.4: data far from 0 against its spread. */
static double offset_volume_at(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    (void)ctx;
    return 1e4 + make_volume_at(v, i, j, k, NULL) / 100.0;
}

/* Data far from 0: region, level and piece reads from a file take the coarsest low-pass band's
 * offset out and add it back to their samples last, as the whole inverse does, so they agree
 * with the whole decode to float32's rounding at the samples' magnitude. Synthesising the band
 * with the offset in it rounded every sum at 1e4's spacing instead: the reads were about ten of
 * those spacings off the whole decode. */
static void wvc2_reads_on_a_large_offset(void)
{
    const char *path = "test_wvc_offset.wvc";
    const size_t nx = 40, ny = 32, nz = 44;
    const int levels = 3;
    wvol_volume *v = fixture_volume(nx, ny, nz, offset_volume_at, NULL);
    wvol_coeffs *c = NULL, *dec = NULL;
    const wvol_filter *flt;
    wvol_wvc_params p;
    wvol_wvc_file *wf = NULL;
    wvol_error err;
    void *buf = NULL;
    size_t n = 0;
    double vmin, vmax;
    if (!v) return;
    wvol_volume_range(v, &vmin, &vmax, NULL);
    CHECK(wvol_filter_get(&flt, "db2", &err) == WVOL_OK && wvol_dwt3(&c, v, flt, levels, &err) == WVOL_OK,
          "dwt3: %s", err.message);
    wvol_wvc_params_default(&p);
    p.value_min = vmin, p.value_max = vmax;
    p.target_sse = wvol_wvc_sse_for_psnr(70, (double)(nx * ny * nz), vmin, vmax);
    p.tile = 8, p.tile_z = 8;
    CHECK(c && wvol_wvc_encode(&buf, &n, c, &p, NULL, &err) == WVOL_OK, "encode: %s", err.message);
    CHECK(buf && wvol_wvc_save(path, buf, n, &err) == WVOL_OK, "save: %s", err.message);
    CHECK(buf && wvol_wvc_decode(&dec, buf, n, NULL, NULL, &err) == WVOL_OK, "decode: %s", err.message);
    CHECK(wvol_wvc_open(&wf, path, 0, &err) == WVOL_OK, "open: %s", err.message);
    for (int level = 0; wf && dec && level < 2; level++) {
        double peak = 0, worst_region = 0, worst_piece = 0, tol;
        wvol_volume *full = level_volume(dec, level, &peak), *reg = NULL;
        size_t lo[3] = {3, 0, 5}, hi[3], cap, nv;
        float *work;
        if (!full) break;
        /* two roundings at the samples' magnitude (the whole decode's and the read's) */
        tol = 2.0 * ldexp(1.0, ilogb(peak) - 23);
        hi[0] = full->nx - 2, hi[1] = full->ny, hi[2] = full->nz - 1;
        CHECK(wvol_wvc_read_region(&reg, wf, lo, hi, level, &err) == WVOL_OK, "region at level %d: %s", level,
              err.message);
        for (size_t k = lo[2]; reg && k < hi[2]; k++)
            for (size_t j = lo[1]; j < hi[1]; j++)
                for (size_t i = lo[0]; i < hi[0]; i++) {
                    double d = fabs((double)reg->data[(i - lo[0]) + reg->nx * ((j - lo[1]) + reg->ny * (k - lo[2]))] -
                                    (double)full->data[i + full->nx * (j + full->ny * k)]);
                    worst_region = d > worst_region ? d : worst_region;
                }
        lo[0] = 0, hi[0] = full->nx;
        cap = wvol_wvc_piece_samples(wf, level, lo, hi);
        nv = full->nx * full->ny * (hi[2] - lo[2]);
        work = cap ? malloc(cap * sizeof *work) : NULL;
        {
            /* a file of its own under the least budget a piece read takes: finding the offset
             * (the coarsest level decoded a chunk at a time) fits in it too */
            wvol_wvc_file *pf = NULL;
            CHECK(wvol_wvc_open(&pf, path, 0, &err) == WVOL_OK, "open: %s", err.message);
            CHECK(pf && wvol_wvc_set_budget(pf, wvol_wvc_piece_budget(pf, 1), &err) == WVOL_OK, "budget: %s",
                  err.message);
            CHECK(pf && work && wvol_wvc_read_piece_into(work, cap, pf, lo, hi, level, 1, NULL, NULL, &err) == WVOL_OK,
                  "piece at level %d: %s", level, work ? err.message : "not a piece");
            wvol_wvc_close(pf);
        }
        for (size_t i = 0; work && i < nv; i++) {
            double d = fabs((double)work[i] - (double)full->data[i + full->nx * full->ny * lo[2]]);
            worst_piece = d > worst_piece ? d : worst_piece;
        }
        CHECK(worst_region <= tol && worst_piece <= tol,
              "level %d on an offset of 1e4: region %.3g and piece %.3g from the whole decode (<= %.3g)", level,
              worst_region, worst_piece, tol);
        free(work);
        wvol_volume_destroy(reg);
        wvol_volume_destroy(full);
    }
    wvol_wvc_close(wf);
    remove(path);
    wvol_coeffs_destroy(dec);
    wvol_coeffs_destroy(c);
    free(buf);
    wvol_volume_destroy(v);
}

int main(void)
{
    const char *fam[] = {"haar", "db2", "coif1", "bl3"};
    for (int i = 0; i < 4; i++) wvc_round_trip_meets_psnr_target(fam[i], 16, 16, 16, 2);
    wvc_round_trip_meets_psnr_target("db4", 32, 32, 32, 3);
    wvc_odd_sizes_and_flat_axes_round_trip();
    /* version 1 is still written on request and read */
    g_version = 1;
    wvc_round_trip_meets_psnr_target("db2", 16, 16, 16, 2);
    wvc_odd_sizes_and_flat_axes_round_trip();
    g_version = 0;
    wvc_coders_decode_to_the_same_coefficients();
    for (int rows_kind = 0; rows_kind < 3; rows_kind++) {
        wvc2_streamed_rows_give_the_same_bytes("db2", 40, 36, 44, 2, 8, 8, rows_kind);
        wvc2_streamed_rows_give_the_same_bytes("haar", 33, 17, 70, 3, 8, 16, rows_kind);
        wvc2_streamed_rows_give_the_same_bytes("bl3", 32, 32, 32, 2, 16, 8, rows_kind);
        wvc2_streamed_rows_give_the_same_bytes("db2", 24, 20, 1, 2, 8, 8, rows_kind);
    }
    wvc2_regions_equal_the_full_decode("db2", 40, 36, 44, 2, 8, 8, 50);
    wvc2_regions_equal_the_full_decode("haar", 33, 17, 70, 3, 8, 16, 50);
    wvc2_regions_equal_the_full_decode("bl3", 32, 32, 32, 2, 16, 8, 50);
    wvc2_regions_equal_the_full_decode("coif1", 24, 20, 1, 2, 8, 8, 50);
    wvc2_regions_equal_the_full_decode("db2", 40, 36, 44, 2, 8, 8, 100);
    wvc2_pieces_equal_the_full_decode("db2", 40, 36, 44, 2, 8, 8);
    wvc2_pieces_equal_the_full_decode("haar", 32, 16, 72, 3, 8, 16);
    wvc2_pieces_equal_the_full_decode("bl3", 32, 32, 32, 2, 16, 8);
    wvc2_pieces_equal_the_full_decode("coif2", 64, 32, 96, 4, 8, 8);
    wvc2_reads_on_a_large_offset();
    wvc2_budget_and_damage();
    wvc_early_stop_gives_the_coarser_volume();
    wvc_dequant_vector_form_matches_reference();
    wvc2_decoded_values_on_the_quantiser_lattice();
    wvc_refuses_truncation_and_bit_flips_everywhere(2);
    wvc_refuses_truncation_and_bit_flips_everywhere(1);
    wvc_refuses_crafted_headers();
    wvc2_refuses_crafted_headers_and_indexes();
    wvc_survives_garbage_payloads_with_valid_checksums(1);
    wvc_survives_garbage_payloads_with_valid_checksums(2);
    /* chunk modes 3 and 4 wherever a chunk has no low-pass cube (auto leaves these small
     * chunks to compact's rule), and --coder compact (auto's rule before mode 4: modes 0-3) */
    {
        const wvol_wvc_coder again[3] = {WVOL_WVC_CODER_RANS, WVOL_WVC_CODER_RANS4, WVOL_WVC_CODER_COMPACT};
        for (int k = 0; k < 3; k++) {
            g_coder = again[k];
            for (int i = 0; i < 4; i++) wvc_round_trip_meets_psnr_target(fam[i], 16, 16, 16, 2);
            wvc_odd_sizes_and_flat_axes_round_trip();
            wvc_refuses_truncation_and_bit_flips_everywhere(2);
            wvc_survives_garbage_payloads_with_valid_checksums(2);
        }
    }
    g_coder = WVOL_WVC_CODER_AUTO;
    wvc_files_are_atomic_and_checked();
    wvc_refuses_bad_parameters();
    wvc_corpus_files_decode_or_are_refused();
    wvc2_mode1_files_decode_to_the_same_values();
    wvc2_sparse_chunks_round_trip();
    wvc2_bands_coded_apart_round_trip();
    wvc_quant_kernels_agree();
    return check_summary("test_wvc");
}
