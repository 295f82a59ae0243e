/* Probe bricks' anti-leak data (see sv_bricks_vis.h): the static scene's tracer for the core's build,
 * the brick tables and visibility records in one storage buffer, the indirection's w. */
#include "sv_bricks_vis.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sv_clock.h"
#include "sv_probe_vis.h"

void sv_bricks_vis_begin(sv_bricks_vis *v, const sv_scene *scene)
{
    memset(v, 0, sizeof *v);
    v->scene = scene;
}

/* pb_segment_fn: sv_segment_first_hit on the static scene, counted. The core calls it from one thread. */
static double counted_segment(void *user, const double a[3], const double b[3])
{
    sv_bricks_vis *v = user;
    v->segments++;
    return sv_segment_first_hit(v->occ, a, b);
}

void sv_bricks_vis_desc(sv_bricks_vis *v, pb_bricks_desc *d)
{
    if (!v) return;
    if (!v->tried) { /* the static scene's BVH, built once for every tree grid */
        v->tried = true;
        v->t0 = sv_now_ms();
        v->occ = sv_static_occluder(v->scene);
        v->triangles = v->occ ? (size_t)pb_occluder_triangle_count(v->occ) : 0u;
    }
    if (!v->occ) return;
    d->segment = counted_segment;
    d->segment_user = v;
}

bool sv_bricks_vis_upload(sv_renderer *r, sv_bricks_vis *v, pb_bricks *const *b, uint32_t grid_count, uint32_t *index,
                          const uint32_t dims[3])
{
    uint64_t rows = 0, records = 0, blocked = 0, traced = 0;
    for (uint32_t g = 0; g < grid_count; ++g) {
        if (!b[g]) continue;
        pb_bricks_info in;
        pb_bricks_get_info(b[g], &in);
        rows += in.brick_count;
        records += in.vis_record_count;
        blocked += in.blocked_leaves;
        traced += in.traced_cells;
    }
    uint64_t words = 4u * rows + 16u * records;
    if (words >= UINT32_MAX) {
        fprintf(stderr,
                "schnee-view: error: --probe-path bricks: %llu brick rows and %llu visibility records "
                "exceed a 32-bit buffer offset\n",
                (unsigned long long)rows, (unsigned long long)records);
        return false;
    }
    uint32_t *buf = calloc(words ? words : 4u, sizeof(uint32_t));
    if (!buf) {
        fprintf(stderr, "schnee-view: error: --probe-path bricks: out of memory for the brick tables\n");
        return false;
    }
    /* Rows (the record offsets rebased to this buffer), records, and the indirection's w, grid by grid
     * in the order of the combined indirection (sv_bricks.c fill_index: bricked grids along z). */
    uint64_t row = 0, rec = 0;
    uint32_t zoff = 0;
    for (uint32_t g = 0; g < grid_count; ++g) {
        if (!b[g]) continue;
        pb_bricks_info in;
        pb_bricks_get_info(b[g], &in);
        const uint32_t *t = pb_bricks_table(b[g]);
        const uint8_t *vr = pb_bricks_vis_records(b[g]);
        for (uint32_t i = 0; i < in.brick_count; ++i) {
            uint32_t *o = buf + 4u * (row + i);
            o[0] = (uint32_t)(4u * rows + 16u * (rec + t[4u * i]));
            o[1] = t[4u * i + 1u];
            o[2] = t[4u * i + 2u];
            o[3] = 0;
        }
        if (vr && in.vis_record_count) /* 64 bytes = 16 uint each, little-endian as the GPU reads them */
            memcpy(buf + 4u * rows + 16u * rec, vr, (size_t)in.vis_record_count * PB_BRICKS_RECORD_BYTES);
        const uint32_t *d = in.indirection_dims;
        for (size_t z = 0; z < d[2]; ++z)
            for (size_t y = 0; y < d[1]; ++y)
                for (size_t x = 0; x < d[0]; ++x) {
                    uint32_t *e = index + (((zoff + z) * dims[1] + y) * dims[0] + x) * 4u;
                    if (e[0] != PB_BRICKS_NONE) e[3] = (uint32_t)row + (e[0] & (PB_BRICKS_MAX - 1u));
                }
        zoff += d[2];
        row += in.brick_count;
        rec += in.vis_record_count;
    }
    sv_buffer_destroy(r->ctx, &r->brick_vis);
    bool ok = sv_buffer_create_with_data(r->ctx, buf, (words ? words : 4u) * sizeof(uint32_t),
                                         VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->brick_vis);
    free(buf);
    if (ok && rows)
        fprintf(stderr,
                "schnee-view: probe brick visibility: %llu record(s) (%.1f KiB) for %llu traced brick cell(s) in "
                "%llu blocked leaf/leaves, %llu B of brick tables; %llu segment(s) against %zu triangle(s), "
                "bricks built in %.1f ms\n",
                (unsigned long long)records, (double)records * PB_BRICKS_RECORD_BYTES / 1024.0,
                (unsigned long long)traced, (unsigned long long)blocked, (unsigned long long)(16u * rows),
                (unsigned long long)v->segments, v->triangles, sv_now_ms() - v->t0);
    return ok;
}

bool sv_bricks_vis_standin(sv_renderer *r)
{
    static const uint32_t zero[4] = {0, 0, 0, 0};
    return sv_buffer_create_with_data(r->ctx, zero, sizeof zero, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->brick_vis);
}

void sv_bricks_vis_end(sv_bricks_vis *v)
{
    if (!v) return;
    pb_occluder_destroy(v->occ);
    v->occ = NULL;
}
