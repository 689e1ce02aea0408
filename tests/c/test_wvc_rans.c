/* SPDX-License-Identifier: MIT */
/* Chunk modes 3 and 4 of .wvc version 2 (codec/wvc_rans.c, codec/wvc_rans4_*.c): the coders'
 * round trips on the cases their tables and streams find hardest (all-zero bands, a single
 * non-zero, impulses and magnitudes up to the 2^30 bound, odd extents, rows shorter than
 * mode 4's group, one to seven bands, with and without parents; mode 4 with raw and modelled
 * signs, through its AVX2 engine and its scalar decoder), their refusal of every truncated
 * payload and survival of every flipped bit (mode 4: both decoders alike); at the file level
 * --coder compact choosing mode 3 for dense chunks only, --coder auto mode 4 for the chunks
 * with 4096 non-zeros, and the rANS coders refused for version 1; the encoder's kept buffers
 * and the writer's pooled job grids reused for a later chunk as if fresh. (test_wvc.c runs
 * its round trips, truncation, bit-flip and garbage-payload tests again with --coder rans,
 * rans4 and compact, and decodes the mode-3 and mode-4 corpus files to the mode-1 and mode-2
 * files' values.) */
#define _POSIX_C_SOURCE 200809L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "codec/wvc2_internal.h"
#include "codec/wvc_internal.h"
#include "fixtures.h"
#include "wvc_fixtures.h"
#include "wvol/wvc.h"

/* n bands of extent e (all the same: a chunk's bands share the tile) on one local grid
 * per band, as the chunk coder lays them out: the tile at x = 0, its parent region beside
 * it along x. */
typedef struct bands {
    int n;
    int32_t *q[8];
    size_t p[8][3];
    wvc_band b[8];
} bands;

static int bands_make(bands *B, int n, const size_t e[3], int with_parent)
{
    memset(B, 0, sizeof *B);
    B->n = n;
    for (int i = 0; i < n; i++) {
        wvc_band *b = &B->b[i];
        size_t pe[3];
        for (int a = 0; a < 3; a++) pe[a] = (e[a] + 1) / 2;
        b->level = 1;
        b->band = 1 + i;
        b->has_parent = with_parent;
        for (int a = 0; a < 3; a++) {
            b->ext[a] = e[a];
            b->pext[a] = with_parent ? pe[a] : 0;
        }
        b->poff[0] = with_parent ? e[0] : 0;
        b->count = (uint64_t)e[0] * e[1] * e[2];
        B->p[i][0] = e[0] + (with_parent ? pe[0] : 0);
        B->p[i][1] = e[1];
        B->p[i][2] = e[2];
        B->q[i] = calloc(B->p[i][0] * e[1] * e[2], sizeof(int32_t));
        if (!B->q[i]) return 0;
    }
    return 1;
}

static void bands_free(bands *B)
{
    for (int i = 0; i < B->n; i++) free(B->q[i]);
}

static int32_t *at(bands *B, int i, size_t x, size_t y, size_t z)
{
    return B->q[i] + x + B->p[i][0] * (y + B->p[i][1] * z);
}

/* The coder under test: chunk mode 3, or mode 4 with its signs as g_signs says (-1 the
 * encoder's choice, 0 modelled, 1 raw). Mode 4's payloads are decoded by the AVX2 engine
 * (where the CPU has it) and by the scalar decoder, which must agree. */
static int g_mode = 3, g_signs = -1, g_packed = 0; /* g_packed: mode 4's tables packed (flags bit 1) */

/* Mode 4's encoder in vectors (where the CPU has AVX2 and the extent is a multiple of 16) and
 * its scalar form, compared on every stream coded with a given sign choice: the same bytes. */
static int g_enc_compared, g_enc_differ;

static int coder_encode(uint8_t **buf, size_t *size, int n, int32_t *const Q[], const size_t *const P[],
                        const wvc_band *const B[])
{
    uint8_t *s = NULL, *t = NULL;
    size_t ts = 0;
    wvc_rans4_opts o = {0};
    if (g_mode == 3) return wvol__wvc_rans_encode(buf, size, n, Q, P, B, NULL);
    if (g_signs < 0) return wvol__wvc_rans4_encode(buf, size, 0, n, Q, P, B, NULL);
    o.raw_signs = g_signs;
    o.packed_tables = g_packed;
    if (wvol__wvc_rans4_encode_stream(&s, size, n, Q, P, B, &o)) return -1;
    o.scalar = 1;
    if (wvol__wvc_rans4_encode_stream(&t, &ts, n, Q, P, B, &o) || ts != *size || memcmp(s, t, ts)) g_enc_differ++;
    g_enc_compared++;
    free(t);
    *buf = malloc(*size + 1);
    if (*buf) {
        (*buf)[0] = (uint8_t)((g_signs ? 0 : 1) | (g_packed ? 2 : 0)); /* the flags: bit 0 signs modelled,
                                                                         * bit 1 tables packed */
        memcpy(*buf + 1, s, *size);
        *size += 1;
    }
    free(s);
    return *buf ? 0 : -1;
}

static int coder_decode(int n, int32_t *const D[], const size_t *const P[], const wvc_band *const B[],
                        const uint8_t *buf, size_t size, int engine, uint64_t *nz, const char **why)
{
    if (g_mode == 3) return wvol__wvc_rans_decode(n, D, P, B, buf, size, nz, why);
    return wvol__wvc_rans4_decode(n, D, P, B, buf, size, engine, nz, why);
}

/* zeroed copies of B's grids (the tiles zero, the parent regions as they are); the tiles'
 * non-zeros counted into *want. Returns 0 when out of memory. */
static int zero_tiles(bands *B, int32_t *D[8], uint64_t *want)
{
    for (int i = 0; i < B->n; i++) {
        size_t cnt = B->p[i][0] * B->p[i][1] * B->p[i][2];
        D[i] = malloc(cnt * sizeof(int32_t));
        if (!D[i]) return 0;
        memcpy(D[i], B->q[i], cnt * sizeof(int32_t));
        for (size_t z = 0; z < B->b[i].ext[2]; z++)
            for (size_t y = 0; y < B->b[i].ext[1]; y++)
                for (size_t x = 0; x < B->b[i].ext[0]; x++) {
                    size_t k = x + B->p[i][0] * (y + B->p[i][1] * z);
                    *want += D[i][k] != 0;
                    D[i][k] = 0;
                }
    }
    return 1;
}

