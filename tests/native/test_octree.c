/* Probe placement (pb_placement_build): counts derived by hand, invariants checked against
 * independent closed-form inside tests and brute-force nearest-probe searches. Geometry is generated
 * here; engine space (Y up), metres. */
#include "schnee/pb_octree.h"
#include "schnee/pb_shprobe.h"
#include "testutil.h"

#include <stdlib.h>

/* ---------------------------------------------------------------------------------------------- */
/* Mesh builder                                                                                    */

typedef struct mesh {
    double *pos;
    uint32_t *idx;
    uint32_t nv, nt, cap_v, cap_t;
} mesh;

static uint32_t mesh_vertex(mesh *m, double x, double y, double z)
{
    if (m->nv == m->cap_v) {
        m->cap_v = m->cap_v ? 2 * m->cap_v : 64;
        m->pos = realloc(m->pos, sizeof(double) * 3 * m->cap_v);
    }
    m->pos[3 * m->nv + 0] = x;
    m->pos[3 * m->nv + 1] = y;
    m->pos[3 * m->nv + 2] = z;
    return m->nv++;
}

static void mesh_tri(mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    if (m->nt == m->cap_t) {
        m->cap_t = m->cap_t ? 2 * m->cap_t : 64;
        m->idx = realloc(m->idx, sizeof(uint32_t) * 3 * m->cap_t);
    }
    m->idx[3 * m->nt + 0] = a;
    m->idx[3 * m->nt + 1] = b;
    m->idx[3 * m->nt + 2] = c;
    m->nt++;
}

/* Closed box, shared vertices, counter-clockwise seen from outside (outward normals). */
static void mesh_box(mesh *m, const double lo[3], const double hi[3])
{
    uint32_t v[8];
    for (int i = 0; i < 8; i++)
        v[i] = mesh_vertex(m, (i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]);
    /* Each face as 4 corners in counter-clockwise order seen from outside. */
    static const int faces[6][4] = {
        {0, 4, 6, 2}, /* −x */
        {1, 3, 7, 5}, /* +x */
        {0, 1, 5, 4}, /* −y */
        {2, 6, 7, 3}, /* +y */
        {0, 2, 3, 1}, /* −z */
        {4, 5, 7, 6}, /* +z */
    };
    for (int f = 0; f < 6; f++) {
        mesh_tri(m, v[faces[f][0]], v[faces[f][1]], v[faces[f][2]]);
        mesh_tri(m, v[faces[f][0]], v[faces[f][2]], v[faces[f][3]]);
    }
}

static void mesh_free(mesh *m)
{
    free(m->pos);
    free(m->idx);
    memset(m, 0, sizeof *m);
}

static pb_mesh_desc mesh_desc(const mesh *m, const char *name)
{
    pb_mesh_desc d = {name, m->pos, m->nv, m->idx, m->nt};
    return d;
}

static void box_at(mesh *m, double x0, double y0, double z0, double x1, double y1, double z1)
{
    double lo[3] = {x0, y0, z0}, hi[3] = {x1, y1, z1};
    mesh_box(m, lo, hi);
}

/* Room of 10 m (x) × 4 m (y, up) × 10 m (z) with min corner o: volume = the room box; geometry =
 * floor, ceiling and four walls as 0.2 m thick boxes outside the room (their inner faces are the
 * room's surfaces). */
static void make_room(mesh *volume, mesh *walls, const double o[3])
{
    const double t = 0.2;
    box_at(volume, o[0], o[1], o[2], o[0] + 10, o[1] + 4, o[2] + 10);
    box_at(walls, o[0] - t, o[1] - t, o[2] - t, o[0] + 10 + t, o[1], o[2] + 10 + t);          /* floor */
    box_at(walls, o[0] - t, o[1] + 4, o[2] - t, o[0] + 10 + t, o[1] + 4 + t, o[2] + 10 + t);  /* ceiling */
    box_at(walls, o[0] - t, o[1] - t, o[2] - t, o[0], o[1] + 4 + t, o[2] + 10 + t);           /* −x wall */
    box_at(walls, o[0] + 10, o[1] - t, o[2] - t, o[0] + 10 + t, o[1] + 4 + t, o[2] + 10 + t); /* +x wall */
    box_at(walls, o[0] - t, o[1] - t, o[2] - t, o[0] + 10 + t, o[1] + 4 + t, o[2]);           /* −z wall */
    box_at(walls, o[0] - t, o[1] - t, o[2] + 10, o[0] + 10 + t, o[1] + 4 + t, o[2] + 10 + t); /* +z wall */
}

/* Furniture: a solid 3 m × 1 m × 4 m block standing on the floor, relative to the room corner. */
static const double furn_lo[3] = {3, 0, 3}, furn_hi[3] = {6, 1, 7};

/* ---------------------------------------------------------------------------------------------- */
/* Shared checks                                                                                    */

static size_t grid_cells(const pb_placement *p) { return (size_t)p->grid_dims[0] * p->grid_dims[1] * p->grid_dims[2]; }

static void grid_cell_centre(const pb_placement *p, size_t i, double c[3])
{
    size_t X = p->grid_dims[0], Y = p->grid_dims[1];
    size_t x = i % X, y = (i / X) % Y, z = i / (X * Y);
    c[0] = p->grid_origin[0] + ((double)x + 0.5) * p->grid_spacing;
    c[1] = p->grid_origin[1] + ((double)y + 0.5) * p->grid_spacing;
    c[2] = p->grid_origin[2] + ((double)z + 0.5) * p->grid_spacing;
}

