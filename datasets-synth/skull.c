/* SPDX-License-Identifier: MIT
 * Skull-like CT phantom in Hounsfield-like units.
 *
 * The anatomy is a set of signed-distance primitives (ellipsoids, flattened
 * capsules, slabs) in a head frame measured in millimetres over a 240 mm field of
 * view: +x patient left, +y posterior, +z superior (DICOM's LPS, which is what the
 * NRRD writer declares), the face toward -y. A voxel is painted tissue by tissue
 * (painter's order); each layer covers the voxel by clamp(0.5 - d / h) with d its
 * signed distance and h the voxel size, a one-voxel ramp that approximates the
 * partial-volume effect of a real scanner, so edges are anti-aliased at any
 * resolution and structures thinner than a voxel still show (dimmer).
 *
 * Based on: standard CT numbers (air -1000, water 0, CSF ~8, white matter ~30,
 * grey matter ~38, cancellous bone 700-1000, cortical bone ~1700-1800 HU);
 * Quilez's ellipsoid distance bound k0 (k0 - 1) / k1 for the ellipsoids. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "synth_internal.h"

#define AIR_HU (-1000.0)


/* ---- distance primitives (mm) -------------------------------------------- */


/* The radii are constants at every call, so once inlined the reciprocals are
 * folded at compile time and the divisions become multiplications. */
static inline double sd_ellipsoid(double x, double y, double z, double rx, double ry, double rz)
{
    const double ix = 1.0 / rx, iy = 1.0 / ry, iz = 1.0 / rz;
    double ax = x * ix, ay = y * iy, az = z * iz;
    double bx = ax * ix, by = ay * iy, bz = az * iz;
    double k0 = sqrt(ax * ax + ay * ay + az * az), k1 = sqrt(bx * bx + by * by + bz * bz);
    double rmin = rx < ry ? (rx < rz ? rx : rz) : (ry < rz ? ry : rz);
    return k1 > 0 ? k0 * (k0 - 1.0) / k1 : -rmin;
}

static inline double sd_ellipse2(double x, double y, double rx, double ry)
{
    const double ix = 1.0 / rx, iy = 1.0 / ry;
    double ax = x * ix, ay = y * iy, bx = ax * ix, by = ay * iy;
    double k0 = sqrt(ax * ax + ay * ay), k1 = sqrt(bx * bx + by * by);
    return k1 > 0 ? k0 * (k0 - 1.0) / k1 : -(rx < ry ? rx : ry);
}

/* Capsule with an elliptical cross-section: radius rw along the direction w
 * (made orthogonal to the axis), rt across; rt at the end caps. */
typedef struct seg {
    double a[3], b[3], w[3];
    double rw, rt;
} seg;

enum { MANDIBLE_SEGS = 8 };

typedef struct skull_ctx {
    double mm_per_u; /* head-frame millimetres per normalised unit */
    double h;        /* anti-aliasing width: largest voxel edge in mm */
    uint64_t seed;   /* bone texture */
    int table;       /* variant "ct": the scanner's patient table under the head (table_sd) */
    seg mandible[MANDIBLE_SEGS];
} skull_ctx;

