/* SPDX-License-Identifier: MIT */
/* Wavelet radiosity: bases (two-scale exactness, duals, vanishing moments), form factors
 * (closed form, quadrature, reciprocity), the energy balance of a closed scene, error falling with
 * basis order on the paper's parallel configuration, and refusal of bad scenes. */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "core/quadrature.h"
#include "radiosity/radiosity_internal.h"
#include "wvol/radiosity.h"
#include "wvol/version.h"

static const wvol_radiosity_basis all_bases[] = {WVOL_RADIOSITY_BASIS_HAAR, WVOL_RADIOSITY_BASIS_M2,
                                                 WVOL_RADIOSITY_BASIS_M3,   WVOL_RADIOSITY_BASIS_M4,
                                                 WVOL_RADIOSITY_BASIS_F2,   WVOL_RADIOSITY_BASIS_F3};

/* integral over [0,1] of g(x) * x^k for the child-c scaled function a: exact composite rule
 * (box edges of every flatlet at both scales lie on the 1/12 grid) */
static double child_moment(const rad_basis *b, int c, int a, int k)
{
    double x[6], w[6], s = 0;
    wvol__gauss_legendre(6, x, w);
    for (int piece = 0; piece < 12; piece++)
        for (int i = 0; i < 6; i++) {
            double t = (piece + x[i]) / 12, xc = 2 * t - c;
            if (xc < 0 || xc > 1) continue;
            s += w[i] / 12 * sqrt(2.0) * wvol__rad_phi(b, a, xc) * pow(t, k);
        }
    return s;
}

static void bases_are_exact_on_what_they_span(void)
{
    for (int ib = 0; ib < 6; ib++) {
        rad_basis b;
        double t[64], ti[64];
        int m, n;
        const char *name = wvol_radiosity_basis_name(all_bases[ib]);
        wvol__rad_basis_init(&b, all_bases[ib]);
        m = b.m, n = 2 * m;
        /* push then pull is the identity (the children's space holds the parent's) */
        for (int a = 0; a < m; a++)
            for (int c2 = 0; c2 < m; c2++) {
                double s = 0;
                for (int c = 0; c < 2; c++)
                    for (int k = 0; k < m; k++) s += b.push[c][k][a] * b.push[c][k][c2];
                CHECK_NEAR(s, a == c2, 1e-13, name);
            }
        /* the wavelet step and its inverse (dual for flatlets) */
        wvol__rad_basis_wavelet(&b, t, ti);
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) {
                double s = 0;
                for (int k = 0; k < n; k++) s += t[i * n + k] * ti[k * n + j];
                CHECK_NEAR(s, i == j, 1e-10, name);
            }
        /* M vanishing moments: detail coefficients of 1, x, ..., x^(M-1) are zero, and the smooth
         * coefficients reconstruct the children's coefficients exactly */
        for (int k = 0; k < m; k++) {
            double child[8], coef[8], back[8];
            for (int c = 0; c < 2; c++)
                for (int a = 0; a < m; a++) child[c * m + a] = child_moment(&b, c, a, k);
            for (int i = 0; i < n; i++) {
                coef[i] = 0;
                for (int j = 0; j < n; j++) coef[i] += t[i * n + j] * child[j];
            }
            /* flatlet detail rows are unnormalised (entries up to ~6^5): relative to the row's size */
            for (int i = m; i < n; i++) {
                double rn = 0;
                for (int j = 0; j < n; j++) rn += fabs(t[i * n + j]);
                CHECK(fabs(coef[i]) < 1e-13 * rn, "%s: detail %d of x^%d = %g", name, i, k, coef[i]);
            }
            for (int i = 0; i < n; i++) {
                back[i] = 0;
                for (int j = 0; j < m; j++) back[i] += ti[i * n + j] * coef[j];
                CHECK_NEAR(back[i], child[i], 1e-12, name);
            }
        }
        /* a function the basis spans, pushed three levels down, evaluates exactly: for M_m the 2D
         * polynomial x^(m-1) y^(m-1) + x; for flatlets a box function of the root's boxes */
        {
            double coef[RAD_MAXNB], lvl[4][64 * RAD_MAXNB];
            int cells = 1;
            for (int a = 0; a < b.nb; a++) {
                int au = a / m, av = a % m;
                double su = 0, sv = 0, s1 = 0;
                if (b.flat) {
                    coef[a] = (au == 0 && av == m - 1) ? 1 : 0; /* one box of the root */
                    continue;
                }
                for (int i = 0; i < 6; i++) {
                    double x6[6], w6[6];
                    wvol__gauss_legendre(6, x6, w6);
                    su += w6[i] * wvol__rad_phi(&b, au, x6[i]) * pow(x6[i], m - 1);
                    sv += w6[i] * wvol__rad_phi(&b, av, x6[i]) * pow(x6[i], m - 1);
                    s1 += w6[i] * wvol__rad_phi(&b, au, x6[i]) * x6[i] * (av == 0) * (m > 1);
                }
                coef[a] = su * sv + s1;
            }
            memcpy(lvl[0], coef, sizeof coef);
            for (int L = 1; L < 4; L++, cells *= 4)
                for (int cell = 0; cell < cells; cell++)
                    for (int c = 0; c < 4; c++)
                        wvol__rad_push(&b, c >> 1, c & 1, lvl[L - 1] + cell * b.nb, lvl[L] + (cell * 4 + c) * b.nb);
            /* evaluate level 3 at points inside each cell; cell index digits are (cu, cv) per level */
            for (int cell = 0; cell < 64; cell++) {
                int iu = 0, iv = 0;
                for (int L = 0; L < 3; L++) {
                    int c = (cell >> (2 * (2 - L))) & 3;
                    iu = 2 * iu + (c >> 1), iv = 2 * iv + (c & 1);
                }
                for (int pt = 0; pt < 3; pt++) {
                    double xu = (pt + 0.37) / 3.1, xv = (pt * 0.29 + 0.11), u = (iu + xu) / 8, v = (iv + xv) / 8, val = 0,
                           want;
                    for (int a = 0; a < b.nb; a++)
                        val += lvl[3][cell * b.nb + a] * wvol__rad_phi(&b, a / m, xu) * wvol__rad_phi(&b, a % m, xv) * 8;
                    if (b.flat)
                        want = (u < 1.0 / m && v >= (m - 1.0) / m) ? m : 0;
                    else
                        want = pow(u, m - 1) * pow(v, m - 1) + (m > 1 ? u : 0);
                    CHECK_NEAR(val, want, 1e-11, name);
                }
            }
        }
    }
}

