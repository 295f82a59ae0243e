/* Tiny shared assertion helpers for the C tests (tests/native/test_*.c).
 *
 * Usage:
 *   #include "testutil.h"
 *   static void test_something(void) { TU_CHECK(x == 1); TU_CHECK_NEAR(y, 2.0, 1e-12); }
 *   int main(void) { TU_RUN(test_something); return TU_EXIT(); }
 *
 * A failed check prints file:line, the expression and the values, counts a failure and continues
 * (so one run reports every broken value); TU_EXIT() returns 1 if anything failed. TU_REQUIRE stops
 * the current test function (returns from it) when a precondition fails.
 */
#ifndef SCHNEE_TESTUTIL_H
#define SCHNEE_TESTUTIL_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

static int tu_failures_ = 0;
static int tu_checks_ = 0;

/* The tests' seeded random numbers: xorshift64*, uniform in [0, 1). Seed by assigning tu_rng_state. */
static uint64_t tu_rng_state = 0x9E3779B97F4A7C15ull;
static inline double tu_rnd(void)
{
    tu_rng_state ^= tu_rng_state >> 12;
    tu_rng_state ^= tu_rng_state << 25;
    tu_rng_state ^= tu_rng_state >> 27;
    return (double)((tu_rng_state * 0x2545F4914F6CDD1Dull) >> 11) / 9007199254740992.0;
}

#define TU_FAIL_(...)                                                                                                  \
    do {                                                                                                               \
        tu_failures_++;                                                                                                \
        fprintf(stderr, "%s:%d: FAIL: ", __FILE__, __LINE__);                                                          \
        fprintf(stderr, __VA_ARGS__);                                                                                  \
        fputc('\n', stderr);                                                                                           \
    } while (0)

/* Boolean condition. */
#define TU_CHECK(cond)                                                                                                 \
    do {                                                                                                               \
        tu_checks_++;                                                                                                  \
        if (!(cond)) TU_FAIL_("%s", #cond);                                                                            \
    } while (0)

/* Like TU_CHECK but returns from the enclosing void function on failure. */
#define TU_REQUIRE(cond)                                                                                               \
    do {                                                                                                               \
        tu_checks_++;                                                                                                  \
        if (!(cond)) {                                                                                                 \
            TU_FAIL_("required: %s", #cond);                                                                           \
            return;                                                                                                    \
        }                                                                                                              \
    } while (0)

/* |a - b| <= tol (absolute). NaN always fails. */
#define TU_CHECK_NEAR(a, b, tol)                                                                                       \
    do {                                                                                                               \
        double tu_a_ = (double)(a), tu_b_ = (double)(b), tu_t_ = (double)(tol);                                        \
        tu_checks_++;                                                                                                  \
        if (!(fabs(tu_a_ - tu_b_) <= tu_t_))                                                                           \
            TU_FAIL_("%s = %.17g, %s = %.17g, |diff| = %.3g > tol %.3g", #a, tu_a_, #b, tu_b_, fabs(tu_a_ - tu_b_),    \
                     tu_t_);                                                                                           \
    } while (0)

/* |a - b| <= rel * |b| (relative to the expected value b). NaN always fails. */
#define TU_CHECK_REL(a, b, rel)                                                                                        \
    do {                                                                                                               \
        double tu_a_ = (double)(a), tu_b_ = (double)(b), tu_r_ = (double)(rel);                                        \
        tu_checks_++;                                                                                                  \
        if (!(fabs(tu_a_ - tu_b_) <= tu_r_ * fabs(tu_b_)))                                                             \
            TU_FAIL_("%s = %.17g, %s = %.17g, rel diff = %.3g > %.3g", #a, tu_a_, #b, tu_b_,                           \
                     fabs(tu_a_ - tu_b_) / fabs(tu_b_), tu_r_);                                                        \
    } while (0)

/* Integer / enum equality. */
#define TU_CHECK_EQ_INT(a, b)                                                                                          \
    do {                                                                                                               \
        long long tu_a_ = (long long)(a), tu_b_ = (long long)(b);                                                      \
        tu_checks_++;                                                                                                  \
        if (tu_a_ != tu_b_) TU_FAIL_("%s = %lld, expected %s = %lld", #a, tu_a_, #b, tu_b_);                           \
    } while (0)

/* `haystack` contains `needle` (e.g. an error message names the offending value). */
#define TU_CHECK_CONTAINS(haystack, needle)                                                                            \
    do {                                                                                                               \
        const char *tu_h_ = (haystack), *tu_n_ = (needle);                                                             \
        tu_checks_++;                                                                                                  \
        if (!tu_h_ || !strstr(tu_h_, tu_n_))                                                                           \
            TU_FAIL_("\"%s\" does not contain \"%s\"", tu_h_ ? tu_h_ : "(null)", tu_n_);                               \
    } while (0)

static inline double tu_now_seconds(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Runs one test function, printing its name, duration and whether it added failures. */
#define TU_RUN(fn)                                                                                                     \
    do {                                                                                                               \
        int tu_before_ = tu_failures_;                                                                                 \
        double tu_t0_ = tu_now_seconds();                                                                              \
        fn();                                                                                                          \
        printf("%-48s %s (%.2f s)\n", #fn, tu_failures_ == tu_before_ ? "ok" : "FAILED", tu_now_seconds() - tu_t0_);   \
        fflush(stdout);                                                                                                \
    } while (0)

#define TU_EXIT() (printf("%d checks, %d failures\n", tu_checks_, tu_failures_), tu_failures_ ? 1 : 0)

#endif
