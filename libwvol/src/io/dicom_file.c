/* SPDX-License-Identifier: MIT
 * DICOM Part 10 file: its data elements read up to the pixel data (explicit and
 * implicit VR little endian; sequences of undefined length skipped), keeping the few
 * a series reader needs (dicom.c).
 * Based on: DICOM PS3.5 (data elements, value representations, transfer syntaxes)
 * and PS3.10 (the file format: preamble, DICM, file meta group). */
#define _POSIX_C_SOURCE 200809L
#include "io/dicom_internal.h"
#include "io/io_internal.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

void wvol__dicom_info_init(dicom_info *s)
{
    memset(s, 0, sizeof *s);
    s->samples = 1;
    s->frames = 1;
    s->iop[0] = s->iop[4] = 1;
    s->pixel_spacing[0] = s->pixel_spacing[1] = 1;
    s->slope = 1;
}

void wvol__dicom_info_free(dicom_info *s)
{
    free(s->file);
    free(s->series);
    free(s->syntax);
}

/* ---- one file's elements -------------------------------------------------------- */

typedef struct parser {
    const unsigned char *b;
    size_t n;
    dicom_info *info;
    wvol_error *err;
} parser;

/* Every failure below is "malformed": the caller returns WVOL_ERR_FORMAT with err set. */
static int bad(parser *ps, const char *why)
{
    wvol_error_set(ps->err, WVOL_ERR_FORMAT, "%s: malformed DICOM file (%s)", ps->info->file, why);
    return -1;
}

static int u16(parser *ps, size_t p, uint16_t *v)
{
    if (p + 2 > ps->n) return bad(ps, "truncated");
    *v = (uint16_t)(ps->b[p] | (ps->b[p + 1] << 8));
    return 0;
}

static int u32(parser *ps, size_t p, uint32_t *v)
{
    if (p + 4 > ps->n) return bad(ps, "truncated");
    *v = (uint32_t)ps->b[p] | ((uint32_t)ps->b[p + 1] << 8) | ((uint32_t)ps->b[p + 2] << 16) |
         ((uint32_t)ps->b[p + 3] << 24);
    return 0;
}

/* A value's text: trailing spaces and NULs and leading spaces removed, control and
 * non-ASCII bytes shown as '?' (the text may end up in a message). NULL: no memory. */
static char *str(const parser *ps, size_t p, uint32_t len)
{
    size_t a = 0, e = len;
    char *s;
    while (e > 0 && (ps->b[p + e - 1] == ' ' || ps->b[p + e - 1] == '\0')) e--;
    while (a < e && ps->b[p + a] == ' ') a++;
    s = malloc(e - a + 1);
    if (!s) return NULL;
    for (size_t i = a; i < e; i++) {
        unsigned char c = ps->b[p + i];
        s[i - a] = (c < 0x20 || c >= 0x7f) ? '?' : (char)c;
    }
    s[e - a] = '\0';
    return s;
}

/* The numbers of a backslash-separated value; returns how many (values: at most 8). */
static int nums(parser *ps, size_t p, uint32_t len, double v[8], size_t *count)
{
    char *s = str(ps, p, len);
    if (!s) return -2;
    for (char *c = s; *c; c++)
        if (*c == '\\') *c = ' ';
    *count = wvol__io_parse_numbers(s, v, 8);
    free(s);
    return 0;
}

/* Returns 0, -1 (malformed: err set) or -2 (out of memory). */
static int take(parser *ps, uint16_t g, uint16_t e, size_t p, uint32_t len)
{
    const uint32_t tag = ((uint32_t)g << 16) | e;
    dicom_info *in = ps->info;
    double v[8];
    size_t nv = 0;
    uint16_t us;
    char *s;
    switch (tag) {
    case 0x00020010:
    case 0x0020000E:
        if (!(s = str(ps, p, len))) return -2;
        if (tag == 0x00020010) free(in->syntax), in->syntax = s;
        else free(in->series), in->series = s;
        break;
    case 0x00200013:
    case 0x00280008:
        if (!(s = str(ps, p, len))) return -2;
        if (tag == 0x00200013) in->instance = atoi(s);
        else in->frames = atoi(s);
        free(s);
        break;
    case 0x00280010:
    case 0x00280011:
    case 0x00280100:
    case 0x00280101:
    case 0x00280103:
    case 0x00280002:
        if (len < 2) break;
        if (u16(ps, p, &us)) return -1;
        if (tag == 0x00280010) in->rows = us;
        else if (tag == 0x00280011) in->cols = us;
        else if (tag == 0x00280100) in->bits = us;
        else if (tag == 0x00280101) in->bits_stored = us;
        else if (tag == 0x00280103) in->signed_pixels = us;
        else in->samples = us;
        break;
    case 0x00280030:
    case 0x00200032:
    case 0x00200037:
    case 0x00281053:
    case 0x00281052:
    case 0x00180050:
    case 0x00180088:
        if (nums(ps, p, len, v, &nv)) return -2;
        if (tag == 0x00280030 && nv == 2) {
            in->pixel_spacing[0] = v[0];
            in->pixel_spacing[1] = v[1];
            in->has_spacing = 1;
        } else if (tag == 0x00200032 && nv == 3) {
            memcpy(in->ipp, v, sizeof in->ipp);
            in->has_ipp = 1;
        } else if (tag == 0x00200037 && nv == 6) {
            memcpy(in->iop, v, sizeof in->iop);
            in->has_iop = 1;
        } else if (nv == 1) {
            if (tag == 0x00281053) in->slope = v[0];
            else if (tag == 0x00281052) in->inter = v[0];
            else if (tag == 0x00180050) in->thickness = v[0];
            else if (tag == 0x00180088) in->between = v[0];
        }
        break;
    case 0x7FE00010:
        in->has_pixels = 1;
        in->pixel_offset = p;
        in->pixel_bytes = len;
        break;
    default: break;
    }
    return 0;
}