/* Encodes B, decodes into zeroed copies of its grids (parents kept), compares the tiles.
 * Returns the payload (caller frees) or NULL after a failed check. */
static uint8_t *round_trip(bands *B, size_t *size, const char *what)
{
    const size_t *P[8];
    const wvc_band *Bp[8];
    int32_t *D[8] = {0};
    uint8_t *buf = NULL;
    uint64_t nz = 0, want = 0;
    const char *why = "";
    for (int i = 0; i < B->n; i++) P[i] = B->p[i], Bp[i] = &B->b[i];
    if (coder_encode(&buf, size, B->n, B->q, P, Bp)) {
        CHECK(0, "%s: encode failed", what);
        return NULL;
    }
    for (int engine = 0; engine <= (g_mode == 4); engine++) {
        int ok = zero_tiles(B, D, &want), r;
        CHECK(ok, "%s: memory", what);
        r = ok ? coder_decode(B->n, D, P, Bp, buf, *size, engine, &nz, &why) : -1;
        CHECK(!ok || r == 0, "%s: decode (engine %d) refused its own payload: %s", what, engine, why);
        if (r == 0) {
            size_t bad = 0;
            for (int i = 0; i < B->n; i++) {
                size_t cnt = B->p[i][0] * B->p[i][1] * B->p[i][2];
                bad += memcmp(D[i], B->q[i], cnt * sizeof(int32_t)) != 0;
            }
            CHECK(bad == 0, "%s: %zu bands decode differently (engine %d)", what, bad, engine);
            CHECK(nz == want, "%s: %llu non-zeros counted, %llu coded", what, (unsigned long long)nz,
                  (unsigned long long)want);
        }
        for (int i = 0; i < B->n; i++) free(D[i]), D[i] = NULL;
        want = 0;
    }
    return buf;
}

/* Laplacian-like integers of scale s (|q| = floor of an exponential), random signs. */
static int32_t draw(uint64_t *rng, double s)
{
    double u = fixture_urand(rng);
    double m = -s * log(1.0 - u);
    int32_t v = m > 1e9 ? 1000000000 : (int32_t)m;
    return fixture_urand(rng) < 0.5 ? -v : v;
}

static void rans_round_trips_hard_cases(void)
{
    /* mode 4's groups of 16 and vectors of 8: rows shorter than a group, whole groups, a last
     * group of 8, extents no multiple of 8 (the scalar decoder only) */
    const size_t shapes[8][3] = {{8, 8, 8}, {5, 3, 7}, {1, 1, 1}, {16, 2, 1}, {9, 9, 4}, {64, 3, 2}, {24, 4, 3}, {40, 6, 3}};
    uint64_t rng = 777;
    for (int sh = 0; sh < 8; sh++)
        for (int n = 1; n <= 7; n += 3)
            for (int par = 0; par <= 1; par++)
                for (int kind = 0; kind < 8; kind++) {
                    bands B;
                    char what[128];
                    uint8_t *buf;
                    size_t size;
                    const size_t *e = shapes[sh];
                    snprintf(what, sizeof what, "mode %d signs %d: %zux%zux%zu, %d bands, parent %d, case %d", g_mode,
                             g_signs, e[0], e[1], e[2], n, par, kind);
                    if (!bands_make(&B, n, e, par)) {
                        CHECK(0, "%s: memory", what);
                        bands_free(&B);
                        continue;
                    }
                    for (int i = 0; i < n; i++) {
                        /* parents: a mix of zeros, ones and larger values */
                        for (size_t z = 0; par && z < B.b[i].pext[2]; z++)
                            for (size_t y = 0; y < B.b[i].pext[1]; y++)
                                for (size_t x = 0; x < B.b[i].pext[0]; x++) *at(&B, i, e[0] + x, y, z) = draw(&rng, 3);
                        for (size_t z = 0; z < e[2]; z++)
                            for (size_t y = 0; y < e[1]; y++)
                                for (size_t x = 0; x < e[0]; x++) {
                                    int32_t v = 0;
                                    if (kind == 2) v = draw(&rng, 2);                  /* dense, small */
                                    if (kind == 3) v = draw(&rng, 5000);               /* dense, wide */
                                    if (kind == 4) v = fixture_urand(&rng) < 0.05 ? draw(&rng, 50) : 0; /* sparse */
                                    if (kind == 5) v = (x + y + z) % 3 == 0 ? (1 << 30) : -(1 << 30) + (int32_t)x; /* the bound */
                                    if (kind == 6) { /* every bit length to 2^30, and both sides of 2^24 (the
                                                      * encoder's lengths go through float's exponent) */
                                        int len = (int)(fixture_urand(&rng) * 31);
                                        uint32_t m = len ? (1u << (len - 1)) | ((uint32_t)(fixture_urand(&rng) * 4294967296.0) & ((1u << (len - 1)) - 1)) : 0;
                                        if ((x + y) % 5 == 1) m = (1u << 24) - 1 + (uint32_t)(z % 3);
                                        v = fixture_urand(&rng) < 0.5 ? -(int32_t)m : (int32_t)m;
                                    }
                                    if (kind == 7 && fixture_urand(&rng) < 0.02) /* impulses of the largest magnitude */
                                        v = fixture_urand(&rng) < 0.5 ? -WVC_QMAX : WVC_QMAX;
                                    *at(&B, i, x, y, z) = v;
                                }
                        if (kind == 1 && i == n - 1) *at(&B, i, e[0] - 1, e[1] - 1, e[2] - 1) = -(1 << 30); /* one */
                    }
                    buf = round_trip(&B, &size, what);
                    free(buf);
                    bands_free(&B);
                }
}