static wvol_radiosity_quad square(double z, double side, int up, double e, double rho)
{
    wvol_radiosity_quad q;
    double h = side / 2, c[4][2] = {{-h, -h}, {h, -h}, {h, h}, {-h, h}};
    memset(&q, 0, sizeof q);
    for (int k = 0; k < 4; k++) {
        int kk = up ? k : 3 - k;
        q.p[k][0] = c[kk][0], q.p[k][1] = c[kk][1], q.p[k][2] = z;
    }
    for (int c2 = 0; c2 < 3; c2++) q.emission[c2] = e, q.reflectance[c2] = rho;
    return q;
}

static void form_factors_match_closed_forms_and_reciprocity(void)
{
    wvol_radiosity_quad q[2] = {square(0, 1, 1, 0, 0.5), square(1, 1, 0, 1, 0)};
    wvol_radiosity_scene *s = NULL, *box = NULL;
    wvol_error err;
    double f, x[3] = {0, 0, 0}, n[3] = {0, 0, 1}, want;
    CHECK(wvol_radiosity_scene_create(&s, q, 2, &err) == WVOL_OK, "%s", err.message);
    if (!s) return;
    /* unit squares facing each other at distance 1: F = 0.19982489 (Howell's catalogue, C-11) */
    CHECK(wvol_radiosity_form_factor(s, 0, 1, 10, &f, &err) == WVOL_OK, "%s", err.message);
    CHECK_NEAR(f, 0.19982489, 1e-6, "parallel unit squares");
    /* point under the centre of a unit square at height 1: four rectangles of sides X = Y = 1/2 with a
     * corner above it, each F = 1/(2 pi) (X' atan(Y/sqrt(1+X^2)) + Y' atan(X/sqrt(1+Y^2))), X' = X/sqrt(1+X^2) */
    {
        double a = 0.5 / sqrt(1 + 0.25);
        want = 4 / (2 * M_PI) * (2 * a * atan(a));
    }
    f = wvol_radiosity_point_form_factor(s, 1, x, n);
    CHECK_NEAR(f, want, 1e-12, "point to square (Lambert)");
    wvol_radiosity_scene_destroy(s);
    /* reciprocity A_i F_ij = A_j F_ji in the box with occluders (rays); the closure sum_j F_ij = 1 is not
     * checked here: a tensor Gauss rule converges slowly on walls that share an edge (the solver's
     * closed-form links and refinement handle that, checked by the energy balance below) */
    CHECK(wvol_radiosity_scene_builtin(&box, "box", &err) == WVOL_OK, "%s", err.message);
    if (!box) return;
    for (size_t i = 0; i < wvol_radiosity_scene_count(box); i += 3) {
        double ai;
        wvol_radiosity_scene_quad_geometry(box, i, &ai, NULL);
        for (size_t j = 0; j < wvol_radiosity_scene_count(box); j++) {
            double fij, fji, aj;
            wvol_radiosity_scene_quad_geometry(box, j, &aj, NULL);
            wvol_radiosity_form_factor(box, i, j, 6, &fij, NULL);
            wvol_radiosity_form_factor(box, j, i, 6, &fji, NULL);
            CHECK(fabs(ai * fij - aj * fji) <= 1e-12 * (ai * fij + 1e-3), "reciprocity %zu %zu: %g vs %g", i, j,
                  ai * fij, aj * fji);
        }
    }
    wvol_radiosity_scene_destroy(box);
}

