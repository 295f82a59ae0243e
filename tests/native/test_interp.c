/* Interpolation on the probes' real positions (pb_interp.h): corner octree with hanging nodes and
 * Delaunay tetrahedra. Closed forms: a field linear in position is reproduced exactly; weights are
 * ≥ 0 and sum to 1; a point moved in small steps across leaf borders (also coarse/fine) changes its
 * value by at most the Lipschitz bound of the interpolant (a jump would be of the order of the probe
 * values' spread, 0.1–1); the hanging rules of a two-leaf tree are the bilinear/linear weights. */
#include "schnee/pb_interp.h"

#include "testutil.h"

#include <stdint.h>
#include <stdlib.h>

static double linear_field(const double p[3]) { return 0.7 + 1.3 * p[0] - 0.4 * p[1] + 2.1 * p[2]; }

/* A tree with hanging nodes over several levels: 2×2×2 roots of 4 min cells (min cell 0.25 m at
 * (-1, 0.5, 2)); root 0 split, its child at the shared corner split again; root 7 split. */
static pb_cotree *make_tree(void)
{
    const double origin[3] = {-1.0, 0.5, 2.0};
    const uint32_t roots[3] = {2, 2, 2};
    pb_cotree *t = NULL;
    pb_error err = {0};
    if (pb_cotree_create(origin, 0.25, 2, roots, &t, &err) != PB_SUCCESS) return NULL;
    uint8_t split[64] = {0};
    split[0] = 1; /* Morton order: root 0 = (0,0,0) */
    split[7] = 1; /* (4,4,4) */
    if (pb_cotree_split(t, split, NULL, &err) != PB_SUCCESS) return NULL;
    /* The child of root 0 at (2,2,2) (level 1) touches the centre of the lattice. */
    memset(split, 0, sizeof split);
    const uint32_t *l = pb_cotree_leaves(t);
    for (uint32_t i = 0; i < pb_cotree_leaf_count(t); i++)
        if (l[4 * i] == 2 && l[4 * i + 1] == 2 && l[4 * i + 2] == 2 && l[4 * i + 3] == 1) split[i] = 1;
    if (pb_cotree_split(t, split, NULL, &err) != PB_SUCCESS) return NULL;
    if (pb_cotree_finalize(t, &err) != PB_SUCCESS) {
        fprintf(stderr, "%s\n", err.message);
        pb_cotree_destroy(t);
        return NULL;
    }
    return t;
}

static double eval(const pb_interp_weights *w, const double *values)
{
    double v = 0.0;
    for (uint32_t i = 0; i < w->count; i++) v += w->weight[i] * values[w->probe[i]];
    return v;
}

static void check_weights(const pb_interp_weights *w)
{
    double sum = 0.0;
    bool nonneg = true;
    for (uint32_t i = 0; i < w->count; i++) {
        sum += w->weight[i];
        if (!(w->weight[i] > 0.0)) nonneg = false;
    }
    TU_CHECK(w->count > 0);
    TU_CHECK(nonneg);
    TU_CHECK_NEAR(sum, 1.0, 1e-12);
}

static void test_hanging_rules_two_leaves(void)
{
    /* Two leaves of 2 min cells side by side along x; the left one split: its face x = 2 has 9
     * lattice points, 4 of them the right leaf's corners, 5 hanging (face centre: 4 sources of 1/4,
     * 4 edge midpoints: 2 sources of 1/2). Probes: 27 + 4 − 5 = 26. */
    const double origin[3] = {0, 0, 0};
    const uint32_t roots[3] = {2, 1, 1};
    pb_cotree *t = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_cotree_create(origin, 1.0, 1, roots, &t, &err) == PB_SUCCESS);
    uint8_t split[2] = {1, 0};
    uint32_t n = 0;
    TU_REQUIRE(pb_cotree_split(t, split, &n, &err) == PB_SUCCESS);
    TU_CHECK(n == 1);
    TU_CHECK(pb_cotree_leaf_count(t) == 9);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    TU_CHECK(pb_cotree_probe_count(t) == 26);
    TU_REQUIRE(pb_cotree_hanging_count(t) == 5);
    uint32_t src[20];
    float w[20];
    pb_cotree_hanging_rules(t, src, w);
    int faces = 0, edges = 0;
    for (int h = 0; h < 5; h++) {
        int used = 0;
        for (int k = 0; k < 4; k++)
            if (w[4 * h + k] > 0) {
                used++;
                TU_CHECK(src[4 * h + k] < 26); /* the right leaf's corners are probes */
            }
        if (used == 4) {
            faces++;
            for (int k = 0; k < 4; k++) TU_CHECK_NEAR(w[4 * h + k], 0.25, 0);
        } else if (used == 2) {
            edges++;
            TU_CHECK_NEAR(w[4 * h], 0.5, 0);
            TU_CHECK_NEAR(w[4 * h + 1], 0.5, 0);
        }
    }
    TU_CHECK(faces == 1);
    TU_CHECK(edges == 4);
    /* Lattice point (2, 1, 1) is the hanging face centre, (0, 0, 0) a probe. */
    TU_CHECK(pb_cotree_find_probe(t, (const uint32_t[3]){2, 1, 1}) == -1);
    TU_CHECK(pb_cotree_find_probe(t, (const uint32_t[3]){0, 0, 0}) == 0);
    TU_CHECK(pb_cotree_find_probe(t, (const uint32_t[3]){4, 2, 2}) >= 0);
    pb_cotree_destroy(t);
}

