/* Per-axis refinement of boxes with per-axis levels (pb_refine.h, docs/aniso-refinement.md "Tests and
 * the split rule"; the Python prototype is bench/bench_aniso.py's KdTree.tests and kd_refine). */
#include "pb_refine_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The two axes other than a, in x, y, z order (the column layout's bit 0 and bit 1). */
static void other_axes(uint32_t a, uint32_t *o0, uint32_t *o1)
{
    *o0 = a == 0 ? 1u : 0u;
    *o1 = a == 2 ? 1u : 2u;
}

bool pb_refine_axis_test_point(const uint32_t corner[3], const uint32_t levels[3], uint32_t column, uint32_t out[3])
{
    if (!corner || !levels || !out || column >= PB_REFINE_AXIS_TESTS) return false;
    uint32_t splittable = 0, zero_axis = 0;
    for (uint32_t a = 0; a < 3; a++) {
        if (levels[a] > PB_COTREE_MAX_LEVEL) return false;
        if (levels[a] > 0)
            splittable |= 1u << a;
        else
            zero_axis = a;
    }
    memcpy(out, corner, 3 * sizeof(uint32_t));
    if (column < 12) {
        uint32_t a = column / 4, e = column % 4, o0, o1;
        if (!(splittable >> a & 1u)) return false;
        other_axes(a, &o0, &o1);
        out[a] += 1u << (levels[a] - 1);
        if (e & 1u) out[o0] += 1u << levels[o0];
        if (e & 2u) out[o1] += 1u << levels[o1];
        return true;
    }
    if (splittable == 7u) { /* the centre */
        if (column == 13) return false;
        for (uint32_t a = 0; a < 3; a++) out[a] += 1u << (levels[a] - 1);
        return true;
    }
    if (splittable == 0u || (splittable & (splittable - 1u)) == 0u) return false; /* two or three level-0 axes */
    /* One level-0 axis: the centres of the two faces across it (column 12 at its min, 13 at its max). */
    for (uint32_t a = 0; a < 3; a++)
        if (a != zero_axis) out[a] += 1u << (levels[a] - 1);
    if (column == 13) out[zero_axis] += 1u;
    return true;
}

pb_result pb_refine_tests_create_axes(const pb_cotree *tree, const uint8_t *active, pb_refine_tests **out,
                                      pb_error *err)
{
    if (!tree || !out)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_refine_tests_create_axes: NULL argument");
    *out = NULL;
    if (!pb_cotree_probe_lattice(tree))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the corner octree is not finalized");
    uint32_t L = pb_cotree_leaf_count(tree);
    const uint32_t *leaves = pb_cotree_leaves(tree);
    pb_refine_tests *t = calloc(1, sizeof *t);
    uint32_t *levels = malloc(((size_t)L + 1) * 3 * sizeof(uint32_t));
    _pb_test_key *keys = malloc(((size_t)L * PB_REFINE_AXIS_TESTS + 1) * sizeof *keys);
    if (t) t->leaf_tests = malloc(((size_t)L * PB_REFINE_AXIS_TESTS + 1) * sizeof(int32_t));
    if (!t || !levels || !keys || !t->leaf_tests) {
        free(levels);
        free(keys);
        pb_refine_tests_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the test points of %u leaves", L);
    }
    t->leaf_count = L;
    t->per_leaf = PB_REFINE_AXIS_TESTS;
    pb_cotree_leaf_levels(tree, levels);
    size_t nk = 0;
    for (uint32_t i = 0; i < L; i++) {
        const uint32_t *lv = levels + 3u * i;
        /* as pb_refine_tests_create: leaves that may still split (some level > 0), the active ones */
        bool on = (lv[0] | lv[1] | lv[2]) > 0 && (!active || active[i]);
        for (uint32_t c = 0; c < PB_REFINE_AXIS_TESTS; c++) {
            uint32_t p[3];
            t->leaf_tests[PB_REFINE_AXIS_TESTS * i + c] = -1;
            if (!on || !pb_refine_axis_test_point(leaves + 4u * i, lv, c, p)) continue;
            keys[nk].key = _pb_test_key_of(p);
            keys[nk].slot = PB_REFINE_AXIS_TESTS * i + c;
            nk++;
        }
    }
    pb_result r = _pb_refine_tests_number(tree, t, keys, nk, err);
    free(keys);
    free(levels);
    if (r != PB_SUCCESS) {
        pb_refine_tests_destroy(t);
        return r;
    }
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_refine_decide_axes(const pb_cotree *tree, const pb_refine_tests *tests, const pb_refine_desc *d,
                                uint8_t *axes, double *leaf_error, double *leaf_threshold, pb_error *err)
{
    double tol, k;
    pb_result r = _pb_refine_check_desc(tree, tests, d, "pb_refine_decide_axes", &tol, &k, err);
    if (r != PB_SUCCESS) return r;
    if (!axes) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_refine_decide_axes: NULL argument");
    if (tests->per_leaf != PB_REFINE_AXIS_TESTS)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "%u tests per leaf: per-axis decisions need pb_refine_tests_create_axes' 14",
                            tests->per_leaf ? tests->per_leaf : PB_REFINE_TESTS_PER_LEAF);
    uint32_t L = tests->leaf_count;
    uint32_t *levels = malloc(((size_t)L + 1) * 3 * sizeof(uint32_t));
    if (!levels) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the levels of %u leaves", L);
    pb_cotree_leaf_levels(tree, levels);
    for (uint32_t i = 0; i < L; i++) {
        const uint32_t *lv = levels + 3u * i;
        uint32_t splittable = (lv[0] > 0) | (lv[1] > 0) << 1 | (lv[2] > 0) << 2, edge_fail = 0;
        bool middle_fail = false;
        double worst = 0.0, worst_thr = tol, worst_margin = -INFINITY;
        for (uint32_t c = 0; c < PB_REFINE_AXIS_TESTS; c++) {
            int32_t ti = tests->leaf_tests[PB_REFINE_AXIS_TESTS * i + c];
            double e, thr;
            if (ti < 0 || !_pb_refine_test_error(tree, tests, d, i, ti, tol, k, &e, &thr)) continue;
            if (e - thr > worst_margin) {
                worst_margin = e - thr;
                worst = e;
                worst_thr = thr;
            }
            if (!(e - thr > 0.0)) continue; /* the test passes (as pb_refine_decide: margin > 0 fails) */
            if (c < 12)
                edge_fail |= 1u << (c / 4);
            else
                middle_fail = true;
        }
        /* A failing edge midpoint along a explains its own axis; the middle point (the sum of the axes'
         * curvatures where the field is smooth) splits along all its axes only when no edge failed: it is
         * there for a compact feature inside the leaf that no edge sees. */
        uint32_t mask = edge_fail ? edge_fail : (middle_fail ? splittable : 0u);
        axes[i] = (uint8_t)(mask & splittable);
        if (leaf_error) leaf_error[i] = worst;
        if (leaf_threshold) leaf_threshold[i] = worst_thr;
    }
    free(levels);
    return PB_SUCCESS;
}