/* Every truncation of a payload is refused; every flipped bit is decoded or refused
 * (raw bits carry no redundancy: the file's CRC-32 per chunk is what catches them), and
 * under ASan/UBSan nothing is read outside the payload, nor outside the decoder's padded
 * copies of the streams: a damaged state runs a stream past its end by up to a row's
 * worth of reads before the decoder's per-row check stops it, which the wide rows (64,
 * the largest magnitudes with 25 raw bits) of the second case exercise. min_refused: the
 * share of the flipped bits that must be refused (the small case's tables, lengths and
 * states are most of its payload; the wide case's payload is mostly raw bits). */
static uint8_t *random_payload(bands *B, const size_t e[3], double scale, int32_t add, uint64_t seed, size_t *size,
                               const char *what)
{
    uint64_t rng = seed;
    if (!bands_make(B, 3, e, 1)) {
        CHECK(0, "%s: memory", what);
        return NULL;
    }
    for (int i = 0; i < 3; i++)
        for (size_t z = 0; z < e[2]; z++)
            for (size_t y = 0; y < e[1]; y++)
                for (size_t x = 0; x < e[0]; x++) *at(B, i, x, y, z) = draw(&rng, scale) + add;
    return round_trip(B, size, what);
}

/* Under AddressSanitizer mode 4's damage loops take every 7th truncation and bit flip (7 is
 * prime to 8: every bit position of a byte still comes up): each decode there maps and unmaps
 * the decoder's 213 kB of tables, which made the whole loop take minutes. The release build
 * runs every one. */
#if defined(WVOL_TEST_ASAN)
#define DAMAGE_STRIDE (g_mode == 4 ? 7 : 1)
#else
#define DAMAGE_STRIDE 1
#endif

static void rans_damage_case(const size_t e[3], double scale, uint64_t seed, double min_refused)
{
    bands B;
    size_t size = 0, bad = 0, refused_flips = 0, flips = 0, differ = 0;
    uint8_t *buf = random_payload(&B, e, scale, 0, seed, &size, "damage fixture");
    for (size_t len = 0; buf && len < size; len += DAMAGE_STRIDE) {
        int32_t *D[8];
        const size_t *P[8];
        const wvc_band *Bp[8];
        uint8_t *t = malloc(len ? len : 1); /* exact size: ASan sees a read past the end */
        uint64_t nz;
        const char *why = NULL;
        memcpy(t, buf, len);
        for (int i = 0; i < 3; i++) {
            D[i] = calloc(B.p[i][0] * e[1] * e[2], sizeof(int32_t));
            P[i] = B.p[i];
            Bp[i] = &B.b[i];
        }
        if (coder_decode(3, D, P, Bp, t, len, 0, &nz, &why) == 0 || !why || !why[0]) bad++;
        for (int i = 0; i < 3; i++) free(D[i]);
        free(t);
    }
    CHECK(bad == 0, "%zu truncations accepted or refused without a reason", bad);
    for (size_t pos = 0; buf && pos < 8 * size; pos += DAMAGE_STRIDE) {
        int32_t *D[8];
        const size_t *P[8];
        const wvc_band *Bp[8];
        uint8_t *t = malloc(size);
        uint64_t nz = 0;
        const char *why = NULL;
        int r;
        flips++;
        memcpy(t, buf, size);
        t[pos / 8] ^= (uint8_t)(1u << (pos % 8));
        for (int i = 0; i < 3; i++) {
            D[i] = calloc(B.p[i][0] * e[1] * e[2], sizeof(int32_t));
            P[i] = B.p[i];
            Bp[i] = &B.b[i];
        }
        r = coder_decode(3, D, P, Bp, t, size, 0, &nz, &why);
        if (r) {
            refused_flips++;
            CHECK(why && why[0], "bit %zu: refused without a reason", pos);
        }
        if (g_mode == 4) { /* the scalar decoder: the same outcome, the same values */
            int32_t *S[8];
            uint64_t nz2 = 0;
            int same = 1, r2;
            for (int i = 0; i < 3; i++) S[i] = calloc(B.p[i][0] * e[1] * e[2], sizeof(int32_t));
            r2 = coder_decode(3, S, P, Bp, t, size, WVC_RANS4_SCALAR, &nz2, &why);
            for (int i = 0; i < 3 && !r; i++) same &= !memcmp(S[i], D[i], B.p[i][0] * e[1] * e[2] * sizeof(int32_t));
            differ += r != r2 || !same || (!r && nz != nz2);
            for (int i = 0; i < 3; i++) free(S[i]);
        }
        for (int i = 0; i < 3; i++) free(D[i]);
        free(t);
    }
    /* the tables, lengths and states are checked: most flips outside the raw bits are caught */
    CHECK((double)refused_flips > min_refused * (double)flips,
          "mode %d: only %zu of %zu bit flips refused (%ux%ux%u)", g_mode, refused_flips, flips, (unsigned)e[0],
          (unsigned)e[1], (unsigned)e[2]);
    CHECK(differ == 0, "mode 4: %zu flipped payloads decode differently by the engine and the scalar decoder", differ);
    free(buf);
    bands_free(&B);
}

/* Reads the LEB128 value at *pos (the payload's own encoding); -1 past the end. */
static int get_varint(const uint8_t *b, size_t size, size_t *pos, uint32_t *v)
{
    *v = 0;
    for (int sh = 0; sh < 35 && *pos < size; sh += 7) {
        uint8_t c = b[(*pos)++];
        *v |= (uint32_t)(c & 0x7F) << sh;
        if (!(c & 0x80)) return 0;
    }
    return -1;
}

/* Passes over the 52 magnitude tables at *pos (each a count, then that many frequencies). */
static int skip_tables(const uint8_t *b, size_t size, size_t *pos)
{
    int ok = 1;
    for (int c = 0; ok && c < 52; c++) {
        uint32_t ns, f;
        ok = !get_varint(b, size, pos, &ns);
        for (uint32_t k = 0; ok && k < ns; k++) ok = !get_varint(b, size, pos, &f);
    }
    return ok;
}

static size_t put_varint(uint8_t *d, uint32_t v)
{
    size_t n = 0;
    do {
        d[n++] = (uint8_t)((v & 0x7F) | (v >= 0x80 ? 0x80 : 0));
        v >>= 7;
    } while (v);
    return n;
}

