/* Probe bricks (pb_bricks.h, docs/probe-bricks.md): the level rule over a pyramid of level-0 regions,
 * the indirection grid with its occupancy bits, the texels N and D from pb_interp's own weights, and
 * the exact sampler. Texels are float64; the pool accessors convert them for an upload.
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_bricks.h"

#include "schnee/pb_interp.h"

#include "pb_interp_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LEVEL_EMPTY 0xFFu /* pyramid entry of a region no leaf overlaps */

struct pb_bricks {
    double origin[3], h;
    uint32_t dims[3];
    uint32_t root_level;
    uint32_t coeff_count, channels, groups;
    uint32_t ind_dims[3];
    uint32_t *ind; /* ind_dims product × 4 (pb_bricks.h "Indirection") */
    uint32_t brick_count, brick_cap;
    uint32_t *regions; /* brick_count × 4: region min (lattice), level */
    double *texels;    /* brick_count × 125 × channels */
    uint32_t pool_bricks[3];
    uint32_t *table;  /* brick_count × 4 (pb_bricks.h "Brick table") */
    uint8_t *records; /* record_count × 64 */
    uint32_t record_count, record_cap, blocked_leaves, traced_cells;
};

/* The build's scratch: the pyramid of per-region smallest leaf levels (level k: regions of 2^(k+2) min
 * cells, ceil(ind_dims / 2^k) per axis). */
typedef struct build {
    pb_bricks *b;
    uint8_t *pyr[PB_COTREE_MAX_LEVEL + 1];
    uint32_t pdims[PB_COTREE_MAX_LEVEL + 1][3];
    uint64_t max_bytes, fixed_bytes;
    pb_error *err;
} build;

static uint64_t prod3(const uint32_t d[3]) { return (uint64_t)d[0] * d[1] * d[2]; }
static uint64_t idx3(const uint32_t d[3], uint64_t x, uint64_t y, uint64_t z) { return x + d[0] * (y + d[1] * z); }
/* Channel of coefficient c, colour k (pb_bricks.h "Channels"): N_0 in 0–2, D in 3, N_c from 4. */
static uint32_t chan(uint32_t c, uint32_t k) { return c ? 3u * c + 1u + k : k; }

void pb_bricks_destroy(pb_bricks *b)
{
    if (!b) return;
    free(b->ind);
    free(b->regions);
    free(b->texels);
    free(b->table);
    free(b->records);
    free(b);
}

