/* `.shprobe` version 3 (docs/shprobe-format.md, "Version 3"): octree and tetrahedra files with SH or
 * ambient cubes in float32 or binary16; byte layout against the table, round trips, the file's
 * interpolation equal to the tree's, the dense version 1 resample, and the reader's rejections. */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_interp.h"
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"

#include "testutil.h"

#include <stdint.h>
#include <stdlib.h>
#include <unistd.h>

static uint64_t rng_state = 0x1234567887654321ull;
static double rnd(void)
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return (double)((rng_state * 0x2545F4914F6CDD1Dull) >> 11) / 9007199254740992.0;
}

static char tmpdir[256];

static void path_in_tmp(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", tmpdir, name); }

static uint8_t *read_all(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc((size_t)len + 1);
    *n = fread(b, 1, (size_t)len, f);
    fclose(f);
    return b;
}

static uint32_t u32_at(const uint8_t *b, size_t off)
{
    return (uint32_t)b[off] | (uint32_t)b[off + 1] << 8 | (uint32_t)b[off + 2] << 16 | (uint32_t)b[off + 3] << 24;
}

static void set_u32(uint8_t *b, size_t off, uint32_t v)
{
    for (int i = 0; i < 4; i++) b[off + (size_t)i] = (uint8_t)(v >> (8 * i));
}

/* The tree of test_interp.c: 2×2×2 roots of 4 min cells (0.25 m), split down unevenly. */
static pb_cotree *make_tree(void)
{
    const double origin[3] = {-1.0, 0.5, 2.0};
    const uint32_t roots[3] = {2, 2, 2};
    pb_cotree *t = NULL;
    pb_error err = {0};
    if (pb_cotree_create(origin, 0.25, 2, roots, &t, &err) != PB_SUCCESS) return NULL;
    uint8_t split[64] = {0};
    split[0] = 1;
    split[7] = 1;
    pb_cotree_split(t, split, NULL, &err);
    memset(split, 0, sizeof split);
    const uint32_t *l = pb_cotree_leaves(t);
    for (uint32_t i = 0; i < pb_cotree_leaf_count(t); i++)
        if (l[4 * i] == 2 && l[4 * i + 1] == 2 && l[4 * i + 2] == 2 && l[4 * i + 3] == 1) split[i] = 1;
    pb_cotree_split(t, split, NULL, &err);
    if (pb_cotree_finalize(t, &err) != PB_SUCCESS) {
        pb_cotree_destroy(t);
        return NULL;
    }
    return t;
}

/* Coefficient k, channel ch of a field linear in position. */
static double field(const double p[3], uint32_t k, uint32_t ch)
{
    return 0.3 + 0.1 * k + 0.05 * ch + (0.2 + 0.01 * k) * p[0] - 0.15 * p[1] + (0.1 + 0.02 * ch) * p[2];
}

static pb_shprobe *octree_file(pb_cotree *t, uint32_t representation, uint32_t band)
{
    pb_shprobe *f = NULL;
    pb_error err = {0};
    if (pb_shprobe_from_cotree(t, representation, band, &f, &err) != PB_SUCCESS) return NULL;
    uint32_t C = pb_shprobe_colour_count(f);
    for (uint32_t i = 0; i < f->probe_count; i++) {
        double p[3] = {f->positions[3 * i], f->positions[3 * i + 1], f->positions[3 * i + 2]};
        for (uint32_t k = 0; k < C; k++)
            for (uint32_t ch = 0; ch < 3; ch++) f->coeffs[(i * C + k) * 3 + ch] = (float)field(p, k, ch);
        f->validity[i] = (float)(0.5 + 0.5 * (i % 2));
        f->probe_scale[i] = 1.0f + 0.01f * (float)(i % 7);
    }
    return f;
}

static void test_octree_layout_and_round_trip(void)
{
    pb_cotree *t = make_tree();
    TU_REQUIRE(t != NULL);
    for (int half = 0; half < 2; half++) {
        pb_shprobe *f = octree_file(t, PB_SHPROBE_SH, 2);
        TU_REQUIRE(f != NULL);
        f->storage = half ? PB_SHPROBE_FLOAT16 : PB_SHPROBE_FLOAT32;
        char path[300];
        path_in_tmp(path, sizeof path, half ? "oct_half.shprobe" : "oct.shprobe");
        pb_error err = {0};
        TU_REQUIRE(pb_shprobe_write(path, f, &err) == PB_SUCCESS);
        size_t n;
        uint8_t *b = read_all(path, &n);
        uint32_t P = f->probe_count, N = f->element_count, H = f->hanging_count;
        /* Table: header 128, records 9 colours × 16 (or 8) + 16, positions 16, leaves 48, hanging 32. */
        uint32_t R = 9 * (half ? 8 : 16) + 16;
        TU_CHECK(n == 128 + (size_t)P * R + 16 * P + 48 * N + 32 * H);
        TU_CHECK(b[0] == 0x53 && b[1] == 0x50 && b[2] == 0x48 && b[3] == 0x52);
        TU_CHECK(u32_at(b, 4) == 3 && u32_at(b, 8) == P && u32_at(b, 12) == 2 && u32_at(b, 16) == 1);
        TU_CHECK(u32_at(b, 20) == 8 && u32_at(b, 24) == 8 && u32_at(b, 28) == 8); /* lattice extent */
        TU_CHECK(u32_at(b, 44) == 0x3E800000u);                                   /* spacing 0.25f */
        TU_CHECK(u32_at(b, 92) == 0 && u32_at(b, 96) == (uint32_t)half && u32_at(b, 100) == 1);
        TU_CHECK(u32_at(b, 104) == N && u32_at(b, 108) == H);
        size_t leaves = 128 + (size_t)P * R + 16 * P;
        TU_CHECK(u32_at(b, leaves + 12) == f->leaves[3] && u32_at(b, leaves + 16) == (uint32_t)f->leaf_corners[0]);
        /* Validity sits at byte 8 of the record tail (after the colours). */
        TU_CHECK(u32_at(b, 128 + R + R - 16 + 8) == 0x3F800000u); /* probe 1: validity 1.0 */
        free(b);

        pb_shprobe *g = NULL;
        TU_REQUIRE(pb_shprobe_read(path, &g, &err) == PB_SUCCESS);
        TU_CHECK(g->version == 3 && g->structure == PB_SHPROBE_OCTREE && g->storage == (uint32_t)half);
        TU_CHECK(g->probe_count == P && g->element_count == N && g->hanging_count == H && g->grid == NULL);
        double worst = 0.0;
        for (size_t k = 0; k < (size_t)P * 27; k++)
            worst = fmax(worst, fabs(g->coeffs[k] - f->coeffs[k]) / fmax(fabs(f->coeffs[k]), 1e-3));
        /* binary16: 11 significant bits, relative rounding ≤ 2^-11 = 4.9e-4 (values here ≥ 0.05). */
        TU_CHECK(worst <= (half ? 4.9e-4 : 0.0));
        TU_CHECK(memcmp(g->leaves, f->leaves, (size_t)N * 16) == 0);
        TU_CHECK(memcmp(g->leaf_corners, f->leaf_corners, (size_t)N * 32) == 0);
        TU_CHECK(memcmp(g->hanging_sources, f->hanging_sources, (size_t)H * 16) == 0);
        TU_CHECK(memcmp(g->hanging_weights, f->hanging_weights, (size_t)H * 16) == 0);
        TU_CHECK(memcmp(g->positions, f->positions, (size_t)P * 12) == 0);
        TU_CHECK(g->validity[1] == 1.0f && g->validity[0] == 0.5f);
        TU_CHECK(pb_shprobe_lookup(g, (const float[3]){0, 1, 3}) == -1); /* no grid */

        /* The file's interpolation equals the tree's at random points. */
        pb_cotree *ft = NULL;
        pb_tetra *ftet = NULL;
        TU_REQUIRE(pb_interp_from_shprobe(g, &ft, &ftet, &err) == PB_SUCCESS && ft && !ftet);
        for (int s = 0; s < 500; s++) {
            double p[3] = {-1 + 2 * rnd(), 0.5 + 2 * rnd(), 2 + 2 * rnd()};
            pb_interp_weights a, c;
            pb_interp_query_cotree(t, p, NULL, &a);
            pb_interp_query_cotree(ft, p, NULL, &c);
            TU_REQUIRE(a.count == c.count);
            for (uint32_t i = 0; i < a.count; i++) {
                TU_CHECK(a.probe[i] == c.probe[i]);
                TU_CHECK_NEAR(a.weight[i], c.weight[i], 1e-7); /* rules stored as float */
            }
        }
        pb_cotree_destroy(ft);
        pb_shprobe_destroy(g);
        pb_shprobe_destroy(f);
    }
    pb_cotree_destroy(t);
}

static void test_half_rounding_bytes(void)
{
    /* One probe, SH band 0: the red/green/blue colour bytes against hand-encoded binary16. */
    const double pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    pb_tetra *tt = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_tetra_create(pos, 4, &tt, &err) == PB_SUCCESS);
    pb_shprobe *f = NULL;
    TU_REQUIRE(pb_shprobe_from_tetra(tt, pos, PB_SHPROBE_SH, 0, &f, &err) == PB_SUCCESS);
    f->storage = PB_SHPROBE_FLOAT16;
    const float vals[4][3] = {{1.0f, 65504.0f, 1.0f / 3.0f},
                              {5.9604645e-08f, 1.00048828125f /* 1 + 2^-11: tie → even 0x3C00 */, -2.0f},
                              {1.00146484375f /* 1 + 3·2^-11: tie → even 0x3C02 */, 0.0f, 1e-3f},
                              {0.5f, 0.25f, 100.0f}};
    memcpy(f->coeffs, vals, sizeof vals);
    char path[300];
    path_in_tmp(path, sizeof path, "half.shprobe");
    TU_REQUIRE(pb_shprobe_write(path, f, &err) == PB_SUCCESS);
    size_t n;
    uint8_t *b = read_all(path, &n);
    /* Records at 128, 8 + 16 = 24 bytes each. */
    const uint16_t want[4][3] = {
        {0x3C00, 0x7BFF, 0x3555}, {0x0001, 0x3C00, 0xC000}, {0x3C02, 0x0000, 0x1419}, {0x3800, 0x3400, 0x5640}};
    for (int i = 0; i < 4; i++)
        for (int c = 0; c < 3; c++) {
            size_t off = 128 + 24 * (size_t)i + 2 * (size_t)c;
            uint16_t got = (uint16_t)(b[off] | b[off + 1] << 8);
            if (got != want[i][c]) fprintf(stderr, "probe %d channel %d: 0x%04X, want 0x%04X\n", i, c, got, want[i][c]);
            TU_CHECK(got == want[i][c]);
        }
    TU_CHECK(n == 128 + 4 * 24 + 4 * 16 + 32 * (size_t)f->element_count);
    /* 65505 does not fit binary16 (rounds to 65504 only below 65520, but values above 65504 are refused). */
    f->coeffs[0] = 70000.0f;
    pb_error e2 = {0};
    TU_CHECK(pb_shprobe_write(path, f, &e2) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(e2.message, "probe 0 coefficient 0 red is 70000 (offset 128); binary16 storage holds at most") !=
             NULL);
    free(b);
    pb_shprobe_destroy(f);
    pb_tetra_destroy(tt);
}

