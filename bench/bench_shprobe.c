/* .shprobe write/read throughput: bench_shprobe [probes] [band] [grid edge] [dir].
 * Writes and reads one file (atomic write incl. fsync) a few times and prints the best times. */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    uint32_t probes = argc > 1 ? (uint32_t)strtoul(argv[1], NULL, 10) : 100000;
    uint32_t band = argc > 2 ? (uint32_t)strtoul(argv[2], NULL, 10) : 2;
    uint32_t edge = argc > 3 ? (uint32_t)strtoul(argv[3], NULL, 10) : 128;
    const char *dir = argc > 4 ? argv[4] : "/tmp";
    char path[512];
    snprintf(path, sizeof path, "%s/bench.shprobe", dir);
    const uint32_t dims[3] = {edge, edge, edge};
    pb_shprobe *p = NULL;
    pb_error err = {0};
    if (pb_shprobe_create(probes, band, dims, band > 2, &p, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    p->grid_spacing = 0.5f;
    size_t n = (size_t)probes * pb_sh_count(band) * 3;
    for (size_t i = 0; i < n; i++) p->coeffs[i] = (float)(i % 1000) * 0.001f;
    uint64_t cells = (uint64_t)edge * edge * edge;
    for (uint64_t j = 0; j < cells; j++) p->grid[j] = (int32_t)(j % probes);
    double best_w = 1e9, best_r = 1e9;
    for (int rep = 0; rep < 3; rep++) {
        double t0 = now();
        if (pb_shprobe_write(path, p, &err)) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        double t1 = now();
        pb_shprobe *r = NULL;
        if (pb_shprobe_read(path, &r, &err)) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        double t2 = now();
        pb_shprobe_destroy(r);
        if (t1 - t0 < best_w) best_w = t1 - t0;
        if (t2 - t1 < best_r) best_r = t2 - t1;
    }
    pb_shprobe r_hdr;
    double t3 = now();
    pb_shprobe_read_header(path, &r_hdr, &err);
    double t4 = now();
    FILE *f = fopen(path, "rb");
    fseek(f, 0, SEEK_END);
    double mb = (double)ftell(f) / 1e6;
    fclose(f);
    printf("probes %u band %u grid %u^3 version %u: %.1f MB, write %.3f s (%.0f MB/s), read+validate "
           "%.3f s (%.0f MB/s), header %.1f us\n",
           probes, band, edge, r_hdr.version, mb, best_w, mb / best_w, best_r, mb / best_r, (t4 - t3) * 1e6);
    remove(path);
    pb_shprobe_destroy(p);
    return 0;
}