static pb_result check_desc(const pb_bricks_desc *d, pb_error *err)
{
    if (!d || !d->tree || !d->coeffs)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_bricks_build: NULL %s",
                            !d         ? "desc"
                            : !d->tree ? "tree"
                                       : "coeffs");
    const pb_cotree *t = d->tree;
    if (!t->finalized)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "pb_bricks_build: the tree is not finalized (call pb_cotree_finalize)");
    uint32_t C = d->coeff_count, band = 0;
    while ((band + 1) * (band + 1) < C) band++;
    if (C == 0 || C > PB_BRICKS_MAX_COEFFS || (band + 1) * (band + 1) != C)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "pb_bricks_build: coeff_count %u is not (band + 1)^2 for a band 0..4 (1, 4, 9, 16, 25)", C);
    uint64_t n = (uint64_t)t->probe_count * C * 3u;
    for (uint64_t i = 0; i < n; i++)
        if (!isfinite(d->coeffs[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE,
                                "pb_bricks_build: value %llu (coefficient × 3 + colour) of probe %llu is %g",
                                (unsigned long long)(i % (3u * C)), (unsigned long long)(i / (3u * C)), d->coeffs[i]);
    for (uint32_t i = 0; d->scale && i < t->probe_count; i++)
        if (!isfinite(d->scale[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "pb_bricks_build: scale of probe %u is %g", i,
                                (double)d->scale[i]);
    return PB_SUCCESS;
}

/* What the texels of n bricks count against the cap. */
static uint64_t texels_bytes(const pb_bricks *b, uint32_t n)
{
    return (uint64_t)n * PB_BRICK_TEXELS * b->channels * 8u + 16u;
}

static pb_result too_large(build *B, const char *what, uint64_t bytes)
{
    return pb_error_set(B->err, PB_ERROR_TOO_LARGE,
                        "pb_bricks_build: %s would take %.1f MiB, over the cap of %.1f MiB (pb_bricks_desc.max_bytes)",
                        what, (double)bytes / 1048576.0, (double)B->max_bytes / 1048576.0);
}

/* The indirection grid and the pyramid's arrays, sized from the lattice and capped. */
static pb_result alloc_grids(build *B)
{
    pb_bricks *b = B->b;
    uint64_t bytes = 0;
    for (uint32_t k = 0; k <= b->root_level; k++) {
        for (int a = 0; a < 3; a++) B->pdims[k][a] = (b->ind_dims[a] + (1u << k) - 1u) >> k;
        bytes += prod3(B->pdims[k]);
    }
    uint64_t n = prod3(b->ind_dims);
    bytes += 16u * n;
    if (bytes > B->max_bytes) return too_large(B, "the indirection grid", bytes);
    B->fixed_bytes = 16u * n;
    b->ind = malloc(16u * (size_t)(n ? n : 1));
    bool ok = b->ind != NULL;
    for (uint32_t k = 0; ok && k <= b->root_level; k++) {
        uint64_t m = prod3(B->pdims[k]);
        ok = (B->pyr[k] = malloc((size_t)(m ? m : 1))) != NULL;
        if (ok) memset(B->pyr[k], LEVEL_EMPTY, (size_t)m);
    }
    if (!ok) return pb_error_set(B->err, PB_ERROR_OUT_OF_MEMORY, "pb_bricks_build: out of memory (indirection)");
    for (uint64_t i = 0; i < n; i++) {
        b->ind[4 * i] = PB_BRICKS_NONE;
        b->ind[4 * i + 1] = b->ind[4 * i + 2] = b->ind[4 * i + 3] = 0;
    }
    return PB_SUCCESS;
}

/* 4-bit mask of the unit cells [c0, c1) of a region that starts at 4r, clipped to it. */
static uint32_t axis_cells(uint64_t lo, uint64_t hi, uint64_t r)
{
    uint64_t c0 = lo > 4 * r ? lo - 4 * r : 0, c1 = hi < 4 * r + 4 ? hi - 4 * r : 4;
    return ((1u << c1) - 1u) & ~((1u << c0) - 1u);
}

/* Leaf (lo, levels) into the level-0 regions it overlaps: smallest axis level and occupancy bits. */
static void add_leaf(build *B, const uint32_t lo[3], const uint32_t lv[3])
{
    pb_bricks *b = B->b;
    uint32_t m = lv[0] < lv[1] ? lv[0] : lv[1];
    m = m < lv[2] ? m : lv[2];
    uint64_t hi[3], r0[3], r1[3];
    for (int a = 0; a < 3; a++) {
        hi[a] = (uint64_t)lo[a] + (UINT64_C(1) << lv[a]);
        r0[a] = lo[a] >> 2;
        r1[a] = (hi[a] - 1) >> 2;
    }
    for (uint64_t z = r0[2]; z <= r1[2]; z++)
        for (uint64_t y = r0[1]; y <= r1[1]; y++)
            for (uint64_t x = r0[0]; x <= r1[0]; x++) {
                uint64_t i = idx3(b->ind_dims, x, y, z);
                if (B->pyr[0][i] > m) B->pyr[0][i] = (uint8_t)m;
                uint32_t mx = axis_cells(lo[0], hi[0], x), my = axis_cells(lo[1], hi[1], y),
                         mz = axis_cells(lo[2], hi[2], z);
                uint64_t bits = 0;
                for (uint32_t k = 0; k < 4; k++)
                    for (uint32_t j = 0; j < 4; j++)
                        if ((mz >> k & 1u) && (my >> j & 1u)) bits |= (uint64_t)mx << (4u * j + 16u * k);
                b->ind[4 * i + 1] |= (uint32_t)bits;
                b->ind[4 * i + 2] |= (uint32_t)(bits >> 32);
            }
}

/* Level k of the pyramid: the smallest entry of the 8 children at level k − 1. */
static void reduce_level(build *B, uint32_t k)
{
    const uint32_t *cd = B->pdims[k - 1], *d = B->pdims[k];
    for (uint64_t z = 0; z < d[2]; z++)
        for (uint64_t y = 0; y < d[1]; y++)
            for (uint64_t x = 0; x < d[0]; x++) {
                uint8_t m = LEVEL_EMPTY;
                for (uint32_t c = 0; c < 8; c++) {
                    uint64_t cx = 2 * x + (c & 1u), cy = 2 * y + (c >> 1 & 1u), cz = 2 * z + (c >> 2 & 1u);
                    if (cx >= cd[0] || cy >= cd[1] || cz >= cd[2]) continue;
                    uint8_t v = B->pyr[k - 1][idx3(cd, cx, cy, cz)];
                    m = v < m ? v : m;
                }
                B->pyr[k][idx3(d, x, y, z)] = m;
            }
}

/* A brick of level L over the level-L region r: appended, and its level-0 entries point at it. */
static pb_result add_brick(build *B, uint32_t L, const uint64_t r[3])
{
    pb_bricks *b = B->b;
    if (b->brick_count >= PB_BRICKS_MAX)
        return pb_error_set(B->err, PB_ERROR_TOO_LARGE, "pb_bricks_build: more than %u bricks", PB_BRICKS_MAX);
    uint64_t texel_bytes = texels_bytes(b, b->brick_count + 1u);
    if (B->fixed_bytes + texel_bytes > B->max_bytes)
        return too_large(B, "the bricks' texels", B->fixed_bytes + texel_bytes);
    if (b->brick_count == b->brick_cap) {
        uint32_t cap = b->brick_cap ? 2u * b->brick_cap : 64u;
        uint32_t *nr = realloc(b->regions, (size_t)cap * 4u * sizeof *nr);
        if (!nr) return pb_error_set(B->err, PB_ERROR_OUT_OF_MEMORY, "pb_bricks_build: out of memory (bricks)");
        b->regions = nr;
        b->brick_cap = cap;
    }
    uint32_t id = b->brick_count++, *reg = b->regions + 4u * id;
    for (int a = 0; a < 3; a++) reg[a] = (uint32_t)(r[a] << (L + 2u));
    reg[3] = L;
    uint64_t n = UINT64_C(1) << L, lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
        lo[a] = r[a] << L;
        hi[a] = lo[a] + n < b->ind_dims[a] ? lo[a] + n : b->ind_dims[a];
    }
    for (uint64_t z = lo[2]; z < hi[2]; z++)
        for (uint64_t y = lo[1]; y < hi[1]; y++)
            for (uint64_t x = lo[0]; x < hi[0]; x++)
                b->ind[4 * idx3(b->ind_dims, x, y, z)] = id | L << PB_BRICKS_INDEX_BITS;
    return PB_SUCCESS;
}

/* The level rule, depth first from the level-L region r (pb_bricks.h "Brick order"). */
static pb_result visit(build *B, uint32_t L, const uint64_t r[3])
{
    uint8_t m = B->pyr[L][idx3(B->pdims[L], r[0], r[1], r[2])];
    if (m == LEVEL_EMPTY) return PB_SUCCESS;
    if (m >= L) return add_brick(B, L, r);
    const uint32_t *cd = B->pdims[L - 1];
    for (uint32_t c = 0; c < 8; c++) {
        uint64_t q[3] = {2 * r[0] + (c & 1u), 2 * r[1] + (c >> 1 & 1u), 2 * r[2] + (c >> 2 & 1u)};
        if (q[0] >= cd[0] || q[1] >= cd[1] || q[2] >= cd[2]) continue;
        pb_result res = visit(B, L - 1, q);
        if (res != PB_SUCCESS) return res;
    }
    return PB_SUCCESS;
}

static pb_result build_levels(build *B, const pb_cotree *t)
{
    pb_result r = alloc_grids(B);
    if (r != PB_SUCCESS) return r;
    for (uint32_t i = 0; i < t->leaf_count; i++) add_leaf(B, t->leaves + 4u * i, t->levels + 3u * i);
    uint32_t R = B->b->root_level;
    for (uint32_t k = 1; k <= R; k++) reduce_level(B, k);
    const uint32_t *d = B->pdims[R];
    for (uint64_t z = 0; z < d[2]; z++)
        for (uint64_t y = 0; y < d[1]; y++)
            for (uint64_t x = 0; x < d[0]; x++) {
                const uint64_t q[3] = {x, y, z};
                if ((r = visit(B, R, q)) != PB_SUCCESS) return r;
            }
    return PB_SUCCESS;
}

/* N and D at lattice point X (docs/probe-bricks.md "Texels"): the weights of a leaf whose closed box
 * holds X (one of the 8 unit cells around it; the field is C0, so which one only changes rounding),
 * without validity; 0 outside every leaf. */
static void texel_value(const pb_bricks_desc *d, const pb_bricks *b, const uint8_t *pv, const int64_t X[3], double *out)
{
    const pb_cotree *t = d->tree;
    memset(out, 0, b->channels * sizeof *out);
    int32_t li = -1;
    for (uint32_t m = 0; m < 8 && li < 0; m++) {
        uint32_t q[3];
        bool in = true;
        for (int a = 0; a < 3; a++) {
            int64_t c = X[a] - (int64_t)(m >> a & 1u);
            in = in && c >= 0 && c < (int64_t)b->dims[a];
            q[a] = in ? (uint32_t)c : 0;
        }
        if (in) li = locate_cell(t, q);
    }
    if (li < 0) return;
    double p[3];
    for (int a = 0; a < 3; a++) p[a] = b->origin[a] + (double)X[a] * b->h;
    pb_interp_weights w;
    const pb_interp_options opt = {.pair_visibility = pv}; /* the visibility texels where pv is given */
    (void)pb_interp_query_cotree_leaf(t, (uint32_t)li, p, &opt, &w);
    uint32_t C = b->coeff_count;
    for (uint32_t i = 0; i < w.count; i++) {
        uint32_t pr = w.probe[i];
        if (d->validity && !(d->validity[pr] > 0.0f)) continue;
        double wm = w.weight[i], ws = wm * (d->scale ? (double)d->scale[pr] : 1.0);
        const double *c = d->coeffs + (size_t)pr * C * 3u;
        out[3] += wm;
        for (uint32_t j = 0; j < C; j++)
            for (uint32_t k = 0; k < 3; k++) out[chan(j, k)] += ws * c[3u * j + k];
    }
}

static pb_result build_texels(const pb_bricks_desc *d, pb_bricks *b, const uint8_t *pv)
{
    size_t per = (size_t)PB_BRICK_TEXELS * b->channels;
    b->texels = malloc(((size_t)b->brick_count * per + 1u) * sizeof *b->texels);
    if (!b->texels) return pb_error_set(NULL, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    for (uint32_t i = 0; i < b->brick_count; i++) {
        const uint32_t *reg = b->regions + 4u * i;
        for (uint32_t t = 0; t < PB_BRICK_TEXELS; t++) {
            uint32_t ijk[3] = {t % 5u, t / 5u % 5u, t / 25u};
            int64_t X[3];
            for (int a = 0; a < 3; a++) X[a] = (int64_t)reg[a] + ((int64_t)ijk[a] << reg[3]);
            texel_value(d, b, pv, X, b->texels + (size_t)i * per + (size_t)t * b->channels);
        }
    }
    return PB_SUCCESS;
}

/* ---- visibility (docs/probe-bricks.md "Back faces and visibility") -------------------------------- */

/* The leaves' pair tables (pb_cotree_pair_visibility) for the visibility texels and for choosing the
 * cells that get records; freed after the build, but counted against the cap while they live. */
static pb_result leaf_tables(build *B, const pb_bricks_desc *d, uint8_t **pv)
{
    pb_bricks *b = B->b;
    uint32_t n = d->tree->leaf_count;
    uint64_t bytes = B->fixed_bytes + (uint64_t)PB_BRICKS_RECORD_BYTES * n;
    if (bytes > B->max_bytes) return too_large(B, "the leaves' visibility tables", bytes);
    if (!(*pv = malloc((size_t)PB_BRICKS_RECORD_BYTES * n + 1u)))
        return pb_error_set(B->err, PB_ERROR_OUT_OF_MEMORY, "pb_bricks_build: out of memory (visibility tables)");
    pb_result r = pb_cotree_pair_visibility(d->tree, d->segment, d->segment_user, *pv, B->err);
    if (r != PB_SUCCESS) return r;
    B->fixed_bytes += (uint64_t)PB_BRICKS_RECORD_BYTES * n;
    for (uint32_t i = 0; i < n; i++)
        for (uint32_t j = 0; j < PB_BRICKS_RECORD_BYTES; j++)
            if ((*pv)[PB_BRICKS_RECORD_BYTES * i + j] != PB_VIS_CLEAR) {
                b->blocked_leaves++;
                break;
            }
    return PB_SUCCESS;
}

/* The pair table of the box [lo, lo + 2^L]³ (lattice), traced exactly as pb_cotree_pair_visibility
 * traces a leaf (pb_cotree.c: the same corner positions, shifted segments and rounding), so a brick cell
 * that is a leaf gets the leaf's table. Returns whether some pair is blocked. */
static bool trace_cell(const pb_bricks *b, const pb_bricks_desc *d, const uint32_t lo[3], uint32_t L, uint8_t o[64])
{
    const uint32_t lv[3] = {L, L, L};
    return pb_vis_trace_box(b->origin, b->h, lo, lv, d->segment, d->segment_user, o);
}

/* The brick table and the records: every brick cell inside a blocked leaf is traced; a record where
 * its own table is not all clear (pb_bricks.h "Visibility record"). */
static pb_result build_records(build *B, const pb_bricks_desc *d, const uint8_t *pv)
{
    pb_bricks *b = B->b;
    for (uint32_t i = 0; i < b->brick_count; i++) {
        const uint32_t *reg = b->regions + 4u * i;
        uint32_t L = reg[3], *e = b->table + 4u * i;
        e[0] = b->record_count;
        for (uint32_t cell = 0; cell < 64u; cell++) {
            uint32_t lo[3] = {reg[0] + ((cell & 3u) << L), reg[1] + ((cell >> 2 & 3u) << L),
                              reg[2] + ((cell >> 4) << L)};
            if (lo[0] >= b->dims[0] || lo[1] >= b->dims[1] || lo[2] >= b->dims[2]) continue;
            int32_t li = locate_cell(d->tree, lo); /* the brick cell lies in this leaf or in none */
            if (li < 0) continue;
            const uint8_t *lt = pv + PB_BRICKS_RECORD_BYTES * (uint32_t)li;
            bool leaf_blocked = false;
            for (uint32_t j = 0; j < PB_BRICKS_RECORD_BYTES && !leaf_blocked; j++) leaf_blocked = lt[j] != PB_VIS_CLEAR;
            if (!leaf_blocked) continue;
            b->traced_cells++;
            uint8_t rec[PB_BRICKS_RECORD_BYTES];
            if (!trace_cell(b, d, lo, L, rec)) continue;
            uint64_t bytes = B->fixed_bytes + (uint64_t)PB_BRICKS_RECORD_BYTES * (b->record_count + 1u);
            if (bytes > B->max_bytes) return too_large(B, "the visibility records", bytes);
            if (b->record_count == b->record_cap) {
                uint32_t cap = b->record_cap ? 2u * b->record_cap : 256u;
                uint8_t *nr = realloc(b->records, (size_t)cap * PB_BRICKS_RECORD_BYTES);
                if (!nr)
                    return pb_error_set(B->err, PB_ERROR_OUT_OF_MEMORY, "pb_bricks_build: out of memory (records)");
                b->records = nr;
                b->record_cap = cap;
            }
            memcpy(b->records + (size_t)PB_BRICKS_RECORD_BYTES * b->record_count++, rec, PB_BRICKS_RECORD_BYTES);
            e[1 + cell / 32u] |= UINT32_C(1) << (cell % 32u);
        }
    }
    return PB_SUCCESS;
}

/* At most PB_BRICKS_POOL_SIDE bricks along x and y, as few layers in z as hold them, then as few rows in y,
 * then as few columns in x: fewer than y · z slots stay empty (the cube of the old rule left up to 22 % of
 * the pool empty on the generated room's 50 bricks; this one none). */
static void pool_layout(pb_bricks *b)
{
    uint64_t n = b->brick_count, s = PB_BRICKS_POOL_SIDE;
    uint64_t z = (n + s * s - 1u) / (s * s);
    uint64_t y = z ? (n + s * z - 1u) / (s * z) : 0;
    uint64_t x = y ? (n + y * z - 1u) / (y * z) : 0;
    b->pool_bricks[0] = (uint32_t)x;
    b->pool_bricks[1] = (uint32_t)y;
    b->pool_bricks[2] = (uint32_t)z;
}

pb_result pb_bricks_build(const pb_bricks_desc *desc, pb_bricks **out, pb_error *err)
{
    if (!out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_bricks_build: NULL out");
    *out = NULL;
    pb_result r = check_desc(desc, err);
    if (r != PB_SUCCESS) return r;
    const pb_cotree *t = desc->tree;
    pb_bricks *b = calloc(1, sizeof *b);
    if (!b) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "pb_bricks_build: out of memory");
    memcpy(b->origin, t->origin, sizeof b->origin);
    memcpy(b->dims, t->dims, sizeof b->dims);
    b->h = t->h;
    b->root_level = t->root_level;
    b->coeff_count = desc->coeff_count;
    b->channels = 3u * desc->coeff_count + 1u;
    b->groups = (b->channels + 3u) / 4u;
    for (int a = 0; a < 3; a++) b->ind_dims[a] = (b->dims[a] + 3u) / 4u;
    build B = {.b = b, .max_bytes = desc->max_bytes ? desc->max_bytes : PB_BRICKS_DEFAULT_MAX_BYTES, .err = err};
    r = build_levels(&B, t);
    for (uint32_t k = 0; k <= PB_COTREE_MAX_LEVEL; k++) free(B.pyr[k]);
    B.fixed_bytes += texels_bytes(b, b->brick_count) + 16u * (uint64_t)b->brick_count;
    if (r == PB_SUCCESS && B.fixed_bytes > B.max_bytes) r = too_large(&B, "the brick table", B.fixed_bytes);
    uint8_t *pv = NULL; /* the leaves' pair tables, with a static scene */
    if (r == PB_SUCCESS && desc->segment) r = leaf_tables(&B, desc, &pv);
    if (r == PB_SUCCESS && (r = build_texels(desc, b, pv)) != PB_SUCCESS)
        pb_error_set(err, r, "pb_bricks_build: out of memory (texels of %u bricks)", b->brick_count);
    if (r == PB_SUCCESS && !(b->table = calloc((size_t)b->brick_count + 1u, 16u)))
        r = pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "pb_bricks_build: out of memory (brick table)");
    if (r == PB_SUCCESS && pv) r = build_records(&B, desc, pv);
    free(pv);
    if (r != PB_SUCCESS) {
        pb_bricks_destroy(b);
        return r;
    }
    pool_layout(b);
    *out = b;
    return PB_SUCCESS;
}

void pb_bricks_get_info(const pb_bricks *b, pb_bricks_info *o)
{
    memset(o, 0, sizeof *o);
    if (!b) return;
    memcpy(o->origin, b->origin, sizeof o->origin);
    memcpy(o->dims, b->dims, sizeof o->dims);
    memcpy(o->indirection_dims, b->ind_dims, sizeof o->indirection_dims);
    memcpy(o->pool_bricks, b->pool_bricks, sizeof o->pool_bricks);
    o->min_cell = b->h;
    o->root_level = b->root_level;
    o->coeff_count = b->coeff_count;
    o->channels = b->channels;
    o->groups = b->groups;
    o->brick_count = b->brick_count;
    for (uint32_t i = 0; i < b->brick_count; i++) o->level_counts[b->regions[4u * i + 3]]++;
    for (int a = 0; a < 3; a++) o->pool_texels[a] = PB_BRICK_TEXELS_AXIS * b->pool_bricks[a];
    o->texel_count = (uint64_t)b->brick_count * PB_BRICK_TEXELS;
    o->indirection_bytes = 16u * prod3(b->ind_dims);
    o->pool_bytes_f32 = prod3(o->pool_texels) * b->groups * 16u;
    o->pool_bytes_f16 = o->pool_bytes_f32 / 2u;
    o->blocked_leaves = b->blocked_leaves;
    o->traced_cells = b->traced_cells;
    o->vis_record_count = b->record_count;
    o->table_bytes = 16u * (uint64_t)b->brick_count;
    o->vis_record_bytes = (uint64_t)PB_BRICKS_RECORD_BYTES * b->record_count;
}

/* ---- sampling (docs/probe-bricks.md "Sampling rule", steps 1–4) ----------------------------------- */

static bool occupied(const pb_bricks *b, const uint32_t q[3])
{
    const uint32_t *e = b->ind + 4u * idx3(b->ind_dims, q[0] >> 2, q[1] >> 2, q[2] >> 2);
    uint32_t bit = (q[0] & 3u) + 4u * (q[1] & 3u) + 16u * (q[2] & 3u);
    return (bit < 32u ? e[1] >> bit : e[2] >> (bit - 32u)) & 1u;
}

/* Step 2's face margin: the first occupied cell q − m (masks x, y, xy, z, ...) whose lower faces u is
 * within the margin above; u clamped into it. */
static bool face_margin(const pb_bricks *b, double u[3], uint32_t q[3])
{
    for (uint32_t m = 1; m < 8; m++) {
        uint32_t r[3];
        bool ok = true;
        for (int a = 0; a < 3; a++) {
            bool down = m >> a & 1u;
            if (down && !(q[a] > 0 && u[a] - (double)q[a] < PB_BRICKS_MARGIN)) ok = false;
            r[a] = down && ok ? q[a] - 1u : q[a];
        }
        if (!ok || !occupied(b, r)) continue;
        for (int a = 0; a < 3; a++) {
            q[a] = r[a];
            u[a] = u[a] < (double)r[a] ? (double)r[a] : (u[a] > r[a] + 1.0 ? r[a] + 1.0 : u[a]);
        }
        return true;
    }
    return false;
}

bool pb_bricks_locate(const pb_bricks *b, const double p[3], uint32_t *brick, double x[3])
{
    if (!b || !p || !b->brick_count) return false;
    double u[3];
    uint32_t q[3];
    for (int a = 0; a < 3; a++) {
        double E = (double)b->dims[a];
        u[a] = (p[a] - b->origin[a]) / b->h;
        if (!(u[a] >= -PB_BRICKS_MARGIN) || !(u[a] <= E + PB_BRICKS_MARGIN)) return false;
        u[a] = u[a] < 0.0 ? 0.0 : (u[a] > E ? E : u[a]);
        double f = floor(u[a]);
        q[a] = f >= E ? b->dims[a] - 1u : (uint32_t)f;
    }
    if (!occupied(b, q) && !face_margin(b, u, q)) return false;
    uint32_t e = b->ind[4u * idx3(b->ind_dims, q[0] >> 2, q[1] >> 2, q[2] >> 2)];
    if (e == PB_BRICKS_NONE) return false; /* not reached: an occupied cell's region has a brick */
    uint32_t L = e >> PB_BRICKS_INDEX_BITS;
    double s = ldexp(1.0, (int)L);
    for (int a = 0; a < 3; a++) {
        uint32_t r = q[a] >> (L + 2u) << (L + 2u);
        double v = (u[a] - (double)r) / s;
        x[a] = v < 0.0 ? 0.0 : (v > 4.0 ? 4.0 : v);
    }
    if (brick) *brick = e & (PB_BRICKS_MAX - 1u);
    return true;
}

/* Σ_c w8[c] T_c over the 8 texels of brick cell k0 (zero weights skipped): the 8-tap form. */
static void cell_weighted(const pb_bricks *b, uint32_t brick, const uint32_t k0[3], const double w8[8], double *out)
{
    uint32_t n = b->channels;
    memset(out, 0, n * sizeof *out);
    const double *tex = b->texels + (size_t)brick * PB_BRICK_TEXELS * n;
    for (uint32_t c = 0; c < 8; c++) {
        if (w8[c] == 0.0) continue;
        uint32_t t = (k0[0] + (c & 1u)) + 5u * (k0[1] + (c >> 1 & 1u)) + 25u * (k0[2] + (c >> 2 & 1u));
        const double *v = tex + (size_t)t * n;
        for (uint32_t i = 0; i < n; i++) out[i] += w8[c] * v[i];
    }
}

/* The filter at k0 + f (f in [0, 1]³), fractions rounded to 2^−bits (bits 1..24): one filtered fetch. */
static void cell_filtered(const pb_bricks *b, uint32_t brick, const uint32_t k0[3], const double f_in[3], uint32_t bits,
                          double *out)
{
    double f[3], w8[8];
    for (int a = 0; a < 3; a++)
        f[a] = bits && bits <= 24u ? ldexp(nearbyint(ldexp(f_in[a], (int)bits)), -(int)bits) : f_in[a];
    trilinear8(f, w8);
    cell_weighted(b, brick, k0, w8, out);
}

/* Step 4/5's cell: k0 = min(floor(x), 3), f = x − k0, x clamped into [0, 4]. */
static void cell_of(const double x[3], uint32_t k0[3], double f[3])
{
    for (int a = 0; a < 3; a++) {
        double v = x[a] < 0.0 ? 0.0 : (x[a] > 4.0 ? 4.0 : x[a]), fl = floor(v);
        k0[a] = fl > 3.0 ? 3u : (uint32_t)fl;
        f[a] = v - (double)k0[a];
    }
}

void pb_bricks_filter(const pb_bricks *b, uint32_t brick, const double x[3], uint32_t bits, double *out)
{
    uint32_t k0[3];
    double f[3];
    cell_of(x, k0, f);
    cell_filtered(b, brick, k0, f, bits, out); /* rounded f in [0, 1]: k0 + 1 ≤ 4 */
}

bool pb_bricks_sample(const pb_bricks *b, const double p[3], double *coeffs_out, double *d_out)
{
    return pb_bricks_sample_bits(b, p, 0u, coeffs_out, d_out);
}

bool pb_bricks_sample_bits(const pb_bricks *b, const double p[3], uint32_t bits, double *coeffs_out, double *d_out)
{
    double nd[3u * PB_BRICKS_MAX_COEFFS + 1u], x[3];
    uint32_t brick = 0;
    bool found = pb_bricks_locate(b, p, &brick, x);
    if (found) pb_bricks_filter(b, brick, x, bits, nd);
    double D = found ? nd[3] : 0.0;
    bool value = D > 0.0;
    if (d_out) *d_out = D;
    for (uint32_t c = 0; coeffs_out && b && c < b->coeff_count; c++)
        for (uint32_t k = 0; k < 3; k++) coeffs_out[3u * c + k] = value ? nd[chan(c, k)] / D : 0.0;
    return value;
}

/* ---- step 5: back faces and visibility ------------------------------------------------------------ */

/* GLSL's smoothstep(e0, e1, x). */
static double smoothstep(double e0, double e1, double x)
{
    double t = (x - e0) / (e1 - e0);
    t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
    return t * t * (3.0 - 2.0 * t);
}

static uint32_t popcount32(uint32_t v)
{
    uint32_t c = 0;
    for (; v; v &= v - 1u) c++;
    return c;
}

static bool finite3(const double v[3]) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

bool pb_bricks_separable(const double w[8], double f_out[3])
{
    /* M[a][b]: the weight on the corners with bit a = b. Separable w_k = c Π_a g_a(bit_a(k)) exactly when
     * w_k (Σ w)² = Π_a M[a][bit_a(k)] for every k; compared relatively (sums of nonnegative terms round
     * to a few ulps relative, also near f' = 0 or 1), so a dropped corner (w_k = 0) must stay dropped. */
    double sw = 0.0, M[3][2] = {{0.0}};
    for (uint32_t k = 0; k < 8; k++) {
        sw += w[k];
        for (int a = 0; a < 3; a++) M[a][k >> a & 1u] += w[k];
    }
    if (!(sw > 0.0)) return false;
    for (int a = 0; a < 3; a++) f_out[a] = M[a][1] / sw;
    for (uint32_t k = 0; k < 8; k++) {
        double lhs = w[k] * sw * sw, rhs = M[0][k & 1u] * M[1][k >> 1 & 1u] * M[2][k >> 2 & 1u];
        if (!(fabs(lhs - rhs) <= PB_BRICKS_SEPARABLE_EPS * fmax(lhs, rhs))) return false;
    }
    return true;
}

pb_result pb_bricks_sample_surface(const pb_bricks *b, const double p_lookup[3], const double p_surface[3],
                                   const double n[3], uint32_t flags, uint32_t bits, double *coeffs_out, double *d_out,
                                   bool *has_value, pb_error *err)
{
    if (has_value) *has_value = false;
    if (d_out) *d_out = 0.0;
    if (!b || !p_lookup)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_bricks_sample_surface: NULL %s",
                            b ? "point" : "bricks");
    for (uint32_t c = 0; coeffs_out && c < 3u * b->coeff_count; c++) coeffs_out[c] = 0.0;
    if (flags & ~(PB_BRICKS_STATIC | PB_BRICKS_8TAP))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "pb_bricks_sample_surface: unknown flags 0x%x (PB_BRICKS_STATIC 0x1, PB_BRICKS_8TAP 0x2)",
                            flags);
    bool is_static = flags & PB_BRICKS_STATIC, taps8 = flags & PB_BRICKS_8TAP;
    const double *ps = p_surface ? p_surface : p_lookup;
    if (is_static && (!n || !finite3(n) || n[0] * n[0] + n[1] * n[1] + n[2] * n[2] == 0.0))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "pb_bricks_sample_surface: PB_BRICKS_STATIC needs a finite nonzero normal, got %s",
                            !n ? "NULL" : (finite3(n) ? "(0, 0, 0)" : "a non-finite one"));
    if (is_static && !finite3(ps))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "pb_bricks_sample_surface: PB_BRICKS_STATIC needs a finite surface point");
    /* 1–3. */
    double x[3], nd[3u * PB_BRICKS_MAX_COEFFS + 1u];
    uint32_t brick = 0;
    if (!pb_bricks_locate(b, p_lookup, &brick, x)) return PB_SUCCESS;
    const uint32_t *reg = b->regions + 4u * brick, L = reg[3];
    /* a. The brick cell and its blocked bit. */
    uint32_t k0[3];
    double f[3];
    cell_of(x, k0, f);
    uint32_t cell = k0[0] + 4u * k0[1] + 16u * k0[2];
    const uint32_t *e = b->table + 4u * brick;
    uint32_t word = e[1 + cell / 32u], below = word & ((UINT32_C(1) << (cell % 32u)) - 1u);
    bool blocked = (word >> (cell % 32u)) & 1u;
    bool done = false;
    if (is_static || blocked) {
        /* b. Trilinear weights; c. back faces. */
        double w[8], wb[8], wv[8], s = ldexp(1.0, (int)L), wbsum = 0.0, sw = 0.0;
        trilinear8(f, w);
        double us[3];
        for (int a = 0; a < 3; a++) us[a] = (ps[a] - b->origin[a]) / b->h;
        for (uint32_t k = 0; k < 8; k++) {
            wb[k] = w[k];
            if (is_static) {
                double dd = 0.0;
                for (int a = 0; a < 3; a++)
                    dd += ((double)reg[a] + s * (double)(k0[a] + (k >> a & 1u)) - us[a]) / s * n[a];
                wb[k] *= smoothstep(-0.1, 0.1, dd);
            }
            wbsum += wb[k];
        }
        /* d. The visibility ramp of the cell's record. */
        if (blocked) {
            uint32_t idx = e[0] + popcount32(below) + (cell >= 32u ? popcount32(e[1]) : 0u);
            const uint8_t *rec = b->records + (size_t)PB_BRICKS_RECORD_BYTES * idx;
            for (uint32_t c = 0; c < 8; c++) {
                double v = 0.0;
                for (uint32_t k = 0; k < 8; k++) v += wb[k] * pb_vis_pair_value(rec[8u * k + c]);
                v = wbsum > 0.0 ? v / wbsum : 0.0;
                wv[c] = wb[c] * smoothstep(0.5, 0.5 + PB_VIS_RAMP, v);
            }
        } else {
            memcpy(wv, wb, sizeof wv);
        }
        for (uint32_t k = 0; k < 8; k++) sw += wv[k];
        /* e. The weighted sample: one tap at the weights' per-axis mean f' where w' is separable (then it is
         *    exactly the trilinear weights of f', up to PB_BRICKS_SEPARABLE_EPS), else (or 8TAP) 8 taps. */
        if (sw > 0.0) {
            double f1[3];
            if (!taps8 && pb_bricks_separable(wv, f1))
                cell_filtered(b, brick, k0, f1, bits, nd);
            else
                cell_weighted(b, brick, k0, wv, nd);
            done = nd[3] > 0.0;
        }
    }
    /* f. The plain sample (also the second pass). */
    if (!done) pb_bricks_filter(b, brick, x, taps8 ? 0u : bits, nd);
    double D = nd[3];
    bool value = D > 0.0;
    if (d_out) *d_out = D;
    if (has_value) *has_value = value;
    for (uint32_t c = 0; coeffs_out && value && c < b->coeff_count; c++)
        for (uint32_t k = 0; k < 3; k++) coeffs_out[3u * c + k] = nd[chan(c, k)] / D;
    return PB_SUCCESS;
}

