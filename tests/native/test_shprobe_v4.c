/* `.shprobe` version 4 (docs/shprobe-format.md, "Version 4"): the kd corner tree (structure 3).
 * A file image written here byte by byte from the format's table (not by the writer) is read back
 * field by field, the writer reproduces its bytes, and each reader check refuses a file with one
 * field corrupted, naming the field. With the box tree of pb_cotree.h: a tree -> version 4 bytes ->
 * read -> pb_interp_from_shprobe queries as the tree does, and a tree of cubes stays version 3. */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_interp.h"
#include "schnee/pb_shprobe.h"

#include "testutil.h"

#include <stdint.h>
#include <stdlib.h>
#include <unistd.h>

static char tmpdir[256];

static void set_u32(uint8_t *b, size_t off, uint32_t v)
{
    for (int i = 0; i < 4; i++) b[off + (size_t)i] = (uint8_t)(v >> (8 * i));
}

static void set_f32(uint8_t *b, size_t off, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    set_u32(b, off, u);
}

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

/* ---- the hand-made file -------------------------------------------------------------------------
 * Lattice 4 x 2 x 2 min cells of 0.5 m from (1, 2, 3), root level R = 1: a root grid of 2 x 1 x 1 boxes
 * of 2 min cells. Root 0 is split along y into two slabs A = (0, 0, 0) levels (1, 0, 1) and
 * B = (0, 1, 0) levels (1, 0, 1); root 1 is the cube C = (2, 0, 0) levels (1, 1, 1). The slabs' corners
 * (2, 1, 0) and (2, 1, 2) lie inside edges of C: hanging nodes, halfway between C's corners. Leaves in
 * Morton order of min corners (A 0, B 2, C 8); probes in Morton order of their lattice points; hanging
 * nodes by decreasing potential ((2, 1, 0): 1 + 0 + 2 = 3, (2, 1, 2): 1 + 0 + 1 = 2). Split tree: node 0
 * = split along y (2) with children 2, 3; node 1 = leaf 2; node 2 = leaf 0; node 3 = leaf 1. SH band 0. */
#define HM_P       14u
#define HM_H       2u
#define HM_N       3u
#define HM_K       4u
#define HM_RECORDS 128u                     /* 14 records of 16 + 16 bytes */
#define HM_POS     (HM_RECORDS + 32u * 14u) /* 576 */
#define HM_LEAVES  (HM_POS + 16u * 14u)     /* 800 */
#define HM_HANG    (HM_LEAVES + 48u * 3u)   /* 944 */
#define HM_NODES   (HM_HANG + 32u * 2u)     /* 1008 */
#define HM_SIZE    (HM_NODES + 4u * 4u)     /* 1024 */

static const uint32_t hm_probes[HM_P][3] = {
    {0, 0, 0}, {0, 1, 0}, {2, 0, 0}, {0, 2, 0}, {2, 2, 0}, {0, 0, 2}, {0, 1, 2},
    {2, 0, 2}, {0, 2, 2}, {2, 2, 2}, {4, 0, 0}, {4, 2, 0}, {4, 0, 2}, {4, 2, 2},
};
static const uint32_t hm_hanging[HM_H][3] = {{2, 1, 0}, {2, 1, 2}};
static const uint32_t hm_leaves[HM_N][4] = {{0, 0, 0, 0x10001u}, {0, 1, 0, 0x10001u}, {2, 0, 0, 0x10101u}};

static uint64_t morton(const uint32_t *p)
{
    uint64_t m = 0;
    for (int b = 0; b < 21; b++)
        for (int k = 0; k < 3; k++) m |= (uint64_t)(p[k] >> b & 1u) << (3 * b + k);
    return m;
}

/* Node index of a lattice point: a probe or a hanging node; -1 if neither. */
static int32_t hm_node(const uint32_t p[3])
{
    for (uint32_t i = 0; i < HM_P; i++)
        if (!memcmp(hm_probes[i], p, 3 * sizeof(uint32_t))) return (int32_t)i;
    for (uint32_t j = 0; j < HM_H; j++)
        if (!memcmp(hm_hanging[j], p, 3 * sizeof(uint32_t))) return (int32_t)(HM_P + j);
    return -1;
}