static void closed_box_absorbs_what_it_emits(void)
{
    wvol_radiosity_scene *box = NULL;
    wvol_radiosity *r = NULL;
    wvol_radiosity_params p;
    wvol_radiosity_stats st;
    wvol_error err;
    CHECK(wvol_radiosity_scene_builtin(&box, "box", &err) == WVOL_OK, "%s", err.message);
    if (!box) return;
    wvol_radiosity_params_default(&p);
    p.basis = WVOL_RADIOSITY_BASIS_F2;
    p.max_level = 4;
    p.epsilon = 1e-3;
    {
        /* flags other than 0 or 1 and a pass count below 1 are refused */
        wvol_radiosity_params bad = p;
        bad.brightness = 9;
        CHECK(wvol_radiosity_solve(&r, box, &bad, &st, &err) == WVOL_ERR_ARG && !r &&
                  strstr(err.message, "brightness = 9"),
              "brightness 9: %s", err.message);
        bad = p;
        bad.refine_passes = -1;
        CHECK(wvol_radiosity_solve(&r, box, &bad, &st, &err) == WVOL_ERR_ARG && !r &&
                  strstr(err.message, "refine_passes = -1"),
              "refine_passes -1: %s", err.message);
    }
    CHECK(wvol_radiosity_solve(&r, box, &p, &st, &err) == WVOL_OK, "%s", err.message);
    if (r) {
        printf("box f2: links %zu evals %zu iterations %d emitted %.6f absorbed %.6f %.6f %.6f energy error %.4f\n",
               st.links, st.kernel_evals, st.iterations, st.emitted[0], st.absorbed[0], st.absorbed[1], st.absorbed[2],
               st.energy_error);
        CHECK_NEAR(st.emitted[0], 0.4, 1e-12, "light power 10 x 0.2^2");
        CHECK(st.change <= p.tolerance, "converged: change %g", st.change);
        /* every ray from a front face ends on a front face, so only discretisation (kernel quadrature
         * near the touching edges, point visibility at shadow edges) can lose or make energy; measured
         * 0.22% at these settings (0.4-0.6% at epsilon 1e-4 or 3e-4, 1.3% with Haar at level 5): 1% */
        CHECK(st.energy_error < 0.01, "energy balance: %g", st.energy_error);
    }
    wvol_radiosity_destroy(r);
    wvol_radiosity_scene_destroy(box);
}