/* ---- arrays --------------------------------------------------------------------------------------- */

const uint32_t *pb_bricks_table(const pb_bricks *b) { return b ? b->table : NULL; }
const uint8_t *pb_bricks_vis_records(const pb_bricks *b) { return b && b->record_count ? b->records : NULL; }
const uint32_t *pb_bricks_indirection(const pb_bricks *b) { return b ? b->ind : NULL; }
const uint32_t *pb_bricks_regions(const pb_bricks *b) { return b ? b->regions : NULL; }
const double *pb_bricks_texels(const pb_bricks *b) { return b ? b->texels : NULL; }

/* binary16 of a finite |v| <= PB_HALF_MAX, round to nearest even (no double rounding through float). */
static uint16_t double_to_half(double v)
{
    uint16_t sign = signbit(v) ? 0x8000u : 0u;
    double a = fabs(v);
    if (a < 6.103515625e-05) return (uint16_t)(sign | (uint16_t)nearbyint(a * 16777216.0)); /* subnormal */
    int e;
    (void)frexp(a, &e);                                                 /* a = m 2^e, m in [0.5, 1) */
    uint32_t q = (uint32_t)nearbyint(ldexp(a, 11 - e));                 /* 11 significant bits: 1024..2048 */
    return (uint16_t)(sign | (((uint32_t)(e + 14) << 10) + q - 1024u)); /* q = 2048 carries into the exponent */
}