/* Every grid entry in [−1, probe_count) and every probe referenced by at least one cell. */
static void check_consistency(const pb_placement *p)
{
    size_t n = grid_cells(p), bad = 0, unref = 0;
    char *ref = calloc(p->probe_count + 1, 1);
    for (size_t i = 0; i < n; i++) {
        int32_t g = p->grid[i];
        if (g < -1 || g >= (int32_t)p->probe_count)
            bad++;
        else if (g >= 0)
            ref[g] = 1;
    }
    for (uint32_t k = 0; k < p->probe_count; k++) unref += !ref[k];
    free(ref);
    TU_CHECK_EQ_INT(bad, 0);
    TU_CHECK_EQ_INT(unref, 0);
    for (uint32_t k = 0; k < p->probe_count; k++) {
        if (!(p->backface_ratio[k] >= 0 && p->backface_ratio[k] <= 0.25f)) {
            TU_CHECK(p->backface_ratio[k] >= 0 && p->backface_ratio[k] <= 0.25f);
            break;
        }
    }
}

static bool strictly_inside_box(const double p[3], const double lo[3], const double hi[3], double margin)
{
    for (int a = 0; a < 3; a++)
        if (!(p[a] > lo[a] + margin && p[a] < hi[a] - margin)) return false;
    return true;
}

static pb_placement *build(const pb_placement_desc *d, pb_error *err)
{
    pb_placement *p = NULL;
    memset(err, 0, sizeof *err);
    pb_result r = pb_placement_build(d, &p, err);
    if (r != PB_SUCCESS) fprintf(stderr, "pb_placement_build: %s: %s\n", pb_result_string(r), err->message);
    return p;
}

/* ---------------------------------------------------------------------------------------------- */
/* Tests                                                                                            */

/* The 10 m × 10 m × 4 m room at the defaults (min 0.5 m, max 16 m), derived by hand in grid units
 * of 0.5 m: the room is [0,20]×[0,8]×[0,20]; the root cell is 16 m = 32 units.
 *   32 → 16: the 4 cells above y = 16 are outside → dropped; the 4 others touch the floor → split.
 *   16 → 8: only x, z ∈ {[0,8], [8,16], [16,24]} and y ∈ [0,8] meet the room (9 cells); all touch
 *           the floor → split.
 *   8 → 4: x, z ∈ 5 ranges ([20,24] is outside), y ∈ 2 ranges: 50 cells; every one touches the
 *           floor (y ∈ [0,4]) or the ceiling (y ∈ [4,8]) → split.
 *   4 → 2 (1 m cells): 10 × 4 × 10 = 400 cells; those not touching a wall, the floor or the ceiling
 *           are x, z ∈ the 8 inner ranges and y ∈ [2,4], [4,6]: 8·2·8 = 128 leaves of 1 m; the other
 *           272 split into 272·8 = 2176 leaves of 0.5 m.
 *   Probes: 128 + 2176 = 2304 (none pruned: every ray from inside first meets a wall's inner face,
 *   a front face). The grid is 20 × 8 × 20 = 3200 cells, all inside the room. */
static void test_room_count(void)
{
    mesh vol = {0}, walls = {0};
    const double o[3] = {0, 0, 0};
    make_room(&vol, &walls, o);
    pb_mesh_desc v = mesh_desc(&vol, "Room"), g = mesh_desc(&walls, "Walls");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.geometry = &g;
    d.geometry_count = 1;
    d.thread_count = 2;
    pb_error err;
    pb_placement *p = build(&d, &err);
    TU_REQUIRE(p);
    TU_CHECK_EQ_INT(p->probe_count, 2304);
    TU_CHECK_EQ_INT(p->pruned_count, 0);
    TU_CHECK_EQ_INT(p->leaf_count, 2304);
    TU_CHECK_EQ_INT(p->grid_dims[0], 20);
    TU_CHECK_EQ_INT(p->grid_dims[1], 8);
    TU_CHECK_EQ_INT(p->grid_dims[2], 20);
    TU_CHECK_NEAR(p->grid_spacing, 0.5, 0);
    for (int a = 0; a < 3; a++) TU_CHECK_NEAR(p->grid_origin[a], 0.0, 0);
    size_t n1 = 0, n05 = 0, other = 0;
    float max_ratio = 0;
    for (uint32_t k = 0; k < p->probe_count; k++) {
        if (p->cell_sizes[k] == 1.0)
            n1++;
        else if (p->cell_sizes[k] == 0.5)
            n05++;
        else
            other++;
        if (p->backface_ratio[k] > max_ratio) max_ratio = p->backface_ratio[k];
    }
    TU_CHECK_EQ_INT(n1, 128);
    TU_CHECK_EQ_INT(n05, 2176);
    TU_CHECK_EQ_INT(other, 0);
    TU_CHECK_NEAR(max_ratio, 0.0, 0);
    /* Each grid cell maps to the probe of the leaf that contains its centre. */
    size_t outside = 0, wrong_leaf = 0;
    for (size_t i = 0; i < grid_cells(p); i++) {
        int32_t k = p->grid[i];
        if (k < 0) {
            outside++;
            continue;
        }
        double c[3];
        grid_cell_centre(p, i, c);
        for (int a = 0; a < 3; a++)
            if (fabs(c[a] - p->positions[3 * k + a]) > 0.5 * p->cell_sizes[k]) {
                wrong_leaf++;
                break;
            }
    }
    TU_CHECK_EQ_INT(outside, 0);
    TU_CHECK_EQ_INT(wrong_leaf, 0);
    check_consistency(p);
    pb_placement_destroy(p);
    mesh_free(&vol);
    mesh_free(&walls);
}

