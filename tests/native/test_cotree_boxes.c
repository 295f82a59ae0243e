/* Boxes with per-axis levels in the corner tree (pb_cotree.h, docs/aniso-refinement.md). Closed forms
 * and independent references: a field linear in position is reproduced exactly by trilinear boxes with
 * hanging corners (1e-9); the two leaves' own fields agree at random points of every kind of leaf
 * border (C0, the nesting rule's purpose; a jump would be of the order of the random probe values,
 * 0.1-1); the forced splits of hand-made crosses follow the rule's text; the split tree's descent,
 * re-implemented here with a step counter, finds the leaf pb_cotree_locate finds in at most 3R steps
 * and does not depend on the order of the splits; a tree of cubes split by masks 7 equals the one split
 * by flags, and its hanging rules keep the octree's order (largest host first). */
#include "schnee/pb_interp.h"

#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static const double ORIGIN[3] = {-2.0, 0.5, 1.0};
#define H 0.25

/* Roots 2 x 1 x 2 of 8 min cells (dims 16 x 8 x 16, as tests/python/test_aniso_prototype.py), then
 * `passes` passes that split every leaf axis with probability 0.3, each finalized (nesting rule). */
static pb_cotree *random_tree(uint32_t passes, uint32_t *forced_total)
{
    const uint32_t roots[3] = {2, 1, 2};
    pb_cotree *t = NULL;
    pb_error err = {0};
    if (pb_cotree_create(ORIGIN, H, 3, roots, &t, &err) != PB_SUCCESS) return NULL;
    *forced_total = 0;
    for (uint32_t p = 0; p < passes; p++) {
        uint32_t L = pb_cotree_leaf_count(t);
        uint8_t *m = calloc(L + 1u, 1);
        for (uint32_t i = 0; i < L; i++)
            for (int a = 0; a < 3; a++)
                if (tu_rnd() < 0.3) m[i] |= (uint8_t)(1u << a);
        pb_result r = pb_cotree_split_axes(t, m, NULL, &err);
        free(m);
        if (r == PB_SUCCESS) r = pb_cotree_finalize(t, &err);
        if (r != PB_SUCCESS) {
            fprintf(stderr, "random tree: %s\n", err.message);
            pb_cotree_destroy(t);
            return NULL;
        }
        *forced_total += pb_cotree_forced_splits(t);
    }
    return t;
}

static double eval(const pb_interp_weights *w, const double *values)
{
    double v = 0.0;
    for (uint32_t i = 0; i < w->count; i++) v += w->weight[i] * values[w->probe[i]];
    return v;
}

static double linear(const double u[3]) { return 0.25 + 0.37 * u[0] - 1.3 * u[1] + 0.71 * u[2]; }

