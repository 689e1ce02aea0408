/* SPDX-License-Identifier: MIT
 * Cameras: look-at frames, default framing of a volume, the text description, ray generation. */
#define _POSIX_C_SOURCE 200809L
#include "render_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

void wvol_geometry_of_volume(wvol_geometry *g, const wvol_volume *v)
{
    int a;
    g->dims[0] = v->nx;
    g->dims[1] = v->ny;
    g->dims[2] = v->nz;
    for (a = 0; a < 3; a++) {
        g->spacing[a] = v->spacing[a];
        g->origin[a] = v->origin[a];
    }
}

void wvol_geometry_of_coeffs(wvol_geometry *g, const wvol_coeffs *c)
{
    int a;
    if (!g) return;
    if (!c) {
        memset(g, 0, sizeof *g);
        return;
    }
    g->dims[0] = c->nx;
    g->dims[1] = c->ny;
    g->dims[2] = c->nz;
    for (a = 0; a < 3; a++) {
        g->spacing[a] = c->spacing[a];
        g->origin[a] = c->origin[a];
    }
}

void wvol_geometry_bounds(const wvol_geometry *g, double lo[3], double hi[3])
{
    int a;
    if (!lo || !hi) return;
    if (!g) {
        for (a = 0; a < 3; a++) lo[a] = hi[a] = 0.0;
        return;
    }
    for (a = 0; a < 3; a++) {
        lo[a] = g->origin[a] - 0.5 * g->spacing[a];
        hi[a] = g->origin[a] + ((double)g->dims[a] - 0.5) * g->spacing[a];
    }
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void cross3(double o[3], const double a[3], const double b[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}
/* Normalises a in place and returns its length; scaled first, so that a finite vector of any
 * magnitude keeps its direction (dot3 of a 1e200 vector is Inf). */
static double norm3(double a[3])
{
    double m = fmax(fabs(a[0]), fmax(fabs(a[1]), fabs(a[2]))), n;
    if (!(m > 0) || !isfinite(m)) return m > 0 ? m : 0.0;
    a[0] /= m, a[1] /= m, a[2] /= m;
    n = sqrt(dot3(a, a));
    a[0] /= n, a[1] /= n, a[2] /= n;
    return n * m;
}
static int finite3(const double a[3]) { return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]); }

/* Camera positions (eye, center) within +-1e150: the rays and the framing take squared lengths of
 * their differences, which overflow to Inf beyond about 1e154. Directions (dir=, up) may have any
 * finite length: norm3 scales them first. */
#define CAMERA_COORD_MAX 1e150
static int in_range3(const double a[3])
{
    return fabs(a[0]) <= CAMERA_COORD_MAX && fabs(a[1]) <= CAMERA_COORD_MAX && fabs(a[2]) <= CAMERA_COORD_MAX;
}

wvol_status wvol_camera_check(const wvol_camera *cam, wvol_error *err)
{
    double f[3], r[3], u[3], nf, nu;
    int a;
    WVOL_RETURN_IF(!cam, err, WVOL_ERR_ARG, "camera: none given");
    WVOL_RETURN_IF(cam->width < 1 || cam->height < 1 || cam->width > 65536 || cam->height > 65536, err,
                   WVOL_ERR_ARG, "camera: image size %dx%d (each side 1..65536)", cam->width, cam->height);
    WVOL_RETURN_IF(cam->projection != WVOL_PROJECTION_ORTHOGRAPHIC && cam->projection != WVOL_PROJECTION_PERSPECTIVE, err, WVOL_ERR_ARG,
                   "camera: unknown projection %d", (int)cam->projection);
    WVOL_RETURN_IF(!finite3(cam->eye) || !finite3(cam->center) || !finite3(cam->up), err, WVOL_ERR_ARG,
                   "camera: eye, center and up must be finite");
    WVOL_RETURN_IF(!in_range3(cam->eye) || !in_range3(cam->center), err, WVOL_ERR_ARG,
                   "camera: eye (%g, %g, %g) and center (%g, %g, %g) must lie within +-%g", cam->eye[0], cam->eye[1],
                   cam->eye[2], cam->center[0], cam->center[1], cam->center[2], CAMERA_COORD_MAX);
    for (a = 0; a < 3; a++) {
        f[a] = cam->center[a] - cam->eye[a];
        u[a] = cam->up[a];
    }
    nf = norm3(f);
    nu = norm3(u);
    WVOL_RETURN_IF(!(nf > 0), err, WVOL_ERR_ARG, "camera: eye and center coincide (%g, %g, %g)", cam->eye[0],
                   cam->eye[1], cam->eye[2]);
    WVOL_RETURN_IF(!(nu > 0), err, WVOL_ERR_ARG, "camera: up vector is zero");
    cross3(r, f, u);
    WVOL_RETURN_IF(!(sqrt(dot3(r, r)) > 1e-9), err, WVOL_ERR_ARG,
                   "camera: up (%g, %g, %g) is parallel to the view direction", cam->up[0], cam->up[1], cam->up[2]);
    if (cam->projection == WVOL_PROJECTION_PERSPECTIVE)
        WVOL_RETURN_IF(!(cam->fov_y > 0 && cam->fov_y < 180), err, WVOL_ERR_ARG,
                       "camera: field of view %g degrees (must be in (0, 180))", cam->fov_y);
    else
        WVOL_RETURN_IF(!(cam->view_height > 0) || !isfinite(cam->view_height), err, WVOL_ERR_ARG,
                       "camera: orthographic view height %g (must be > 0)", cam->view_height);
    return WVOL_OK;
}