/* Stream lengths that add up but leave band 0's magnitude stream (which = 0) or its raw
 * bits (which = 1) far too short for its coefficients: the decoder reads zeros past the
 * stream's end (its copy is padded by one row's worth of reads) and must stop at the end
 * of the first row, with a reason, not run on through the band (ASan sees a read past the
 * padding). Rows of 64 with large magnitudes: a row takes 64 words and up to 64 x 25 raw
 * bits. */
static void rans_short_stream_is_stopped(int which)
{
    const size_t e[3] = {64, 4, 3};
    bands B;
    uint8_t *buf, *t;
    size_t size = 0, pos = 0, lenpos, o;
    uint32_t v, len[3][3];
    int ok = 1;
    buf = random_payload(&B, e, 3e6, 1, 5 + (uint64_t)which, &size, "short stream fixture");
    /* the tables: 52 magnitude contexts, 189 signs */
    ok = buf && skip_tables(buf, size, &pos);
    for (int c = 0; buf && ok && c < 189; c++) ok = !get_varint(buf, size, &pos, &v);
    lenpos = pos;
    for (int i = 0; buf && ok && i < 3; i++)
        for (int k = 0; ok && k < 3; k++) ok = !get_varint(buf, size, &pos, &len[i][k]);
    CHECK(buf && ok, "short stream fixture: payload header not parsed");
    t = buf && ok ? malloc(size + 16) : NULL;
    if (t) {
        const uint32_t need = which == 0 ? len[0][0] - 4 : len[0][2] & ~1u; /* bytes moved */
        uint64_t nz;
        const char *why = NULL;
        int32_t *D[8];
        const size_t *P[8];
        const wvc_band *Bp[8];
        /* more than the padding (65 words; 240 bytes of raw bits), or the test shows nothing */
        CHECK(need > (which == 0 ? 4 * 65 : 2 * 240), "short stream fixture: stream %d of band 0 holds only %u bytes",
              which, need);
        if (which == 0) len[0][0] = 4, len[0][2] += need; /* no magnitude words; raw bits get them */
        else len[0][2] -= need, len[0][1] += need;        /* almost no raw bits; the sign stream gets them */
        memcpy(t, buf, lenpos);
        o = lenpos;
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++) o += put_varint(t + o, len[i][k]);
        memcpy(t + o, buf + pos, size - pos);
        o += size - pos;
        for (int i = 0; i < 3; i++) {
            D[i] = calloc(B.p[i][0] * e[1] * e[2], sizeof(int32_t));
            P[i] = B.p[i];
            Bp[i] = &B.b[i];
        }
        CHECK(wvol__wvc_rans_decode(3, D, P, Bp, t, o, &nz, &why) != 0 && why && why[0],
              "stream %d of band 0 cut short: decoded, or refused without a reason", which);
        for (int i = 0; i < 3; i++) free(D[i]);
    }
    free(t);
    free(buf);
    bands_free(&B);
}

/* Mode 4: word and raw-bit counts that add up but leave the words (which = 0) or the raw
 * bits (which = 1) far too short: the decoder reads the payload in place, so its fast rows
 * run while a row's worth of reads remains in the payload and the scalar decoder's checked
 * reads take the rest; it must stop with a reason, and ASan sees every read past the
 * (exactly sized) payload. */
static void rans4_short_stream_is_stopped(int which)
{
    const size_t e[3] = {64, 4, 3};
    bands B;
    uint8_t *buf, *t;
    size_t size = 0, pos = 1 + 96, lenpos, o;
    uint32_t v, nw = 0, nraw = 0;
    int ok = 1;
    buf = random_payload(&B, e, 3e6, 1, 5 + (uint64_t)which, &size, "mode-4 short stream fixture");
    /* 52 magnitude tables, 32 group flags, 189 signs when modelled, 12 row flags */
    ok = buf && skip_tables(buf, size, &pos);
    for (int c = 0; buf && ok && c < 32 + (buf[0] & 1 ? 189 : 0) + 12; c++) ok = !get_varint(buf, size, &pos, &v);
    lenpos = pos;
    ok = ok && buf && !get_varint(buf, size, &pos, &nw) && !get_varint(buf, size, &pos, &nraw);
    CHECK(buf && ok && nw > 300 && nraw > 600, "mode-4 short stream fixture: %u words, %u raw bytes", nw, nraw);
    t = buf && ok ? malloc(size) : NULL;
    if (t) {
        const uint32_t moved = which == 0 ? nw - 4 : (nraw - 8) / 2; /* words */
        uint64_t nz;
        const char *why = NULL;
        int32_t *D[8];
        const size_t *P[8];
        const wvc_band *Bp[8];
        if (which == 0) nw -= moved, nraw += 2 * moved;
        else nw += moved, nraw -= 2 * moved;
        memcpy(t, buf, lenpos);
        o = lenpos + put_varint(t + lenpos, nw);
        o += put_varint(t + o, nraw);
        if (o <= pos) { /* the lengths' varints no longer than before: the streams shift left */
            memmove(t + o, buf + pos, size - pos);
            o += size - pos;
            for (int engine = 0; engine <= 1; engine++) {
                uint8_t *u = malloc(o); /* exact size */
                memcpy(u, t, o);
                for (int i = 0; i < 3; i++) {
                    D[i] = calloc(B.p[i][0] * e[1] * e[2], sizeof(int32_t));
                    P[i] = B.p[i];
                    Bp[i] = &B.b[i];
                }
                why = NULL;
                CHECK(coder_decode(3, D, P, Bp, u, o, engine, &nz, &why) != 0 && why && why[0],
                      "mode 4, %s cut short (engine %d): decoded, or refused without a reason",
                      which ? "raw bits" : "words", engine);
                for (int i = 0; i < 3; i++) free(D[i]);
                free(u);
            }
        } else {
            CHECK(0, "mode-4 short stream fixture: the lengths' varints grew");
        }
    }
    free(t);
    free(buf);
    bands_free(&B);
}

