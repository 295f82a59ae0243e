/* Internal (not installed): what the two refinement sources share. pb_refine.c holds the octree's
 * tests (centre, face centres) and decision, pb_refine_axes.c the per-axis ones
 * (docs/aniso-refinement.md "Tests and the split rule"); both number test points and measure a test the
 * same way, through these helpers. */
#ifndef SCHNEE_PB_REFINE_INTERNAL_H
#define SCHNEE_PB_REFINE_INTERNAL_H

#include "schnee/pb_refine.h"

#include <stdbool.h>

/* One (leaf, column) test point before deduplication: key = x | y << 21 | z << 42 (lattice). */
typedef struct _pb_test_key {
    uint64_t key;
    uint32_t slot; /* leaf × per_leaf + column */
} _pb_test_key;

static inline uint64_t _pb_test_key_of(const uint32_t p[3])
{
    return (uint64_t)p[0] | (uint64_t)p[1] << 21 | (uint64_t)p[2] << 42;
}

/* Sorts keys[0..nk) (lattice order), numbers the distinct points, fills t->lattice, ->positions,
 * ->probe, ->point_count and t->leaf_tests[slot] (the caller set every slot to −1 first). On error the
 * caller frees keys and t. */
pb_result _pb_refine_tests_number(const pb_cotree *tree, pb_refine_tests *t, _pb_test_key *keys, size_t nk,
                                  pb_error *err);

/* Checks a decision's arguments; *tol, *k get the defaults applied. */
pb_result _pb_refine_check_desc(const pb_cotree *tree, const pb_refine_tests *tests, const pb_refine_desc *d,
                                const char *fn, double *tol, double *k, pb_error *err);

/* Test point ti of leaf `leaf`: *e = the leaf's interpolation's error there, *thr = sqrt(tol² + k²σ²).
 * False when the test is not compared (an invalid test point, a probe inside a solid, no weights). */
bool _pb_refine_test_error(const pb_cotree *tree, const pb_refine_tests *tests, const pb_refine_desc *d, uint32_t leaf,
                           int32_t ti, double tol, double k, double *e, double *thr);

#endif
