/* SPDX-License-Identifier: MIT */
/* The C++ adapters (VTK, OpenVDB, tinyobjloader) live in a module of their own,
 * libwvol_adapters.so, loaded with dlopen the first time a command reads or writes one
 * of their formats. A program that links libwvol then does not pay for loading and
 * relocating VTK, OpenVDB, Boost, TBB and the C++ runtime at every start (most commands
 * never touch those formats). This file answers the adapters.h calls by forwarding them
 * to the module; the module carries its own copy of the library code the adapters call
 * (linked from the static archive, hidden), so it needs nothing from the program.
 *
 * Where the module is looked for, in order: beside the object that holds this code (the
 * program, a shared libwvol, the Python extension), the install's library folder
 * relative to that object (bin/../lib), the build folder and the install library folder
 * recorded at configure time. docs/install.md says the same. */
#define _GNU_SOURCE
#include "io/adapters.h"

#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

#ifndef WVOL_ADAPTERS_MODULE_NAME
#error "build system: WVOL_ADAPTERS_MODULE_NAME (file name of the adapter module) is not defined"
#endif

static pthread_once_t module_once = PTHREAD_ONCE_INIT;
static void *module_handle;
static char module_why[1024];

/* dir/name into buf; 0 when it does not fit */
static int join(char *buf, size_t cap, const char *dir, size_t dir_len, const char *name)
{
    int n = snprintf(buf, cap, "%.*s/%s", (int)dir_len, dir, name);
    return n > 0 && (size_t)n < cap;
}

static void *try_open(const char *dir, size_t dir_len, const char *rel)
{
    char path[PATH_MAX], name[PATH_MAX];
    void *h;
    if (snprintf(name, sizeof name, "%s%s", rel, WVOL_ADAPTERS_MODULE_NAME) >= (int)sizeof name) return NULL;
    if (!join(path, sizeof path, dir, dir_len, name)) return NULL;
    h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        const char *e = dlerror();
        /* a module that is there but cannot load (a missing VTK library) is what to report */
        if (e && !strstr(e, "No such file")) snprintf(module_why, sizeof module_why, "%s", e);
    }
    return h;
}

static void module_load(void)
{
    Dl_info info;
    const char *dirs[2] = {WVOL_ADAPTERS_BUILD_DIR, WVOL_ADAPTERS_INSTALL_DIR};
    module_why[0] = '\0';
    if (dladdr((void *)&module_load, &info) && info.dli_fname && strchr(info.dli_fname, '/')) {
        const char *slash = strrchr(info.dli_fname, '/');
        size_t n = (size_t)(slash - info.dli_fname);
        module_handle = try_open(info.dli_fname, n, "");
        if (!module_handle) module_handle = try_open(info.dli_fname, n, WVOL_ADAPTERS_BIN_TO_LIB "/");
    }
    for (int i = 0; i < 2 && !module_handle; i++) module_handle = try_open(dirs[i], strlen(dirs[i]), "");
    if (!module_handle && !module_why[0])
        snprintf(module_why, sizeof module_why, "not found beside the program, in %s or in %s",
                 WVOL_ADAPTERS_BUILD_DIR, WVOL_ADAPTERS_INSTALL_DIR);
}

/* The module's definition of `name`, or NULL with the reason in err. */
static void *adapter_symbol(const char *name, const char *path, const char *library, wvol_error *err)
{
    void *f;
    pthread_once(&module_once, module_load);
    if (!module_handle) {
        wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: the %s adapter module %s could not be loaded: %s", path,
                       library, WVOL_ADAPTERS_MODULE_NAME, module_why);
        return NULL;
    }
    f = dlsym(module_handle, name);
    if (!f)
        wvol_error_set(err, WVOL_ERR_UNSUPPORTED, "%s: the adapter module %s has no %s (built from another libwvol?)",
                       path, WVOL_ADAPTERS_MODULE_NAME, name);
    return f;
}

/* One forwarder per adapters.h function; `fallback` is the value a failure returns. */
#define FORWARD(type, name, library, path, ...)                                     \
    do {                                                                            \
        type fn;                                                                    \
        *(void **)&fn = adapter_symbol(#name, path, library, err);                  \
        if (!fn) return WVOL_ERR_UNSUPPORTED;                                       \
        return fn(__VA_ARGS__);                                                     \
    } while (0)

#ifdef WVOL_HAVE_OPENVDB
typedef wvol_status (*vdb_read_fn)(wvol_volume **, const char *, const char *, wvol_error *);
typedef wvol_status (*vdb_write_fn)(const wvol_volume *, const char *, wvol_error *);
wvol_status wvol__vdb_read(wvol_volume **out, const char *path, const char *grid_name, wvol_error *err)
{
    if (out) *out = NULL;
    FORWARD(vdb_read_fn, wvol__vdb_read, "OpenVDB", path, out, path, grid_name, err);
}
wvol_status wvol__vdb_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    FORWARD(vdb_write_fn, wvol__vdb_write, "OpenVDB", path, v, path, err);
}
#endif

#ifdef WVOL_HAVE_VTK
typedef wvol_status (*vtk_read_fn)(wvol_volume **, const char *, wvol_error *);
typedef wvol_status (*vtk_write_fn)(const wvol_volume *, const char *, wvol_error *);
typedef wvol_status (*vtk_mesh_fn)(const char *, const float *, size_t, const unsigned *, size_t, const float *,
                                   wvol_error *);
wvol_status wvol__vtk_read(wvol_volume **out, const char *path, wvol_error *err)
{
    if (out) *out = NULL;
    FORWARD(vtk_read_fn, wvol__vtk_read, "VTK", path, out, path, err);
}
wvol_status wvol__vtk_write(const wvol_volume *v, const char *path, wvol_error *err)
{
    FORWARD(vtk_write_fn, wvol__vtk_write, "VTK", path, v, path, err);
}
wvol_status wvol__vtk_write_mesh(const char *path, const float *xyz, size_t nverts, const unsigned *tris,
                                 size_t ntris, const float *normals, wvol_error *err)
{
    FORWARD(vtk_mesh_fn, wvol__vtk_write_mesh, "VTK", path, path, xyz, nverts, tris, ntris, normals, err);
}
#endif

#ifdef WVOL_HAVE_TINYOBJLOADER
typedef wvol_status (*obj_read_fn)(wvol__obj *, const char *, wvol_error *);
typedef void (*obj_free_fn)(wvol__obj *);
wvol_status wvol__obj_read(wvol__obj *out, const char *path, wvol_error *err)
{
    if (out) memset(out, 0, sizeof *out);
    FORWARD(obj_read_fn, wvol__obj_read, "tinyobjloader", path, out, path, err);
}
/* Only the module fills a wvol__obj, so a filled one means the module is loaded; a
 * zeroed one (a failed read) needs no module. */
void wvol__obj_free(wvol__obj *o)
{
    obj_free_fn fn;
    if (!o) return;
    pthread_once(&module_once, module_load);
    *(void **)&fn = module_handle ? dlsym(module_handle, "wvol__obj_free") : NULL;
    if (fn) fn(o);
}
#endif