static void rans_refuses_truncation_and_survives_bit_flips(void)
{
    const size_t small[3] = {6, 5, 4}, wide[3] = {64, 3, 2}, wide8[3] = {24, 5, 3};
    rans_damage_case(small, 6, 99, 0.5);
    rans_damage_case(wide, 5000, 7, 0.05);
    if (g_mode == 3) {
        rans_short_stream_is_stopped(0);
        rans_short_stream_is_stopped(1);
    } else {
        rans_damage_case(wide8, 40, 11, 0.05);
        if (!g_packed) { /* it rewrites the lengths after LEB128 tables; the streams are read alike */
            rans4_short_stream_is_stopped(0);
            rans4_short_stream_is_stopped(1);
        }
    }
}

/* Mode 4's packed tables against its LEB128 ones on the same sparse bands (3% non-zero, seven
 * bands with parents, as a 40 dB chunk's): both decode to the bands (round_trip), and packed
 * takes at least 150 bytes fewer. A LEB128 frequency takes 1-2 bytes and a binary entry 1-2; in
 * a sparse chunk most contexts hold a few events, which the packed form describes in a few bits
 * at a lower precision or as p = 1/2. */
static void rans4_packed_tables_are_smaller(void)
{
    const size_t e[3] = {64, 16, 8};
    uint64_t rng = 4242;
    size_t size[2] = {0, 0};
    bands B;
    if (!bands_make(&B, 7, e, 1)) {
        CHECK(0, "packed tables: memory");
        bands_free(&B);
        return;
    }
    for (int i = 0; i < 7; i++) {
        for (size_t z = 0; z < B.b[i].pext[2]; z++)
            for (size_t y = 0; y < B.b[i].pext[1]; y++)
                for (size_t x = 0; x < B.b[i].pext[0]; x++)
                    *at(&B, i, e[0] + x, y, z) = fixture_urand(&rng) < 0.1 ? draw(&rng, 3) : 0;
        for (size_t z = 0; z < e[2]; z++)
            for (size_t y = 0; y < e[1]; y++)
                for (size_t x = 0; x < e[0]; x++) *at(&B, i, x, y, z) = fixture_urand(&rng) < 0.03 ? draw(&rng, 3) : 0;
    }
    g_mode = 4, g_signs = 0;
    for (g_packed = 0; g_packed <= 1; g_packed++) free(round_trip(&B, &size[g_packed], "packed tables fixture"));
    CHECK(size[1] + 150 <= size[0], "packed tables: %zu bytes against LEB128's %zu", size[1], size[0]);
    g_packed = 0;
    bands_free(&B);
}

/* Mode 4's encoder on bands whose parent region lies in a block of its own (wvc_band's pq, psy,
 * psz: a chunk coded where its rows lie, wvc2_chunk.c) and whose rows are further apart than
 * the tile: the same bytes as from the local grids, the parent beside the tile, for both
 * encoders and both table forms. Sizes with a parent region at least half the tile (the vector
 * pass) and narrower (the scalar pass), and a short last group. */
static void rans4_parent_in_own_block(void)
{
    const size_t exts[3][3] = {{64, 16, 8}, {32, 9, 5}, {48, 7, 6}};
    for (int k = 0; k < 3; k++) {
        const size_t *e = exts[k];
        const size_t gap = 24, sy = e[0] + gap, sz = sy * (e[1] + 3);
        uint64_t rng = 777 + (uint64_t)k;
        bands B;
        int32_t *Q2[7] = {0}, *P2[7] = {0};
        size_t dims2[7][3];
        wvc_band b2[7];
        const size_t *Ps2[7];
        const wvc_band *Bs2[7];
        int32_t *Qs[7];
        const size_t *Ps[7];
        const wvc_band *Bs[7];
        int ok = bands_make(&B, 7, e, 1);
        for (int i = 0; i < 7 && ok; i++) {
            const wvc_band *b = &B.b[i];
            const size_t psy = b->pext[0] + 5, psz = psy * (b->pext[1] + 2);
            Q2[i] = calloc(sz * e[2], sizeof(int32_t));
            P2[i] = calloc(psz * b->pext[2], sizeof(int32_t));
            ok = Q2[i] && P2[i];
            for (size_t z = 0; ok && z < b->pext[2]; z++)
                for (size_t y = 0; y < b->pext[1]; y++)
                    for (size_t x = 0; x < b->pext[0]; x++)
                        P2[i][x + psy * y + psz * z] = *at(&B, i, e[0] + x, y, z) =
                            fixture_urand(&rng) < 0.4 ? draw(&rng, 6) : 0;
            for (size_t z = 0; ok && z < e[2]; z++)
                for (size_t y = 0; y < e[1]; y++)
                    for (size_t x = 0; x < e[0]; x++)
                        Q2[i][x + sy * y + sz * z] = *at(&B, i, x, y, z) = fixture_urand(&rng) < 0.3 ? draw(&rng, 5) : 0;
            b2[i] = *b;
            memset(b2[i].poff, 0, sizeof b2[i].poff); /* unused: the parent is at pq */
            b2[i].pq = P2[i], b2[i].psy = psy, b2[i].psz = psz;
            dims2[i][0] = sy, dims2[i][1] = sz / sy, dims2[i][2] = e[2];
            Qs[i] = B.q[i], Ps[i] = B.p[i], Bs[i] = &B.b[i];
            Ps2[i] = dims2[i], Bs2[i] = &b2[i];
        }
        CHECK(ok, "parent in its own block: memory");
        for (int packed = 0; ok && packed <= 1; packed++)
            for (int scalar = 0; scalar <= 1; scalar++) {
                wvc_rans4_opts o = {0};
                uint8_t *s1 = NULL, *s2 = NULL;
                size_t n1 = 0, n2 = 0;
                o.packed_tables = packed, o.scalar = scalar;
                CHECK(!wvol__wvc_rans4_encode_stream(&s1, &n1, 7, Qs, Ps, Bs, &o) &&
                          !wvol__wvc_rans4_encode_stream(&s2, &n2, 7, Q2, Ps2, Bs2, &o),
                      "parent in its own block: encode");
                CHECK(n1 > 0 && n1 == n2 && s1 && s2 && !memcmp(s1, s2, n1),
                      "parent in its own block, %zux%zux%zu, packed %d, scalar %d: %zu bytes against %zu", e[0], e[1],
                      e[2], packed, scalar, n2, n1);
                free(s1);
                free(s2);
            }
        for (int i = 0; i < 7; i++) free(Q2[i]), free(P2[i]);
        bands_free(&B);
    }
}

