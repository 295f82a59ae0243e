/* Schnee probes bake core — shared result codes and error detail.
 *
 * Every fallible function returns a pb_result by value (PB_SUCCESS = 0) and, when the caller
 * passes a non-NULL pb_error, fills it with the first error's code and a human-readable detail
 * that a Python caller can raise verbatim. There is no global mutable state.
 */
#ifndef SCHNEE_PB_COMMON_H
#define SCHNEE_PB_COMMON_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum pb_result {
    PB_SUCCESS = 0,
    PB_ERROR_INVALID_ARGUMENT, /* a parameter is out of range or inconsistent */
    PB_ERROR_OUT_OF_MEMORY,
    PB_ERROR_IO,         /* a file could not be opened, read, written or renamed */
    PB_ERROR_FORMAT,     /* a file is malformed (wrong magic, truncated, bad sizes, ...) */
    PB_ERROR_NON_FINITE, /* NaN or Inf in input data */
    PB_ERROR_NEGATIVE,   /* negative radiance where it is not allowed */
    PB_ERROR_TOO_SMALL,  /* e.g. a panorama too small to represent the requested band */
    PB_ERROR_TOO_LARGE,  /* e.g. a dense occupancy grid past the documented limit */
    PB_ERROR_OPEN_MESH,  /* a probe-volume mesh is not watertight */
    PB_ERROR_EMBREE,     /* Embree reported an error */
    PB_ERROR_CANCELLED,  /* the progress callback returned false */
    PB_RESULT_COUNT_
} pb_result;

/* First error of an operation, with detail. Zero-initialise before use. */
typedef struct pb_error {
    pb_result code;
    char message[512];
} pb_error;

/* Long operations report progress in [0, 1] with a short stage name; returning false cancels
 * the operation, which then returns PB_ERROR_CANCELLED having freed everything it allocated. */
typedef bool (*pb_progress_fn)(void *user, double fraction, const char *stage);

/* Static English name of a result code ("success", "invalid argument", ...). */
const char *pb_result_string(pb_result result);

/* Records code + printf-style detail into err if err is non-NULL and holds no error yet;
 * returns code so callers can `return pb_error_set(err, PB_ERROR_IO, "...", ...)`. */
pb_result pb_error_set(pb_error *err, pb_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

#ifdef __cplusplus
}
#endif
#endif