static void test_tetra_and_cube_round_trip(void)
{
    pb_cotree *t = make_tree();
    TU_REQUIRE(t != NULL);
    uint32_t P = pb_cotree_probe_count(t);
    double *pos = malloc(P * 3 * sizeof(double));
    pb_cotree_probe_positions(t, pos);
    pb_cotree_destroy(t);
    pb_tetra *tt = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_tetra_create(pos, P, &tt, &err) == PB_SUCCESS);
    pb_shprobe *f = NULL;
    TU_REQUIRE(pb_shprobe_from_tetra(tt, pos, PB_SHPROBE_AMBIENT_CUBE, 2, &f, &err) == PB_SUCCESS);
    TU_CHECK(pb_shprobe_colour_count(f) == 6);
    for (uint32_t i = 0; i < P * 18; i++) f->coeffs[i] = (float)(i % 97) * 0.125f - 3.0f; /* negative allowed */
    char path[300];
    path_in_tmp(path, sizeof path, "tet_cube.shprobe");
    TU_REQUIRE(pb_shprobe_write(path, f, &err) == PB_SUCCESS);
    pb_shprobe *g = NULL;
    TU_REQUIRE(pb_shprobe_read(path, &g, &err) == PB_SUCCESS);
    TU_CHECK(g->representation == PB_SHPROBE_AMBIENT_CUBE && g->structure == PB_SHPROBE_TETRA);
    TU_CHECK(g->grid_dims[0] == 0 && g->element_count == pb_tetra_count(tt));
    TU_CHECK(memcmp(g->coeffs, f->coeffs, (size_t)P * 18 * sizeof(float)) == 0);
    TU_CHECK(memcmp(g->tets, f->tets, (size_t)g->element_count * 16) == 0);
    TU_CHECK(memcmp(g->tet_neighbours, f->tet_neighbours, (size_t)g->element_count * 16) == 0);
    pb_shprobe hdr;
    TU_CHECK(pb_shprobe_read_header(path, &hdr, &err) == PB_SUCCESS);
    TU_CHECK(hdr.version == 3 && hdr.structure == PB_SHPROBE_TETRA && hdr.element_count == g->element_count);
    /* Cubes cannot be resampled to version 1. */
    pb_shprobe *dense = NULL;
    pb_error e2 = {0};
    TU_CHECK(pb_interp_resample_dense(g, 0.25, &dense, &e2) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(e2.message, "holds SH only") != NULL);
    /* Asking version 1 or 2 for a v3-only file is an error, never silent loss. */
    f->version = 2;
    pb_error e3 = {0};
    TU_CHECK(pb_shprobe_write(path, f, &e3) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(e3.message, "version 2 cannot hold an ambient cube") != NULL);
    pb_shprobe_destroy(g);
    pb_shprobe_destroy(f);
    pb_tetra_destroy(tt);
    free(pos);
}