/* Relative L1 error of the receiver's radiosity against the point-to-emitter form factor. */
static double parallel_error(wvol_radiosity_basis basis, int level, double eps, size_t *links)
{
    wvol_radiosity_scene *s = NULL;
    wvol_radiosity *r = NULL;
    wvol_radiosity_params p;
    wvol_radiosity_stats st;
    wvol_error err;
    double gx[4], gw[4], num = 0, den = 0;
    const int cells = 32;
    if (wvol_radiosity_scene_builtin(&s, "parallel", &err) != WVOL_OK) return NAN;
    wvol_radiosity_params_default(&p);
    p.basis = basis;
    p.max_level = level;
    p.epsilon = eps;
    if (wvol_radiosity_solve(&r, s, &p, &st, &err) != WVOL_OK) {
        wvol_radiosity_scene_destroy(s);
        return NAN;
    }
    *links = st.links;
    wvol__gauss_legendre(4, gx, gw);
    for (int cu = 0; cu < cells; cu++)
        for (int cv = 0; cv < cells; cv++)
            for (int i = 0; i < 16; i++) {
                double uv[2] = {(cu + gx[i / 4]) / cells, (cv + gx[i % 4]) / cells}, rgb[3], x[3], n[3] = {0, 0, 1},
                       w = gw[i / 4] * gw[i % 4], exact;
                x[0] = -1 + 2 * uv[0], x[1] = -1 + 2 * uv[1], x[2] = 0;
                exact = wvol_radiosity_point_form_factor(s, 0, x, n);
                wvol_radiosity_eval(r, 1, 1, uv, rgb, NULL);
                num += w * fabs(rgb[0] - exact);
                den += w * exact;
            }
    wvol_radiosity_destroy(r);
    wvol_radiosity_scene_destroy(s);
    return num / den;
}

static void parallel_error_falls_with_order(void)
{
    size_t l1, l2, l3;
    double e1 = parallel_error(WVOL_RADIOSITY_BASIS_HAAR, 4, 1e-7, &l1);
    double e2 = parallel_error(WVOL_RADIOSITY_BASIS_M2, 4, 1e-7, &l2);
    double e3 = parallel_error(WVOL_RADIOSITY_BASIS_M3, 4, 1e-7, &l3);
    printf("parallel, h = 1/16, eps 1e-7: M1 %.3e (%zu links), M2 %.3e (%zu), M3 %.3e (%zu)\n", e1, l1, e2, l2, e3,
           l3);
    /* projection error O(h^M) with a peaked form factor (emitter 0.1 above): at h = 1/16 each order
     * gains well over a factor 2 (measured 0.111, 0.021, 0.0015) */
    CHECK(e1 < 0.15, "haar error %g", e1);
    CHECK(e2 < e1 / 2, "m2 %g vs haar %g", e2, e1);
    CHECK(e3 < e2 / 2, "m3 %g vs m2 %g", e3, e2);
}

static void expect_refused(const wvol_radiosity_quad *q, size_t n, const char *what, wvol_status want, const char *a,
                           const char *b)
{
    wvol_radiosity_scene *s = NULL;
    wvol_error err;
    wvol_status st = wvol_radiosity_scene_create(&s, q, n, &err);
    CHECK(st == want && !s, "%s: status %d, expected %d", what, (int)st, (int)want);
    if (st != WVOL_OK)
        CHECK(strstr(err.message, a) && (!b || strstr(err.message, b)), "%s: message '%s' lacks '%s'/'%s'", what,
              err.message, a, b ? b : "");
    wvol_radiosity_scene_destroy(s);
}

static int write_file(const char *path, const char *text)
{
    FILE *fp = fopen(path, "w");
    if (!fp) return 0;
    fputs(text, fp);
    return fclose(fp) == 0;
}

/* An OBJ file with `text` is refused with status want and a message holding a (and b when not
 * NULL). */
static void obj_refused(const char *path, const char *text, wvol_status want, const char *a, const char *b)
{
    wvol_radiosity_scene *s = NULL;
    wvol_error err;
    wvol_status st;
    write_file(path, text);
    st = wvol_radiosity_scene_load_obj(&s, path, &err);
    CHECK(st == want && !s, "obj: status %d, expected %d: %s", (int)st, (int)want, text);
    if (st != WVOL_OK)
        CHECK(strstr(err.message, a) && (!b || strstr(err.message, b)), "message '%s' lacks '%s'/'%s'", err.message, a,
              b ? b : "");
    wvol_radiosity_scene_destroy(s);
}