/* Room with a solid block: no probe inside the block, the block's grid cells map to the nearest
 * valid probe (checked by brute force over all probes). */
static pb_placement *build_furnished_room(const double o[3], uint32_t threads, pb_error *err)
{
    mesh vol = {0}, geo = {0};
    make_room(&vol, &geo, o);
    box_at(&geo, o[0] + furn_lo[0], o[1] + furn_lo[1], o[2] + furn_lo[2], o[0] + furn_hi[0], o[1] + furn_hi[1],
           o[2] + furn_hi[2]);
    pb_mesh_desc v = mesh_desc(&vol, "Room"), g = mesh_desc(&geo, "Walls+Block");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.geometry = &g;
    d.geometry_count = 1;
    d.thread_count = threads;
    pb_placement *p = build(&d, err);
    mesh_free(&vol);
    mesh_free(&geo);
    return p;
}

static void test_furniture(void)
{
    const double o[3] = {0, 0, 0};
    pb_error err;
    pb_placement *p = build_furnished_room(o, 2, &err);
    TU_REQUIRE(p);
    check_consistency(p);
    /* The block's 6×2×8 = 96 cells of 0.5 m all have centres inside it; the 0.5 m leaves there are
     * pruned (every ray from inside hits the block's faces from behind). */
    TU_CHECK(p->pruned_count >= 1);
    size_t probes_in_block = 0;
    for (uint32_t k = 0; k < p->probe_count; k++)
        probes_in_block += strictly_inside_box(&p->positions[3 * k], furn_lo, furn_hi, -1e-9);
    TU_CHECK_EQ_INT(probes_in_block, 0);
    size_t block_cells = 0, not_nearest = 0, unmapped = 0;
    for (size_t i = 0; i < grid_cells(p); i++) {
        double c[3];
        grid_cell_centre(p, i, c);
        if (p->grid[i] < 0) unmapped++;
        if (!strictly_inside_box(c, furn_lo, furn_hi, 0)) continue;
        block_cells++;
        int32_t k = p->grid[i];
        if (k < 0) continue;
        double best = INFINITY;
        for (uint32_t j = 0; j < p->probe_count; j++) {
            double dx = p->positions[3 * j] - c[0], dy = p->positions[3 * j + 1] - c[1],
                   dz = p->positions[3 * j + 2] - c[2];
            best = fmin(best, dx * dx + dy * dy + dz * dz);
        }
        double dx = p->positions[3 * k] - c[0], dy = p->positions[3 * k + 1] - c[1],
               dz = p->positions[3 * k + 2] - c[2];
        if (fabs(dx * dx + dy * dy + dz * dz - best) > 1e-9) not_nearest++;
    }
    TU_CHECK_EQ_INT(block_cells, 96);
    TU_CHECK_EQ_INT(unmapped, 0); /* the whole grid is inside the room */
    TU_CHECK_EQ_INT(not_nearest, 0);
    pb_placement_destroy(p);
}

/* Same input, 1 and 2 threads: identical output (order included). */
static void test_deterministic(void)
{
    const double o[3] = {0, 0, 0};
    pb_error err;
    pb_placement *a = build_furnished_room(o, 1, &err);
    pb_placement *b = build_furnished_room(o, 2, &err);
    TU_REQUIRE(a && b);
    TU_CHECK_EQ_INT(a->probe_count, b->probe_count);
    if (a->probe_count == b->probe_count) {
        TU_CHECK(!memcmp(a->positions, b->positions, sizeof(double) * 3 * a->probe_count));
        TU_CHECK(!memcmp(a->cell_sizes, b->cell_sizes, sizeof(double) * a->probe_count));
        TU_CHECK(!memcmp(a->backface_ratio, b->backface_ratio, sizeof(float) * a->probe_count));
        TU_CHECK(!memcmp(a->grid, b->grid, sizeof(int32_t) * grid_cells(a)));
    }
    pb_placement_destroy(a);
    pb_placement_destroy(b);
}

/* A scene 10 km from the origin gives the same placement relative to it as at the origin (the core
 * works relative to the volumes' centre, so the offsets below are exact in double). */