/* The pool (pb_bricks.h): every texel value passed through put(out, index, value). */
static pb_result pool_fill(const pb_bricks *b, void *out, uint64_t capacity, size_t elem,
                           void (*put)(void *, uint64_t, double), pb_error *err)
{
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    uint64_t texels = prod3(in.pool_texels), need = texels * b->groups * 4u;
    if (!out || capacity < need)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "pb_bricks_pool: capacity %llu below the pool's %llu values", (unsigned long long)capacity,
                            (unsigned long long)need);
    memset(out, 0, (size_t)need * elem);
    const uint32_t *pb = b->pool_bricks, *pt = in.pool_texels;
    for (uint32_t i = 0; i < b->brick_count; i++) {
        uint64_t o[3] = {5u * (i % pb[0]), 5u * (i / pb[0] % pb[1]), 5u * (i / (pb[0] * pb[1]))};
        for (uint32_t t = 0; t < PB_BRICK_TEXELS; t++) {
            const double *v = b->texels + ((size_t)i * PB_BRICK_TEXELS + t) * b->channels;
            uint64_t pos = idx3(pt, o[0] + t % 5u, o[1] + t / 5u % 5u, o[2] + t / 25u);
            for (uint32_t ch = 0; ch < b->channels; ch++) put(out, ((ch / 4u) * texels + pos) * 4u + ch % 4u, v[ch]);
        }
    }
    return PB_SUCCESS;
}