static double sd_seg(const seg *s, const double p[3])
{
    double t[3], e_w[3], e_n[3], d[3], len2 = 0, tt = 0, dt, dw, dn, wt = 0, n = 0;
    double ax, ay, az, bx, by, bz, k0, k1;
    int a;
    for (a = 0; a < 3; a++) {
        t[a] = s->b[a] - s->a[a];
        len2 += t[a] * t[a];
        tt += (p[a] - s->a[a]) * t[a];
    }
    tt = len2 > 0 ? synth_clamp(tt / len2, 0.0, 1.0) : 0.0;
    for (a = 0; a < 3; a++) {
        d[a] = p[a] - (s->a[a] + tt * t[a]);
        t[a] /= sqrt(len2);
    }
    for (a = 0; a < 3; a++) wt += s->w[a] * t[a];
    for (a = 0; a < 3; a++) {
        e_w[a] = s->w[a] - wt * t[a];
        n += e_w[a] * e_w[a];
    }
    n = sqrt(n);
    for (a = 0; a < 3; a++) e_w[a] /= n;
    e_n[0] = t[1] * e_w[2] - t[2] * e_w[1];
    e_n[1] = t[2] * e_w[0] - t[0] * e_w[2];
    e_n[2] = t[0] * e_w[1] - t[1] * e_w[0];
    dt = d[0] * t[0] + d[1] * t[1] + d[2] * t[2];
    dw = d[0] * e_w[0] + d[1] * e_w[1] + d[2] * e_w[2];
    dn = d[0] * e_n[0] + d[1] * e_n[1] + d[2] * e_n[2];
    ax = dt / s->rt, ay = dw / s->rw, az = dn / s->rt;
    bx = ax / s->rt, by = ay / s->rw, bz = az / s->rt;
    k0 = sqrt(ax * ax + ay * ay + az * az);
    k1 = sqrt(bx * bx + by * by + bz * bz);
    return k1 > 0 ? k0 * (k0 - 1.0) / k1 : -(s->rt < s->rw ? s->rt : s->rw);
}

/* Round capsule from a to b. */
static inline double sd_capsule(const double p[3], double ax, double ay, double az, double bx,
                                double by, double bz, double r)
{
    double tx = bx - ax, ty = by - ay, tz = bz - az;
    double px = p[0] - ax, py = p[1] - ay, pz = p[2] - az;
    double tt = synth_clamp((px * tx + py * ty + pz * tz) / (tx * tx + ty * ty + tz * tz), 0.0, 1.0);
    px -= tt * tx;
    py -= tt * ty;
    pz -= tt * tz;
    return sqrt(px * px + py * py + pz * pz) - r;
}

static inline double smin(double a, double b, double k)
{
    double h = k - fabs(a - b);
    h = h > 0 ? h / k : 0;
    return (a < b ? a : b) - h * h * k * 0.25;
}

static inline double dmax(double a, double b)
{
    return a > b ? a : b;
}

static inline double dmin(double a, double b)
{
    return a < b ? a : b;
}

/* ---- bone texture: seeded value noise ------------------------------------ */

static double value_noise(uint64_t seed, double x, double y, double z)
{
    double fx = floor(x), fy = floor(y), fz = floor(z), acc = 0;
    double tx = x - fx, ty = y - fy, tz = z - fz;
    long ix = (long)fx, iy = (long)fy, iz = (long)fz;
    int c;
    tx = tx * tx * (3 - 2 * tx);
    ty = ty * ty * (3 - 2 * ty);
    tz = tz * tz * (3 - 2 * tz);
    for (c = 0; c < 8; c++) {
        int dx = c & 1, dy = (c >> 1) & 1, dz = c >> 2;
        uint64_t key = (uint64_t)(ix + dx) * 0x9E3779B1u + (uint64_t)(iy + dy) * 0x85EBCA77u +
                       (uint64_t)(iz + dz) * 0xC2B2AE3Du;
        double v = (double)(wvol_hash64(seed ^ wvol_hash64(key)) >> 11) * (1.0 / 9007199254740992.0);
        acc += v * (dx ? tx : 1 - tx) * (dy ? ty : 1 - ty) * (dz ? tz : 1 - tz);
    }
    return acc;
}

/* Cancellous bone (diploe, marrow) 720..1000 HU with a trabecular-looking texture. */
static inline double cancellous(const skull_ctx *c, const double p[3])
{
    return 720.0 + 280.0 * value_noise(c->seed, p[0] / 1.7, p[1] / 1.7, p[2] / 1.7);
}

/* Cortical near the surface (depth < ~1.2 mm), cancellous deeper than ~2.4 mm. */
static inline double bone_value(const skull_ctx *c, const double p[3], double depth)
{
    double w = synth_smoothstep(1.2, 2.4, depth);
    return w > 0 ? 1750.0 + (cancellous(c, p) - 1750.0) * w : 1750.0;
}

