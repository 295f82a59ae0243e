#include "schnee/pb_common.h"

#include <stdarg.h>
#include <stdio.h>

const char *pb_result_string(pb_result result)
{
    switch (result) {
    case PB_SUCCESS: return "success";
    case PB_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case PB_ERROR_OUT_OF_MEMORY: return "out of memory";
    case PB_ERROR_IO: return "I/O error";
    case PB_ERROR_FORMAT: return "malformed file";
    case PB_ERROR_NON_FINITE: return "non-finite value";
    case PB_ERROR_NEGATIVE: return "negative value";
    case PB_ERROR_TOO_SMALL: return "input too small";
    case PB_ERROR_TOO_LARGE: return "input too large";
    case PB_ERROR_OPEN_MESH: return "open mesh";
    case PB_ERROR_EMBREE: return "Embree error";
    case PB_ERROR_CANCELLED: return "cancelled";
    case PB_RESULT_COUNT_: break;
    }
    return "unknown error";
}

pb_result pb_error_set(pb_error *err, pb_result code, const char *fmt, ...)
{
    if (err && err->code == PB_SUCCESS && code != PB_SUCCESS) {
        va_list ap;
        va_start(ap, fmt);
        err->code = code;
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return code;
}
