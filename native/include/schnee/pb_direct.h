/* Schnee probes — direct light of lamps and of the sky, projected exactly onto SH (docs/direct-light.md).
 *
 * How to use it:
 *   1. Optionally build an occluder scene from the render geometry (pb_direct_scene_create, engine
 *      space, the same pb_mesh_desc lists as placement); NULL means nothing occludes.
 *   2. Describe the lamps as pb_light records (engine space, Blender/Cycles units) and call
 *      pb_direct_project() once per probe: it ADDS the radiance projection
 *      L_i += ∫ L_lamp(ω) V(ω) Y_i(ω) dω of every lamp, RGB, pb_sh_count(max_band) coefficients.
 *   3. For the sky: pb_direct_sky_table() pre-integrates the world (an equirect at any resolution)
 *      into panorama cells; pb_direct_add_sky() adds Σ_cells vis(cell) · table(cell).
 *
 * Lamp radiance (Cycles, verified against renders in tests/blender/test_direct_light.py):
 *   Sun:   strength S (W/m²) over a cone of half-angle α = angle/2; L(θ) = S / (π tan²α cos³θ), so
 *          ∫ L dω = S exactly; α = 0 is a delta: S · Y(d).
 *   Point: power P (W), radius r. L = P / (4π² r²) over the lamp's apparent disc; r = 0 is a delta of
 *          intensity P / (4π) (W/sr). Shape: Cycles ≤ 3.6 draws a disc of radius r facing the
 *          viewer (cone half-angle atan(r/d)), and so does Cycles ≥ 4.0 with Soft Falloff on (its
 *          default); with it off a sphere (asin(r/d)): `legacy_point`.
 *   Spot:  a point lamp times the cone attenuation: smoothstep((cos γ − cos(size/2)) / smooth) with
 *          smooth = (1 − cos(size/2)) · blend, γ the angle off the spot axis; Cycles ≤ 3.6 also
 *          multiplies by cos γ (`spot_cosine`).
 *   Area:  power P (W), one-sided (emits along `direction`), uniform radiance L = P / (4 A) over the
 *          rectangle/ellipse of area A (square/disk: size_v = size_u).
 * Visibility: one shadow ray per quadrature cell from the probe to the cell's point on the lamp
 * (deterministic stratification, `samples` cells per lamp), opaque occluders.
 */
#ifndef SCHNEE_PB_DIRECT_H
#define SCHNEE_PB_DIRECT_H

#include "schnee/pb_common.h"
#include "schnee/pb_octree.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum pb_light_type {
    PB_LIGHT_SUN = 0,
    PB_LIGHT_POINT = 1,
    PB_LIGHT_SPOT = 2,
    PB_LIGHT_AREA_RECT = 3,    /* square or rectangle */
    PB_LIGHT_AREA_ELLIPSE = 4, /* disk or ellipse */
    PB_LIGHT_TYPE_COUNT_
} pb_light_type;

typedef struct pb_light {
    pb_light_type type;
    double position[3];  /* engine space, metres (ignored for a sun) */
    double direction[3]; /* unit, engine space: where the lamp emits (its local −Z); for a sun the
                            direction its light travels */
    double axis_u[3];    /* area: unit, engine space, the lamp's local +X (size_u along it) */
    double color[3];     /* colour × strength: sun W/m², point/spot/area W */
    double radius;       /* point/spot: radius (m); sun: angular diameter `angle` (rad) */
    double size_u;       /* area: size along axis_u (m) */
    double size_v;       /* area: size along direction × axis_u (m) */
    double spot_size;    /* spot: full cone angle (rad) */
    double spot_blend;   /* spot: 0..1 */
    bool legacy_point;   /* point/spot drawn as a disc facing the viewer (Cycles ≤ 3.6, and 4.0+ with
                            Soft Falloff on); false: a sphere (4.0+, Soft Falloff off) */
    bool spot_cosine;    /* spot cone also × cos γ (Cycles ≤ 3.6) */
} pb_light;

typedef struct pb_direct_scene pb_direct_scene;

/* Occluders for the shadow rays (engine space). count 0 is allowed (nothing occludes). */
pb_result pb_direct_scene_create(const pb_mesh_desc *geometry, uint32_t count, pb_direct_scene **out, pb_error *err);
void pb_direct_scene_destroy(pb_direct_scene *scene);

typedef struct pb_direct_desc {
    uint32_t max_band;            /* 0..4 */
    uint32_t samples;             /* quadrature cells (= shadow rays) per lamp; 0 = 256; rounded to the
                               stratification (docs/direct-light.md) */
    double ray_offset;            /* metres the shadow rays start from the probe and stop short of the
                               lamp; 0 = 1e-4 */
    const pb_direct_scene *scene; /* NULL: no occlusion */
} pb_direct_desc;

/* Adds the direct radiance projection of `count` lamps seen from `probe` (engine space) to out
 * (pb_sh_count(max_band) * 3 doubles, coefficient-major RGB). Lamps the probe cannot see (behind an
 * area lamp, outside a spot cone, inside a legacy point lamp's radius...) add nothing. */
pb_result pb_direct_project(const pb_direct_desc *desc, const pb_light *lights, uint32_t count, const double probe[3],
                            double *out, pb_error *err);

/* Sky table: for a panorama of pano_width × pano_height cells in the canonical mapping (DESIGN.md
 * §3, the panorama rendered by the bake), table[cell][i][c] = ∫_cell L_world(ω) Y_i(ω) dω with the
 * world given as an equirect of any resolution in the same mapping (RGB first, `channels` floats
 * per pixel, row 0 at the top), each world texel integrated with its exact solid angle and the
 * basis at its centre. World pixels must be finite and >= 0. `rotation` as in pb_sh_project_desc
 * (NULL = Blender → engine). table: pano_width * pano_height * pb_sh_count(max_band) * 3 doubles. */
pb_result pb_direct_sky_table(const float *world, uint32_t world_width, uint32_t world_height, uint32_t channels,
                              uint32_t pano_width, uint32_t pano_height, uint32_t max_band, const double *rotation,
                              double *table, pb_error *err);

/* out += Σ_cells vis[cell] · table[cell] (vis: pano_width * pano_height values in [0, 1], e.g. the
 * alpha coverage of a panorama rendered with a transparent film, read from `vis_stride` floats apart,
 * row-major, row 0 at the top). */
void pb_direct_add_sky(const double *table, uint32_t pano_width, uint32_t pano_height, uint32_t max_band,
                       const float *vis, size_t vis_stride, double *out);

#ifdef __cplusplus
}
#endif
#endif