void wvol__cam_init(wvol__cam *k, const wvol_camera *cam)
{
    int a;
    double aspect = (double)cam->width / (double)cam->height;
    k->c = *cam;
    for (a = 0; a < 3; a++) k->fwd[a] = cam->center[a] - cam->eye[a];
    norm3(k->fwd);
    cross3(k->right, k->fwd, cam->up);
    norm3(k->right);
    cross3(k->up, k->right, k->fwd);
    if (cam->projection == WVOL_PROJECTION_ORTHOGRAPHIC) {
        k->half_h = 0.5 * cam->view_height;
        k->half_w = k->half_h * aspect;
    } else {
        k->half_h = tan(0.5 * cam->fov_y * PI / 180.0);
        k->half_w = k->half_h * aspect;
    }
}

void wvol__cam_ray(const wvol__cam *k, double px, double py, double o[3], double d[3])
{
    double u = px / k->c.width * 2.0 - 1.0, v = 1.0 - py / k->c.height * 2.0;
    int a;
    if (k->c.projection == WVOL_PROJECTION_ORTHOGRAPHIC) {
        for (a = 0; a < 3; a++) {
            o[a] = k->c.eye[a] + u * k->half_w * k->right[a] + v * k->half_h * k->up[a];
            d[a] = k->fwd[a];
        }
    } else {
        for (a = 0; a < 3; a++) {
            o[a] = k->c.eye[a];
            d[a] = k->fwd[a] + u * k->half_w * k->right[a] + v * k->half_h * k->up[a];
        }
        norm3(d);
    }
}

void wvol__cam_box_pixels(const wvol__cam *k, const double lo[3], const double hi[3], int r[4])
{
    const int w = k->c.width, h = k->c.height;
    double pmin[2] = {INFINITY, INFINITY}, pmax[2] = {-INFINITY, -INFINITY};
    r[0] = 0, r[1] = 0, r[2] = w, r[3] = h;
    for (int c = 0; c < 8; c++) {
        double rel[3], x, y, z, u, v;
        for (int a = 0; a < 3; a++) rel[a] = ((c >> a) & 1 ? hi[a] : lo[a]) - k->c.eye[a];
        x = dot3(rel, k->right), y = dot3(rel, k->up), z = dot3(rel, k->fwd);
        if (k->c.projection == WVOL_PROJECTION_PERSPECTIVE) {
            if (!(z > 0)) return; /* a corner at or behind the eye's plane: the whole image */
            x /= z, y /= z;
        }
        u = x / k->half_w, v = y / k->half_h;
        if (!isfinite(u) || !isfinite(v)) return;
        /* pixel coordinates: cam_ray's u = px / width * 2 - 1, v = 1 - py / height * 2 */
        x = 0.5 * (u + 1.0) * w, y = 0.5 * (1.0 - v) * h;
        pmin[0] = fmin(pmin[0], x), pmax[0] = fmax(pmax[0], x);
        pmin[1] = fmin(pmin[1], y), pmax[1] = fmax(pmax[1], y);
    }
    /* pixel i's centre is at i + 1/2: keep every pixel whose centre lies within two pixels of
     * the corners' box (far beyond the rounding of either computation) */
    for (int a = 0; a < 2; a++) {
        const double n = a ? h : w, l = floor(pmin[a] - 2.5), u = ceil(pmax[a] + 2.5);
        r[a] = l > 0 ? (l < n ? (int)l : (int)n) : 0;
        r[a + 2] = u < n ? (u > r[a] ? (int)u : r[a]) : (int)n;
    }
}