static void test_cotree_linear_exact(void)
{
    pb_cotree *t = make_tree();
    TU_REQUIRE(t != NULL);
    uint32_t P = pb_cotree_probe_count(t);
    TU_CHECK(pb_cotree_hanging_count(t) > 0);
    double *pos = malloc(P * 3 * sizeof(double)), *val = malloc(P * sizeof(double));
    pb_cotree_probe_positions(t, pos);
    for (uint32_t i = 0; i < P; i++) val[i] = linear_field(pos + 3 * i);
    double worst = 0.0;
    uint32_t max_count = 0;
    for (int s = 0; s < 4000; s++) {
        double p[3] = {-1.0 + 2.0 * tu_rnd(), 0.5 + 2.0 * tu_rnd(), 2.0 + 2.0 * tu_rnd()};
        pb_interp_weights w;
        TU_REQUIRE(pb_interp_query_cotree(t, p, NULL, &w) == PB_SUCCESS);
        check_weights(&w);
        worst = fmax(worst, fabs(eval(&w, val) - linear_field(p)));
        if (w.count > max_count) max_count = w.count;
    }
    /* Values are O(10); double arithmetic. */
    TU_CHECK_NEAR(worst, 0.0, 1e-12);
    TU_CHECK(max_count <= 16); /* 8 corners, hanging ones expanded over ≤ 4 face corners each */
    /* Outside: no weights. */
    pb_interp_weights w;
    TU_CHECK(pb_interp_query_cotree(t, (const double[3]){-1.01, 1, 3}, NULL, &w) == PB_SUCCESS && w.count == 0);
    /* The max faces are closed: a point on them is inside. */
    TU_CHECK(pb_interp_query_cotree(t, (const double[3]){1.0, 2.5, 4.0}, NULL, &w) == PB_SUCCESS && w.count == 1);
    free(pos);
    free(val);
    pb_cotree_destroy(t);
}

/* Random probe values in [0, 1]; a line crossing the coarse/fine borders at the lattice centre. */
static void test_cotree_continuous(void)
{
    pb_cotree *t = make_tree();
    TU_REQUIRE(t != NULL);
    uint32_t P = pb_cotree_probe_count(t);
    double *val = malloc(P * sizeof(double));
    for (uint32_t i = 0; i < P; i++) val[i] = tu_rnd();
    const double h = 0.25, step = 1e-4 * h;
    /* Inside a leaf of size s the trilinear field's gradient is at most √3·(value spread)/s per unit
     * length, the smallest leaf here is h: each step moves the value by at most √3·step/h. */
    const double bound = sqrt(3.0) * step / h * (1.0 + 1e-9);
    const double a[3][3] = {{-0.9, 0.6, 2.1}, {-1.0, 0.5 + 0.37, 2.0 + 1.93}, {-0.95, 2.45, 2.05}};
    const double b[3][3] = {{0.95, 2.4, 3.9}, {1.0, 0.5 + 1.61, 2.0 + 0.11}, {0.93, 0.55, 3.97}};
    for (int line = 0; line < 3; line++) {
        double prev = 0.0, worst = 0.0;
        double len =
            sqrt(pow(b[line][0] - a[line][0], 2) + pow(b[line][1] - a[line][1], 2) + pow(b[line][2] - a[line][2], 2));
        int n = (int)(len / step);
        for (int s = 0; s <= n; s++) {
            double f = (double)s / n, p[3];
            for (int k = 0; k < 3; k++) p[k] = a[line][k] + f * (b[line][k] - a[line][k]);
            pb_interp_weights w;
            TU_REQUIRE(pb_interp_query_cotree(t, p, NULL, &w) == PB_SUCCESS && w.count > 0);
            double v = eval(&w, val);
            if (s > 0) worst = fmax(worst, fabs(v - prev));
            prev = v;
        }
        TU_CHECK(worst <= bound * (len / n) / step);
    }
    free(val);
    pb_cotree_destroy(t);
}