static void test_random_trees_linear_and_c0(void)
{
    uint32_t aniso_leaves = 0, hanging = 0, forced = 0, borders = 0;
    for (int seed = 0; seed < 6; seed++) {
        uint32_t f = 0;
        pb_cotree *t = random_tree(4, &f);
        TU_REQUIRE(t != NULL);
        TU_CHECK(!pb_cotree_all_cubes(t));
        forced += f;
        uint32_t L = pb_cotree_leaf_count(t), P = pb_cotree_probe_count(t);
        hanging += pb_cotree_hanging_count(t);
        uint32_t *lv = malloc(3u * L * sizeof(uint32_t)), dims[3];
        pb_cotree_leaf_levels(t, lv);
        pb_cotree_frame(t, NULL, NULL, dims);
        const uint32_t *leaves = pb_cotree_leaves(t), *lat = pb_cotree_probe_lattice(t);
        for (uint32_t i = 0; i < L; i++) {
            aniso_leaves += lv[3 * i] != lv[3 * i + 1] || lv[3 * i + 1] != lv[3 * i + 2];
            uint32_t mx = lv[3 * i] > lv[3 * i + 1] ? lv[3 * i] : lv[3 * i + 1];
            TU_CHECK_EQ_INT(leaves[4 * i + 3], mx > lv[3 * i + 2] ? mx : lv[3 * i + 2]);
        }
        /* (a) a field linear in lattice coordinates, given at the probes, everywhere. */
        double *lin = malloc(P * sizeof(double)), *rv = malloc(P * sizeof(double));
        for (uint32_t p = 0; p < P; p++) {
            double u[3] = {lat[3 * p], lat[3 * p + 1], lat[3 * p + 2]};
            lin[p] = linear(u);
            rv[p] = tu_rnd();
        }
        double worst_lin = 0.0, worst_jump = 0.0, worst_sum = 0.0, worst_vis = 0.0;
        /* The visibility field with every pair clear (255) is the plain field. */
        uint8_t *clear = malloc(64u * L);
        memset(clear, PB_VIS_CLEAR, 64u * L);
        const pb_interp_options vis = {.pair_visibility = clear};
        for (int n = 0; n < 4000; n++) {
            double u[3], x[3];
            for (int k = 0; k < 3; k++) u[k] = tu_rnd() * dims[k], x[k] = ORIGIN[k] + H * u[k];
            pb_interp_weights w;
            TU_REQUIRE(pb_interp_query_cotree(t, x, NULL, &w) == PB_SUCCESS && w.count > 0);
            double s = 0.0;
            for (uint32_t k = 0; k < w.count; k++) s += w.weight[k];
            worst_sum = fmax(worst_sum, fabs(s - 1.0));
            worst_lin = fmax(worst_lin, fabs(eval(&w, lin) - linear(u)));
            TU_REQUIRE(pb_interp_query_cotree(t, x, &vis, &w) == PB_SUCCESS && w.count > 0);
            worst_vis = fmax(worst_vis, fabs(eval(&w, lin) - linear(u)));
        }
        TU_CHECK(worst_vis < 1e-9);
        free(clear);
        /* (b) random points on random leaves' upper faces: both leaves' own fields. */
        for (int n = 0; n < 6000; n++) {
            uint32_t i = (uint32_t)(tu_rnd() * L), a = (uint32_t)(tu_rnd() * 3);
            const uint32_t *l = leaves + 4 * i;
            uint32_t hi = l[a] + (1u << lv[3 * i + a]);
            if (hi >= dims[a]) continue;
            double x[3];
            for (int k = 0; k < 3; k++) x[k] = ORIGIN[k] + H * (l[k] + tu_rnd() * (double)(1u << lv[3 * i + k]));
            x[a] = ORIGIN[a] + H * hi;
            int32_t j = pb_cotree_locate(t, x);
            TU_REQUIRE(j >= 0 && (uint32_t)j != i);
            pb_interp_weights wi, wj;
            TU_REQUIRE(pb_interp_query_cotree_leaf(t, i, x, NULL, &wi) == PB_SUCCESS);
            TU_REQUIRE(pb_interp_query_cotree_leaf(t, (uint32_t)j, x, NULL, &wj) == PB_SUCCESS);
            worst_jump = fmax(worst_jump, fabs(eval(&wi, rv) - eval(&wj, rv)));
            borders++;
        }
        TU_CHECK(worst_lin < 1e-9);
        TU_CHECK(worst_jump < 1e-9);
        TU_CHECK(worst_sum < 1e-12);
        /* Hanging rules name only probes or earlier hanging nodes, weights summing to 1. */
        uint32_t Hc = pb_cotree_hanging_count(t);
        uint32_t *src = malloc((4u * Hc + 1) * sizeof(uint32_t));
        float *wt = malloc((4u * Hc + 1) * sizeof(float));
        pb_cotree_hanging_rules(t, src, wt);
        for (uint32_t h = 0; h < Hc; h++) {
            double s = 0.0;
            for (int k = 0; k < 4; k++) {
                if (wt[4 * h + k] > 0.0f) TU_CHECK(src[4 * h + k] < P + h);
                s += wt[4 * h + k];
            }
            TU_CHECK_NEAR(s, 1.0, 1e-6);
        }
        /* Resolution order: decreasing potential (docs/aniso-refinement.md), hanging points from the
         * leaves' corners. */
        uint32_t *hp = calloc(3u * Hc + 3, sizeof(uint32_t));
        int32_t *corners = malloc(32u * L);
        pb_cotree_leaf_corners(t, corners);
        for (uint32_t i = 0; i < L; i++)
            for (uint32_t c = 0; c < 8; c++)
                if ((uint32_t)corners[8 * i + c] >= P)
                    for (int k = 0; k < 3; k++)
                        hp[3 * (corners[8 * i + c] - P) + k] =
                            leaves[4 * i + k] + ((c >> k) & 1u ? 1u << lv[3 * i + k] : 0u);
        uint32_t prev = UINT32_MAX;
        for (uint32_t h = 0; h < Hc; h++) {
            uint32_t pot = 0;
            for (int k = 0; k < 3; k++) {
                uint32_t z = 0, v = hp[3 * h + k];
                while (z <= 3 && !((v >> z) & 1u)) z++;
                pot += z;
            }
            TU_CHECK(pot <= prev);
            prev = pot;
        }
        free(hp);
        free(corners);
        free(src);
        free(wt);
        free(lin);
        free(rv);
        free(lv);
        pb_cotree_destroy(t);
    }
    printf("  anisotropic leaves %u, hanging nodes %u, forced splits %u, border points %u\n", aniso_leaves, hanging,
           forced, borders);
    TU_CHECK(aniso_leaves > 100);
    TU_CHECK(hanging > 100);
    TU_CHECK(forced > 0); /* random per-axis splits make crosses */
    TU_CHECK(borders > 20000);
}

/* Leaves of a tree sorted as pb_cotree_leaves gives them, with their packed levels. */
static uint32_t *packed_leaves(const pb_cotree *t)
{
    uint32_t L = pb_cotree_leaf_count(t), *lv = malloc(3u * L * sizeof(uint32_t)),
             *out = malloc(4u * L * sizeof(uint32_t));
    pb_cotree_leaf_levels(t, lv);
    for (uint32_t i = 0; i < L; i++) {
        memcpy(out + 4 * i, pb_cotree_leaves(t) + 4 * i, 3 * sizeof(uint32_t));
        out[4 * i + 3] = PB_LEVELS_PACK(lv[3 * i], lv[3 * i + 1], lv[3 * i + 2]);
    }
    free(lv);
    return out;
}