/* Crafted packed tables (wvc_rans4.h's layout), to see each check refuse its own defect. The
 * payload: flags (packed, raw signs), 24 states at 2^16, the tables (table 0: symbols 0 and 1 at
 * P = 3, F_0 = 5; group-flag entry 0 given at P = 4, f0 = 3; the rest unused, p = 1/2 or zeros
 * only), zero word and raw-byte counts. With every row flag "zeros only" (an identity step) the
 * valid payload decodes, to zeros; each defect must be refused as a malformed table. */
enum { PT_VALID, PT_NS, PT_SUM, PT_EG, PT_P_LOW, PT_P_HIGH, PT_F0, PT_CASES };
typedef struct crafted_bits {
    uint8_t b[512];
    size_t n;
} crafted_bits;

static void cb_put(crafted_bits *w, uint32_t v, int len)
{
    for (int i = len; i-- > 0; w->n++)
        if (v >> i & 1) w->b[w->n >> 3] |= (uint8_t)(0x80u >> (w->n & 7));
}

static void cb_eg(crafted_bits *w, uint32_t v)
{
    const int n = 31 - __builtin_clz(v);
    cb_put(w, 0, n);
    cb_put(w, v, n + 1);
}

static size_t crafted_packed(uint8_t *out, int defect)
{
    crafted_bits w;
    size_t len = 0;
    memset(&w, 0, sizeof w);
    for (int c = 0; c < 52; c++) { /* magnitude tables */
        if (c) {
            cb_eg(&w, 1);
            continue;
        }
        if (defect == PT_EG) cb_put(&w, 0, 11); /* 11 leading zeros: a value of 2^11 or more */
        cb_eg(&w, defect == PT_NS ? 64 : 3);    /* ns + 1: ns = 63 is one symbol too many */
        cb_put(&w, 0, 3);                       /* P - 3 */
        cb_eg(&w, (defect == PT_SUM ? 8 : 5) + 1); /* F_0 = 8 leaves the last 0 */
    }
    for (int c = 0; c < 32; c++) { /* group-flag entries */
        if (c) {
            cb_put(&w, 2, 2);
            continue;
        }
        cb_put(&w, 3, 2);
        cb_put(&w, defect == PT_P_LOW ? 1 : defect == PT_P_HIGH ? 11 : 4, 4); /* R4_BPMIN .. 10 */
        cb_put(&w, defect == PT_F0 ? 0 : 3, 4);                                /* f0 in 1 .. 2^P - 1 */
    }
    for (int c = 0; c < 12; c++) cb_put(&w, 0, 2); /* row-flag entries: zeros only */
    out[len++] = 2;                                /* flags: tables packed, signs raw */
    for (int l = 0; l < 24; l++, len += 4) {
        const uint32_t x = 1u << 16;
        memcpy(out + len, &x, 4);
    }
    memcpy(out + len, w.b, (w.n + 7) / 8);
    len += (w.n + 7) / 8;
    out[len++] = 0; /* words */
    out[len++] = 0; /* raw bytes */
    return len;
}

static void rans4_packed_tables_refused(void)
{
    const size_t e[3] = {16, 4, 2};
    bands B;
    if (!bands_make(&B, 1, e, 0)) {
        CHECK(0, "crafted packed tables: memory");
        bands_free(&B);
        return;
    }
    for (int defect = 0; defect < PT_CASES; defect++)
        for (int engine = 0; engine <= 1; engine++) {
            uint8_t buf[1024];
            const size_t size = crafted_packed(buf, defect);
            uint8_t *t = malloc(size); /* exact size: ASan sees a read past the end */
            const size_t *P[1] = {B.p[0]};
            const wvc_band *Bp[1] = {&B.b[0]};
            int32_t *D[1] = {calloc(B.p[0][0] * e[1] * e[2], sizeof(int32_t))};
            uint64_t nz = 1;
            const char *why = NULL;
            int r = -1;
            if (t && D[0]) {
                memcpy(t, buf, size);
                r = wvol__wvc_rans4_decode(1, D, P, Bp, t, size, engine ? WVC_RANS4_SCALAR : WVC_RANS4_AUTO, &nz, &why);
            }
            if (defect == PT_VALID)
                CHECK(r == 0 && nz == 0, "crafted packed tables (engine %d): the valid payload refused (%s)", engine,
                      why ? why : "");
            else
                CHECK(r != 0 && why && !strcmp(why, "mode-4 table malformed"),
                      "crafted packed tables, defect %d (engine %d): %s", defect, engine,
                      r ? (why ? why : "no reason") : "accepted");
            free(t);
            free(D[0]);
        }
    bands_free(&B);
}

/* --coder compact: mode 3 for the dense chunks of a fine quantiser, none for a coarse one
 * (its chunks are sparse); --coder auto: mode 4 for the chunks with 4096 non-zeros; all
 * decode to what --coder cabac's file decodes to. The
 * default tiles, so that level 1's dense chunks hold more than 65536 non-zeros (mode 3
 * alone). */
static double noisy_blob(const wvol_volume *v, size_t i, size_t j, size_t k, const void *ctx)
{
    uint64_t s = 0x9E3779B97F4A7C15ull * (1 + i + 1000 * j + 1000000 * k);
    (void)ctx;
    return 100 * fixture_shell_blob(v, i, j, k, NULL) + 4 * (fixture_urand(&s) - 0.5);
}