static void put_f32(void *out, uint64_t i, double v) { ((float *)out)[i] = (float)v; }
static void put_f16(void *out, uint64_t i, double v) { ((uint16_t *)out)[i] = double_to_half(v); }

pb_result pb_bricks_pool_f32(const pb_bricks *b, float *out, uint64_t capacity, pb_error *err)
{
    if (!b) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_bricks_pool_f32: NULL bricks");
    return pool_fill(b, out, capacity, sizeof *out, put_f32, err);
}

pb_result pb_bricks_pool_f16(const pb_bricks *b, uint16_t *out, uint64_t capacity, pb_error *err)
{
    if (!b) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_bricks_pool_f16: NULL bricks");
    uint64_t n = (uint64_t)b->brick_count * PB_BRICK_TEXELS * b->channels;
    for (uint64_t i = 0; i < n; i++)
        if (!(fabs(b->texels[i]) <= PB_HALF_MAX))
            return pb_error_set(
                err, PB_ERROR_TOO_LARGE,
                "pb_bricks_pool_f16: texel value %g (channel %llu) exceeds binary16's %g: upload float32", b->texels[i],
                (unsigned long long)(i % b->channels), PB_HALF_MAX);
    return pool_fill(b, out, capacity, sizeof *out, put_f16, err);
}