/* ---- painting ------------------------------------------------------------ */

typedef struct paint {
    double v;
    int label;
    double h;
} paint;

static inline void layer(paint *s, double d, double value, int label)
{
    double a = 0.5 - d / s->h;
    if (a <= 0) return;
    if (a >= 1) {
        s->v = value;
        s->label = label;
        return;
    }
    s->v += (value - s->v) * a;
    if (a >= 0.5) s->label = label;
}

/* ---- anatomy ------------------------------------------------------------- */

static void mandible_init(skull_ctx *c)
{
    /* One side: condyle -> angle (ramus: wide along y), angle -> chin (body: tall along z). */
    static const double pts[5][3] = {
        {51, 6, -34}, {49, 14, -76}, {43, -20, -84}, {28, -50, -88}, {0, -62, -90}};
    int s, side, n = 0, a;
    for (side = 0; side < 2; side++)
        for (s = 0; s < 4; s++) {
            seg *g = &c->mandible[n++];
            double sign = side ? -1.0 : 1.0;
            for (a = 0; a < 3; a++) {
                g->a[a] = pts[s][a] * (a == 0 ? sign : 1.0);
                g->b[a] = pts[s + 1][a] * (a == 0 ? sign : 1.0);
                g->w[a] = 0;
            }
            if (s == 0) {
                g->w[1] = 1;
                g->rw = 12.0, g->rt = 4.0;
            } else {
                g->w[2] = 1;
                g->rw = 12.5 - 1.0 * s, g->rt = 5.5;
            }
        }
}

static double sd_mandible(const skull_ctx *c, const double p[3])
{
    double dm = INFINITY;
    int n;
    for (n = 0; n < MANDIBLE_SEGS; n++) {
        const seg *g = &c->mandible[n];
        if ((g->a[0] > 0) != (p[0] > 0) && fabs(p[0]) > 8) continue;
        dm = dmin(dm, sd_seg(g, p));
    }
    return dm;
}

/* Floor of the cranial cavity (top of the skull base) as a height field:
 * anterior fossa over the orbits, middle fossae (lower at the sides), posterior fossa. */
static inline double skull_base_z(double x, double y)
{
    double zb = -8.0 - 16.0 * synth_smoothstep(-40.0, -15.0, y) - 16.0 * synth_smoothstep(0.0, 30.0, y);
    return zb - 4.0 * synth_smoothstep(10.0, 40.0, fabs(x)) * (1.0 - synth_smoothstep(5.0, 30.0, y));
}

/* Variant "ct": the patient table, a thin curved shell outside the head (a carbon-fibre
 * cradle: 2.4 mm thick, 250 HU), an arc of a cylinder along z behind the head (+y,
 * posterior: the patient lies supine), concave towards it, 8 mm clear of the occiput at
 * its deepest point. Signed distance in mm. */
#define TABLE_HU 250.0
static inline double table_sd(double x, double y)
{
    const double R = 300.0, yc = 110.0 - R, half = 1.2;
    double r = sqrt(x * x + (y - yc) * (y - yc));
    return dmax(fabs(r - R) - half, fabs(x) - 115.0);
}

/* Paints one point; returns the distance (mm) to the nearest thing that is not air (the
 * head, and the table for variant "ct") so the caller can skip ahead through air. */