static void test_visibility_and_validity(void)
{
    pb_cotree *t = make_tree();
    TU_REQUIRE(t != NULL);
    const double p[3] = {-0.61, 0.93, 2.27}; /* inside the finest leaves near the origin corner */
    pb_interp_weights all, some;
    TU_REQUIRE(pb_interp_query_cotree(t, p, NULL, &all) == PB_SUCCESS && all.count >= 4);
    float *validity = malloc(pb_cotree_probe_count(t) * sizeof(float));
    for (uint32_t i = 0; i < pb_cotree_probe_count(t); i++) validity[i] = 1.0f;
    uint32_t dropped = all.probe[0];
    validity[dropped] = 0.0f;
    pb_interp_options opt = {.validity = validity};
    TU_REQUIRE(pb_interp_query_cotree(t, p, &opt, &some) == PB_SUCCESS);
    TU_CHECK(some.count == all.count - 1);
    check_weights(&some);
    /* Renormalised: each remaining weight is its old weight / (1 − dropped weight). */
    for (uint32_t i = 0; i < some.count; i++) {
        TU_CHECK(some.probe[i] != dropped);
        for (uint32_t j = 0; j < all.count; j++)
            if (all.probe[j] == some.probe[i])
                TU_CHECK_NEAR(some.weight[i], all.weight[j] / (1.0 - all.weight[0]), 1e-14);
    }
    free(validity);
    pb_cotree_destroy(t);
}

static bool visible_below_plane(void *user, uint32_t probe, const double point[3])
{
    const double *pos = user; /* a "wall" at y = 1.5: probes above it cannot see points below */
    (void)point;
    return pos[3 * probe + 1] < 1.5;
}

static void test_visibility_callback(void)
{
    pb_cotree *t = make_tree();
    TU_REQUIRE(t != NULL);
    double *pos = malloc(pb_cotree_probe_count(t) * 3 * sizeof(double));
    pb_cotree_probe_positions(t, pos);
    pb_interp_options opt = {.visible = visible_below_plane, .visible_user = pos};
    pb_interp_weights w;
    const double p[3] = {0.2, 1.4, 3.1};
    TU_REQUIRE(pb_interp_query_cotree(t, p, &opt, &w) == PB_SUCCESS);
    check_weights(&w);
    for (uint32_t i = 0; i < w.count; i++) TU_CHECK(pos[3 * w.probe[i] + 1] < 1.5);
    free(pos);
    pb_cotree_destroy(t);
}

/* ---- the continuous visibility field (pb_interp.h) ---- */

/* Occluders for pb_cotree_pair_visibility: infinite planes x = wall[i] (closed form). */
typedef struct walls_x {
    int count;
    double x[4];
} walls_x;

static double walls_first_hit(void *user, const double a[3], const double b[3])
{
    const walls_x *w = user;
    double best = 1.0;
    for (int i = 0; i < w->count; i++) {
        double d = b[0] - a[0];
        if (fabs(d) < 1e-15) continue;
        double s = (w->x[i] - a[0]) / d;
        if (s > 1e-9 && s < best) best = s;
    }
    return best;
}

/* A wall x = 0.3 m through a 1 m leaf: V(k, c) = 1 - 1/(2t) puts the far corners' 1/2 crossing on the
 * wall exactly (closed form: v_c = 1 - (1 - tx) / (2 (1 - 0.3)) for a corner c at x = 1), so on the near
 * side (x < 0.3) the corners beyond get weight 0 and the near corners carry the whole field, on the far
 * side the opposite past the ramp; without a wall the field is the plain trilinear one. */