static void rans_auto_choice(void)
{
    wvol_volume *v = fixture_volume(96, 96, 72, noisy_blob, NULL);
    wvol_coeffs *c = NULL;
    const wvol_filter *f = fixture_filter("db2");
    wvol_error err;
    double vmin = 0, vmax = 0;
    if (!v || wvol_dwt3(&c, v, f, 2, &err) != WVOL_OK) {
        CHECK(0, "fixture");
        wvol_volume_destroy(v);
        return;
    }
    wvol_volume_range(v, &vmin, &vmax, NULL);
    for (int fine = 0; fine <= 1; fine++) {
        const wvol_wvc_coder coders[3] = {WVOL_WVC_CODER_CABAC, WVOL_WVC_CODER_COMPACT, WVOL_WVC_CODER_AUTO};
        void *buf[3] = {NULL, NULL, NULL};
        size_t n[3] = {0, 0, 0};
        wvol_coeffs *d[3] = {NULL, NULL, NULL};
        for (int k = 0; k < 3; k++) {
            wvol_wvc_params p;
            wvol_wvc_params_default(&p);
            p.value_min = vmin;
            p.value_max = vmax;
            p.step = fine ? 0.05 : 40;
            p.coder = coders[k];
            CHECK(wvol_wvc_encode(&buf[k], &n[k], c, &p, NULL, &err) == WVOL_OK, "encode: %s", err.message);
            CHECK(buf[k] && wvol_wvc_decode(&d[k], buf[k], n[k], NULL, NULL, &err) == WVOL_OK, "decode: %s",
                  err.message);
        }
        if (buf[1]) {
            int modes[5];
            CHECK(wvc_chunk_modes(buf[1], n[1], modes), "modes");
            CHECK((fine ? modes[3] > 0 : modes[3] == 0) && modes[4] == 0,
                  "compact, step %s: %d chunks of mode 3, %d of mode 2, %d of mode 4", fine ? "fine" : "coarse",
                  modes[3], modes[2], modes[4]);
        }
        /* auto: mode 4 for every chunk without the low-pass cube (the coarsest level's one
         * chunk holds it) that has 4096 non-zeros, the others as compact's (modes 0-3) */
        if (buf[1] && buf[2]) {
            int modes[5], big[5], mc[5];
            CHECK(wvc_chunk_modes(buf[2], n[2], modes) && wvc_chunk_modes_from(buf[2], n[2], 4096, big) &&
                      wvc_chunk_modes(buf[1], n[1], mc),
                  "modes");
            CHECK(modes[0] + modes[1] + modes[2] + modes[3] + modes[4] == mc[0] + mc[1] + mc[2] + mc[3] &&
                      modes[4] == big[4] && big[0] + big[1] + big[2] + big[3] <= 1 && (!fine || modes[4] > 0),
                  "auto, step %s: %d chunks of mode 4 (of %d with 4096 non-zeros), %d of modes 0-3",
                  fine ? "fine" : "coarse", modes[4], big[0] + big[1] + big[2] + big[3] + big[4],
                  modes[0] + modes[1] + modes[2] + modes[3]);
        }
        for (int k = 1; k < 3; k++)
            if (d[0] && d[k])
                CHECK(!memcmp(d[0]->data, d[k]->data, d[0]->px * d[0]->py * d[0]->pz * sizeof(float)),
                      "coder %d and cabac decode differently", (int)coders[k]);
        for (int k = 0; k < 3; k++) {
            free(buf[k]);
            wvol_coeffs_destroy(d[k]);
        }
    }
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
}

/* The rANS coders are version 2's: asking for either with version 1 is refused. */
static void rans_needs_version_2(void)
{
    wvol_volume *v = fixture_volume(8, 8, 8, fixture_shell_blob, NULL);
    wvol_coeffs *c = NULL;
    wvol_wvc_params p;
    wvol_error err;
    void *buf = NULL;
    size_t n = 0;
    if (!v || wvol_dwt3(&c, v, fixture_filter("haar"), 1, &err) != WVOL_OK) {
        CHECK(0, "fixture");
        wvol_volume_destroy(v);
        return;
    }
    wvol_wvc_params_default(&p);
    p.value_min = 0;
    p.value_max = 1;
    p.step = 0.01;
    p.version = 1;
    for (int k = 0; k < 2; k++) {
        p.coder = k ? WVOL_WVC_CODER_RANS4 : WVOL_WVC_CODER_RANS;
        memset(&err, 0, sizeof err);
        CHECK(wvol_wvc_encode(&buf, &n, c, &p, NULL, &err) == WVOL_ERR_ARG && strstr(err.message, "rANS"),
              "version 1 with rANS (mode %d): '%s'", 3 + k, err.message);
        free(buf);
        buf = NULL;
    }
    wvol_coeffs_destroy(c);
    wvol_volume_destroy(v);
}

/* The encoder's kept buffers (wvc_rans_scratch) and the writer's pool of job grids
 * (wvc2_job_pool) serve chunk after chunk: a chunk coded or copied out after a larger,
 * denser one must come out as it does from fresh memory (no value of the earlier chunk
 * left in a buffer or in a grid's zero margin). */
