/* The engine's one clock: monotonic milliseconds (timing prints, the window's frame time). */
#ifndef SV_CLOCK_H
#define SV_CLOCK_H

#include <time.h>

static inline double sv_now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

#endif