static bool has_box(const uint32_t *packed, uint32_t n, uint32_t x, uint32_t y, uint32_t z, uint32_t lvl)
{
    for (uint32_t i = 0; i < n; i++)
        if (packed[4 * i] == x && packed[4 * i + 1] == y && packed[4 * i + 2] == z && packed[4 * i + 3] == lvl)
            return true;
    return false;
}

/* (c) Hand-made crosses through create_boxes; finalize splits the coarser leaf on the axis of the
 * smaller level difference (a tie: the leaf below the face). */
static void test_forced_splits_of_crosses(void)
{
    pb_error err = {0};
    pb_cotree *t = NULL;
    /* A (levels 2, 2, 3) left of B (levels 2, 3, 1) on x = 4: A finer on y by 1, coarser on z by 2:
     * B splits along y, once. */
    const uint32_t dims8[3] = {8, 8, 8};
    const uint32_t one[8] = {0, 0, 0, PB_LEVELS_PACK(2, 2, 3), 4, 0, 0, PB_LEVELS_PACK(2, 3, 1)};
    TU_REQUIRE(pb_cotree_create_boxes(ORIGIN, H, 3, dims8, one, 2, &t, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(pb_cotree_forced_splits(t), 1);
    TU_CHECK_EQ_INT(pb_cotree_leaf_count(t), 3);
    uint32_t *pk = packed_leaves(t);
    TU_CHECK(has_box(pk, 3, 0, 0, 0, PB_LEVELS_PACK(2, 2, 3)));
    TU_CHECK(has_box(pk, 3, 4, 0, 0, PB_LEVELS_PACK(2, 2, 1)));
    TU_CHECK(has_box(pk, 3, 4, 4, 0, PB_LEVELS_PACK(2, 2, 1)));
    free(pk);
    pb_cotree_destroy(t);
    /* Four leaves, each pair across x = 2 a cross with equal differences: both left leaves split
     * along z (the leaf below the face, on its coarser axis). */
    const uint32_t dims4[3] = {4, 4, 4};
    const uint32_t tie[16] = {0, 0, 0, PB_LEVELS_PACK(1, 1, 2), 0, 2, 0, PB_LEVELS_PACK(1, 1, 2),
                              2, 0, 0, PB_LEVELS_PACK(1, 2, 1), 2, 0, 2, PB_LEVELS_PACK(1, 2, 1)};
    TU_REQUIRE(pb_cotree_create_boxes(ORIGIN, H, 2, dims4, tie, 4, &t, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(pb_cotree_forced_splits(t), 2);
    TU_CHECK_EQ_INT(pb_cotree_leaf_count(t), 6);
    pk = packed_leaves(t);
    for (uint32_t y = 0; y < 4; y += 2)
        for (uint32_t z = 0; z < 4; z += 2) TU_CHECK(has_box(pk, 6, 0, y, z, PB_LEVELS_PACK(1, 1, 1)));
    TU_CHECK(has_box(pk, 6, 2, 0, 0, PB_LEVELS_PACK(1, 2, 1)));
    free(pk);
    /* The field after the forced splits is C0 across x = 2 (random values at the probes). */
    uint32_t P = pb_cotree_probe_count(t);
    double *v = malloc(P * sizeof(double)), worst = 0.0;
    for (uint32_t p = 0; p < P; p++) v[p] = tu_rnd();
    for (int n = 0; n < 2000; n++) {
        double x[3] = {ORIGIN[0] + H * 2.0, ORIGIN[1] + H * 4.0 * tu_rnd(), ORIGIN[2] + H * 4.0 * tu_rnd()};
        double xl[3] = {x[0] - 1e-3 * H, x[1], x[2]};
        int32_t a = pb_cotree_locate(t, xl), b = pb_cotree_locate(t, x);
        pb_interp_weights wa, wb;
        TU_REQUIRE(a >= 0 && b >= 0 && a != b);
        pb_interp_query_cotree_leaf(t, (uint32_t)a, x, NULL, &wa);
        pb_interp_query_cotree_leaf(t, (uint32_t)b, x, NULL, &wb);
        worst = fmax(worst, fabs(eval(&wa, v) - eval(&wb, v)));
    }
    TU_CHECK(worst < 1e-9);
    free(v);
    pb_cotree_destroy(t);
}

/* The descent of docs/aniso-refinement.md, written again with a step counter. */
static int32_t descend(const uint32_t *nodes, const uint32_t grid[3], uint32_t R, const uint32_t q[3], uint32_t *steps)
{
    uint32_t lo[3], lv[3] = {R, R, R}, node = 0, mul = 1;
    for (int k = 0; k < 3; k++) {
        lo[k] = (q[k] >> R) << R;
        node += (q[k] >> R) * mul;
        mul *= grid[k];
    }
    *steps = 0;
    while (nodes[node] & 3u) {
        uint32_t a = (nodes[node] & 3u) - 1u, child = nodes[node] >> 2;
        lv[a]--;
        bool up = q[a] >= lo[a] + (1u << lv[a]);
        if (up) lo[a] += 1u << lv[a];
        node = child + up;
        ++*steps;
    }
    return (nodes[node] >> 2) == PB_SPLIT_TREE_EMPTY ? -1 : (int32_t)(nodes[node] >> 2);
}

static uint32_t *split_tree(const pb_cotree *t, uint32_t *count)
{
    pb_error err = {0};
    if (pb_cotree_split_tree(t, NULL, 0, count, &err) != PB_SUCCESS) return NULL;
    uint32_t *nodes = malloc((*count + 1u) * sizeof(uint32_t));
    if (pb_cotree_split_tree(t, nodes, *count, count, &err) != PB_SUCCESS) {
        free(nodes);
        return NULL;
    }
    return nodes;
}

/* (d) the split tree locates what pb_cotree_locate locates, in at most 3R steps; it is the same for
 * the same leaves given in any order. */
static void test_split_tree(void)
{
    for (int seed = 0; seed < 4; seed++) {
        uint32_t f, K, dims[3];
        pb_cotree *t = random_tree(4, &f);
        TU_REQUIRE(t != NULL);
        uint32_t *nodes = split_tree(t, &K), R = pb_cotree_root_level(t), L = pb_cotree_leaf_count(t);
        TU_REQUIRE(nodes != NULL);
        pb_cotree_frame(t, NULL, NULL, dims);
        const uint32_t grid[3] = {dims[0] >> R, dims[1] >> R, dims[2] >> R};
        TU_CHECK_EQ_INT(K, 4 + 2 * (L - 4)); /* G + 2 (internal nodes), every root non-empty */
        uint32_t deepest = 0;
        for (int n = 0; n < 3000; n++) {
            double x[3];
            uint32_t q[3], steps;
            for (int k = 0; k < 3; k++) {
                double u = tu_rnd() * dims[k];
                q[k] = (uint32_t)u;
                x[k] = ORIGIN[k] + H * u;
            }
            int32_t li = descend(nodes, grid, R, q, &steps);
            TU_CHECK_EQ_INT(li, pb_cotree_locate(t, x));
            TU_CHECK_EQ_INT(li, pb_cotree_split_tree_find(nodes, grid, R, q));
            if (steps > deepest) deepest = steps;
        }
        TU_CHECK(deepest <= 3 * R && deepest > R);
        /* Every leaf reached exactly once: a leaf node per leaf. */
        uint32_t *seen = calloc(L, sizeof(uint32_t));
        for (uint32_t k = 0; k < K; k++)
            if (!(nodes[k] & 3u) && (nodes[k] >> 2) < L) seen[nodes[k] >> 2]++;
        for (uint32_t i = 0; i < L; i++) TU_CHECK_EQ_INT(seen[i], 1);
        free(seen);
        /* The same leaves, shuffled, through create_boxes: same leaf order, same tree. */
        uint32_t *pk = packed_leaves(t);
        for (uint32_t i = L - 1; i > 0; i--) {
            uint32_t j = (uint32_t)(tu_rnd() * (i + 1)), tmp[4];
            memcpy(tmp, pk + 4 * i, sizeof tmp);
            memcpy(pk + 4 * i, pk + 4 * j, sizeof tmp);
            memcpy(pk + 4 * j, tmp, sizeof tmp);
        }
        pb_cotree *u = NULL;
        pb_error err = {0};
        TU_REQUIRE(pb_cotree_create_boxes(ORIGIN, H, R, dims, pk, L, &u, &err) == PB_SUCCESS);
        uint32_t K2, *nodes2 = split_tree(u, &K2);
        TU_CHECK(K2 == K && nodes2 && memcmp(nodes, nodes2, K * sizeof(uint32_t)) == 0);
        TU_CHECK(memcmp(pb_cotree_leaves(t), pb_cotree_leaves(u), 16u * L) == 0);
        /* The tree is nested already: finalize forces nothing, numbers the same probes. */
        TU_REQUIRE(pb_cotree_finalize(u, &err) == PB_SUCCESS);
        TU_CHECK_EQ_INT(pb_cotree_forced_splits(u), 0);
        TU_CHECK_EQ_INT(pb_cotree_probe_count(u), pb_cotree_probe_count(t));
        TU_CHECK(memcmp(pb_cotree_probe_lattice(t), pb_cotree_probe_lattice(u), 12u * pb_cotree_probe_count(t)) == 0);
        free(nodes2);
        free(pk);
        free(nodes);
        pb_cotree_destroy(u);
        pb_cotree_destroy(t);
    }
    /* Split orders: x then y, or y then x (and z on the way): the same leaves, the same tree. */
    const uint32_t roots[3] = {1, 1, 1};
    uint32_t *trees[2], counts[2];
    for (int order = 0; order < 2; order++) {
        pb_cotree *t = NULL;
        pb_error err = {0};
        TU_REQUIRE(pb_cotree_create(ORIGIN, H, 2, roots, &t, &err) == PB_SUCCESS);
        uint8_t m1[1] = {order ? 2u : 1u}, m2[2] = {order ? 5u : 6u, order ? 5u : 6u};
        TU_REQUIRE(pb_cotree_split_axes(t, m1, NULL, &err) == PB_SUCCESS);
        TU_REQUIRE(pb_cotree_split_axes(t, m2, NULL, &err) == PB_SUCCESS);
        TU_CHECK_EQ_INT(pb_cotree_leaf_count(t), 8);
        trees[order] = split_tree(t, &counts[order]);
        pb_cotree_destroy(t);
    }
    TU_CHECK(counts[0] == counts[1] && memcmp(trees[0], trees[1], counts[0] * sizeof(uint32_t)) == 0);
    /* Canonical: the root (levels 2, 2, 2) splits along x; the tree of one cube split into 8 is
     * 1 + 2 + 4 + 8 nodes, the root's children split along y. */
    TU_CHECK_EQ_INT(counts[0], 15);
    TU_CHECK_EQ_INT(trees[0][0] & 3u, 1);
    TU_CHECK_EQ_INT(trees[0][trees[0][0] >> 2] & 3u, 2);
    free(trees[0]);
    free(trees[1]);
}

/* A sparse tree: a dropped root is an empty root node, a dropped leaf an empty box in its root. */
static void test_split_tree_sparse(void)
{
    const uint32_t roots[3] = {2, 1, 1};
    pb_cotree *t = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_cotree_create(ORIGIN, H, 1, roots, &t, &err) == PB_SUCCESS);
    uint8_t m[2] = {1, 0}, drop[3] = {1, 0, 1}; /* root 0 split along x; drop its lower half, root 1 */
    TU_REQUIRE(pb_cotree_split_axes(t, m, NULL, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_drop(t, drop, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_leaf_count(t) == 1);
    uint32_t K, *nodes = split_tree(t, &K);
    TU_REQUIRE(nodes != NULL);
    TU_CHECK_EQ_INT(K, 4);
    TU_CHECK_EQ_INT(nodes[0], 2u << 2 | 1u);             /* root 0: split along x, children 2, 3 */
    TU_CHECK_EQ_INT(nodes[1], PB_SPLIT_TREE_EMPTY << 2); /* root 1 dropped */
    TU_CHECK_EQ_INT(nodes[2], PB_SPLIT_TREE_EMPTY << 2); /* the dropped lower half */
    TU_CHECK_EQ_INT(nodes[3], 0u << 2);                  /* leaf 0 */
    const double in[3] = {ORIGIN[0] + 1.5 * H, ORIGIN[1] + 1.0 * H, ORIGIN[2] + 0.5 * H};
    const double out[3] = {ORIGIN[0] + 0.5 * H, ORIGIN[1] + 1.0 * H, ORIGIN[2] + 0.5 * H};
    TU_CHECK_EQ_INT(pb_cotree_locate(t, in), 0);
    TU_CHECK_EQ_INT(pb_cotree_locate(t, out), -1);
    /* A point on the kept leaf's upper x face, just inside the dropped root: the face rule (within
     * 0.01 min cells above a lower cell face the cell below is tried). */
    const double face[3] = {ORIGIN[0] + 2.004 * H, ORIGIN[1] + 1.0 * H, ORIGIN[2] + 0.5 * H};
    TU_CHECK_EQ_INT(pb_cotree_locate(t, face), 0);
    const double beyond[3] = {ORIGIN[0] + 2.02 * H, ORIGIN[1] + 1.0 * H, ORIGIN[2] + 0.5 * H};
    TU_CHECK_EQ_INT(pb_cotree_locate(t, beyond), -1);
    free(nodes);
    pb_cotree_destroy(t);
}

/* (e) cubes: split by masks 7 = split by flags, and the octree's rules: largest host first. */
static void test_cube_trees_unchanged(void)
{
    for (int seed = 0; seed < 4; seed++) {
        const uint32_t roots[3] = {2, 2, 1};
        pb_cotree *a = NULL, *b = NULL;
        pb_error err = {0};
        TU_REQUIRE(pb_cotree_create(ORIGIN, H, 3, roots, &a, &err) == PB_SUCCESS);
        TU_REQUIRE(pb_cotree_create(ORIGIN, H, 3, roots, &b, &err) == PB_SUCCESS);
        for (int pass = 0; pass < 3; pass++) {
            uint32_t L = pb_cotree_leaf_count(a);
            uint8_t *f = calloc(L + 1u, 1), *m = calloc(L + 1u, 1);
            for (uint32_t i = 0; i < L; i++) f[i] = tu_rnd() < 0.35, m[i] = f[i] ? 7u : 0u;
            uint32_t na = 0, nb = 0;
            TU_REQUIRE(pb_cotree_split(a, f, &na, &err) == PB_SUCCESS);
            TU_REQUIRE(pb_cotree_split_axes(b, m, &nb, &err) == PB_SUCCESS);
            TU_CHECK_EQ_INT(na, nb);
            free(f);
            free(m);
        }
        TU_REQUIRE(pb_cotree_finalize(a, &err) == PB_SUCCESS);
        TU_REQUIRE(pb_cotree_finalize(b, &err) == PB_SUCCESS);
        uint32_t L = pb_cotree_leaf_count(a), P = pb_cotree_probe_count(a), Hc = pb_cotree_hanging_count(a);
        TU_CHECK_EQ_INT(pb_cotree_leaf_count(b), L);
        TU_CHECK_EQ_INT(pb_cotree_probe_count(b), P);
        TU_CHECK_EQ_INT(pb_cotree_hanging_count(b), Hc);
        TU_CHECK_EQ_INT(pb_cotree_forced_splits(a), 0);
        TU_CHECK(pb_cotree_all_cubes(a) && pb_cotree_all_cubes(b));
        TU_CHECK(Hc > 0);
        TU_CHECK(memcmp(pb_cotree_leaves(a), pb_cotree_leaves(b), 16u * L) == 0);
        TU_CHECK(memcmp(pb_cotree_probe_lattice(a), pb_cotree_probe_lattice(b), 12u * P) == 0);
        int32_t *ca = malloc(32u * L), *cb = malloc(32u * L);
        uint32_t *sa = malloc(16u * Hc), *sb = malloc(16u * Hc);
        float *wa = malloc(16u * Hc), *wb = malloc(16u * Hc);
        pb_cotree_leaf_corners(a, ca);
        pb_cotree_leaf_corners(b, cb);
        pb_cotree_hanging_rules(a, sa, wa);
        pb_cotree_hanging_rules(b, sb, wb);
        TU_CHECK(memcmp(ca, cb, 32u * L) == 0);
        TU_CHECK(memcmp(sa, sb, 16u * Hc) == 0 && memcmp(wa, wb, 16u * Hc) == 0);
        /* Every level is the leaf's: cubes. The octree's order: hanging node h's largest-source
         * spacing (its host's size) never grows with h. */
        uint32_t *lv = malloc(12u * L);
        pb_cotree_leaf_levels(a, lv);
        for (uint32_t i = 0; i < L; i++)
            for (int k = 0; k < 3; k++) TU_CHECK_EQ_INT(lv[3 * i + k], pb_cotree_leaves(a)[4 * i + 3]);
        free(lv);
        free(ca);
        free(cb);
        free(sa);
        free(sb);
        free(wa);
        free(wb);
        pb_cotree_destroy(a);
        pb_cotree_destroy(b);
    }
}

/* Cube trees as the octree built them before boxes existed: an FNV-1a 64 digest of leaves, probe
 * lattice, leaf corners and hanging rules of 12 random cube trees. Expected value: the same program
 * linked against native/src/pb_cotree.c and pb_interp.c of commit 1dd9c79 (the octree code before
 * this change): eb93e44ce95dd204. */
static uint64_t digest_rng = 88172645463325252ull;
static double digest_rnd(void) /* xorshift64 */
{
    digest_rng ^= digest_rng << 13;
    digest_rng ^= digest_rng >> 7;
    digest_rng ^= digest_rng << 17;
    return (double)(digest_rng >> 11) / 9007199254740992.0;
}

static void fnv_mix(uint64_t *h, const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++) *h = (*h ^ b[i]) * 1099511628211ull;
}

static void test_cube_trees_digest(void)
{
    uint64_t h = 1469598103934665603ull;
    for (uint32_t seed = 0; seed < 12; seed++) {
        const double o[3] = {-1, 0.5, 2};
        const uint32_t roots[3] = {1 + seed % 3, 2, 1 + seed % 2};
        pb_cotree *t = NULL;
        pb_error e = {0};
        TU_REQUIRE(pb_cotree_create(o, 0.25, 3, roots, &t, &e) == PB_SUCCESS);
        for (int p = 0; p < 3; p++) {
            uint32_t L = pb_cotree_leaf_count(t);
            uint8_t *f = calloc(L + 1, 1);
            for (uint32_t i = 0; i < L; i++) f[i] = digest_rnd() < 0.3;
            TU_CHECK(pb_cotree_split(t, f, NULL, &e) == PB_SUCCESS);
            free(f);
        }
        TU_REQUIRE(pb_cotree_finalize(t, &e) == PB_SUCCESS);
        uint32_t L = pb_cotree_leaf_count(t), P = pb_cotree_probe_count(t), Hc = pb_cotree_hanging_count(t);
        fnv_mix(&h, pb_cotree_leaves(t), 16u * L);
        fnv_mix(&h, pb_cotree_probe_lattice(t), 12u * P);
        int32_t *c = malloc(32u * L);
        pb_cotree_leaf_corners(t, c);
        fnv_mix(&h, c, 32u * L);
        uint32_t *sr = malloc(16u * Hc + 1);
        float *w = malloc(16u * Hc + 1);
        pb_cotree_hanging_rules(t, sr, w);
        fnv_mix(&h, sr, 16u * Hc);
        fnv_mix(&h, w, 16u * Hc);
        free(c);
        free(sr);
        free(w);
        pb_cotree_destroy(t);
    }
    TU_CHECK(h == 0xeb93e44ce95dd204ull);
}

/* A y-split root beside an unsplit one (test_aniso_prototype.py's case): the 2 corners at mid-height
 * on the shared face hang on the neighbour's edges, 1/2 and 1/2; boxes' pair visibility traces the
 * box's own corners, 152 segments per leaf. */
typedef struct seg_log {
    uint32_t calls;
    double max_len[3];
} seg_log;

static double log_segment(void *user, const double a[3], const double b[3])
{
    seg_log *s = user;
    s->calls++;
    for (int k = 0; k < 3; k++) s->max_len[k] = fmax(s->max_len[k], fabs(b[k] - a[k]));
    return 1.0;
}

static void test_hanging_edge_and_visibility(void)
{
    const uint32_t roots[3] = {2, 1, 1};
    pb_cotree *t = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_cotree_create(ORIGIN, H, 3, roots, &t, &err) == PB_SUCCESS);
    uint8_t m[2] = {2, 0};
    TU_REQUIRE(pb_cotree_split_axes(t, m, NULL, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(pb_cotree_leaf_count(t), 3);
    TU_CHECK_EQ_INT(pb_cotree_probe_count(t), 12 + 2);
    TU_REQUIRE(pb_cotree_hanging_count(t) == 2);
    uint32_t src[8];
    float w[8];
    pb_cotree_hanging_rules(t, src, w);
    for (int h = 0; h < 2; h++) {
        TU_CHECK_NEAR(w[4 * h], 0.5, 0);
        TU_CHECK_NEAR(w[4 * h + 1], 0.5, 0);
        TU_CHECK_NEAR(w[4 * h + 2], 0.0, 0);
        const uint32_t *p0 = pb_cotree_probe_lattice(t) + 3 * src[4 * h],
                       *p1 = pb_cotree_probe_lattice(t) + 3 * src[4 * h + 1];
        TU_CHECK(p0[0] == 8 && p1[0] == 8 && p0[2] == p1[2] && p0[1] + p1[1] == 8);
    }
    pb_cotree_destroy(t);
    /* One root halved along y: two boxes of 8 x 4 x 8 min cells. */
    const uint32_t one[3] = {1, 1, 1};
    TU_REQUIRE(pb_cotree_create(ORIGIN, H, 3, one, &t, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_split_axes(t, m, NULL, &err) == PB_SUCCESS);
    seg_log s = {0};
    uint8_t pv[128];
    TU_REQUIRE(pb_cotree_pair_visibility(t, log_segment, &s, pv, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(s.calls, 2 * 152);
    TU_CHECK_NEAR(s.max_len[0], 8 * H, 1e-12);
    TU_CHECK_NEAR(s.max_len[1], 4 * H, 1e-12);
    TU_CHECK_NEAR(s.max_len[2], 8 * H, 1e-12);
    TU_CHECK_EQ_INT(pv[0], PB_VIS_CLEAR);
    pb_cotree_destroy(t);
}

static void test_create_boxes_rejects(void)
{
    const uint32_t dims[3] = {8, 8, 8};
    struct {
        uint32_t leaves[12], n, R;
        const char *msg;
    } cases[] = {
        {{0, 1, 0, PB_LEVELS_PACK(0, 1, 0)}, 1, 3, "is not aligned to its size 2 on axis Y"},
        {{0, 0, 4, PB_LEVELS_PACK(0, 0, 3)}, 1, 3, "is not aligned to its size 8 on axis Z"},
        {{0, 0, 0, PB_LEVELS_PACK(3, 0, 0)}, 1, 2, "above the root level 2"},
        {{8, 0, 0, PB_LEVELS_PACK(0, 0, 0)}, 1, 2, "reaches past the lattice extent 8 on axis X"},
        {{0, 0, 0, 1u << 24}, 1, 3, "top byte"},
        {{0, 0, 0, PB_LEVELS_PACK(2, 0, 0), 2, 0, 0, PB_LEVELS_PACK(1, 1, 0)}, 2, 3, "overlaps leaf"},
        {{0, 0, 0, PB_LEVELS_PACK(1, 1, 1), 0, 0, 0, PB_LEVELS_PACK(1, 1, 1)},
         2,
         3,
         "overlaps another leaf"}, /* cubes: the Morton check */
        /* A pinwheel: 3 boxes, each crossing one middle plane of the root, no overlap. */
        {{0, 0, 0, PB_LEVELS_PACK(3, 2, 2), 0, 0, 4, PB_LEVELS_PACK(2, 3, 2), 4, 4, 0, PB_LEVELS_PACK(2, 2, 3)},
         3,
         3,
         "are not 2:1 splits of it"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        pb_cotree *t = NULL;
        pb_error err = {0};
        TU_CHECK(pb_cotree_create_boxes(ORIGIN, H, cases[c].R, dims, cases[c].leaves, cases[c].n, &t, &err) ==
                 PB_ERROR_INVALID_ARGUMENT);
        TU_CHECK_CONTAINS(err.message, cases[c].msg);
        TU_CHECK(t == NULL);
    }
    pb_cotree *t = NULL;
    pb_error err = {0};
    const uint32_t ok[4] = {0, 0, 0, PB_LEVELS_PACK(1, 2, 0)};
    TU_CHECK(pb_cotree_create_boxes(ORIGIN, H, 21, dims, ok, 1, &t, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_REQUIRE(pb_cotree_create_boxes(ORIGIN, H, 3, dims, ok, 1, &t, &err) == PB_SUCCESS);
    TU_CHECK_EQ_INT(pb_cotree_root_level(t), 3);
    TU_CHECK_EQ_INT(pb_cotree_leaves(t)[3], 2);
    uint32_t K;
    TU_CHECK(pb_cotree_split_tree(t, NULL, 0, &K, &err) == PB_SUCCESS && K == 1 + 2 * 6); /* 2 + 1 + 3 halvings */
    uint32_t small[2];
    TU_CHECK(pb_cotree_split_tree(t, small, 2, &K, &err) == PB_ERROR_INVALID_ARGUMENT);
    pb_cotree_destroy(t);
}

/* Hostile boxes (a file's leaves go to create_boxes): random sets, mostly refused; any accepted set
 * finalizes (or is too unbalanced: PB_ERROR_TOO_LARGE), its split tree finds what locate finds at every
 * lattice cell, and it reproduces a linear field at the points its leaves cover. Run under ASan/UBSan by
 * test.sh's sanitizer build. */
/* Whether lattice point u lies in a leaf (not only within the face rule's 0.01 of one). */
static bool covered(const pb_cotree *t, const double u[3])
{
    const uint32_t *l = pb_cotree_leaves(t);
    uint32_t L = pb_cotree_leaf_count(t), *lv = malloc(12u * L + 4), in = 0;
    pb_cotree_leaf_levels(t, lv);
    for (uint32_t i = 0; i < L && !in; i++) {
        in = 1;
        for (int k = 0; k < 3; k++)
            if (!(u[k] >= l[4 * i + k] && u[k] <= l[4 * i + k] + (double)(1u << lv[3 * i + k]))) in = 0;
    }
    free(lv);
    return in;
}

static void test_hostile_boxes(void)
{
    const uint32_t dims[3] = {8, 4, 8};
    uint32_t accepted = 0, finalized = 0;
    for (int iter = 0; iter < 20000; iter++) {
        uint32_t n = 1 + (uint32_t)(tu_rnd() * 6), R = (uint32_t)(tu_rnd() * 4), leaves[24];
        for (uint32_t i = 0; i < n; i++) {
            uint32_t lv[3];
            for (int k = 0; k < 3; k++) {
                lv[k] = (uint32_t)(tu_rnd() * (R + 1.5));
                uint32_t s = 1u << (lv[k] > 8 ? 8 : lv[k]);
                leaves[4 * i + (uint32_t)k] =
                    tu_rnd() < 0.9 ? s * (uint32_t)(tu_rnd() * (dims[k] / s + 1)) : (uint32_t)(tu_rnd() * 9);
            }
            leaves[4 * i + 3] = PB_LEVELS_PACK(lv[0], lv[1], lv[2]);
        }
        pb_cotree *t = NULL;
        pb_error err = {0};
        pb_result r = pb_cotree_create_boxes(ORIGIN, H, R, dims, leaves, n, &t, &err);
        TU_CHECK(r == PB_SUCCESS || (r == PB_ERROR_INVALID_ARGUMENT && err.message[0] && !t));
        if (r != PB_SUCCESS) continue;
        accepted++;
        uint32_t K, *nodes = split_tree(t, &K);
        TU_REQUIRE(nodes != NULL);
        const uint32_t grid[3] = {(dims[0] + (1u << R) - 1) >> R, (dims[1] + (1u << R) - 1) >> R,
                                  (dims[2] + (1u << R) - 1) >> R};
        for (uint32_t z = 0; z < dims[2]; z++)
            for (uint32_t y = 0; y < dims[1]; y++)
                for (uint32_t x = 0; x < dims[0]; x++) {
                    const uint32_t q[3] = {x, y, z};
                    const double c[3] = {ORIGIN[0] + H * (x + 0.5), ORIGIN[1] + H * (y + 0.5),
                                         ORIGIN[2] + H * (z + 0.5)};
                    TU_CHECK_EQ_INT(pb_cotree_split_tree_find(nodes, grid, R, q), pb_cotree_locate(t, c));
                }
        free(nodes);
        r = pb_cotree_finalize(t, &err);
        TU_CHECK(r == PB_SUCCESS || r == PB_ERROR_TOO_LARGE);
        if (r == PB_SUCCESS) {
            finalized++;
            uint32_t P = pb_cotree_probe_count(t);
            const uint32_t *lat = pb_cotree_probe_lattice(t);
            double *lin = malloc((P + 1) * sizeof(double)), worst = 0.0;
            for (uint32_t p = 0; p < P; p++) {
                double u[3] = {lat[3 * p], lat[3 * p + 1], lat[3 * p + 2]};
                lin[p] = linear(u);
            }
            for (int k = 0; k < 50; k++) {
                double u[3], x[3];
                for (int a = 0; a < 3; a++) u[a] = tu_rnd() * dims[a], x[a] = ORIGIN[a] + H * u[a];
                pb_interp_weights w;
                if (pb_interp_query_cotree(t, x, NULL, &w) == PB_SUCCESS && w.count && covered(t, u))
                    worst = fmax(worst, fabs(eval(&w, lin) - linear(u)));
            }
            TU_CHECK(worst < 1e-9);
            free(lin);
        }
        pb_cotree_destroy(t);
    }
    printf("  accepted %u box sets (of 20000), finalized %u\n", accepted, finalized);
    TU_CHECK(accepted > 500);
}

int main(void)
{
    tu_rng_state = 0x2545F4914F6CDD1Dull; /* this file's seed (the random trees' digest depends on it) */
    TU_RUN(test_random_trees_linear_and_c0);
    TU_RUN(test_forced_splits_of_crosses);
    TU_RUN(test_split_tree);
    TU_RUN(test_split_tree_sparse);
    TU_RUN(test_cube_trees_unchanged);
    TU_RUN(test_cube_trees_digest);
    TU_RUN(test_hanging_edge_and_visibility);
    TU_RUN(test_create_boxes_rejects);
    TU_RUN(test_hostile_boxes);
    return TU_EXIT();
}