static double skull_point(const skull_ctx *c, const double p[3], float *out_v, float *out_l)
{
    const double x = p[0], y = p[1], z = p[2], ax = fabs(x), sx = x < 0 ? -1.0 : 1.0, h = c->h;
    paint s = {AIR_HU, WVOL_SKULL_AIR, h};
    double d_cr, d_face, d_head, d, t, dm = INFINITY;
    int jaw_zone = y < 25 && z < -20 && z > -115 && ax < 66;

    /* Head outline: cranium, face (a rounded back part and a flatter front), chin,
     * soft tissue around the jaw, neck, nose, ears. */
    d_cr = sd_ellipsoid(x, y - 5.0, z - 25.0, 74.0, 94.0, 84.0);
    d_face = smin(sd_ellipsoid(x, y + 12.0, z + 50.0, 60.0, 60.0, 58.0),
                  sd_ellipsoid(x, y + 55.0, z + 35.0, 62.0, 38.0, 55.0), 10.0);
    d_head = smin(d_cr, d_face, 16.0);
    d_head = smin(d_head, dmax(sd_ellipse2(x, y - 15.0, 50.0, 48.0), z + 40.0), 20.0);
    if (z < -60 && y < -20) d_head = smin(d_head, sd_ellipsoid(x, y + 55.0, z + 88.0, 32.0, 20.0, 22.0), 8.0);
    if (jaw_zone) {
        dm = sd_mandible(c, p);
        d_head = smin(d_head, dm - 7.0, 6.0);
    }
    if (y < -60 && z < 5 && z > -70)
        d_head = smin(d_head, sd_ellipsoid(x, y + 92.0, z + 28.0, 13.0, 16.0, 24.0), 6.0);
    if (ax > 60 && z < 30 && z > -45)
        d_head = smin(d_head, sd_ellipsoid(ax - 76.0, y - 8.0, z + 8.0, 7.0, 17.0, 27.0), 4.0);
    if (c->table) { /* outside the head only: paint it, and let the skip ahead stop at it */
        double dt = table_sd(x, y);
        if (d_head > h) {
            layer(&s, dt, TABLE_HU, WVOL_SKULL_AIR); /* not anatomy */
            *out_v = (float)s.v;
            if (out_l) *out_l = (float)s.label;
            return dmin(d_head, dt);
        }
    }
    if (d_head > h) {
        *out_v = (float)AIR_HU;
        if (out_l) *out_l = WVOL_SKULL_AIR;
        return d_head;
    }
    /* Soft tissue, skin slightly denser. */
    layer(&s, d_head, 45.0 + 20.0 * (1.0 - synth_smoothstep(1.0, 3.0, -d_head)), WVOL_SKULL_SOFT);

    /* Cranial vault: a shell under 5 mm of scalp whose thickness varies from ~3 mm
     * (temporal squama) to ~9 mm (occipital), closed below by the skull base. */
    if (d_cr < h) {
        const double scalp = 5.0;
        double zb = skull_base_z(x, y), T, d_in, shell, plate, hole, cav;
        T = 6.5 + 2.5 * synth_smoothstep(40.0, 90.0, y) + 1.5 * synth_smoothstep(-40.0, -85.0, y) -
            3.5 * synth_smoothstep(45.0, 68.0, ax) * (1.0 - synth_smoothstep(30.0, 60.0, z));
        d_in = d_cr + scalp + T; /* < 0 inside the inner table */
        shell = dmax(dmax(d_cr + scalp, -d_in), (zb - 5.0) - z);
        if (shell < h) {
            /* frontal sinus: a thin air pocket inside the forehead bone */
            double fs = sd_ellipsoid(x, y + 77.0, z - 4.0, 15.0, 2.4, 9.0);
            layer(&s, shell, bone_value(c, p, dmin(-shell, fs)), WVOL_SKULL_BONE);
            if (fs < h) layer(&s, fs, AIR_HU, WVOL_SKULL_AIR);
        }
        /* skull base plate with the foramen magnum */
        hole = sd_ellipse2(x, y - 28.0, 14.0, 17.0);
        plate = dmax(dmax(fabs(z - (zb - 2.5)) - 2.5, d_cr + scalp + 1.0), -hole);
        if (plate < h) layer(&s, plate, bone_value(c, p, -plate), WVOL_SKULL_BONE);
        /* clivus: from the dorsum sellae down to the front rim of the foramen magnum */
        if (ax < 12 && y > -20 && y < 20 && z < -5 && z > -55) {
            d = sd_capsule(p, 0, -6, -22, 0, 9, -42, 5.0);
            layer(&s, d, bone_value(c, p, -d), WVOL_SKULL_BONE);
        }
        /* intracranial: CSF under the inner table, brain (grey rim, white core) */
        cav = dmax(d_in, zb - z);
        if (cav < h) {
            double brain = dmax(d_in + 2.0, zb + 2.0 - z);
            layer(&s, cav, 8.0, WVOL_SKULL_CSF);
            if (brain < h) {
                layer(&s, brain, 39.0 - 10.0 * synth_smoothstep(2.5, 5.0, -brain), WVOL_SKULL_BRAIN);
                /* lateral ventricles and the thin third ventricle */
                if (ax < 25 && z > -5 && z < 45 && y > -40 && y < 40) {
                    d = dmin(sd_ellipsoid(ax - 11.0, y - 2.0, z - 27.0, 6.0, 28.0, 9.0),
                             dmax(dmax(ax - 1.5, fabs(y - 2.0) - 12.0), fabs(z - 10.0) - 9.0));
                    layer(&s, d, 8.0, WVOL_SKULL_CSF);
                }
                /* falx cerebri: a 1.2 mm dural sheet in the midline */
                if (ax < 2 && z > 20)
                    layer(&s, dmax(dmax(ax - 0.6, brain + 1.0), 20.0 - z), 55.0, WVOL_SKULL_SOFT);
            }
        }
        /* brainstem through the foramen magnum */
        if (ax < 14 && y > 5 && y < 40 && z < 5)
            layer(&s, dmax(dmax(sd_ellipse2(x, y - 24.0, 11.0, 10.0), z - 2.0), -z - 46.0), 34.0,
                  WVOL_SKULL_BRAIN);
    }

    /* Face skeleton: a bone block below the anterior fossa and above the palate
     * (reaching back to the sphenoid above, to the pterygoid plates below),
     * hollowed by the orbits, nasal cavity and sinuses, whose walls are thin. */
    if (y < 0 && z < 0 && z > -66) {
        double yb = -2.0 - 26.0 * synth_smoothstep(-28.0, -36.0, z);
        double block = dmax(dmax(d_face + 9.0, y - yb), dmax(-62.0 - z, z + 4.0));
        if (block < h) {
            double orbit = sd_ellipsoid(ax - 33.0, y + 62.0, z + 18.0, 17.0, 24.0, 16.0);
            double nasal = sd_ellipsoid(x, y + 60.0, z + 38.0, 12.0, 34.0, 20.0);
            double maxs = sd_ellipsoid(ax - 26.0, y + 56.0, z + 46.0, 13.0, 17.0, 12.0);
            double sph = sd_ellipsoid(x, y + 15.0, z + 24.0, 11.0, 10.0, 9.0);
            double cavs = dmin(dmin(orbit, nasal), dmin(maxs, sph));
            layer(&s, block, bone_value(c, p, dmin(-block, cavs)), WVOL_SKULL_BONE);
            layer(&s, dmax(block - 0.5, orbit), 25.0, WVOL_SKULL_SOFT);
            layer(&s, dmax(block - 0.5, maxs), AIR_HU, WVOL_SKULL_AIR);
            layer(&s, dmax(block - 0.5, sph), AIR_HU, WVOL_SKULL_AIR);
        }
    }
    /* Airway: trachea and pharynx up to the back of the nasal cavity. */
    if (z < -30 && y > -35 && y < 0 && ax < 12) {
        d = dmin(sd_capsule(p, 0, -16, -140, 0, -16, -62, 7.0), sd_capsule(p, 0, -16, -62, 0, -24, -42, 7.5));
        layer(&s, d, AIR_HU, WVOL_SKULL_AIR);
    }
    /* Nasal cavity (air) reaching into the nose, nostrils, septum (1.4 mm: bone
     * behind, cartilage in front), turbinates (rods of 2.4 to 3.2 mm). */
    if (ax < 16 && y < -20 && y > -110 && z < -15 && z > -62) {
        double nasal = sd_ellipsoid(x, y + 60.0, z + 38.0, 12.0, 34.0, 20.0);
        double nost = sd_capsule(p, 6.0 * sx, -88, -44, 6.0 * sx, -101, -57, 3.5);
        double sept, turb;
        layer(&s, dmin(nasal, nost), AIR_HU, WVOL_SKULL_AIR);
        sept = dmax(dmax(ax - 0.7, nasal + 0.3), -z - 56.0);
        layer(&s, sept, y < -80 ? 75.0 : 1250.0, y < -80 ? WVOL_SKULL_SOFT : WVOL_SKULL_BONE);
        turb = dmin(dmin(sd_capsule(p, 8.5 * sx, -72, -50, 8.5 * sx, -38, -50, 1.6),
                         sd_capsule(p, 8.5 * sx, -70, -41, 8.5 * sx, -36, -41, 1.4)),
                    sd_capsule(p, 8.0 * sx, -64, -31, 8.0 * sx, -36, -31, 1.2));
        layer(&s, dmax(turb, nasal), 900.0, WVOL_SKULL_BONE);
    }
    /* Eyes: globe, lens, optic nerve (a 4.4 mm rod). */
    if (ax > 10 && ax < 52 && y < -20 && y > -90 && z < 0 && z > -36) {
        double ex = ax - 33.0;
        layer(&s, sd_capsule(p, 33.0 * sx, -62, -18, 14.0 * sx, -30, -14, 2.2), 36.0, WVOL_SKULL_SOFT);
        layer(&s, sd_ellipsoid(ex, y + 72.0, z + 18.0, 11.5, 11.5, 11.5), 12.0, WVOL_SKULL_SOFT);
        layer(&s, sd_ellipsoid(ex, y + 81.5, z + 18.0, 4.5, 2.0, 4.5), 75.0, WVOL_SKULL_SOFT);
    }
    /* Zygomatic arches, styloid processes (2 mm rods), mastoids. */
    if (ax > 25 && ax < 66 && y > -62 && y < 35 && z < -15 && z > -72) {
        double m;
        d = sd_capsule(p, 42.0 * sx, -55, -28, 52.0 * sx, 2, -24, 3.2);
        layer(&s, d, bone_value(c, p, -d), WVOL_SKULL_BONE);
        layer(&s, sd_capsule(p, 34.0 * sx, 8, -40, 30.0 * sx, -6, -68, 1.0), 1300.0, WVOL_SKULL_BONE);
        m = sd_ellipsoid(ax - 40.0, y - 20.0, z + 38.0, 7.0, 9.0, 12.0);
        layer(&s, m, bone_value(c, p, -m), WVOL_SKULL_BONE);
    }
    /* Jaw: the mandible (cortical shell, marrow inside) and two rows of teeth. */
    if (jaw_zone) {
        layer(&s, dm, bone_value(c, p, -dm * 0.8), WVOL_SKULL_BONE);
        if (z < -58 && z > -86 && y < -20) {
            double dt = INFINITY;
            int n;
            for (n = 0; n < 7; n++) {
                double th = ((double)n + 0.5) / 7.0 * 1.396, r = 2.6 + 0.25 * n;
                double tx = 32.0 * sin(th) * sx, ty = -62.0 + 37.0 * (1.0 - cos(th));
                dt = dmin(dt, sd_ellipsoid(x - tx, y - ty, z + 66.5, r, r, 4.5));
                dt = dmin(dt, sd_ellipsoid(x - tx, y - ty, z + 77.0, r, r, 4.5));
            }
            layer(&s, dt, 1800.0, WVOL_SKULL_BONE);
        }
    }
    /* Cervical spine: vertebral bodies with discs, posterior arches, canal, cord. */
    if (z < -40 && y > -10 && y < 50 && ax < 20) {
        double zl = z + 140.0, loc, body, arch, canal;
        loc = zl - 17.0 * floor(zl / 17.0); /* 0..17 within one level */
        t = fabs(loc - 6.5) - 6.5;          /* < 0 within the 13 mm bone part */
        body = dmax(dmax(sd_ellipse2(x, y - 6.0, 13.0, 10.0), t), z + 58.0);
        layer(&s, dmax(sd_ellipse2(x, y - 6.0, 12.5, 9.5), z + 58.0), 75.0, WVOL_SKULL_SOFT);
        layer(&s, body, bone_value(c, p, -body), WVOL_SKULL_BONE);
        canal = sd_ellipse2(x, y - 28.0, 9.0, 8.0);
        arch = dmax(dmax(dmax(sd_ellipse2(x, y - 28.0, 14.0, 13.0), -canal), t), z + 50.0);
        layer(&s, dmax(arch, 17.0 - y), bone_value(c, p, -arch), WVOL_SKULL_BONE);
        layer(&s, dmax(canal, z + 44.0), 8.0, WVOL_SKULL_CSF);
        layer(&s, dmax(sd_ellipse2(x, y - 28.0, 5.5, 5.0), z + 44.0), 34.0, WVOL_SKULL_BRAIN);
    }

    *out_v = (float)s.v;
    if (out_l) *out_l = (float)s.label;
    return d_head;
}