static int element(parser *ps, size_t *pos, int explicit_vr, int depth);

/* Skips the items of a sequence of undefined length (up to its delimiter). */
static int skip_sequence(parser *ps, size_t *pos, int explicit_vr, int depth)
{
    if (depth > 32) return bad(ps, "sequences nested too deep");
    for (;;) {
        uint16_t g, e;
        uint32_t len;
        int r;
        if (u16(ps, *pos, &g) || u16(ps, *pos + 2, &e) || u32(ps, *pos + 4, &len)) return -1;
        *pos += 8;
        if (g != 0xFFFE) return bad(ps, "sequence item expected");
        if (e == 0xE0DD) return 0; /* sequence delimiter */
        if (e != 0xE000) return bad(ps, "sequence item expected");
        if (len != 0xFFFFFFFFu) {
            if (len > ps->n - *pos) return bad(ps, "truncated item");
            *pos += len;
            continue;
        }
        for (;;) { /* item of undefined length: elements up to the item delimiter */
            uint16_t ig, ie;
            if (u16(ps, *pos, &ig)) return -1;
            if (ig == 0xFFFE) {
                if (u16(ps, *pos + 2, &ie)) return -1;
                if (ie == 0xE00D) {
                    *pos += 8;
                    break;
                }
            }
            if ((r = element(ps, pos, explicit_vr, depth + 1))) return r;
        }
    }
}

static int element(parser *ps, size_t *pos, int explicit_vr, int depth)
{
    static const char *long_vrs[] = {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV", NULL};
    uint16_t g, e;
    uint32_t len;
    int inner_explicit = explicit_vr;
    if (u16(ps, *pos, &g) || u16(ps, *pos + 2, &e)) return -1;
    if (g == 0xFFFE) return bad(ps, "unexpected item tag");
    if (explicit_vr) {
        char vr[3] = {0, 0, 0};
        int is_long = 0;
        if (*pos + 8 > ps->n) return bad(ps, "truncated");
        vr[0] = (char)ps->b[*pos + 4];
        vr[1] = (char)ps->b[*pos + 5];
        for (int i = 0; long_vrs[i]; i++)
            if (!strcmp(vr, long_vrs[i])) is_long = 1;
        if (is_long) {
            if (u32(ps, *pos + 8, &len)) return -1;
            *pos += 12;
        } else {
            uint16_t l16;
            if (u16(ps, *pos + 6, &l16)) return -1;
            len = l16;
            *pos += 8;
        }
        if (!strcmp(vr, "UN")) inner_explicit = 0; /* UN of undefined length: implicit VR inside */
    } else {
        if (u32(ps, *pos + 4, &len)) return -1;
        *pos += 8;
    }
    if (len == 0xFFFFFFFFu) {
        if (g == 0x7FE0 && e == 0x0010 && depth == 0) {
            ps->info->has_pixels = ps->info->encapsulated = 1;
            *pos = ps->n;
            return 0;
        }
        return skip_sequence(ps, pos, inner_explicit, depth);
    }
    if (len > ps->n - *pos) {
        if (g == 0x7FE0 && e == 0x0010 && depth == 0) return bad(ps, "pixel data truncated");
        return bad(ps, "element runs past the end of the file");
    }
    if (depth == 0) {
        int r = take(ps, g, e, *pos, len);
        if (r) return r;
    }
    *pos += len;
    return 0;
}

/* 1: a DICOM Part 10 file, parsed up to its pixel data; 0: not DICOM; -1 malformed
 * (err set); -2 out of memory. */
static int parse(parser *ps)
{
    size_t pos = 132;
    int explicit_vr, r;
    uint16_t g;
    if (ps->n < 132 || memcmp(ps->b + 128, "DICM", 4) != 0) return 0;
    /* file meta group (always explicit VR little endian) */
    while (pos + 8 <= ps->n) {
        if (u16(ps, pos, &g)) return -1;
        if (g != 0x0002) break;
        if ((r = element(ps, &pos, 1, 0))) return r;
    }
    if (!ps->info->syntax || !ps->info->syntax[0]) {
        free(ps->info->syntax);
        if (!(ps->info->syntax = strdup(WVOL__DICOM_EXPLICIT_LE))) return -2;
    }
    explicit_vr = strcmp(ps->info->syntax, WVOL__DICOM_IMPLICIT_LE) != 0;
    while (pos + 8 <= ps->n && !ps->info->has_pixels)
        if ((r = element(ps, &pos, explicit_vr, 0))) return r;
    return 1;
}

int wvol__dicom_parse_file(dicom_info *info, const unsigned char *b, size_t n, wvol_error *err)
{
    parser ps;
    ps.b = b;
    ps.n = n;
    ps.info = info;
    ps.err = err;
    return parse(&ps);
}
