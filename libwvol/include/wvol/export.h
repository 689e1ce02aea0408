/* SPDX-License-Identifier: MIT
 * WVOL_API marks the functions of the public API. The library is compiled with
 * hidden visibility (-fvisibility=hidden), so a shared libwvol exports exactly
 * these; a static one keeps them global too, and its internal symbols (wvol__*)
 * stay linkable for the project's own tests.
 * On Windows a DLL build defines WVOL_DLL for itself and its users (and
 * WVOL_BUILDING_LIBRARY while compiling the library) to get dllexport/dllimport. */
#ifndef WVOL_EXPORT_H
#define WVOL_EXPORT_H

#if defined(_WIN32) || defined(__CYGWIN__)
#  if defined(WVOL_DLL) && defined(WVOL_BUILDING_LIBRARY)
#    define WVOL_API __declspec(dllexport)
#  elif defined(WVOL_DLL)
#    define WVOL_API __declspec(dllimport)
#  else
#    define WVOL_API
#  endif
#elif defined(__GNUC__) || defined(__clang__)
#  define WVOL_API __attribute__((visibility("default")))
#else
#  define WVOL_API
#endif

#endif