static void test_far_from_origin(void)
{
    const double o0[3] = {0, 0, 0}, o1[3] = {8000, 300, -6000}; /* |o1| ≈ 10.0 km */
    pb_error err;
    pb_placement *a = build_furnished_room(o0, 2, &err);
    pb_placement *b = build_furnished_room(o1, 2, &err);
    TU_REQUIRE(a && b);
    TU_CHECK_EQ_INT(b->probe_count, a->probe_count);
    TU_CHECK_EQ_INT(b->pruned_count, a->pruned_count);
    for (int k = 0; k < 3; k++) {
        TU_CHECK_EQ_INT(b->grid_dims[k], a->grid_dims[k]);
        TU_CHECK_NEAR(b->grid_origin[k] - o1[k], a->grid_origin[k], 1e-9);
    }
    if (a->probe_count == b->probe_count) {
        double worst = 0;
        for (uint32_t k = 0; k < a->probe_count; k++)
            for (int c = 0; c < 3; c++)
                worst = fmax(worst, fabs(b->positions[3 * k + c] - o1[c] - a->positions[3 * k + c]));
        TU_CHECK_NEAR(worst, 0.0, 1e-9);
        TU_CHECK(!memcmp(a->grid, b->grid, sizeof(int32_t) * grid_cells(a)));
    }
    pb_placement_destroy(a);
    pb_placement_destroy(b);
}

/* Union of two overlapping volumes, no geometry, min 1 m, max 4 m. A = [0,4]³, B = [3,7]×[0,4]×[0,4].
 * By hand: the grid is 7×4×4 (origin 0); the two 4 m root cells are [0,4]³ (B's face x = 3 crosses
 * it, its centre (2,2,2) is inside A → one leaf) and [4,8]×[0,4]² (B's face x = 7 crosses it, its
 * centre (6,2,2) is inside B → one leaf): 2 probes; the overlap x ∈ [3,4] belongs to the first. */
static void test_union_hand_count(void)
{
    mesh a = {0}, b = {0};
    box_at(&a, 0, 0, 0, 4, 4, 4);
    box_at(&b, 3, 0, 0, 7, 4, 4);
    pb_mesh_desc v[2] = {mesh_desc(&a, "A"), mesh_desc(&b, "B")};
    pb_placement_desc d = {0};
    d.volumes = v;
    d.volume_count = 2;
    d.min_cell_size = 1;
    d.max_cell_size = 4;
    pb_error err;
    pb_placement *p = build(&d, &err);
    TU_REQUIRE(p);
    TU_CHECK_EQ_INT(p->probe_count, 2);
    TU_CHECK_EQ_INT(p->grid_dims[0], 7);
    TU_CHECK_EQ_INT(p->grid_dims[1], 4);
    TU_CHECK_EQ_INT(p->grid_dims[2], 4);
    if (p->probe_count == 2) {
        const double want[2][3] = {{2, 2, 2}, {6, 2, 2}};
        for (int k = 0; k < 2; k++) {
            for (int c = 0; c < 3; c++) TU_CHECK_NEAR(p->positions[3 * k + c], want[k][c], 0);
            TU_CHECK_NEAR(p->cell_sizes[k], 4.0, 0);
        }
        size_t wrong = 0;
        for (size_t i = 0; i < grid_cells(p); i++) {
            size_t x = i % 7;
            wrong += p->grid[i] != (x < 4 ? 0 : 1);
        }
        TU_CHECK_EQ_INT(wrong, 0);
    }
    check_consistency(p);
    pb_placement_destroy(p);
    mesh_free(&a);
    mesh_free(&b);
}

/* Union of two overlapping, unaligned volumes with some geometry: every probe inside the union,
 * probes in both volumes, no duplicate, every grid cell inside the union (closed form) mapped and
 * every cell outside −1. */
static void test_union_generic(void)
{
    const double alo[3] = {0.1, 0.2, 0.05}, ahi[3] = {3.3, 2.1, 1.9};
    const double blo[3] = {2.05, 0.3, 0.15}, bhi[3] = {5.7, 3.6, 2.2};
    mesh a = {0}, b = {0}, geo = {0};
    mesh_box(&a, alo, ahi);
    mesh_box(&b, blo, bhi);
    box_at(&geo, 1.0, 0.2, 0.5, 4.5, 0.4, 1.4); /* a slab crossing both volumes */
    pb_mesh_desc v[2] = {mesh_desc(&a, "A"), mesh_desc(&b, "B")}, g = mesh_desc(&geo, "Slab");
    pb_placement_desc d = {0};
    d.volumes = v;
    d.volume_count = 2;
    d.geometry = &g;
    d.geometry_count = 1;
    d.min_cell_size = 0.25;
    d.max_cell_size = 2;
    pb_error err;
    pb_placement *p = build(&d, &err);
    TU_REQUIRE(p);
    check_consistency(p);
    size_t outside = 0, in_a_only = 0, in_b_only = 0, dup = 0;
    for (uint32_t k = 0; k < p->probe_count; k++) {
        const double *q = &p->positions[3 * k];
        bool ia = strictly_inside_box(q, alo, ahi, 0), ib = strictly_inside_box(q, blo, bhi, 0);
        outside += !ia && !ib;
        in_a_only += ia && !ib;
        in_b_only += ib && !ia;
        for (uint32_t j = 0; j < k; j++) dup += !memcmp(q, &p->positions[3 * j], 3 * sizeof(double));
    }
    TU_CHECK_EQ_INT(outside, 0);
    TU_CHECK(in_a_only > 0);
    TU_CHECK(in_b_only > 0);
    TU_CHECK_EQ_INT(dup, 0);
    size_t wrong = 0, inside_cells = 0;
    for (size_t i = 0; i < grid_cells(p); i++) {
        double c[3];
        grid_cell_centre(p, i, c);
        bool in = strictly_inside_box(c, alo, ahi, 0) || strictly_inside_box(c, blo, bhi, 0);
        inside_cells += in;
        wrong += in != (p->grid[i] >= 0);
    }
    TU_CHECK_EQ_INT(wrong, 0);
    TU_CHECK(inside_cells > 0);
    pb_placement_destroy(p);
    mesh_free(&a);
    mesh_free(&b);
    mesh_free(&geo);
}

