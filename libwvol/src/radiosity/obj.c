/* SPDX-License-Identifier: MIT
 * A small strict Wavefront OBJ + MTL reader for radiosity scenes: v, f (quads), usemtl, mtllib;
 * newmtl, Kd, Ke. Comments, o, g, s, vt, vn and the other MTL statements are skipped; anything
 * else is refused with the file and line (docs/radiosity.md says why not tinyobjloader). */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "radiosity_internal.h"

typedef struct obj_mtl {
    char name[128];
    double kd[3], ke[3];
    int has_kd;
} obj_mtl;

typedef struct obj_state {
    double (*v)[3];
    size_t nv, capv;
    wvol_radiosity_quad *q;
    char **labels;
    size_t nq, capq, capl;
    obj_mtl *m;
    size_t nm, capm;
} obj_state;

static int grow(void **p, size_t *cap, size_t need, size_t elem)
{
    void *np;
    size_t c;
    if (need <= *cap) return 1;
    c = *cap ? 2 * *cap : 64;
    while (c < need) c *= 2;
    np = realloc(*p, c * elem);
    if (!np) return 0;
    *p = np, *cap = c;
    return 1;
}

static int parse3(const char *s, double out[3])
{
    char *end;
    for (int k = 0; k < 3; k++) {
        errno = 0;
        out[k] = strtod(s, &end);
        if (end == s || errno == ERANGE) return 0;
        s = end;
    }
    while (isspace((unsigned char)*s)) s++;
    return *s == 0;
}

static char *trim(char *s)
{
    size_t n;
    while (isspace((unsigned char)*s)) s++;
    n = strlen(s);
    while (n && isspace((unsigned char)s[n - 1])) s[--n] = 0;
    return s;
}

static wvol_status read_mtl(obj_state *st, const char *path, wvol_error *err)
{
    FILE *fp = fopen(path, "r");
    char buf[1024];
    long line = 0;
    obj_mtl *cur = NULL;
    WVOL_RETURN_IF(!fp, err, WVOL_ERR_IO, "%s: cannot open the material library", path);
    while (fgets(buf, sizeof buf, fp)) {
        char *s = trim(buf);
        line++;
        if (!*s || *s == '#') continue;
        if (!strncmp(s, "newmtl", 6) && isspace((unsigned char)s[6])) {
            if (!grow((void **)&st->m, &st->capm, st->nm + 1, sizeof *st->m)) {
                fclose(fp);
                return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: materials", path);
            }
            cur = &st->m[st->nm++];
            memset(cur, 0, sizeof *cur);
            snprintf(cur->name, sizeof cur->name, "%s", trim(s + 6));
        } else if ((!strncmp(s, "Kd", 2) || !strncmp(s, "Ke", 2)) && isspace((unsigned char)s[2])) {
            double v[3];
            if (!cur || !parse3(s + 2, v)) {
                fclose(fp);
                return wvol_error_set(err, WVOL_ERR_FORMAT, "%s:%ld: %s", path, line,
                                      cur ? "expected three numbers" : "Kd/Ke before newmtl");
            }
            if (s[1] == 'd') memcpy(cur->kd, v, sizeof v), cur->has_kd = 1;
            else memcpy(cur->ke, v, sizeof v);
        }
        /* Ka, Ks, Ns, Ni, d, Tr, illum, map_*: not part of the radiosity model */
    }
    fclose(fp);
    return WVOL_OK;
}

static const obj_mtl *find_mtl(const obj_state *st, const char *name)
{
    for (size_t i = 0; i < st->nm; i++)
        if (!strcmp(st->m[i].name, name)) return &st->m[i];
    return NULL;
}

/* The directory of path joined with name. */
static char *sibling(const char *path, const char *name)
{
    const char *slash = strrchr(path, '/');
    size_t dl = slash ? (size_t)(slash - path + 1) : 0, n = dl + strlen(name) + 1;
    char *s = malloc(n);
    if (!s) return NULL;
    memcpy(s, path, dl);
    strcpy(s + dl, name);
    return s;
}

static void free_state(obj_state *st)
{
    for (size_t i = 0; i < st->nq; i++) free(st->labels[i]);
    free(st->v);
    free(st->q);
    free(st->labels);
    free(st->m);
}

#define FAIL(status, ...)                                    \
    do {                                                     \
        s = wvol_error_set(err, status, __VA_ARGS__);        \
        goto done;                                           \
    } while (0)

