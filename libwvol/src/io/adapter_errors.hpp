/* SPDX-License-Identifier: MIT */
/* What the C++ adapters (vdb_adapter.cpp, vtk_adapter.cpp) share: leaving with a
 * status and message from deep inside, and turning every exception into a wvol_error
 * at the C boundary. */
#ifndef WVOL_IO_ADAPTER_ERRORS_HPP
#define WVOL_IO_ADAPTER_ERRORS_HPP

#include <new>
#include <stdexcept>
#include <string>
#include <utility>

#include "wvol/status.h"

namespace wvol_adapter {

// Thrown inside an adapter to leave with a given status and message.
struct Failure {
    wvol_status status;
    std::string message;
};

[[noreturn]] inline void fail(wvol_status s, std::string msg)
{
    throw Failure{s, std::move(msg)};
}

// Call only inside a catch block: fills err from the exception being handled
// (library names the adapter in the message for an exception of unknown type).
inline wvol_status current_error(const char *path, const char *library, wvol_error *err)
{
    try {
        throw;
    } catch (const Failure &f) {
        return wvol_error_set(err, f.status, "%s", f.message.c_str());
    } catch (const std::bad_alloc &) {
        return wvol_error_set(err, WVOL_ERR_NOMEM, "%s: out of memory", path);
    } catch (const std::exception &e) {
        return wvol_error_set(err, WVOL_ERR_FORMAT, "%s: %s", path, e.what());
    } catch (...) {
        return wvol_error_set(err, WVOL_ERR_INTERNAL, "%s: unknown C++ exception in the %s adapter", path, library);
    }
}

} // namespace wvol_adapter

#endif