/* A rotated cube (not aligned with the grid): the inside/outside answer of every grid cell matches
 * the closed form (the point's coordinates in the cube's frame), which exercises the multi-ray
 * inside vote and the recursive fill of leaves that straddle the volume surface. */
static void test_rotated_volume(void)
{
    const double ay = 0.5235987755982988, ax = 0.3490658503988659; /* 30° about y, then 20° about x */
    const double cy = cos(ay), sy = sin(ay), cx = cos(ax), sx = sin(ax);
    /* R = Rx · Ry; rows are the cube's axes in world space. */
    const double R[3][3] = {{cy, 0, sy}, {sx * sy, cx, -sx * cy}, {-cx * sy, sx, cx * cy}};
    const double half = 1.3, centre[3] = {0.37, -0.21, 0.11};
    mesh vol = {0};
    box_at(&vol, -half, -half, -half, half, half, half);
    for (uint32_t i = 0; i < vol.nv; i++) {
        double q[3] = {vol.pos[3 * i], vol.pos[3 * i + 1], vol.pos[3 * i + 2]}, w[3];
        for (int r = 0; r < 3; r++) w[r] = R[0][r] * q[0] + R[1][r] * q[1] + R[2][r] * q[2];
        for (int r = 0; r < 3; r++) vol.pos[3 * i + r] = centre[r] + w[r];
    }
    pb_mesh_desc v = mesh_desc(&vol, "Rotated");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.min_cell_size = 0.125;
    d.max_cell_size = 1;
    pb_error err;
    pb_placement *p = build(&d, &err);
    TU_REQUIRE(p);
    check_consistency(p);
    size_t wrong = 0, inside = 0, ambiguous = 0;
    for (size_t i = 0; i < grid_cells(p); i++) {
        double c[3], l[3], m = 0;
        grid_cell_centre(p, i, c);
        for (int r = 0; r < 3; r++) {
            l[r] = R[r][0] * (c[0] - centre[0]) + R[r][1] * (c[1] - centre[1]) + R[r][2] * (c[2] - centre[2]);
            m = fmax(m, fabs(l[r]));
        }
        if (fabs(m - half) < 1e-6) {
            ambiguous++;
            continue;
        }
        inside += m < half;
        wrong += (m < half) != (p->grid[i] >= 0);
    }
    TU_CHECK_EQ_INT(wrong, 0);
    TU_CHECK_EQ_INT(ambiguous, 0);
    /* Cube volume 2.6³ = 17.576 m³ over cells of 0.125³ m³ ≈ 9000 cells (sampling error ~1 %). */
    TU_CHECK_REL((double)inside, 17.576 / (0.125 * 0.125 * 0.125), 0.03);
    for (uint32_t k = 0; k < p->probe_count; k++) {
        double m = 0;
        for (int r = 0; r < 3; r++) {
            double l = R[r][0] * (p->positions[3 * k] - centre[0]) + R[r][1] * (p->positions[3 * k + 1] - centre[1]) +
                       R[r][2] * (p->positions[3 * k + 2] - centre[2]);
            m = fmax(m, fabs(l));
        }
        if (!(m < half)) {
            TU_CHECK(m < half); /* every probe inside the cube */
            break;
        }
    }
    pb_placement_destroy(p);
    mesh_free(&vol);
}

/* A volume with a missing triangle, and one with a flipped triangle: PB_ERROR_OPEN_MESH naming it. */
static void test_open_volume(void)
{
    for (int variant = 0; variant < 2; variant++) {
        mesh vol = {0};
        box_at(&vol, 0, 0, 0, 2, 2, 2);
        if (variant == 0) {
            vol.nt--; /* drop the last triangle */
        } else {
            uint32_t t = vol.idx[1];
            vol.idx[1] = vol.idx[2];
            vol.idx[2] = t;
        }
        pb_mesh_desc v = mesh_desc(&vol, "LeakyVolume");
        pb_placement_desc d = {0};
        d.volumes = &v;
        d.volume_count = 1;
        pb_placement *p = (pb_placement *)&d; /* must be reset to NULL */
        pb_error err = {0};
        pb_result r = pb_placement_build(&d, &p, &err);
        TU_CHECK_EQ_INT(r, PB_ERROR_OPEN_MESH);
        TU_CHECK_EQ_INT(err.code, PB_ERROR_OPEN_MESH);
        TU_CHECK(p == NULL);
        TU_CHECK_CONTAINS(err.message, "'LeakyVolume'");
        TU_CHECK_CONTAINS(err.message, "not a closed mesh");
        mesh_free(&vol);
    }
}

/* Degenerate triangles (repeated indices, collinear, a point) in the geometry and the volume change
 * nothing: they lie on existing surfaces (the floor's top edge), so the result equals the clean
 * room's (2304 probes, same grid). */
