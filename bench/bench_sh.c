/* Equirect SH projection speed: pb_sh_project_equirect (separable) at 128×64 … 8192×4096, L = 2 and
 * L = 4, RGB float, one thread; and, for scale, a naive per-pixel loop (pb_sh_eval_basis at every
 * pixel) up to 2048×1024. Prints a Markdown table (best of N runs).
 *
 *   cmake --build build -j2 --target bench_sh && ./build/native/bench_sh
 */
#include "schnee/pb_sh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The obvious implementation: direction, engine conversion and full basis per pixel. */
static void naive_project(const float *px, uint32_t w, uint32_t h, uint32_t L, double *out)
{
    const uint32_t n = pb_sh_count(L);
    for (uint32_t q = 0; q < n * 3; q++) out[q] = 0.0;
    const double pi = 3.14159265358979323846;
    for (uint32_t r = 0; r < h; r++) {
        const double th = pi * (r + 0.5) / h;
        const double om = 2 * pi / w * (cos(pi * r / h) - cos(pi * (r + 1) / h));
        for (uint32_t i = 0; i < w; i++) {
            const double ph = pi - 2 * pi * (i + 0.5) / w;
            const double e[3] = {sin(th) * cos(ph), cos(th), -sin(th) * sin(ph)};
            double y[PB_SH_MAX_COEFFS];
            pb_sh_eval_basis(L, e, y);
            const float *p = px + ((size_t)r * w + i) * 3;
            for (uint32_t q = 0; q < n; q++)
                for (int c = 0; c < 3; c++) out[q * 3 + c] += p[c] * om * y[q];
        }
    }
}

int main(void)
{
    const uint32_t max_w = 8192, max_h = 4096;
    float *px = malloc(sizeof(float) * (size_t)max_w * max_h * 3);
    if (!px) {
        fprintf(stderr, "bench_sh: out of memory\n");
        return 1;
    }
    uint64_t s = 1;
    for (size_t q = 0; q < (size_t)max_w * max_h * 3; q++) {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        px[q] = (float)((s >> 40) * (1.0 / 16777216.0));
    }
    printf("| panorama | L | separable (ms) | Mpixel/s | naive per-pixel (ms) |\n");
    printf("|---|---|---|---|---|\n");
    for (uint32_t w = 128; w <= max_w; w *= 2) {
        const uint32_t h = w / 2;
        for (uint32_t L = 2; L <= 4; L += 2) {
            const int runs = w <= 1024 ? 20 : (w <= 2048 ? 5 : 3);
            double best = 1e30, out[75];
            for (int k = 0; k < runs; k++) {
                pb_sh_project_desc d = {.pixels = px, .width = w, .height = h, .channels = 3, .max_band = L};
                pb_error err = {0};
                const double t0 = now();
                if (pb_sh_project_equirect(&d, out, &err) != PB_SUCCESS) {
                    fprintf(stderr, "bench_sh: %s\n", err.message);
                    free(px);
                    return 1;
                }
                best = fmin(best, now() - t0);
            }
            char naive[32] = "—";
            if (w <= 2048) {
                double nb = 1e30, ref[75];
                for (int k = 0; k < (w <= 512 ? 5 : 1); k++) {
                    const double t0 = now();
                    naive_project(px, w, h, L, ref);
                    nb = fmin(nb, now() - t0);
                }
                snprintf(naive, sizeof naive, "%.2f", nb * 1e3);
                /* sanity: both give the same numbers */
                for (uint32_t q = 0; q < pb_sh_count(L) * 3; q++)
                    if (fabs(ref[q] - out[q]) > 1e-9 * fabs(out[0])) {
                        fprintf(stderr, "bench_sh: mismatch at %u: %g vs %g\n", q, ref[q], out[q]);
                        free(px);
                        return 1;
                    }
            }
            printf("| %ux%u | %u | %.3f | %.0f | %s |\n", w, h, L, best * 1e3, (double)w * h / best / 1e6, naive);
            fflush(stdout);
        }
    }
    free(px);
    return 0;
}