void wvol_camera_ray(const wvol_camera *cam, double px, double py, double origin[3], double dir[3])
{
    wvol__cam k;
    if (!origin || !dir) return;
    if (!cam) {
        for (int a = 0; a < 3; a++) origin[a] = dir[a] = 0.0;
        return;
    }
    wvol__cam_init(&k, cam);
    wvol__cam_ray(&k, px, py, origin, dir);
}

int wvol__ray_box(const double o[3], const double d[3], const double lo[3], const double hi[3], double *t0,
                  double *t1)
{
    double a = -INFINITY, b = INFINITY;
    int i;
    for (i = 0; i < 3; i++) {
        if (d[i] == 0.0) {
            if (!(o[i] > lo[i] && o[i] < hi[i])) return 0;
        } else {
            double inv = 1.0 / d[i], ta = (lo[i] - o[i]) * inv, tb = (hi[i] - o[i]) * inv;
            if (ta > tb) {
                double s = ta;
                ta = tb;
                tb = s;
            }
            if (ta > a) a = ta;
            if (tb < b) b = tb;
        }
    }
    if (!(b > a)) return 0;
    *t0 = a;
    *t1 = b;
    return 1;
}

wvol_status wvol_camera_frame(wvol_camera *cam, const wvol_geometry *g, const double view_dir[3],
                              wvol_projection projection, int width, int height, double fov_y, wvol_error *err)
{
    double lo[3], hi[3], c[3], d[3], up[3] = {0, 0, 1}, r[3], u[3], radius = 0, ulo = INFINITY, uhi = -INFINITY,
                                                                    vlo = INFINITY, vhi = -INFINITY, aspect;
    int a, corner;
    WVOL_RETURN_IF(!cam || !g, err, WVOL_ERR_ARG, "camera: no camera or geometry");
    WVOL_RETURN_IF(!view_dir || !finite3(view_dir), err, WVOL_ERR_ARG, "camera: view direction must be finite");
    for (a = 0; a < 3; a++) d[a] = view_dir[a];
    WVOL_RETURN_IF(!(norm3(d) > 0), err, WVOL_ERR_ARG, "camera: view direction is zero");
    WVOL_RETURN_IF(width < 1 || height < 1 || width > 65536 || height > 65536, err, WVOL_ERR_ARG,
                   "camera: image size %dx%d (each side 1..65536)", width, height);
    /* fov_y <= 0 asks for the default; NaN or Inf would make every ray NaN */
    WVOL_RETURN_IF(projection == WVOL_PROJECTION_PERSPECTIVE && (!isfinite(fov_y) || fov_y >= 180), err, WVOL_ERR_ARG,
                   "camera: field of view %g degrees (must be below 180, or <= 0 for the default)", fov_y);
    wvol_geometry_bounds(g, lo, hi);
    for (a = 0; a < 3; a++) c[a] = 0.5 * (lo[a] + hi[a]);
    if (fabs(d[2]) > 0.999999 * sqrt(dot3(d, d))) up[1] = 1, up[2] = 0;
    cross3(r, d, up);
    norm3(r);
    cross3(u, r, d);
    for (corner = 0; corner < 8; corner++) {
        double p[3], pu, pv;
        for (a = 0; a < 3; a++) p[a] = ((corner >> a) & 1 ? hi[a] : lo[a]) - c[a];
        pu = dot3(p, r);
        pv = dot3(p, u);
        ulo = fmin(ulo, pu), uhi = fmax(uhi, pu), vlo = fmin(vlo, pv), vhi = fmax(vhi, pv);
        radius = fmax(radius, sqrt(dot3(p, p)));
    }
    aspect = (double)width / (double)height;
    memset(cam, 0, sizeof *cam);
    cam->projection = projection;
    cam->width = width;
    cam->height = height;
    cam->fov_y = fov_y > 0 ? fov_y : 30.0;
    for (a = 0; a < 3; a++) {
        cam->center[a] = c[a];
        cam->up[a] = up[a];
    }
    if (projection == WVOL_PROJECTION_ORTHOGRAPHIC) {
        /* the projected box is symmetric about the centre: frame its larger relative extent */
        double hu = fmax(fabs(ulo), fabs(uhi)), hv = fmax(fabs(vlo), fabs(vhi));
        cam->view_height = 2.0 * fmax(hv, hu / aspect);
        for (a = 0; a < 3; a++) cam->eye[a] = c[a] - d[a] * 2.0 * radius;
    } else {
        double half = 0.5 * cam->fov_y * PI / 180.0, t = tan(half), s = t * fmin(aspect, 1.0), dist;
        cam->view_height = 2.0 * radius;
        dist = radius / sin(atan(s));
        for (a = 0; a < 3; a++) cam->eye[a] = c[a] - d[a] * dist;
    }
    return wvol_camera_check(cam, err);
}