static void test_resample_dense_v1(void)
{
    pb_cotree *t = make_tree();
    TU_REQUIRE(t != NULL);
    pb_shprobe *f = octree_file(t, PB_SHPROBE_SH, 2);
    TU_REQUIRE(f != NULL);
    for (uint32_t i = 0; i < f->probe_count; i++) f->validity[i] = 1.0f;
    pb_shprobe *d = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_interp_resample_dense(f, 0.0, &d, &err) == PB_SUCCESS);
    TU_CHECK(d->grid_dims[0] == 8 && d->grid_dims[1] == 8 && d->grid_dims[2] == 8 && d->probe_count == 512);
    TU_CHECK_NEAR(d->grid_spacing, 0.25, 0);
    /* The field is linear: each cell's probe holds the field at the cell centre (float storage). */
    double worst = 0.0;
    for (uint32_t j = 0; j < 512; j++) {
        double p[3] = {-1.0 + 0.25 * (j % 8 + 0.5), 0.5 + 0.25 * ((j / 8) % 8 + 0.5), 2.0 + 0.25 * (j / 64 + 0.5)};
        int32_t idx = d->grid[j];
        TU_REQUIRE(idx >= 0);
        for (uint32_t k = 0; k < 9; k++)
            for (uint32_t ch = 0; ch < 3; ch++)
                worst = fmax(worst, fabs(d->coeffs[((uint32_t)idx * 9 + k) * 3 + ch] - field(p, k, ch)));
    }
    TU_CHECK_NEAR(worst, 0.0, 2e-6); /* float coefficients of magnitude ≤ 3 */
    d->version = 1;
    char path[300];
    path_in_tmp(path, sizeof path, "dense_v1.shprobe");
    TU_REQUIRE(pb_shprobe_write(path, d, &err) == PB_SUCCESS);
    size_t n;
    uint8_t *b = read_all(path, &n);
    TU_CHECK(n == 48 + 160 * 512 + 4 * 512 && u32_at(b, 4) == 1);
    free(b);
    /* The writer's option does the same in one call, byte for byte. */
    char path2[300];
    path_in_tmp(path2, sizeof path2, "dense_v1_option.shprobe");
    TU_REQUIRE(pb_shprobe_write_resampled(path2, f, 0.0, 1, &err) == PB_SUCCESS);
    size_t n2;
    uint8_t *b1 = read_all(path, &n), *b2 = read_all(path2, &n2);
    TU_CHECK(n2 == n && memcmp(b1, b2, n) == 0);
    free(b1);
    free(b2);
    pb_error e3 = {0};
    TU_CHECK(pb_shprobe_write_resampled(path2, f, 0.0, 3, &e3) == PB_ERROR_INVALID_ARGUMENT);
    pb_shprobe_destroy(d);
    pb_shprobe_destroy(f);
    pb_cotree_destroy(t);
}