static void test_pair_visibility_wall_closed_form(void)
{
    pb_cotree *t = NULL;
    TU_REQUIRE(pb_cotree_create((const double[3]){0, 0, 0}, 1.0, 0, (const uint32_t[3]){1, 1, 1}, &t, NULL) ==
               PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, NULL) == PB_SUCCESS);
    uint8_t table[64];
    walls_x w = {1, {0.3}};
    TU_REQUIRE(pb_cotree_pair_visibility(t, walls_first_hit, &w, table, NULL) == PB_SUCCESS);
    for (uint32_t k = 0; k < 8; k++)
        for (uint32_t c = 0; c < 8; c++) {
            /* Across the wall: from a corner at x = 1 the wall is 0.7 of the way, from x = 0 0.3. */
            uint8_t want = (k ^ c) & 1u ? (uint8_t)lround(255.0 * ((c & 1u) ? 0.7 : 0.3)) : PB_VIS_CLEAR;
            TU_CHECK(table[8 * k + c] == want);
        }
    pb_interp_options opt = {.pair_visibility = table};
    double pos[8 * 3];
    pb_cotree_probe_positions(t, pos);
    for (int i = 0; i < 20; i++) {
        double x = 0.05 * i + 0.01, p[3] = {x, 0.37, 0.61};
        pb_interp_weights wt;
        TU_REQUIRE(pb_interp_query_cotree(t, p, &opt, &wt) == PB_SUCCESS && wt.count > 0);
        check_weights(&wt);
        double far = 0.0; /* weight of the corners at x = 1 */
        for (uint32_t j = 0; j < wt.count; j++)
            if (pos[3 * wt.probe[j]] > 0.5) far += wt.weight[j];
        /* Near side: v_far = 1 - (1 - x)/(2 t) < 1/2 with t = 0.7 (as stored, round(178.5)/255): only
         * the near corners; far side: the same with x and t = 0.3 mirrored. The field steps at the
         * wall itself (light does not cross it), nowhere else. */
        TU_CHECK_NEAR(far, x < 0.3 ? 0.0 : 1.0, 1e-15);
    }
    /* No occluder: every table entry clear, the plain field. */
    walls_x none = {0, {0}};
    TU_REQUIRE(pb_cotree_pair_visibility(t, walls_first_hit, &none, table, NULL) == PB_SUCCESS);
    for (int i = 0; i < 64; i++) TU_CHECK(table[i] == PB_VIS_CLEAR);
    const double p[3] = {0.23, 0.71, 0.42};
    pb_interp_weights a, b;
    TU_REQUIRE(pb_interp_query_cotree(t, p, &opt, &a) == PB_SUCCESS && pb_interp_query_cotree(t, p, NULL, &b) == 0);
    TU_REQUIRE(a.count == b.count);
    for (uint32_t j = 0; j < a.count; j++) TU_CHECK(a.probe[j] == b.probe[j] && a.weight[j] == b.weight[j]);
    TU_CHECK(pb_cotree_pair_visibility(t, NULL, NULL, table, NULL) == PB_ERROR_INVALID_ARGUMENT);
    pb_cotree_destroy(t);
}

/* Occluders: triangles (Möller–Trumbore, two-sided). */
typedef struct tris {
    int count;
    double v[16][9];
} tris;

static double tris_first_hit(void *user, const double a[3], const double b[3])
{
    const tris *T = user;
    double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, best = 1.0;
    for (int i = 0; i < T->count; i++) {
        const double *v = T->v[i];
        double e1[3], e2[3], s[3], pv[3], qv[3];
        for (int k = 0; k < 3; k++) e1[k] = v[3 + k] - v[k], e2[k] = v[6 + k] - v[k], s[k] = a[k] - v[k];
        pv[0] = d[1] * e2[2] - d[2] * e2[1], pv[1] = d[2] * e2[0] - d[0] * e2[2], pv[2] = d[0] * e2[1] - d[1] * e2[0];
        double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        if (fabs(det) < 1e-14) continue;
        double u = (s[0] * pv[0] + s[1] * pv[1] + s[2] * pv[2]) / det;
        qv[0] = s[1] * e1[2] - s[2] * e1[1], qv[1] = s[2] * e1[0] - s[0] * e1[2], qv[2] = s[0] * e1[1] - s[1] * e1[0];
        double w = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
        double tt = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
        if (u >= 0 && w >= 0 && u + w <= 1 && tt > 1e-9 && tt < best) best = tt;
    }
    return best;
}