static wvol_status parse_face(obj_state *st, const obj_mtl *mtl, char *s, const char *path, long line,
                              wvol_error *err)
{
    long idx[5];
    int n = 0;
    wvol_radiosity_quad q;
    char label[300];
    size_t face = st->nq + 1;
    while (*s) {
        char *end;
        while (isspace((unsigned char)*s)) s++;
        if (!*s) break;
        WVOL_RETURN_IF(n == 5, err, WVOL_ERR_UNSUPPORTED, "%s:%ld: face %zu has more than 4 vertices (quads only)",
                       path, line, face);
        idx[n] = strtol(s, &end, 10);
        WVOL_RETURN_IF(end == s || idx[n] == 0, err, WVOL_ERR_FORMAT, "%s:%ld: face %zu: bad vertex index", path,
                       line, face);
        if (idx[n] < 0) idx[n] += (long)st->nv + 1; /* relative index */
        WVOL_RETURN_IF(idx[n] < 1 || (size_t)idx[n] > st->nv, err, WVOL_ERR_FORMAT,
                       "%s:%ld: face %zu: vertex %ld does not exist (%zu so far)", path, line, face, idx[n], st->nv);
        n++;
        while (*end && !isspace((unsigned char)*end)) end++; /* skip /vt/vn */
        s = end;
    }
    WVOL_RETURN_IF(n != 4, err, WVOL_ERR_UNSUPPORTED, "%s:%ld: face %zu has %d vertices (quads only)", path, line,
                   face, n);
    WVOL_RETURN_IF(!mtl, err, WVOL_ERR_FORMAT, "%s:%ld: face %zu has no material (usemtl)", path, line, face);
    WVOL_RETURN_IF(!mtl->has_kd, err, WVOL_ERR_FORMAT, "%s:%ld: face %zu: material '%s' has no Kd", path, line, face,
                   mtl->name);
    for (int k = 0; k < 4; k++) memcpy(q.p[k], st->v[idx[k] - 1], sizeof q.p[k]);
    memcpy(q.emission, mtl->ke, sizeof q.emission);
    memcpy(q.reflectance, mtl->kd, sizeof q.reflectance);
    WVOL_RETURN_IF(!grow((void **)&st->q, &st->capq, st->nq + 1, sizeof *st->q) ||
                       !grow((void **)&st->labels, &st->capl, st->nq + 1, sizeof *st->labels),
                   err, WVOL_ERR_NOMEM, "%s: faces", path);
    snprintf(label, sizeof label, "%s:%ld: face %zu (material %s)", path, line, face, mtl->name);
    st->labels[st->nq] = strdup(label);
    st->q[st->nq++] = q;
    return WVOL_OK;
}

wvol_status wvol_radiosity_scene_load_obj(wvol_radiosity_scene **out, const char *path, wvol_error *err)
{
    obj_state st;
    FILE *fp;
    char buf[4096];
    long line = 0;
    const obj_mtl *cur = NULL;
    char curname[128] = "";
    wvol_status s = WVOL_OK;
    WVOL_RETURN_IF(!out || !path, err, WVOL_ERR_ARG, "radiosity OBJ: NULL argument");
    *out = NULL;
    memset(&st, 0, sizeof st);
    fp = fopen(path, "r");
    WVOL_RETURN_IF(!fp, err, WVOL_ERR_IO, "%s: cannot open", path);
    while (fgets(buf, sizeof buf, fp)) {
        char *l = trim(buf);
        line++;
        if (!*l || *l == '#') continue;
        if (l[0] == 'v' && isspace((unsigned char)l[1])) {
            double v[3];
            if (!parse3(l + 1, v)) FAIL(WVOL_ERR_FORMAT, "%s:%ld: vertex: expected three numbers", path, line);
            if (!grow((void **)&st.v, &st.capv, st.nv + 1, sizeof *st.v)) FAIL(WVOL_ERR_NOMEM, "%s: vertices", path);
            memcpy(st.v[st.nv++], v, sizeof v);
        } else if (l[0] == 'f' && isspace((unsigned char)l[1])) {
            if (!cur && curname[0]) cur = find_mtl(&st, curname);
            if (curname[0] && !cur)
                FAIL(WVOL_ERR_FORMAT, "%s:%ld: material '%s' is not in the material library", path, line, curname);
            s = parse_face(&st, cur, l + 1, path, line, err);
            if (s != WVOL_OK) goto done;
        } else if (!strncmp(l, "usemtl", 6) && isspace((unsigned char)l[6])) {
            snprintf(curname, sizeof curname, "%s", trim(l + 6));
            cur = NULL;
        } else if (!strncmp(l, "mtllib", 6) && isspace((unsigned char)l[6])) {
            char *mp = sibling(path, trim(l + 6));
            if (!mp) FAIL(WVOL_ERR_NOMEM, "%s: path", path);
            s = read_mtl(&st, mp, err);
            free(mp);
            if (s != WVOL_OK) {
                wvol_error_prefix(err, "%s:%ld: mtllib: ", path, line);
                goto done;
            }
        } else if ((l[0] == 'o' || l[0] == 'g' || l[0] == 's') && (isspace((unsigned char)l[1]) || !l[1])) {
            /* object, group and smoothing names do not matter here */
        } else if (!strncmp(l, "vt", 2) || !strncmp(l, "vn", 2)) {
        } else {
            FAIL(WVOL_ERR_UNSUPPORTED, "%s:%ld: unsupported statement '%.20s'", path, line, l);
        }
    }
    if (!st.nq) FAIL(WVOL_ERR_ARG, "%s: empty scene (no faces)", path);
    s = wvol__rad_scene_build(out, st.q, st.nq, (const char *const *)st.labels, err);
done:
    fclose(fp);
    free_state(&st);
    return s;
}