typedef struct reject_case {
    size_t offset; /* SIZE_MAX = resize instead */
    uint32_t value;
    long resize;
    pb_result code;
    const char *message;
} reject_case;

static void test_read_rejects(void)
{
    /* A small octree file: 2 leaves along x, the left one split → P = 26, H = 5, N = 9, SH band 0. */
    const double o[3] = {0, 0, 0};
    const uint32_t roots[3] = {2, 1, 1};
    pb_cotree *t = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_cotree_create(o, 1.0, 1, roots, &t, &err) == PB_SUCCESS);
    uint8_t split[2] = {1, 0};
    TU_REQUIRE(pb_cotree_split(t, split, NULL, &err) == PB_SUCCESS && pb_cotree_finalize(t, &err) == PB_SUCCESS);
    pb_shprobe *f = NULL;
    TU_REQUIRE(pb_shprobe_from_cotree(t, PB_SHPROBE_SH, 0, &f, &err) == PB_SUCCESS);
    TU_REQUIRE(f->probe_count == 26 && f->hanging_count == 5 && f->element_count == 9);
    char path[300];
    path_in_tmp(path, sizeof path, "reject.shprobe");
    TU_REQUIRE(pb_shprobe_write(path, f, &err) == PB_SUCCESS);
    size_t n;
    uint8_t *base = read_all(path, &n);
    /* Offsets: records at 128 (32 B each: 1 colour + tail), positions at 960, leaves at 1376 (48 B),
     * hanging rules at 1808 (32 B), end 1968. */
    TU_REQUIRE(n == 1968);
    const uint32_t nan_bits = 0x7FC00000u;
    const reject_case cases[] = {
        {92, 2, 0, PB_ERROR_FORMAT, "unknown representation 2 at offset 92; this reader knows 0 = SH, 1 = ambient"},
        {96, 7, 0, PB_ERROR_FORMAT, "unknown storage 7 at offset 96"},
        {100, 4, 0, PB_ERROR_FORMAT, "unknown structure 4 at offset 100"},
        {16, 0, 0, PB_ERROR_FORMAT, "the octree structure needs probe positions (flag bit 0 at offset 16)"},
        {104, 0, 0, PB_ERROR_FORMAT, "the octree structure has no leaves (offset 104)"},
        {104, (1u << 26) + 1, 0, PB_ERROR_TOO_LARGE, "67108865 leaves (offset 104) are above the limit of 67108864"},
        {108, (1u << 26) + 1, 0, PB_ERROR_TOO_LARGE, "67108865 hanging nodes (offset 108) are above the limit"},
        {20, (1u << 20) + 1, 0, PB_ERROR_TOO_LARGE, "octree lattice extent X at offset 20 is 1048577"},
        {104, 10, 0, PB_ERROR_FORMAT,
         "truncated: 1968 bytes, but 26 probes (max band 0, positions) and a 4 x 2 x 2 "
         "octree need 2016"},
        {SIZE_MAX, 0, 1, PB_ERROR_FORMAT, "1 bytes of trailing data after the octree, which ends at offset 1968"},
        {SIZE_MAX, 0, -100 - 1968 + 127, PB_ERROR_FORMAT, "truncated: 27 bytes, the version 3 header needs 128"},
        {1376 + 16 + 4 * 3, 31, 0, PB_ERROR_FORMAT,
         "leaf 0 corner 3 (offset 1404) is 31; it must be a node index below 31"},
        {1376 + 48 + 12, 1, 0, PB_ERROR_FORMAT, "leaf 1 at (1, 0, 0) level 1 (offset 1424) is not aligned"},
        {1376 + 48, 0, 0, PB_ERROR_FORMAT, "leaf 1 at (0, 0, 0) (offset 1424) overlaps the leaf before it"},
        {1808, 26, 0, PB_ERROR_FORMAT, "hanging node 0 source 0 (offset 1808) is 26; it must be a probe or an earlier"},
        {1808 + 16, 0x3E800000u, 0, PB_ERROR_FORMAT, "hanging node 0 weights sum to 0.75"},
        {1808 + 16, nan_bits, 0, PB_ERROR_NON_FINITE, "hanging node 0 weight 0 is nan (offset 1824)"},
        {1808 + 16, 0xBF800000u, 0, PB_ERROR_FORMAT,
         "hanging node 0 weight 0 is -1 (offset 1824); it must be in [0, 1]"},
        {128 + 32, nan_bits, 0, PB_ERROR_NON_FINITE, "probe 1 coefficient 0 red is nan (offset 160)"},
        {128 + 16 + 8, 0x40000000u, 0, PB_ERROR_FORMAT, "probe 0 validity is 2 (offset 152)"},
        {960 + 4, nan_bits, 0, PB_ERROR_NON_FINITE, "probe 0 position[1] is nan (offset 964)"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        const reject_case *rc = cases + c;
        size_t len = rc->offset == SIZE_MAX ? (size_t)((long)n + rc->resize) : n;
        uint8_t *b = calloc(len + 1, 1);
        memcpy(b, base, len < n ? len : n);
        if (rc->offset != SIZE_MAX) set_u32(b, rc->offset, rc->value);
        pb_shprobe *p = NULL;
        pb_error e = {0};
        pb_result r = pb_shprobe_read_memory(b, len, &p, &e);
        if (r != rc->code || !strstr(e.message, rc->message))
            fprintf(stderr, "case %zu: got %d '%s', want %d '%s'\n", c, (int)r, e.message, (int)rc->code, rc->message);
        TU_CHECK(r == rc->code);
        TU_CHECK(strstr(e.message, rc->message) != NULL);
        TU_CHECK(p == NULL);
        free(b);
    }
    /* Binary16: an all-ones exponent is Inf/NaN (a half file of the same tree). */
    f->storage = PB_SHPROBE_FLOAT16;
    TU_REQUIRE(pb_shprobe_write(path, f, &err) == PB_SUCCESS);
    free(base);
    base = read_all(path, &n);
    base[128 + 24 + 2] = 0x00;
    base[128 + 24 + 3] = 0x7C; /* probe 1 green = +Inf */
    pb_shprobe *p = NULL;
    pb_error e = {0};
    TU_CHECK(pb_shprobe_read_memory(base, n, &p, &e) == PB_ERROR_NON_FINITE);
    TU_CHECK(strstr(e.message, "probe 1 coefficient 0 green is inf (offset 154)") != NULL);
    free(base);
    pb_shprobe_destroy(f);
    pb_cotree_destroy(t);

    /* Tetrahedra: vertex out of range, repeated vertex, neighbour out of range, dims not 0. */
    const double pos[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
    pb_tetra *tt = NULL;
    TU_REQUIRE(pb_tetra_create(pos, 5, &tt, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_shprobe_from_tetra(tt, pos, PB_SHPROBE_SH, 0, &f, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_shprobe_write(path, f, &err) == PB_SUCCESS);
    base = read_all(path, &n);
    size_t tets = 128 + 5 * 32 + 5 * 16;
    const reject_case tcases[] = {
        {tets + 4, 5, 0, PB_ERROR_FORMAT, "tetrahedron 0 vertex 1 (offset 372) is 5; it must be a probe index below 5"},
        {tets + 4, u32_at(base, tets), 0, PB_ERROR_FORMAT, "tetrahedron 0 (offset 368) repeats vertex"},
        {tets + 16, 9, 0, PB_ERROR_FORMAT, "tetrahedron 0 neighbour 0 (offset 384) is 9; it must be -1 or below"},
        {24, 2, 0, PB_ERROR_FORMAT, "tetrahedra have no lattice: dim Y at offset 24 must be 0, not 2"},
        {108, 1, 0, PB_ERROR_FORMAT, "tetrahedra have no hanging nodes"},
    };
    for (size_t c = 0; c < sizeof tcases / sizeof tcases[0]; c++) {
        uint8_t *b = malloc(n);
        memcpy(b, base, n);
        set_u32(b, tcases[c].offset, tcases[c].value);
        pb_error e4 = {0};
        pb_result r = pb_shprobe_read_memory(b, n, &p, &e4);
        if (r != tcases[c].code || !strstr(e4.message, tcases[c].message))
            fprintf(stderr, "tet case %zu: got %d '%s'\n", c, (int)r, e4.message);
        TU_CHECK(r == tcases[c].code && strstr(e4.message, tcases[c].message) != NULL);
        free(b);
    }
    free(base);
    pb_shprobe_destroy(f);
    pb_tetra_destroy(tt);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/schnee_v3_XXXXXX");
    if (!mkdtemp(tmpdir)) return 1;
    TU_RUN(test_octree_layout_and_round_trip);
    TU_RUN(test_half_rounding_bytes);
    TU_RUN(test_tetra_and_cube_round_trip);
    TU_RUN(test_resample_dense_v1);
    TU_RUN(test_read_rejects);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    if (system(cmd) != 0) return 1;
    return TU_EXIT();
}