static void reused_buffers_leave_nothing_behind(void)
{
    const size_t ea[3] = {9, 7, 6}, eb[3] = {5, 6, 3};
    bands A, B;
    wvc_rans_scratch s = {0};
    uint8_t *pa = NULL, *pb = NULL, *pf = NULL;
    size_t na = 0, nb = 0, nf = 0;
    uint32_t r = 12345;
    if (!bands_make(&A, 7, ea, 1) || !bands_make(&B, 3, eb, 1)) {
        CHECK(0, "fixture");
        bands_free(&A);
        bands_free(&B);
        return;
    }
    for (int i = 0; i < A.n; i++)
        for (size_t k = 0; k < A.p[i][0] * ea[1] * ea[2]; k++) {
            r = r * 1103515245u + 12345u;
            A.q[i][k] = (int32_t)(r >> 16) % 4001 - 2000;
        }
    *at(&B, 1, 2, 3, 1) = 7;
    *at(&B, 2, 0, 0, 0) = -1;
    {
        const size_t *PA[8], *PB[8];
        const wvc_band *BA[8], *BB[8];
        for (int i = 0; i < A.n; i++) PA[i] = A.p[i], BA[i] = &A.b[i];
        for (int i = 0; i < B.n; i++) PB[i] = B.p[i], BB[i] = &B.b[i];
        CHECK(wvol__wvc_rans_encode(&pa, &na, A.n, A.q, PA, BA, &s) == 0, "dense chunk with scratch");
        CHECK(wvol__wvc_rans_encode(&pb, &nb, B.n, B.q, PB, BB, &s) == 0, "sparse chunk with scratch");
        CHECK(wvol__wvc_rans_encode(&pf, &nf, B.n, B.q, PB, BB, NULL) == 0, "sparse chunk fresh");
        CHECK(pb && pf && nb == nf && memcmp(pb, pf, nb) == 0,
              "the sparse chunk after the dense one: %zu bytes against %zu from fresh buffers", nb, nf);
    }
    wvol__wvc_rans_scratch_free(&s);
    CHECK(s.p[0] == NULL && s.cap[0] == 0, "scratch released");
    free(pa), free(pb), free(pf);
    bands_free(&A);
    bands_free(&B);

    /* job grids: a 32^3 grid, two levels, tiles 16 x 16 x 8; a level-1 chunk's bands taken
     * from filled boxes, then a chunk with zeros and smaller extent from the same pool */
    {
        wvc2_geom g;
        const size_t P[3] = {32, 32, 32}, full[3] = {16, 16, 8}, part[3] = {10, 16, 5};
        int32_t *child = calloc(16 * 16 * 8 * 8, sizeof *child), *par = calloc(8 * 8 * 4 * 8, sizeof *par);
        wvc2_qbox c[8], pr[8];
        wvc2_job_pool pool = {0};
        wvc2_job j1, j2, jf, jn;
        wvc2_coded out;
        int32_t *kept;
        int same = 1;
        if (!child || !par || wvol__wvc2_geom(&g, P, 2, 16, 8)) {
            CHECK(0, "job fixture");
            free(child), free(par);
            return;
        }
        pool.max = 1;
        for (int i = 0; i < 8; i++) {
            c[i].q = child + (size_t)i * 16 * 16 * 8, c[i].sy = 16, c[i].sz = 256;
            pr[i].q = par + (size_t)i * 8 * 8 * 4, pr[i].sy = 8, pr[i].sz = 64;
        }
        for (size_t k = 0; k < 16 * 16 * 8 * 8; k++) child[k] = (int32_t)(k % 17) - 8;
        for (size_t k = 0; k < 8 * 8 * 4 * 8; k++) par[k] = (int32_t)(k % 5) + 1;
        CHECK(wvol__wvc2_job_make(&j1, &g, 1, full, c, pr, NULL, &pool) == 0 && j1.nused == g.lv[1].nb, "dense job");
        kept = j1.block;
        CHECK(wvol__wvc2_job_code(&out, &j1, &g, WVOL_WVC_CODER_AUTO, 3, NULL, &pool) == 0, "dense job coded");
        free(out.payload);
        CHECK(pool.n == 1 && pool.block[0] == kept, "the coded job's block kept (%d)", pool.n);
        /* the next chunk: smaller, two bands all zero, a sparse parent */
        memset(child, 0, 16 * 16 * 8 * 8 * sizeof *child);
        memset(par, 0, 8 * 8 * 4 * 8 * sizeof *par);
        for (int i = 2; i < 8; i++) c[i].q[3 + 16 * (2 + 16 * 1)] = i;
        par[5] = 9;
        CHECK(wvol__wvc2_job_make(&j2, &g, 1, part, c, pr, NULL, &pool) == 0, "sparse job from the pool");
        CHECK(j2.block == kept && pool.n == 0, "the pool's block taken");
        CHECK(wvol__wvc2_job_make(&jf, &g, 1, part, c, pr, NULL, NULL) == 0, "sparse job, fresh");
        /* the counts given (as the writer gives its quantiser's): the same job */
        CHECK(wvol__wvc2_job_make(&jn, &g, 1, part, c, pr, jf.nzb, NULL) == 0, "sparse job, counts given");
        CHECK(jn.mask == jf.mask && jn.nonzero == jf.nonzero && jn.nonzero == (uint64_t)g.lv[1].nb - 2,
              "counts given: mask 0x%x, %llu",
              jn.mask, (unsigned long long)jn.nonzero);
        CHECK(j2.mask == jf.mask && j2.nused == jf.nused, "same bands: 0x%x / 0x%x", j2.mask, jf.mask);
        for (int i = 0; i < 8; i++) {
            size_t n = jf.lg[i].p[0] * jf.lg[i].p[1] * jf.lg[i].p[2];
            if (!(jf.mask >> i & 1)) continue;
            same &= memcmp(j2.lg[i].p, jf.lg[i].p, sizeof jf.lg[i].p) == 0 &&
                    memcmp(j2.lg[i].q, jf.lg[i].q, n * sizeof *jf.lg[i].q) == 0 &&
                    memcmp(jn.lg[i].q, jf.lg[i].q, n * sizeof *jf.lg[i].q) == 0;
        }
        CHECK(same, "a job's grids from a reused block equal a fresh job's (zero margins included)");
        wvol__wvc2_job_free(&j2, &pool);
        wvol__wvc2_job_free(&jf, NULL);
        wvol__wvc2_job_free(&jn, NULL);
        CHECK(pool.n == 1, "block back in the pool");
        wvol__wvc2_job_pool_free(&pool);
        CHECK(pool.n == 0, "pool released");
        free(child), free(par);
    }
}

int main(void)
{
    rans_round_trips_hard_cases();
    rans_refuses_truncation_and_survives_bit_flips();
    g_mode = 4; /* mode 4: the encoder's choice of signs (packed tables), then each way with either table form */
    g_signs = -1;
    rans_round_trips_hard_cases();
    for (g_packed = 0; g_packed <= 1; g_packed++)
        for (g_signs = 0; g_signs <= 1; g_signs++) {
            rans_round_trips_hard_cases();
            rans_refuses_truncation_and_survives_bit_flips();
        }
    g_packed = 0;
    rans4_packed_tables_are_smaller();
    rans4_packed_tables_refused();
    rans4_parent_in_own_block();
    CHECK(g_enc_compared > 0 && g_enc_differ == 0, "mode 4: %d of %d streams differ between the vector and scalar encoders",
          g_enc_differ, g_enc_compared);
    g_mode = 3;
    rans_auto_choice();
    rans_needs_version_2();
    reused_buffers_leave_nothing_behind();
    return check_summary("test_wvc_rans");
}