static void test_degenerate_triangles(void)
{
    mesh vol = {0}, walls = {0};
    const double o[3] = {0, 0, 0};
    make_room(&vol, &walls, o);
    pb_mesh_desc v = mesh_desc(&vol, "Room"), g = mesh_desc(&walls, "Walls");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.geometry = &g;
    d.geometry_count = 1;
    pb_error err;
    pb_placement *clean = build(&d, &err);

    uint32_t a = mesh_vertex(&walls, 0, 0, 0), b = mesh_vertex(&walls, 5, 0, 0), c = mesh_vertex(&walls, 10, 0, 0);
    mesh_tri(&walls, a, a, b); /* repeated index */
    mesh_tri(&walls, a, b, c); /* collinear: zero area */
    mesh_tri(&walls, c, c, c); /* a point */
    mesh_tri(&vol, 0, 0, 1);   /* repeated index in the volume: no area, does not open it */
    mesh_tri(&vol, 3, 3, 3);
    v = mesh_desc(&vol, "Room");
    g = mesh_desc(&walls, "Walls");
    pb_placement *dirty = build(&d, &err);
    TU_REQUIRE(clean && dirty);
    TU_CHECK_EQ_INT(dirty->probe_count, 2304);
    TU_CHECK_EQ_INT(dirty->probe_count, clean->probe_count);
    if (dirty->probe_count == clean->probe_count) {
        TU_CHECK(!memcmp(dirty->positions, clean->positions, sizeof(double) * 3 * clean->probe_count));
        TU_CHECK(!memcmp(dirty->grid, clean->grid, sizeof(int32_t) * grid_cells(clean)));
    }
    pb_placement_destroy(clean);
    pb_placement_destroy(dirty);
    mesh_free(&vol);
    mesh_free(&walls);
}

static void expect_error(const pb_placement_desc *d, pb_result code, const char *needle)
{
    pb_placement *p = NULL;
    pb_error err = {0};
    pb_result r = pb_placement_build(d, &p, &err);
    TU_CHECK_EQ_INT(r, code);
    TU_CHECK_EQ_INT(err.code, code);
    TU_CHECK(p == NULL);
    if (needle) TU_CHECK_CONTAINS(err.message, needle);
    pb_placement_destroy(p);
}