static void hm_bytes(uint8_t b[HM_SIZE])
{
    memset(b, 0, HM_SIZE);
    set_u32(b, 0, 0x52485053u);
    set_u32(b, 4, 4);
    set_u32(b, 8, HM_P);
    set_u32(b, 12, 0); /* max band */
    set_u32(b, 16, 1); /* positions */
    set_u32(b, 20, 4);
    set_u32(b, 24, 2);
    set_u32(b, 28, 2);
    const float origin[3] = {1.0f, 2.0f, 3.0f};
    for (int k = 0; k < 3; k++) set_f32(b, 32u + 4u * (uint32_t)k, origin[k]);
    set_f32(b, 44, 0.5f);
    for (int k = 0; k < 3; k++) set_f32(b, 48u + 16u * (uint32_t)k, 1.0f); /* identity rows */
    set_f32(b, 84, 1.0f);
    set_f32(b, 88, 0.1f);
    set_u32(b, 100, 3); /* structure: kd corner tree */
    set_u32(b, 104, HM_N);
    set_u32(b, 108, HM_H);
    set_u32(b, 112, 1); /* R */
    set_u32(b, 116, HM_K);
    for (uint32_t i = 0; i < HM_P; i++) {
        size_t r = HM_RECORDS + 32u * i;
        set_f32(b, r, 1.0f + (float)i);           /* L00 red */
        set_f32(b, r + 4, 2.0f * (float)i);       /* green */
        set_f32(b, r + 8, 0.25f);                 /* blue */
        set_f32(b, r + 16, 1.0f);                 /* scale */
        set_f32(b, r + 20, 0.1f);                 /* ambient */
        set_f32(b, r + 24, i == 5 ? 0.5f : 1.0f); /* validity */
        for (int k = 0; k < 3; k++)
            set_f32(b, HM_POS + 16u * i + 4u * (uint32_t)k, origin[k] + 0.5f * (float)hm_probes[i][k]);
    }
    for (uint32_t i = 0; i < HM_N; i++) {
        const uint32_t *l = hm_leaves[i];
        for (int k = 0; k < 4; k++) set_u32(b, HM_LEAVES + 48u * i + 4u * (uint32_t)k, l[k]);
        for (uint32_t c = 0; c < 8; c++) {
            uint32_t p[3];
            for (int k = 0; k < 3; k++) p[k] = l[k] + ((c >> k & 1u) << (l[3] >> (8 * k) & 0xffu));
            set_u32(b, HM_LEAVES + 48u * i + 16u + 4u * c, (uint32_t)hm_node(p));
        }
    }
    for (uint32_t j = 0; j < HM_H; j++) { /* on C's edge along y: (2, 0, z) and (2, 2, z) */
        uint32_t lo[3] = {2, 0, hm_hanging[j][2]}, hi[3] = {2, 2, hm_hanging[j][2]};
        set_u32(b, HM_HANG + 32u * j, (uint32_t)hm_node(lo));
        set_u32(b, HM_HANG + 32u * j + 4, (uint32_t)hm_node(hi));
        set_f32(b, HM_HANG + 32u * j + 16, 0.5f);
        set_f32(b, HM_HANG + 32u * j + 20, 0.5f);
    }
    set_u32(b, HM_NODES + 0, 2u << 2 | 2u); /* split along y, children 2, 3 */
    set_u32(b, HM_NODES + 4, 2u << 2);      /* leaf 2 (C) */
    set_u32(b, HM_NODES + 8, 0u << 2);      /* leaf 0 (A) */
    set_u32(b, HM_NODES + 12, 1u << 2);     /* leaf 1 (B) */
}