static int parse_vec(const char *s, double out[3])
{
    char *end;
    int i;
    for (i = 0; i < 3; i++) {
        out[i] = strtod(s, &end);
        if (end == s || !isfinite(out[i])) return 0;
        s = end;
        if (i < 2) {
            if (*s != ',') return 0;
            s++;
        }
    }
    return *s == 0;
}

static int parse_num(const char *s, double *out)
{
    char *end;
    *out = strtod(s, &end);
    return end != s && *end == 0 && isfinite(*out);
}

static int parse_axis(const char *s, double dir[3])
{
    int a;
    if ((s[0] != '+' && s[0] != '-') || !s[1] || s[2]) return 0;
    a = s[1] == 'x' || s[1] == 'X' ? 0 : s[1] == 'y' || s[1] == 'Y' ? 1 : s[1] == 'z' || s[1] == 'Z' ? 2 : -1;
    if (a < 0) return 0;
    if (!dir) return 1; /* only asked whether s is an axis */
    dir[0] = dir[1] = dir[2] = 0;
    dir[a] = s[0] == '+' ? -1.0 : 1.0; /* looking from +a means looking along -a */
    return 1;
}

wvol_status wvol_camera_parse(wvol_camera *cam, const char *spec, const wvol_geometry *g, int width, int height,
                              wvol_error *err)
{
    char buf[512], *tok, *save = NULL;
    double dir[3] = {0, 0, -1}, eye[3], center[3], up[3], fov = 0, height_w = 0, zoom = 1;
    int have_eye = 0, have_center = 0, have_up = 0, a;
    int n_proj = 0, n_dir = 0, n_fov = 0, n_height = 0, n_zoom = 0; /* each said at most once */
    wvol_projection proj = WVOL_PROJECTION_ORTHOGRAPHIC;
    wvol_status s;

    WVOL_RETURN_IF(!spec, err, WVOL_ERR_ARG, "camera: no description");
    WVOL_RETURN_IF(strlen(spec) >= sizeof buf, err, WVOL_ERR_ARG, "camera: description too long");
    strcpy(buf, spec);
    for (tok = strtok_r(buf, " \t;", &save); tok; tok = strtok_r(NULL, " \t;", &save)) {
        char *eq = strchr(tok, '=');
        const char *val = eq ? eq + 1 : NULL;
        if (eq) *eq = 0;
        /* a second word of one kind would silently override the first ("ortho persp", "+x +y") */
        int proj_word = !eq && (!strcmp(tok, "ortho") || !strcmp(tok, "orthographic") || !strcmp(tok, "persp") ||
                                !strcmp(tok, "perspective"));
        int dir_word = (!eq && parse_axis(tok, NULL)) || (eq && (!strcmp(tok, "from") || !strcmp(tok, "dir")));
        int dup = (proj_word && n_proj++) || (dir_word && n_dir++) || (eq && !strcmp(tok, "eye") && have_eye) ||
                  (eq && !strcmp(tok, "center") && have_center) || (eq && !strcmp(tok, "up") && have_up) ||
                  (eq && !strcmp(tok, "fov") && n_fov++) || (eq && !strcmp(tok, "height") && n_height++) ||
                  (eq && !strcmp(tok, "zoom") && n_zoom++);
        WVOL_RETURN_IF(dup, err, WVOL_ERR_ARG, "camera: '%s%s%s' says again what an earlier word said (%s)", tok,
                       eq ? "=" : "", val ? val : "",
                       proj_word ? "the projection" : dir_word ? "the direction" : "the same setting");
        if (!eq && (!strcmp(tok, "ortho") || !strcmp(tok, "orthographic"))) proj = WVOL_PROJECTION_ORTHOGRAPHIC;
        else if (!eq && (!strcmp(tok, "persp") || !strcmp(tok, "perspective"))) proj = WVOL_PROJECTION_PERSPECTIVE;
        else if (!eq && parse_axis(tok, dir)) continue;
        else if (eq && !strcmp(tok, "from")) {
            WVOL_RETURN_IF(!parse_axis(val, dir), err, WVOL_ERR_ARG,
                           "camera: from='%s' is not an axis (+x -x +y -y +z -z)", val);
        } else if (eq && !strcmp(tok, "dir")) {
            WVOL_RETURN_IF(!parse_vec(val, dir), err, WVOL_ERR_ARG, "camera: dir='%s' is not X,Y,Z", val);
        } else if (eq && !strcmp(tok, "eye")) {
            WVOL_RETURN_IF(!parse_vec(val, eye), err, WVOL_ERR_ARG, "camera: eye='%s' is not X,Y,Z", val);
            WVOL_RETURN_IF(!in_range3(eye), err, WVOL_ERR_ARG, "camera: eye='%s' lies beyond +-%g", val,
                           CAMERA_COORD_MAX);
            have_eye = 1;
        } else if (eq && !strcmp(tok, "center")) {
            WVOL_RETURN_IF(!parse_vec(val, center), err, WVOL_ERR_ARG, "camera: center='%s' is not X,Y,Z", val);
            WVOL_RETURN_IF(!in_range3(center), err, WVOL_ERR_ARG, "camera: center='%s' lies beyond +-%g", val,
                           CAMERA_COORD_MAX);
            have_center = 1;
        } else if (eq && !strcmp(tok, "up")) {
            WVOL_RETURN_IF(!parse_vec(val, up), err, WVOL_ERR_ARG, "camera: up='%s' is not X,Y,Z", val);
            have_up = 1;
        } else if (eq && !strcmp(tok, "fov")) {
            WVOL_RETURN_IF(!parse_num(val, &fov) || !(fov > 0 && fov < 180), err, WVOL_ERR_ARG,
                           "camera: fov='%s' (degrees in (0, 180))", val);
        } else if (eq && !strcmp(tok, "height")) {
            WVOL_RETURN_IF(!parse_num(val, &height_w) || !(height_w > 0), err, WVOL_ERR_ARG,
                           "camera: height='%s' (world units, > 0)", val);
        } else if (eq && !strcmp(tok, "zoom")) {
            WVOL_RETURN_IF(!parse_num(val, &zoom) || !(zoom > 0), err, WVOL_ERR_ARG, "camera: zoom='%s' (> 0)", val);
        } else {
            return wvol_error_set(err, WVOL_ERR_ARG,
                                  "camera: unknown word '%s%s%s' (expected ortho, persp, an axis such as +z, "
                                  "from=, dir=, eye=, center=, up=, fov=, height=, zoom=)",
                                  tok, eq ? "=" : "", val ? val : "");
        }
    }
    WVOL_RETURN_IF((have_eye || have_center) && n_dir, err, WVOL_ERR_ARG,
                   "camera: eye=/center= and a direction (an axis, from= or dir=) both give the view direction");
    WVOL_RETURN_IF(n_fov && proj != WVOL_PROJECTION_PERSPECTIVE, err, WVOL_ERR_ARG,
                   "camera: fov= is for a perspective camera (persp)");
    WVOL_RETURN_IF(n_height && proj == WVOL_PROJECTION_PERSPECTIVE, err, WVOL_ERR_ARG,
                   "camera: height= is for an orthographic camera (a perspective one takes fov= and zoom=)");
    if (have_eye || have_center) {
        double lo[3], hi[3];
        WVOL_RETURN_IF(!g && !(have_eye && have_center), err, WVOL_ERR_ARG, "camera: eye and center both needed");
        if (g) wvol_geometry_bounds(g, lo, hi);
        if (!have_center)
            for (a = 0; a < 3; a++) center[a] = 0.5 * (lo[a] + hi[a]);
        if (!have_eye) {
            WVOL_RETURN_IF(1, err, WVOL_ERR_ARG, "camera: center= given without eye=");
        }
        for (a = 0; a < 3; a++) dir[a] = center[a] - eye[a];
        WVOL_RETURN_IF(dir[0] == 0 && dir[1] == 0 && dir[2] == 0, err, WVOL_ERR_ARG,
                       "camera: eye and center coincide (%g, %g, %g)", eye[0], eye[1], eye[2]);
    }
    WVOL_RETURN_IF(!g, err, WVOL_ERR_ARG, "camera: no volume geometry to frame");
    s = wvol_camera_frame(cam, g, dir, proj, width, height, fov, err);
    if (s != WVOL_OK) return s;
    if (have_eye) {
        for (a = 0; a < 3; a++) {
            cam->eye[a] = eye[a];
            cam->center[a] = center[a];
        }
        if (proj == WVOL_PROJECTION_ORTHOGRAPHIC && !height_w) {
            /* keep the framed height */
        }
    }
    if (have_up)
        for (a = 0; a < 3; a++) cam->up[a] = up[a];
    if (height_w > 0) cam->view_height = height_w;
    if (zoom != 1) {
        if (proj == WVOL_PROJECTION_ORTHOGRAPHIC) {
            cam->view_height /= zoom;
        } else {
            double t = tan(0.5 * cam->fov_y * PI / 180.0) / zoom;
            cam->fov_y = 2.0 * atan(t) * 180.0 / PI;
        }
    }
    return wvol_camera_check(cam, err);
}