static void test_bad_input(void)
{
    mesh vol = {0}, geo = {0};
    box_at(&vol, 0, 0, 0, 2, 2, 2);
    box_at(&geo, 0.5, 0.5, 0.5, 1, 1, 1);
    pb_mesh_desc v = mesh_desc(&vol, "Vol"), g = mesh_desc(&geo, "Chair");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.geometry = &g;
    d.geometry_count = 1;

    /* index out of range in the geometry and in the volume */
    uint32_t keep_geo = geo.idx[7];
    geo.idx[7] = geo.nv;
    expect_error(&d, PB_ERROR_INVALID_ARGUMENT, "'Chair'");
    geo.idx[7] = keep_geo;
    uint32_t keep = vol.idx[4];
    vol.idx[4] = 1000;
    expect_error(&d, PB_ERROR_INVALID_ARGUMENT, "'Vol'");
    vol.idx[4] = keep;

    /* NaN / Inf positions */
    geo.pos[4] = NAN;
    expect_error(&d, PB_ERROR_NON_FINITE, "'Chair'");
    geo.pos[4] = 0.5;
    vol.pos[0] = INFINITY;
    expect_error(&d, PB_ERROR_NON_FINITE, "'Vol'");
    vol.pos[0] = 0;

    /* parameters */
    pb_placement_desc e = d;
    e.volume_count = 0;
    expect_error(&e, PB_ERROR_INVALID_ARGUMENT, "at least one probe volume");
    e = d;
    e.min_cell_size = -1;
    expect_error(&e, PB_ERROR_INVALID_ARGUMENT, "min_cell_size");
    e = d;
    e.min_cell_size = NAN;
    expect_error(&e, PB_ERROR_INVALID_ARGUMENT, "min_cell_size");
    e = d;
    e.min_cell_size = 2;
    e.max_cell_size = 1;
    expect_error(&e, PB_ERROR_INVALID_ARGUMENT, "smaller than min_cell_size");
    e = d;
    e.solid_backface_ratio = 1.5;
    expect_error(&e, PB_ERROR_INVALID_ARGUMENT, "solid_backface_ratio");
    e = d;
    e.geometry = NULL;
    expect_error(&e, PB_ERROR_INVALID_ARGUMENT, "geometry");
    pb_placement *p = NULL;
    TU_CHECK_EQ_INT(pb_placement_build(NULL, &p, NULL), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_EQ_INT(pb_placement_build(&d, NULL, NULL), PB_ERROR_INVALID_ARGUMENT);
    pb_placement_destroy(NULL);

    /* and the fixed input works */
    pb_error err;
    p = build(&d, &err);
    TU_CHECK(p != NULL);
    if (p) check_consistency(p);
    pb_placement_destroy(p);
    mesh_free(&vol);
    mesh_free(&geo);
}

/* min_cell_size 0.01 m with max_cell_size 1024 m: a 0.5 × 0.3 × 0.4 m volume (grid 50×30×40) with a
 * small block inside: the block refines cells down to exactly 0.01 m, every cell size is 0.01·2^k. */
static void test_tiny_cells(void)
{
    mesh vol = {0}, geo = {0};
    box_at(&vol, 0, 0, 0, 0.5, 0.3, 0.4);
    box_at(&geo, 0.2, 0.1, 0.1, 0.3, 0.2, 0.3);
    pb_mesh_desc v = mesh_desc(&vol, "Tiny"), g = mesh_desc(&geo, "Box");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.geometry = &g;
    d.geometry_count = 1;
    d.min_cell_size = 0.01;
    d.max_cell_size = 1024;
    pb_error err;
    pb_placement *p = build(&d, &err);
    TU_REQUIRE(p);
    TU_CHECK_EQ_INT(p->grid_dims[0], 50);
    TU_CHECK_EQ_INT(p->grid_dims[1], 30);
    TU_CHECK_EQ_INT(p->grid_dims[2], 40);
    TU_CHECK(p->pruned_count > 0);
    size_t n_min = 0, not_pow2 = 0;
    for (uint32_t k = 0; k < p->probe_count; k++) {
        double r = p->cell_sizes[k] / 0.01, l = log2(r);
        n_min += p->cell_sizes[k] == 0.01;
        not_pow2 += fabs(l - round(l)) > 1e-9;
    }
    TU_CHECK(n_min > 0);
    TU_CHECK_EQ_INT(not_pow2, 0);
    size_t unmapped = 0;
    for (size_t i = 0; i < grid_cells(p); i++) unmapped += p->grid[i] < 0;
    TU_CHECK_EQ_INT(unmapped, 0); /* every cell centre is inside the box volume */
    check_consistency(p);
    pb_placement_destroy(p);
    mesh_free(&vol);
    mesh_free(&geo);
}

/* max_cell_size 1024 m with min 16 m (1024 = 16·2^6, a root cell of exactly 1024 m) over a
 * 1530 m cube at the origin, no geometry. By hand, per axis the root cells are [0,1024] (inside)
 * and [1024,2048] (crosses the face at 1530, centre outside → split into [1024,1536], whose centre
 * 1280 is inside, and [1536,2048], past the 96-cell grid). The root [0,1024]³ is one probe of
 * 1024 m; a root with m "high" axes gives 2^(3−m) children of 512 m: 3·4 + 3·2 + 1 = 19.
 * Total 20 probes. Grid 96³ (1530/16 = 95.6), every cell centre (≤ 1528 m) inside. */
static void test_huge_cells(void)
{
    mesh vol = {0};
    box_at(&vol, 0, 0, 0, 1530, 1530, 1530);
    pb_mesh_desc v = mesh_desc(&vol, "Huge");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.min_cell_size = 16;
    d.max_cell_size = 1024;
    pb_error err;
    pb_placement *p = build(&d, &err);
    TU_REQUIRE(p);
    TU_CHECK_EQ_INT(p->probe_count, 20);
    TU_CHECK_EQ_INT(p->grid_dims[0], 96);
    size_t n1024 = 0, n512 = 0, unmapped = 0;
    for (uint32_t k = 0; k < p->probe_count; k++) {
        n1024 += p->cell_sizes[k] == 1024;
        n512 += p->cell_sizes[k] == 512;
    }
    TU_CHECK_EQ_INT(n1024, 1);
    TU_CHECK_EQ_INT(n512, 19);
    for (size_t i = 0; i < grid_cells(p); i++) unmapped += p->grid[i] < 0;
    TU_CHECK_EQ_INT(unmapped, 0);
    check_consistency(p);
    pb_placement_destroy(p);
    mesh_free(&vol);
}

/* Dense grids past the limit are refused with a message naming the size and the remedy. */
static void test_too_large(void)
{
    mesh vol = {0};
    box_at(&vol, 0, 0, 0, 100, 100, 100);
    pb_mesh_desc v = mesh_desc(&vol, "Big");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.min_cell_size = 0.01; /* 10^4 per axis: 10^12 cells */
    expect_error(&d, PB_ERROR_TOO_LARGE, "10000 x 10000 x 10000 = 1e+12 cells");
    expect_error(&d, PB_ERROR_TOO_LARGE, "Min Cell Size");
    d.min_cell_size = 1; /* 10^6 cells, but a custom limit of 1000 */
    d.max_grid_cells = 1000;
    expect_error(&d, PB_ERROR_TOO_LARGE, "limit of 1000 cells");
    mesh_free(&vol);
    /* an axis alone past 2^30 cells: no overflow, the same error */
    box_at(&vol, 0, 0, 0, 1e9, 1, 1);
    v = mesh_desc(&vol, "Long");
    d.min_cell_size = 0.01;
    d.max_grid_cells = 0;
    expect_error(&d, PB_ERROR_TOO_LARGE, "Min Cell Size");
    mesh_free(&vol);
}

/* Issue 14: a NaN/Inf vertex is named as such with its index and coordinates (a sign-bit NaN was
 * printed "-nan", an Inf read as "(-nan)" after the add-on's transform); a 1e-300 m cell size gives a
 * short message (it printed a 300-digit cell count); max_grid_cells past the .shprobe grid limit
 * (e.g. (uint64_t)-1, which Python's -1 became) is refused; the limit itself is accepted. */
static void test_messages_and_limits(void)
{
    mesh vol = {0};
    box_at(&vol, 0, 0, 0, 2, 2, 2);
    pb_mesh_desc v = mesh_desc(&vol, "Vol");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    char want[160];
    const double keep = vol.pos[4];
    snprintf(want, sizeof want, "vertex 1 = (%g, inf, %g) has a non-finite y coordinate (infinite)", vol.pos[3],
             vol.pos[5]);
    vol.pos[4] = INFINITY;
    expect_error(&d, PB_ERROR_NON_FINITE, want);
    vol.pos[4] = -NAN; /* sign bit set: printf's %g gives "-nan" */
    snprintf(want, sizeof want, "vertex 1 = (%g, nan, %g) has a non-finite y coordinate (NaN)", vol.pos[3], vol.pos[5]);
    expect_error(&d, PB_ERROR_NON_FINITE, want);
    pb_placement *p = NULL;
    pb_error err = {0};
    TU_CHECK(pb_placement_build(&d, &p, &err) == PB_ERROR_NON_FINITE && strstr(err.message, "-nan") == NULL);
    vol.pos[4] = keep;

    d.min_cell_size = 1e-300;
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_placement_build(&d, &p, &err), PB_ERROR_TOO_LARGE);
    /* 2 m / 1e-300 m = 2e300 cells per axis; the suggestion 1e-300 · 2e300 / cbrt(2^26) · 1.01 =
     * 0.00497 m (computed factor by factor: the cell count itself overflows a double). */
    TU_CHECK_CONTAINS(err.message, "2e+300 x 2e+300 x 2e+300 = more than 1e308 cells");
    TU_CHECK_CONTAINS(err.message, "about 0.00497 m or more");
    TU_CHECK_CONTAINS(err.message, "at Min Cell Size 1e-300 m");
    TU_CHECK(strlen(err.message) < 400);
    d.min_cell_size = 0;

    d.max_grid_cells = UINT64_MAX;
    expect_error(&d, PB_ERROR_INVALID_ARGUMENT,
                 "max_grid_cells 18446744073709551615 is above the hard limit of 268435456 cells");
    d.max_grid_cells = PB_SHPROBE_MAX_GRID_CELLS + 1;
    expect_error(&d, PB_ERROR_INVALID_ARGUMENT, "above the hard limit");
    d.max_grid_cells = PB_SHPROBE_MAX_GRID_CELLS;
    p = build(&d, &err);
    TU_CHECK(p != NULL);
    pb_placement_destroy(p);
    mesh_free(&vol);
}