static void bad_scenes_are_refused(void)
{
    wvol_radiosity_quad good = square(0, 1, 1, 0, 0.5), q[2];
    wvol_radiosity_scene *s = NULL;
    wvol_error err;
    char dir[] = "/tmp/wvol_rad_XXXXXX", path[256], mtl[256];
    q[0] = good, q[1] = good;
    q[1].p[2][2] = 0.3;
    expect_refused(q, 2, "non-planar", WVOL_ERR_ARG, "quad 1", "non-planar");
    q[1] = good;
    memcpy(q[1].p[2], q[1].p[1], sizeof q[1].p[1]);
    expect_refused(q, 2, "degenerate", WVOL_ERR_ARG, "quad 1", "degenerate");
    q[1] = good;
    q[1].p[0][1] = NAN;
    expect_refused(q, 2, "NaN corner", WVOL_ERR_NONFINITE, "quad 1", "not finite");
    q[1] = good;
    q[1].reflectance[2] = 1.5;
    expect_refused(q, 2, "reflectance > 1", WVOL_ERR_ARG, "quad 1", "reflectance[2]");
    q[1] = good;
    q[1].reflectance[0] = -0.1;
    expect_refused(q, 2, "reflectance < 0", WVOL_ERR_ARG, "quad 1", "reflectance[0]");
    q[1] = good;
    q[1].emission[1] = NAN;
    expect_refused(q, 2, "NaN emission", WVOL_ERR_NONFINITE, "quad 1", "emission[1]");
    expect_refused(q, 0, "empty scene", WVOL_ERR_ARG, "empty", NULL);
    CHECK(wvol_radiosity_scene_builtin(&s, "cornell", &err) == WVOL_ERR_ARG && strstr(err.message, "cornell"),
          "unknown built-in");
    if (!mkdtemp(dir)) return;
    /* OBJ: a good file, then a missing MTL, a triangle, a face without material, Kd > 1 */
    snprintf(path, sizeof path, "%s/s.obj", dir);
    snprintf(mtl, sizeof mtl, "%s/s.mtl", dir);
    if (!wvol_has_feature(WVOL_FEATURE_TINYOBJLOADER)) { /* a build without it says so */
        write_file(path, "v 0 0 0\n");
        CHECK(wvol_radiosity_scene_load_obj(&s, path, &err) == WVOL_ERR_UNSUPPORTED && strstr(err.message, "tinyobjloader"),
              "OBJ without tinyobjloader: %s", err.message);
        unlink(path);
        rmdir(dir);
        return;
    }
    write_file(mtl, "newmtl light\nKd 0 0 0\nKe 5 5 5\nnewmtl white\nKd 0.7 0.7 0.7\nnewmtl bad\nKd 0.5 1.2 0.5\n");
    write_file(path, "mtllib s.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 0 1 1\nv 1 1 1\nv 1 0 1\n"
                     "usemtl white\nf 1 2 3 4\nusemtl light\nf 5 6 7 8\n");
    CHECK(wvol_radiosity_scene_load_obj(&s, path, &err) == WVOL_OK, "good obj: %s", err.message);
    if (s) {
        CHECK(wvol_radiosity_scene_count(s) == 2, "obj quads %zu", wvol_radiosity_scene_count(s));
        /* tinyobjloader's number parser is not correctly rounded (0.7 reads as 0.7 + 1 ulp):
         * 4 ulps of slack */
        CHECK(wvol_radiosity_scene_quad(s, 1)->emission[0] == 5, "Ke");
        CHECK(fabs(wvol_radiosity_scene_quad(s, 0)->reflectance[1] - 0.7) <= 4 * DBL_EPSILON, "Kd");
    }
    wvol_radiosity_scene_destroy(s);
    obj_refused(path, "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl white\nf 1 2 3 4\n",
                WVOL_ERR_FORMAT, "missing.mtl", NULL); /* the OBJ names what cannot be found: its content */
    obj_refused(path, "mtllib s.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nusemtl white\nf 1 2 3\n", WVOL_ERR_UNSUPPORTED, "face 1",
                "3 vertices");
    obj_refused(path, "mtllib s.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n", WVOL_ERR_FORMAT, "face 1",
                "no material");
    obj_refused(path,
                "mtllib s.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl white\nf 1 2 3 4\nusemtl bad\nf 4 3 2 1\n",
                WVOL_ERR_ARG, "face 2", "reflectance[1]");
    obj_refused(path, "mtllib s.mtl\n", WVOL_ERR_ARG, "empty", NULL);
    unlink(path);
    unlink(mtl);
    rmdir(dir);
}

int main(void)
{
    bases_are_exact_on_what_they_span();
    form_factors_match_closed_forms_and_reciprocity();
    bad_scenes_are_refused();
    parallel_error_falls_with_order();
    closed_box_absorbs_what_it_emits();
    return check_summary("test_radiosity");
}