/* Issue 27: across a face shared by two leaves the per-pixel weights, visibility included, do not
 * step, whatever the occluders: random triangles through both leaves of a 2 x 1 x 1 tree, random
 * probe values, random points of the shared face x = 1 approached from both sides (1e-9 m): the two
 * values agree to float rounding. And the field does not reduce to the plain one (the triangles
 * matter somewhere on the face). */
static void test_pair_visibility_continuous_across_leaves(void)
{
    pb_cotree *t = NULL;
    TU_REQUIRE(pb_cotree_create((const double[3]){0, 0, 0}, 1.0, 0, (const uint32_t[3]){2, 1, 1}, &t, NULL) ==
               PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, NULL) == PB_SUCCESS);
    uint32_t P = pb_cotree_probe_count(t);
    double val[12];
    TU_REQUIRE(P == 12);
    int differ = 0;
    for (int trial = 0; trial < 20; trial++) {
        tris T = {6, {{0}}};
        for (int i = 0; i < T.count; i++)
            for (int k = 0; k < 9; k++) T.v[i][k] = k % 3 == 0 ? 2.0 * tu_rnd() : tu_rnd();
        for (uint32_t i = 0; i < P; i++) val[i] = tu_rnd();
        uint8_t table[2 * 64];
        TU_REQUIRE(pb_cotree_pair_visibility(t, tris_first_hit, &T, table, NULL) == PB_SUCCESS);
        pb_interp_options opt = {.pair_visibility = table};
        for (int i = 0; i < 200; i++) {
            double y = tu_rnd(), z = tu_rnd(), lo[3] = {1.0 - 1e-9, y, z}, hi[3] = {1.0 + 1e-9, y, z};
            pb_interp_weights wl, wh, wp;
            TU_REQUIRE(pb_interp_query_cotree(t, lo, &opt, &wl) == PB_SUCCESS && wl.count > 0);
            TU_REQUIRE(pb_interp_query_cotree(t, hi, &opt, &wh) == PB_SUCCESS && wh.count > 0);
            TU_REQUIRE(pb_interp_query_cotree(t, hi, NULL, &wp) == PB_SUCCESS && wp.count > 0);
            TU_CHECK_NEAR(eval(&wl, val), eval(&wh, val), 1e-6);
            if (fabs(eval(&wh, val) - eval(&wp, val)) > 1e-3) differ++;
        }
    }
    TU_CHECK(differ > 100);
    pb_cotree_destroy(t);
}

