/* Schnee probes tests: what the tests that feed readers special files share (tests/native/
 * test_hostile_files.c, tests/engine/readers/test_engine_readers.c). A temp folder for the files, a
 * SIGALRM watchdog that names the call that blocked (a FIFO opened for reading without O_NONBLOCK
 * blocks forever), and the time and peak-RSS bounds of one call (a 2 GiB sparse file read whole
 * would add 2 GiB). Include after testutil.h's users define _DEFAULT_SOURCE. */
#ifndef SCHNEE_TESTS_WATCHDOG_H
#define SCHNEE_TESTS_WATCHDOG_H

#include "testutil.h"

#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#define WATCHDOG_S        20
#define MAX_CALL_S        2.0
#define MAX_RSS_GROWTH_KB (64 * 1024)

static char g_dir[64];
static const char *g_current = "";

static inline void join(char *out, size_t n, const char *name) { snprintf(out, n, "%s/%s", g_dir, name); }

static inline void wd_on_alarm(int sig)
{
    (void)sig;
    static const char msg[] = "FAIL: a reader blocked (watchdog fired) on: ";
    ssize_t ignored = write(2, msg, sizeof msg - 1);
    ignored = write(2, g_current, strlen(g_current));
    ignored = write(2, "\n", 1);
    (void)ignored;
    _exit(1);
}

static inline double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static inline long peak_rss_kb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss;
}

/* The temp folder /tmp/<prefix>_XXXXXX and the watchdog's handler; false when the folder cannot be
 * made. */
static inline bool wd_setup(const char *prefix)
{
    signal(SIGALRM, wd_on_alarm);
    snprintf(g_dir, sizeof g_dir, "/tmp/%s_XXXXXX", prefix);
    if (!mkdtemp(g_dir)) {
        perror("mkdtemp");
        return false;
    }
    return true;
}

static inline void wd_cleanup(void)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
}

/* One watched call: wd_begin(label) before it, wd_end() after; wd_end fails the test when the call
 * took more than MAX_CALL_S or grew the peak RSS by more than MAX_RSS_GROWTH_KB. */
typedef struct wd_call {
    const char *label;
    double t0, seconds;
    long rss0, grown_kb;
} wd_call;

static inline wd_call wd_begin(const char *label)
{
    g_current = label;
    wd_call c = {.label = label, .rss0 = peak_rss_kb(), .t0 = now_s()};
    alarm(WATCHDOG_S);
    return c;
}

static inline void wd_end(wd_call *c)
{
    alarm(0);
    c->seconds = now_s() - c->t0;
    c->grown_kb = peak_rss_kb() - c->rss0;
    if (c->seconds > MAX_CALL_S) TU_FAIL_("%s took %.2f s (limit %.1f s)", c->label, c->seconds, MAX_CALL_S);
    if (c->grown_kb > MAX_RSS_GROWTH_KB)
        TU_FAIL_("%s grew the peak RSS by %ld KiB (limit %d KiB)", c->label, c->grown_kb, MAX_RSS_GROWTH_KB);
    g_current = "";
}

#endif
