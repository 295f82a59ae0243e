/* The brick view (see sv_brick_view.h): the bricks' regions kept from the build, drawn one brick per
 * draw with the brick in the push constants. */
#include "sv_brick_view.h"

#include <stdlib.h>
#include <string.h>

typedef struct brick_view_brick {
    float region[3]; /* min corner, lattice coordinates */
    float level;
    uint32_t grid, brick;
} brick_view_brick;

struct sv_brick_view {
    uint32_t count;
    brick_view_brick *bricks;
};

bool sv_brick_view_capture(sv_renderer *r, pb_bricks *const *bricks, uint32_t grid_count)
{
    sv_brick_view_destroy(r);
    uint64_t n = 0;
    for (uint32_t g = 0; g < grid_count; ++g) {
        if (!bricks[g]) continue;
        pb_bricks_info in;
        pb_bricks_get_info(bricks[g], &in);
        n += in.brick_count;
    }
    if (!n) return true;
    struct sv_brick_view *v = calloc(1, sizeof *v);
    brick_view_brick *out = v ? malloc((size_t)n * sizeof *out) : NULL;
    if (!out) {
        free(v);
        fprintf(stderr, "schnee-view: error: out of memory for the brick view (%llu bricks)\n", (unsigned long long)n);
        return false;
    }
    for (uint32_t g = 0; g < grid_count; ++g) {
        if (!bricks[g]) continue;
        pb_bricks_info in;
        pb_bricks_get_info(bricks[g], &in);
        const uint32_t *reg = pb_bricks_regions(bricks[g]); /* min x, y, z, level per brick */
        for (uint32_t b = 0; b < in.brick_count; ++b) {
            brick_view_brick *o = &out[v->count++];
            for (int k = 0; k < 3; ++k) o->region[k] = (float)reg[4u * b + (uint32_t)k];
            o->level = (float)reg[4u * b + 3u];
            o->grid = g;
            o->brick = b;
        }
    }
    v->bricks = out;
    r->brick_view = v;
    return true;
}

uint32_t sv_brick_view_count(const sv_renderer *r) { return r->brick_view ? r->brick_view->count : 0u; }

/* One brick's push constants (shaders/sv_gpu_brick_view.h). */
static void push_brick(const sv_renderer *r, VkCommandBuffer cmd, const brick_view_brick *b, uint32_t mode)
{
    sv_gpu_draw d;
    memset(&d, 0, sizeof d);
    memcpy(d.model, b->region, 3 * sizeof(float));
    d.model[3] = b->level;
    d.material_index = b->grid;
    d.probe_index = b->brick;
    d.object_index = mode;
    d.normal_matrix[0][0] = (float)r->width; /* the target's size: the texels' pixel rays */
    d.normal_matrix[0][1] = (float)r->height;
    vkCmdPushConstants(cmd, r->scene_layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof d,
                       &d);
}

void sv_brick_view_draw(const sv_renderer *r, VkCommandBuffer cmd, uint32_t mode)
{
    const struct sv_brick_view *v = r->brick_view;
    if (!v) return;
    if (mode == SV_BRICK_VIEW_TEXELS || mode == SV_BRICK_VIEW_VALIDITY) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipelines[SV_PIPELINE_BRICK_TEXELS]);
        for (uint32_t i = 0; i < v->count; ++i) {
            push_brick(r, cmd, &v->bricks[i], mode);
            vkCmdDrawIndexed(cmd, r->sphere_index_count, PB_BRICK_TEXELS, r->sphere_first_index,
                             r->sphere_vertex_offset, 0);
        }
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipelines[SV_PIPELINE_BRICK_OUTLINE]);
    for (uint32_t i = 0; i < v->count; ++i) {
        push_brick(r, cmd, &v->bricks[i], mode);
        vkCmdDraw(cmd, 24, 1, 0, 0);
    }
}

void sv_brick_view_destroy(sv_renderer *r)
{
    if (!r->brick_view) return;
    free(r->brick_view->bricks);
    free(r->brick_view);
    r->brick_view = NULL;
}