static void test_hand_made_file_reads_field_by_field(void)
{
    for (uint32_t i = 1; i < HM_P; i++) TU_REQUIRE(morton(hm_probes[i - 1]) < morton(hm_probes[i]));
    for (uint32_t i = 1; i < HM_N; i++) TU_REQUIRE(morton(hm_leaves[i - 1]) < morton(hm_leaves[i]));
    uint8_t b[HM_SIZE];
    hm_bytes(b);
    pb_shprobe *p = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_shprobe_read_memory(b, HM_SIZE, &p, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(p->version, 4);
    TU_CHECK_EQ_INT(p->structure, PB_SHPROBE_KDTREE);
    TU_CHECK_EQ_INT(p->probe_count, HM_P);
    TU_CHECK_EQ_INT(p->element_count, HM_N);
    TU_CHECK_EQ_INT(p->hanging_count, HM_H);
    TU_CHECK_EQ_INT(p->root_level, 1);
    TU_CHECK_EQ_INT(p->split_node_count, HM_K);
    TU_CHECK_EQ_INT(p->grid_dims[0], 4);
    TU_CHECK_EQ_INT(p->grid_dims[2], 2);
    TU_CHECK_NEAR(p->grid_spacing, 0.5, 0);
    TU_CHECK_NEAR(p->grid_origin[2], 3.0, 0);
    const uint32_t nodes[HM_K] = {10, 8, 0, 4};
    for (uint32_t i = 0; i < HM_K; i++) TU_CHECK_EQ_INT(p->split_nodes[i], nodes[i]);
    for (uint32_t i = 0; i < HM_N; i++)
        for (int k = 0; k < 4; k++) TU_CHECK_EQ_INT(p->leaves[4u * i + (uint32_t)k], hm_leaves[i][k]);
    TU_CHECK_EQ_INT(p->leaf_corners[8 * 0 + 3], HM_P + 0); /* A's (2, 1, 0) */
    TU_CHECK_EQ_INT(p->leaf_corners[8 * 1 + 7], 9);        /* B's (2, 2, 2) */
    TU_CHECK_EQ_INT(p->leaf_corners[8 * 2 + 7], 13);       /* C's (4, 2, 2) */
    TU_CHECK_EQ_INT(p->hanging_sources[4], 7);             /* (2, 1, 2) from (2, 0, 2) */
    TU_CHECK_EQ_INT(p->hanging_sources[5], 9);             /* and (2, 2, 2) */
    TU_CHECK_NEAR(p->hanging_weights[5], 0.5, 0);
    TU_CHECK_NEAR(p->coeffs[3 * 13], 14.0, 0);
    TU_CHECK_NEAR(p->coeffs[3 * 13 + 1], 26.0, 0);
    TU_CHECK_NEAR(p->validity[5], 0.5, 0);
    TU_CHECK_NEAR(p->positions[3 * 13 + 0], 3.0, 0);
    TU_CHECK_NEAR(p->positions[3 * 13 + 2], 4.0, 0);

    /* The writer reproduces the bytes exactly (auto version: 4 for structure 3). */
    char path[300];
    snprintf(path, sizeof path, "%s/hand.shprobe", tmpdir);
    p->version = 0;
    TU_CHECK(pb_shprobe_write(path, p, &err) == PB_SUCCESS);
    size_t n = 0;
    uint8_t *w = read_all(path, &n);
    TU_CHECK(w && n == HM_SIZE && memcmp(w, b, HM_SIZE) == 0);
    free(w);
    pb_shprobe hdr;
    TU_CHECK(pb_shprobe_read_header(path, &hdr, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(hdr.root_level, 1);
    TU_CHECK_EQ_INT(hdr.split_node_count, HM_K);
    TU_CHECK(hdr.split_nodes == NULL);

    /* Versions that cannot hold it, and version 4 for another structure. */
    p->version = 3;
    TU_CHECK(pb_shprobe_write(path, p, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "version 3 cannot hold a kd corner tree (structure 3); write version 4");
    p->version = 4;
    err = (pb_error){0};         /* a context keeps its first error */
    p->split_nodes[1] = 7u << 2; /* the writer runs the reader's checks */
    TU_CHECK(pb_shprobe_write(path, p, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "split-tree node 1 (offset 1012) names leaf 7; leaves are below 3");
    pb_shprobe_destroy(p);
    const uint32_t dims[3] = {2, 2, 2};
    TU_REQUIRE(pb_shprobe_create_v3(1, PB_SHPROBE_SH, 0, PB_SHPROBE_OCTREE, dims, 1, 0, &p, &err) == PB_SUCCESS);
    p->grid_spacing = 1.0f;
    p->version = 4;
    err = (pb_error){0};
    TU_CHECK(pb_shprobe_write(path, p, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "version 4 holds the kd corner tree (structure 3) only");
    pb_shprobe_destroy(p);
    err = (pb_error){0};
    TU_CHECK(pb_shprobe_create_v3(1, PB_SHPROBE_SH, 0, PB_SHPROBE_KDTREE, dims, 1, 0, &p, &err) ==
             PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "the kd corner tree (structure 3 at offset 100) needs version 4, not 3");
}

typedef struct reject_case {
    size_t offset;  /* SIZE_MAX: no change but the size */
    uint32_t value; /* written at offset */
    long size_delta;
    pb_result code;
    const char *message;
} reject_case;

static void test_each_check_refuses_one_corrupt_field(void)
{
    const uint32_t E = PB_SHPROBE_SPLIT_EMPTY;
    const reject_case cases[] = {
        {4, 5, 0, PB_ERROR_FORMAT, "unknown version 5 at offset 4; this reader knows versions 1, 2, 3 and 4"},
        {4, 3, 0, PB_ERROR_FORMAT, "the kd corner tree (structure 3 at offset 100) needs version 4, not 3"},
        {100, 1, 0, PB_ERROR_FORMAT, "structure 1 at offset 100 in a version 4 file; version 4 holds 3 = kd corner"},
        {16, 0, 0, PB_ERROR_FORMAT, "the kd corner tree structure needs probe positions (flag bit 0 at offset 16)"},
        {104, 0, 0, PB_ERROR_FORMAT, "the kd corner tree structure has no leaves (offset 104)"},
        {104, (1u << 26) + 1u, 0, PB_ERROR_TOO_LARGE, "67108865 leaves (offset 104) are above the limit"},
        {20, 0, 0, PB_ERROR_FORMAT, "octree lattice extent X at offset 20 is 0; it must be 1..1048576 min cells"},
        {120, 1, 0, PB_ERROR_FORMAT, "reserved word at offset 120 is 0x1; it must be 0"},
        {124, 0x80000000u, 0, PB_ERROR_FORMAT, "reserved word at offset 124 is 0x80000000; it must be 0"},
        {112, 21, 0, PB_ERROR_FORMAT, "root level 21 at offset 112 is out of range 0..20"},
        {116, (1u << 28) + 1u, 0, PB_ERROR_TOO_LARGE, "268435457 split-tree nodes (offset 116) are above the limit"},
        {116, 1, 0, PB_ERROR_FORMAT,
         "split-tree node count 1 (offset 116) is below the 2 root cells of a 4 x 2 x 2 lattice at root level 1"},
        {112, 0, 0, PB_ERROR_FORMAT, "is below the 16 root cells of a 4 x 2 x 2 lattice at root level 0"},
        {116, 5, 0, PB_ERROR_FORMAT,
         "truncated: 1024 bytes, but 14 probes (max band 0, positions) and a 4 x 2 x 2 "
         "kd corner tree need 1028"},
        {SIZE_MAX, 0, 4, PB_ERROR_FORMAT,
         "4 bytes of trailing data after the kd corner tree, which ends at offset 1024"},
        {HM_LEAVES + 12, 0x01010001u, 0, PB_ERROR_FORMAT,
         "leaf 0 levels word 0x01010001 (offset 812) has a nonzero top byte"},
        {HM_LEAVES + 96 + 12, 0x010102u, 0, PB_ERROR_FORMAT,
         "leaf 2 level x is 2 (offset 908); it must be at most the root level 1"},
        {HM_LEAVES + 96, 3, 0, PB_ERROR_FORMAT,
         "leaf 2 at (3, 0, 0) levels (1, 1, 1) (offset 896) is not aligned to its size or reaches past the lattice "
         "extent 4 x 2 x 2"},
        {20, 3, 0, PB_ERROR_FORMAT,
         "leaf 2 at (2, 0, 0) levels (1, 1, 1) (offset 896) is not aligned to its size or "
         "reaches past the lattice extent 3 x 2 x 2"},
        {HM_LEAVES + 48 + 4, 0, 0, PB_ERROR_FORMAT,
         "leaf 1 at (0, 0, 0) (offset 848) is not after the leaf before it in Morton order of min corners"},
        {HM_LEAVES + 16 + 12, 16, 0, PB_ERROR_FORMAT,
         "leaf 0 corner 3 (offset 828) is 16; it must be a node index below 16"},
        {HM_HANG, 14, 0, PB_ERROR_FORMAT,
         "hanging node 0 source 0 (offset 944) is 14; it must be a probe or an earlier hanging node, below 14"},
        {HM_NODES + 8, 4u << 2 | 2u, 0, PB_ERROR_FORMAT,
         "split-tree node 2 (offset 1016) splits along y a box of level 0 on that axis, at (0, 0, 0) levels (1, 0, 1)"},
        {HM_NODES, 0u << 2 | 2u, 0, PB_ERROR_FORMAT,
         "split-tree node 0 (offset 1008) names children 0 and 1; they must come after it and after the 2 root cells"},
        {HM_NODES, 1u << 2 | 1u, 0, PB_ERROR_FORMAT, "split-tree node 0 (offset 1008) names children 1 and 2"},
        {HM_NODES, 3u << 2 | 2u, 0, PB_ERROR_FORMAT,
         "split-tree node 0 (offset 1008) names children 3 and 4; they must come after it and after the 2 root cells, "
         "below the node count 4"},
        {HM_NODES + 4, 2u << 2 | 1u, 0, PB_ERROR_FORMAT,
         "split-tree node 2 (offset 1016) is the child of two splits (the second: node 1)"},
        {HM_NODES, E << 2, 0, PB_ERROR_FORMAT,
         "split-tree node 2 (offset 1016) is not the child of any split reached from the root cells"},
        {HM_NODES + 4, 5u << 2, 0, PB_ERROR_FORMAT,
         "split-tree node 1 (offset 1012) names leaf 5; leaves are below 3 (or 1073741823 = none)"},
        {HM_NODES + 8, 1u << 2, 0, PB_ERROR_FORMAT,
         "split-tree node 2 (offset 1016) reaches leaf 1 at (0, 1, 0) levels word 0x10001, but the node's box is at "
         "(0, 0, 0) levels (1, 0, 1)"},
        {HM_NODES + 4, 0u << 2, 0, PB_ERROR_FORMAT,
         "split-tree node 1 (offset 1012) reaches leaf 0 at (0, 0, 0) levels word 0x10001, but the node's box is at "
         "(2, 0, 0) levels (1, 1, 1)"},
        {HM_NODES + 4, E << 2, 0, PB_ERROR_FORMAT, "the split tree (offset 1008) reaches 2 of the 3 leaves"},
    };
    uint8_t good[HM_SIZE + 8];
    hm_bytes(good);
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        const reject_case *rc = cases + c;
        uint8_t b[HM_SIZE + 8];
        memcpy(b, good, sizeof b);
        if (rc->offset != SIZE_MAX) set_u32(b, rc->offset, rc->value);
        pb_shprobe *p = NULL;
        pb_error err = {0};
        pb_result r = pb_shprobe_read_memory(b, (size_t)((long)HM_SIZE + rc->size_delta), &p, &err);
        if (r != rc->code || !strstr(err.message, rc->message))
            fprintf(stderr, "case %zu: result %d, message: %s\n", c, (int)r, err.message);
        TU_CHECK_EQ_INT(r, rc->code);
        TU_CHECK_CONTAINS(err.message, rc->message);
        TU_CHECK(p == NULL);
    }
    /* Control: the unmodified bytes load, so each refusal comes from its one field. */
    pb_shprobe *p = NULL;
    pb_error err = {0};
    TU_CHECK(pb_shprobe_read_memory(good, HM_SIZE, &p, &err) == PB_SUCCESS);
    pb_shprobe_destroy(p);
}

/* Version 3 files keep their words: structure 3 needs version 4, a structure above is unknown. */
static void test_version_3_structures_are_unchanged(void)
{
    uint8_t b[HM_SIZE];
    hm_bytes(b);
    set_u32(b, 4, 3);
    set_u32(b, 100, 4);
    pb_shprobe *p = NULL;
    pb_error err = {0};
    TU_CHECK(pb_shprobe_read_memory(b, HM_SIZE, &p, &err) == PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message,
                      "unknown structure 4 at offset 100; this reader knows 0 = grid, 1 = octree, 2 = tetrahedra");
}

/* ---- with the box tree of pb_cotree.h -------------------------------------------------------------- */

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double rnd(void)
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return (double)((rng_state * 0x2545F4914F6CDD1Dull) >> 11) / 9007199254740992.0;
}

/* The hand-made file's boxes as a tree: the writer's image is the hand-made file, field by field (its
 * canonical split tree, probe numbering and hanging rules are the ones written out above from the
 * format's rules), and with the same records the bytes are equal. */
static void test_tree_of_the_hand_made_boxes_writes_the_same_file(void)
{
    const double origin[3] = {1.0, 2.0, 3.0};
    const uint32_t dims[3] = {4, 2, 2};
    pb_cotree *t = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_cotree_create_boxes(origin, 0.5, 1, dims, &hm_leaves[0][0], HM_N, &t, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    pb_shprobe *p = NULL;
    TU_REQUIRE(pb_shprobe_from_cotree(t, PB_SHPROBE_SH, 0, &p, &err) == PB_SUCCESS);
    uint8_t b[HM_SIZE];
    hm_bytes(b);
    pb_shprobe *want = NULL;
    TU_REQUIRE(pb_shprobe_read_memory(b, HM_SIZE, &want, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(p->structure, PB_SHPROBE_KDTREE);
    TU_CHECK_EQ_INT(p->probe_count, HM_P);
    TU_CHECK_EQ_INT(p->hanging_count, HM_H);
    TU_CHECK_EQ_INT(p->root_level, 1);
    TU_REQUIRE(p->split_node_count == HM_K);
    TU_CHECK(memcmp(p->split_nodes, want->split_nodes, HM_K * 4) == 0);
    TU_CHECK(memcmp(p->leaves, want->leaves, HM_N * 16) == 0);
    TU_CHECK(memcmp(p->leaf_corners, want->leaf_corners, HM_N * 32) == 0);
    TU_CHECK(memcmp(p->hanging_sources, want->hanging_sources, HM_H * 16) == 0);
    TU_CHECK(memcmp(p->hanging_weights, want->hanging_weights, HM_H * 16) == 0);
    TU_CHECK(memcmp(p->positions, want->positions, HM_P * 12) == 0);
    memcpy(p->coeffs, want->coeffs, HM_P * 3 * sizeof(float));
    memcpy(p->validity, want->validity, HM_P * sizeof(float));
    char path[300];
    snprintf(path, sizeof path, "%s/tree.shprobe", tmpdir);
    TU_CHECK(pb_shprobe_write(path, p, &err) == PB_SUCCESS);
    size_t n = 0;
    uint8_t *w = read_all(path, &n);
    TU_CHECK(w && n == HM_SIZE && memcmp(w, b, HM_SIZE) == 0);
    free(w);
    pb_shprobe_destroy(want);
    pb_shprobe_destroy(p);
    pb_cotree_destroy(t);
}

/* A random tree of boxes (2 x 1 x 2 roots of 4 min cells, 4 passes of random axis masks, the nesting
 * rule's forced splits) -> version 4 bytes -> read -> pb_interp_from_shprobe: the weights at 4000 random
 * points equal the tree's (same probes, 1e-12). A tree of cubes stays version 3. */
static void test_box_tree_round_trip_queries_as_the_tree(void)
{
    const double origin[3] = {-1.0, 0.5, 2.0};
    const uint32_t roots[3] = {2, 1, 2};
    for (int trial = 0; trial < 6; trial++) {
        pb_cotree *t = NULL;
        pb_error err = {0};
        TU_REQUIRE(pb_cotree_create(origin, 0.25, 2, roots, &t, &err) == PB_SUCCESS);
        for (int pass = 0; pass < 4; pass++) {
            uint32_t n = pb_cotree_leaf_count(t);
            uint8_t *axes = calloc(n, 1);
            for (uint32_t i = 0; i < n; i++)
                axes[i] = (uint8_t)(trial == 0 ? (rnd() < 0.3 ? 7 : 0) : rnd() < 0.35 ? 1u + (uint32_t)(rnd() * 7) : 0);
            TU_REQUIRE(pb_cotree_split_axes(t, axes, NULL, &err) == PB_SUCCESS);
            free(axes);
        }
        TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
        pb_shprobe *p = NULL;
        TU_REQUIRE(pb_shprobe_from_cotree(t, PB_SHPROBE_SH, 1, &p, &err) == PB_SUCCESS);
        /* trial 0 splits whole cubes only: version 3, structure 1 */
        TU_CHECK_EQ_INT(p->structure, trial == 0 ? PB_SHPROBE_OCTREE : PB_SHPROBE_KDTREE);
        for (size_t k = 0; k < (size_t)p->probe_count * 4 * 3; k++) p->coeffs[k] = (float)rnd();
        char path[300];
        snprintf(path, sizeof path, "%s/round%d.shprobe", tmpdir, trial);
        TU_REQUIRE(pb_shprobe_write(path, p, &err) == PB_SUCCESS);
        pb_shprobe *f = NULL;
        TU_REQUIRE(pb_shprobe_read(path, &f, &err) == PB_SUCCESS);
        TU_CHECK_EQ_INT(f->version, trial == 0 ? 3 : 4);
        pb_cotree *ft = NULL;
        pb_tetra *tet = NULL;
        TU_REQUIRE(pb_interp_from_shprobe(f, &ft, &tet, &err) == PB_SUCCESS);
        TU_REQUIRE(ft && !tet);
        int bad = 0, inside = 0;
        for (int q = 0; q < 4000; q++) {
            double pt[3] = {origin[0] + 2.0 * rnd(), origin[1] + 1.0 * rnd(), origin[2] + 2.0 * rnd()};
            if (q % 10 == 0) pt[q / 10 % 3] = origin[q / 10 % 3] + 0.25 * (double)(uint32_t)(rnd() * 8); /* faces */
            pb_interp_weights a, b;
            pb_interp_query_cotree(t, pt, NULL, &a);
            pb_interp_query_cotree(ft, pt, NULL, &b);
            inside += a.count > 0;
            bool same = a.count == b.count;
            for (uint32_t k = 0; same && k < a.count; k++)
                same = a.probe[k] == b.probe[k] && fabs(a.weight[k] - b.weight[k]) <= 1e-12;
            bad += !same;
        }
        TU_CHECK_EQ_INT(bad, 0);
        TU_CHECK(inside > 3900);
        pb_cotree_destroy(ft);
        pb_shprobe_destroy(f);
        pb_shprobe_destroy(p);
        pb_cotree_destroy(t);
    }
}

/* The dense resample of a version 4 file of a linear field: exact (float) at every cell centre, since
 * trilinear boxes with hanging rules reproduce a linear field. */
static void test_resample_dense_of_a_box_tree(void)
{
    const double origin[3] = {1.0, 2.0, 3.0};
    const uint32_t dims[3] = {4, 2, 2};
    pb_cotree *t = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_cotree_create_boxes(origin, 0.5, 1, dims, &hm_leaves[0][0], HM_N, &t, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    pb_shprobe *p = NULL;
    TU_REQUIRE(pb_shprobe_from_cotree(t, PB_SHPROBE_SH, 0, &p, &err) == PB_SUCCESS);
    for (uint32_t i = 0; i < p->probe_count; i++) {
        const float *x = p->positions + 3u * i;
        p->coeffs[3u * i] = 1.0f + 0.5f * x[0] - 0.25f * x[1] + 0.75f * x[2];
    }
    pb_shprobe *d = NULL;
    TU_REQUIRE(pb_interp_resample_dense(p, 0.0, &d, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(d->grid_dims[0], 4);
    TU_CHECK_EQ_INT(d->probe_count, 16);
    for (uint32_t j = 0; j < 16; j++) {
        uint32_t c[3] = {j % 4, j / 4 % 2, j / 8};
        int32_t pi = d->grid[j];
        TU_REQUIRE(pi >= 0);
        double x[3];
        for (int k = 0; k < 3; k++) x[k] = origin[k] + 0.5 * (c[k] + 0.5);
        TU_CHECK_NEAR(d->coeffs[3u * (uint32_t)pi], 1.0 + 0.5 * x[0] - 0.25 * x[1] + 0.75 * x[2], 2e-6);
    }
    pb_shprobe_destroy(d);
    pb_shprobe_destroy(p);
    pb_cotree_destroy(t);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/schnee_v4_XXXXXX");
    if (!mkdtemp(tmpdir)) return 1;
    TU_RUN(test_hand_made_file_reads_field_by_field);
    TU_RUN(test_each_check_refuses_one_corrupt_field);
    TU_RUN(test_version_3_structures_are_unchanged);
    TU_RUN(test_tree_of_the_hand_made_boxes_writes_the_same_file);
    TU_RUN(test_box_tree_round_trip_queries_as_the_tree);
    TU_RUN(test_resample_dense_of_a_box_tree);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    return TU_EXIT();
}