static void skull_row(const void *vctx, const synth_grid *g, size_t j, size_t k, float *row, float *lab)
{
    const skull_ctx *c = vctx;
    double p[3], dx = g->spacing[0] * g->scale * c->mm_per_u;
    size_t i = 0;
    p[1] = synth_u(g, 1, j) * c->mm_per_u;
    p[2] = synth_u(g, 2, k) * c->mm_per_u;
    while (i < g->nx) {
        double d;
        size_t skip, e;
        p[0] = synth_u(g, 0, i) * c->mm_per_u;
        d = skull_point(c, p, row + i, lab ? lab + i : NULL);
        i++;
        if (d <= c->h) continue;
        /* Every point closer than d - h is still air. The distance is an estimate
         * (smooth unions only shrink it), so only half of the margin is trusted. */
        skip = (size_t)(0.5 * (d - c->h) / dx);
        for (e = 0; e < skip && i < g->nx; e++, i++) {
            row[i] = (float)AIR_HU;
            if (lab) lab[i] = WVOL_SKULL_AIR;
        }
    }
}

wvol_status wvol__synth_plan_skull(synth_plan *pl, const wvol_synth_params *p, wvol_error *err)
{
    skull_ctx *cp;
    double def[3], nmax;
    WVOL_RETURN_IF(!p, err, WVOL_ERR_ARG, "synth skull: NULL parameters");
    WVOL_RETURN_IF(p->variant && *p->variant && strcmp(p->variant, "head") && strcmp(p->variant, "ct"), err,
                   WVOL_ERR_ARG, "synth skull: unknown variant '%s' (known: head, ct)", p->variant);
    nmax = (double)(p->dims[0] > p->dims[1] ? p->dims[0] : p->dims[1]);
    if ((double)p->dims[2] > nmax) nmax = (double)p->dims[2];
    def[0] = def[1] = def[2] = nmax > 0 ? 240.0 / nmax : 1.0;
    WVOL_FORWARD(wvol__synth_geometry(&pl->g, p, def, "skull", err));
    WVOL_RETURN_IF(!(cp = wvol__synth_plan_ctx(pl, sizeof *cp, skull_row)), err, WVOL_ERR_NOMEM,
                   "synth skull: out of memory");
    pl->has_labels = 1;
    mandible_init(cp);
    cp->mm_per_u = 120.0;
    cp->h = pl->g.voxel_u * 120.0;
    cp->seed = wvol_hash64(p->seed ^ 0x5C011ull);
    cp->table = p->variant && !strcmp(p->variant, "ct");
    return WVOL_OK;
}

wvol_status wvol_synth_skull(wvol_volume **out, wvol_volume **labels, const wvol_synth_params *p,
                             wvol_error *err)
{
    return wvol__synth_whole(out, labels, wvol__synth_plan_skull, p, "skull", err);
}