static void test_tetra_linear_exact_and_continuous(void)
{
    /* (1) the octree's probes (a lattice: cospherical, degenerate for Delaunay), (2) random points. */
    for (int set = 0; set < 2; set++) {
        pb_cotree *t = make_tree();
        TU_REQUIRE(t != NULL);
        uint32_t P = set == 0 ? pb_cotree_probe_count(t) : 300;
        double *pos = malloc(P * 3 * sizeof(double)), *val = malloc(P * sizeof(double)),
               *rv = malloc(P * sizeof(double));
        if (set == 0) {
            pb_cotree_probe_positions(t, pos);
        } else {
            for (uint32_t i = 0; i < 8; i++) /* the box's corners: the hull is the box */
                for (int k = 0; k < 3; k++) pos[3 * i + k] = (i >> k & 1) ? 1.0 : 0.0;
            for (uint32_t i = 8; i < P * 3 / 3; i++)
                for (int k = 0; k < 3; k++) pos[3 * i + k] = tu_rnd();
        }
        pb_cotree_destroy(t);
        for (uint32_t i = 0; i < P; i++) val[i] = linear_field(pos + 3 * i), rv[i] = tu_rnd();
        pb_tetra *tt = NULL;
        pb_error err = {0};
        TU_REQUIRE(pb_tetra_create(pos, P, &tt, &err) == PB_SUCCESS);
        TU_CHECK(pb_tetra_count(tt) >= P); /* about 5–6 tetrahedra per point in 3-D */
        const double lo[2][3] = {{-1.0, 0.5, 2.0}, {0, 0, 0}}, ext = set == 0 ? 2.0 : 1.0;
        double worst = 0.0;
        int found = 0;
        for (int s = 0; s < 4000; s++) {
            double p[3];
            for (int k = 0; k < 3; k++) p[k] = lo[set][k] + ext * tu_rnd();
            pb_interp_weights w;
            TU_REQUIRE(pb_interp_query_tetra(tt, p, NULL, &w) == PB_SUCCESS);
            if (w.count == 0) continue;
            found++;
            check_weights(&w);
            TU_CHECK(w.count <= 4);
            worst = fmax(worst, fabs(eval(&w, val) - linear_field(p)));
        }
        TU_CHECK(found == 4000); /* the hull is the box in both sets */
        TU_CHECK_NEAR(worst, 0.0, 1e-11);
        /* Continuity along a line through many tetrahedra: step 1e-5 of the box; a jump at a face
         * would be of the order of the random values' spread (0.1–1). */
        const double step = 1e-5 * ext;
        double prev = 0.0, maxstep = 0.0;
        int n = (int)(ext * 0.9 / step);
        for (int s = 0; s <= n; s++) {
            double f = (double)s / n * 0.9 + 0.05, p[3] = {lo[set][0] + ext * f, lo[set][1] + ext * (0.3 + 0.4 * f),
                                                           lo[set][2] + ext * (0.8 - 0.7 * f)};
            pb_interp_weights w;
            TU_REQUIRE(pb_interp_query_tetra(tt, p, NULL, &w) == PB_SUCCESS && w.count > 0);
            double v = eval(&w, rv);
            if (s > 0) maxstep = fmax(maxstep, fabs(v - prev));
            prev = v;
        }
        TU_CHECK(maxstep < 1e-2);
        /* Outside the hull. */
        pb_interp_weights w;
        TU_CHECK(pb_interp_query_tetra(tt, (const double[3]){lo[set][0] - 0.1, lo[set][1], lo[set][2]}, NULL, &w) ==
                     PB_SUCCESS &&
                 w.count == 0);
        /* Neighbour symmetry. */
        const int32_t *nb = pb_tetra_neighbours(tt);
        bool sym = true;
        for (uint32_t i = 0; i < pb_tetra_count(tt); i++)
            for (int k = 0; k < 4; k++) {
                int32_t j = nb[4 * i + k];
                if (j < 0) continue;
                bool back = false;
                for (int m = 0; m < 4; m++) back |= nb[4 * j + m] == (int32_t)i;
                sym &= back;
            }
        TU_CHECK(sym);
        pb_tetra_destroy(tt);
        free(pos);
        free(val);
        free(rv);
    }
}

static void test_tetra_rejects(void)
{
    const double flat[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0.5, 0.5, 0};
    pb_tetra *t = NULL;
    pb_error err = {0};
    TU_CHECK(pb_tetra_create(flat, 5, &t, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(err.message, "cannot be tetrahedralised") != NULL);
    TU_CHECK(t == NULL);
    pb_error err2 = {0};
    TU_CHECK(pb_tetra_create(flat, 3, &t, &err2) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(err2.message, "at least 4") != NULL);
}

static void test_cotree_rejects(void)
{
    const double o[3] = {0, 0, 0};
    const uint32_t dims[3] = {4, 4, 4};
    const uint32_t overlap[8] = {0, 0, 0, 1, 1, 1, 1, 0};
    const uint32_t misaligned[4] = {1, 0, 0, 1};
    const uint32_t outside[4] = {4, 0, 0, 0};
    pb_cotree *t = NULL;
    pb_error e1 = {0}, e2 = {0}, e3 = {0};
    TU_CHECK(pb_cotree_create_leaves(o, 1.0, dims, overlap, 2, &t, &e1) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(e1.message, "overlaps") != NULL);
    TU_CHECK(pb_cotree_create_leaves(o, 1.0, dims, misaligned, 1, &t, &e2) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(e2.message, "not aligned") != NULL);
    TU_CHECK(pb_cotree_create_leaves(o, 1.0, dims, outside, 1, &t, &e3) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(e3.message, "past the lattice") != NULL);
    TU_CHECK(t == NULL);
}

int main(void)
{
    TU_RUN(test_hanging_rules_two_leaves);
    TU_RUN(test_cotree_linear_exact);
    TU_RUN(test_cotree_continuous);
    TU_RUN(test_visibility_and_validity);
    TU_RUN(test_visibility_callback);
    TU_RUN(test_pair_visibility_wall_closed_form);
    TU_RUN(test_pair_visibility_continuous_across_leaves);
    TU_RUN(test_tetra_linear_exact_and_continuous);
    TU_RUN(test_tetra_rejects);
    TU_RUN(test_cotree_rejects);
    return TU_EXIT();
}