/* Cancel at every progress call in turn: PB_ERROR_CANCELLED, nothing returned, nothing leaked (the
 * ASan build checks the last part). */
typedef struct cancel_state {
    int calls, cancel_at, non_monotonic;
    double last;
} cancel_state;

static bool cancel_progress(void *user, double fraction, const char *stage)
{
    cancel_state *s = (cancel_state *)user;
    (void)stage;
    if (!(fraction >= 0 && fraction <= 1)) return false;
    s->non_monotonic += fraction < s->last;
    s->last = fraction;
    return ++s->calls != s->cancel_at;
}

static void test_cancel(void)
{
    mesh vol = {0}, geo = {0};
    const double o[3] = {0, 0, 0};
    make_room(&vol, &geo, o);
    box_at(&geo, 3, 0, 3, 6, 1, 7);
    pb_mesh_desc v = mesh_desc(&vol, "Room"), g = mesh_desc(&geo, "Walls");
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.geometry = &g;
    d.geometry_count = 1;
    d.progress = cancel_progress;
    int cancels = 0;
    bool completed = false;
    for (int at = 1; at < 200 && !completed; at++) {
        cancel_state s = {0, at, 0, 0.0};
        d.progress_user = &s;
        pb_placement *p = NULL;
        pb_error err = {0};
        pb_result r = pb_placement_build(&d, &p, &err);
        if (r == PB_SUCCESS) {
            completed = true;
            TU_CHECK(s.calls < at); /* finished before reaching the cancelling call */
            TU_CHECK(p != NULL);
            TU_CHECK_EQ_INT(s.non_monotonic, 0); /* fractions never go back */
            TU_CHECK_NEAR(s.last, 1.0, 0);
        } else {
            cancels++;
            TU_CHECK_EQ_INT(r, PB_ERROR_CANCELLED);
            TU_CHECK(p == NULL);
            TU_CHECK_CONTAINS(err.message, "cancelled");
        }
        pb_placement_destroy(p);
    }
    TU_CHECK(completed);
    TU_CHECK(cancels >= 8); /* at least one call per stage boundary */
    mesh_free(&vol);
    mesh_free(&geo);
}

int main(void)
{
    TU_RUN(test_room_count);
    TU_RUN(test_furniture);
    TU_RUN(test_deterministic);
    TU_RUN(test_far_from_origin);
    TU_RUN(test_union_hand_count);
    TU_RUN(test_union_generic);
    TU_RUN(test_rotated_volume);
    TU_RUN(test_open_volume);
    TU_RUN(test_degenerate_triangles);
    TU_RUN(test_bad_input);
    TU_RUN(test_tiny_cells);
    TU_RUN(test_huge_cells);
    TU_RUN(test_too_large);
    TU_RUN(test_messages_and_limits);
    TU_RUN(test_cancel);
    return TU_EXIT();
}
