/* The sky's sun split (pb_sky_sun.h) against closed forms: a constant sky with a uniform sun disc
 * of known direction, radiance and angular radius, rendered into an equirect with 16×16
 * equal-area subsamples per texel (the coverage of the edge texels errs by up to 0.15 %). Expected:
 * irradiance (L_sun − L_sky)·2π(1 − cos α), direction the disc's axis, angle 2α, rest = the
 * constant sky, and sun + rest = the image (the sum of texel·dω) to double rounding. Soft, faint
 * and black skies keep their image bit for bit; bad input is refused with its code. */
#include "schnee/pb_sky_sun.h"
#include "testutil.h"

#include <stdlib.h>

#define PI 3.14159265358979323846

static const double SKY[3] = {0.5, 0.6, 0.8};

/* Blender-space unit vector at elevation `elev` above the horizon, azimuth `az` from +X to +Y. */
static void blender_dir(double elev, double az, double d[3])
{
    d[0] = cos(elev) * cos(az);
    d[1] = cos(elev) * sin(az);
    d[2] = sin(elev);
}

/* width × height × channels: SKY + (sun − SKY) · coverage of the disc of half-angle alpha about
 * `axis` (Blender space); channel 3 (when present) is 0.25. */
static float *render_disc(uint32_t w, uint32_t h, uint32_t channels, const double axis[3], double alpha,
                          const double sun[3])
{
    float *img = malloc(sizeof(float) * w * h * channels);
    const int S = 16;
    const double ca = cos(alpha);
    for (uint32_t row = 0; row < h; row++) {
        const double z0 = cos(PI * row / h), z1 = cos(PI * (row + 1.0) / h);
        for (uint32_t col = 0; col < w; col++) {
            /* a cheap reject: the texel centre far from the disc */
            const double th = PI * (row + 0.5) / h, ph = PI - 2.0 * PI * (col + 0.5) / w;
            const double c = sin(th) * cos(ph) * axis[0] + sin(th) * sin(ph) * axis[1] + cos(th) * axis[2];
            double cover = 0.0;
            if (c > cos(alpha + 0.05)) {
                int in = 0;
                for (int i = 0; i < S; i++)
                    for (int j = 0; j < S; j++) {
                        const double z = z0 + (z1 - z0) * (i + 0.5) / S; /* equal area: uniform in cos θ */
                        const double p = PI - 2.0 * PI * (col + (j + 0.5) / S) / w;
                        const double s = sqrt(1.0 - z * z);
                        in += s * cos(p) * axis[0] + s * sin(p) * axis[1] + z * axis[2] >= ca;
                    }
                cover = (double)in / (S * S);
            }
            float *px = img + ((size_t)row * w + col) * channels;
            for (int k = 0; k < 3; k++) px[k] = (float)(SKY[k] + (sun[k] - SKY[k]) * cover);
            for (uint32_t k = 3; k < channels; k++) px[k] = 0.25f;
        }
    }
    return img;
}

/* Σ texel · dω per channel (double), the image's irradiance-sum (its L0 up to a constant). */
static void flux(const float *img, uint32_t w, uint32_t h, uint32_t channels, double out[3])
{
    out[0] = out[1] = out[2] = 0.0;
    for (uint32_t row = 0; row < h; row++) {
        const double dw = (2.0 * PI / w) * (cos(PI * row / h) - cos(PI * (row + 1.0) / h));
        for (uint32_t col = 0; col < w; col++)
            for (int k = 0; k < 3; k++) out[k] += img[((size_t)row * w + col) * channels + k] * dw;
    }
}

static void check_disc(double elev, double az, double alpha, uint32_t w, uint32_t channels, bool in_place)
{
    const uint32_t h = w / 2;
    const double sun[3] = {2000.0, 1800.0, 1500.0};
    double axis[3];
    blender_dir(elev, az, axis);
    float *img = render_disc(w, h, channels, axis, alpha, sun);
    float *rest = in_place ? img : malloc(sizeof(float) * w * h * channels);
    double before[3];
    flux(img, w, h, channels, before);
    pb_sky_sun_desc desc = {0};
    pb_sky_sun s;
    pb_error err = {0};
    pb_result r = pb_sky_sun_split(&desc, img, w, h, channels, rest, &s, &err);
    TU_CHECK_EQ_INT(r, PB_SUCCESS);
    TU_CHECK(s.found);
    TU_CHECK_EQ_INT(s.verdict, PB_SKY_SUN_FOUND);
    /* Closed form: the disc's excess radiance times its solid angle 2π(1 − cos α); 0.3 % covers
     * the 16×16-subsample coverage of its edge texels (measured: 0.04–0.15 %, printed). */
    const double omega = 2.0 * PI * (1.0 - cos(alpha));
    for (int k = 0; k < 3; k++) TU_CHECK_REL(s.irradiance[k], (sun[k] - SKY[k]) * omega, 3e-3);
    /* Direction: the light travels along −axis, engine space (x, z, −y); within 0.02° (a texel is
     * 360°/w: 0.35° at 1024). */
    const double travel[3] = {-axis[0], -axis[2], axis[1]};
    const double dot = s.direction[0] * travel[0] + s.direction[1] * travel[1] + s.direction[2] * travel[2];
    TU_CHECK(acos(fmin(1.0, dot)) <= 0.02 * PI / 180.0);
    TU_CHECK_NEAR(s.direction[0] * s.direction[0] + s.direction[1] * s.direction[1] + s.direction[2] * s.direction[2],
                  1.0, 1e-12);
    /* Angle: the diameter 2α within 0.5 % (the solid angle within 1 %). */
    TU_CHECK_REL(s.angle, 2.0 * alpha, 5e-3);
    for (int k = 0; k < 3; k++) TU_CHECK_REL(s.background[k], SKY[k], 1e-6);
    /* The rest is the constant sky (float rounding of SKY only), alpha untouched. */
    double worst = 0.0;
    size_t alpha_changed = 0;
    for (size_t i = 0; i < (size_t)w * h; i++) {
        for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(rest[i * channels + k] - SKY[k]) / SKY[k]);
        for (uint32_t k = 3; k < channels; k++) alpha_changed += rest[i * channels + k] != 0.25f;
    }
    TU_CHECK(worst <= 1e-7);
    TU_CHECK_EQ_INT(alpha_changed, 0);
    printf("  disc %.4g deg at elevation %.3g deg, %ux%u: irradiance %+.2e, direction %.4f deg, angle %+.2e "
           "(relative to the closed form), %u texels\n",
           2.0 * alpha * 180.0 / PI, elev * 180.0 / PI, w, h, s.irradiance[1] / ((sun[1] - SKY[1]) * omega) - 1.0,
           acos(fmin(1.0, dot)) * 180.0 / PI, s.angle / (2.0 * alpha) - 1.0, s.texels);
    /* Energy: rest + sun = the image, to the rounding of double sums over ~0.5–2 M texels. */
    double after[3];
    flux(rest, w, h, channels, after);
    for (int k = 0; k < 3; k++) TU_CHECK_REL(after[k] + s.irradiance[k], before[k], 1e-10);
    /* The share: the sun's luminance flux over the image's. */
    const double y_sun = 0.2126 * s.irradiance[0] + 0.7152 * s.irradiance[1] + 0.0722 * s.irradiance[2];
    const double y_all = 0.2126 * before[0] + 0.7152 * before[1] + 0.0722 * before[2];
    TU_CHECK_REL(s.share, y_sun / y_all, 1e-9);
    TU_CHECK(s.texels > 0 && s.extent > 0.0 && s.extent <= 5.0 * PI / 180.0);
    if (!in_place) free(rest);
    free(img);
}

static void test_disc_closed_form(void)
{
    check_disc(30.0 * PI / 180.0, 40.0 * PI / 180.0, 1.0 * PI / 180.0, 1024, 3, false);
}

static void test_disc_small_sun_high_resolution(void)
{
    /* Nishita's sun: 0.545° wide, in a 2048 capture (3 texels across), RGBA, split in place. */
    check_disc(12.0 * PI / 180.0, -120.0 * PI / 180.0, 0.2725 * PI / 180.0, 2048, 4, true);
}

static void test_disc_across_the_pole_and_the_seam(void)
{
    /* 1° from the zenith: the region crosses the pole (neighbours half a turn on). */
    check_disc(89.0 * PI / 180.0, 10.0 * PI / 180.0, 1.5 * PI / 180.0, 1024, 3, false);
    /* On the φ seam (azimuth 180°: columns 0 and w − 1). */
    check_disc(5.0 * PI / 180.0, PI, 1.0 * PI / 180.0, 1024, 3, false);
}

/* A sky without a compact sun keeps its image bit for bit. */
static void check_unchanged(const float *img, uint32_t w, uint32_t h, pb_sky_sun_verdict expect)
{
    float *rest = malloc(sizeof(float) * w * h * 3);
    pb_sky_sun_desc desc = {0};
    pb_sky_sun s;
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, w, h, 3, rest, &s, NULL), PB_SUCCESS);
    TU_CHECK(!s.found);
    TU_CHECK_EQ_INT(s.verdict, expect);
    TU_CHECK(memcmp(rest, img, sizeof(float) * w * h * 3) == 0);
    TU_CHECK(s.irradiance[0] == 0.0 && s.share == 0.0);
    free(rest);
}

static void test_soft_sky_has_no_sun(void)
{
    /* A bright overcast sky: a gradient plus a Gaussian glow of 10° about a point 40° up, 5× the
     * sky at its centre. Its 1 %-of-peak region is the whole sky. */
    const uint32_t w = 512, h = 256;
    float *img = malloc(sizeof(float) * w * h * 3);
    double axis[3];
    blender_dir(40.0 * PI / 180.0, 1.0, axis);
    for (uint32_t row = 0; row < h; row++)
        for (uint32_t col = 0; col < w; col++) {
            const double th = PI * (row + 0.5) / h, ph = PI - 2.0 * PI * (col + 0.5) / w;
            const double c = sin(th) * cos(ph) * axis[0] + sin(th) * sin(ph) * axis[1] + cos(th) * axis[2];
            const double a = acos(fmin(1.0, c)), sigma = 10.0 * PI / 180.0;
            const double v = 1.0 + 0.5 * cos(th) + 5.0 * exp(-0.5 * a * a / (sigma * sigma));
            for (int k = 0; k < 3; k++) img[((size_t)row * w + col) * 3 + k] = (float)(v * SKY[k]);
        }
    check_unchanged(img, w, h, PB_SKY_SUN_WIDE);
    /* A compact but faint spot: a 0.3° disc at 500× the sky holds 0.34 % of the light (< 1 %). */
    double axis2[3];
    blender_dir(20.0 * PI / 180.0, 0.3, axis2);
    const double faint[3] = {500 * SKY[0], 500 * SKY[1], 500 * SKY[2]};
    float *spot = render_disc(w, h, 3, axis2, 0.3 * PI / 180.0, faint);
    check_unchanged(spot, w, h, PB_SKY_SUN_FAINT);
    /* Black: nothing at all. */
    memset(img, 0, sizeof(float) * w * h * 3);
    check_unchanged(img, w, h, PB_SKY_SUN_BLACK);
    free(spot);
    free(img);
}

static void test_detect_only_and_desc(void)
{
    /* rest = NULL only detects; a tighter max_radius than the disc refuses it (wide). */
    const uint32_t w = 512, h = 256;
    double axis[3];
    blender_dir(0.5, 2.0, axis);
    const double sun[3] = {500.0, 500.0, 500.0};
    float *img = render_disc(w, h, 3, axis, 2.0 * PI / 180.0, sun);
    pb_sky_sun s;
    pb_sky_sun_desc desc = {0};
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, w, h, 3, NULL, &s, NULL), PB_SUCCESS);
    TU_CHECK(s.found);
    desc.max_radius = 1.0 * PI / 180.0;
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, w, h, 3, NULL, &s, NULL), PB_SUCCESS);
    TU_CHECK(!s.found && s.verdict == PB_SKY_SUN_WIDE);
    /* min_share above the disc's share: faint. */
    desc.max_radius = 0.0;
    desc.min_share = 0.9;
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, w, h, 3, NULL, &s, NULL), PB_SUCCESS);
    TU_CHECK(!s.found && s.verdict == PB_SKY_SUN_FAINT);
    TU_CHECK(strcmp(pb_sky_sun_verdict_string(PB_SKY_SUN_FAINT), "faint") == 0);
    free(img);
}

static void test_bad_input(void)
{
    float img[8 * 4 * 3];
    for (size_t i = 0; i < sizeof img / sizeof img[0]; i++) img[i] = 1.0f;
    pb_sky_sun s;
    pb_sky_sun_desc desc = {0};
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_sky_sun_split(NULL, img, 8, 4, 3, NULL, &s, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, NULL, 8, 4, 3, NULL, &s, NULL), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, 8, 4, 3, NULL, NULL, NULL), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, 0, 4, 3, NULL, &s, NULL), PB_ERROR_INVALID_ARGUMENT);
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, 8, 4, 2, NULL, &s, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "2 channels");
    desc.peak_fraction = 1.5;
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, 8, 4, 3, NULL, &s, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "peak_fraction 1.5");
    desc.peak_fraction = 0.0;
    desc.max_radius = -1.0;
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, 8, 4, 3, NULL, &s, NULL), PB_ERROR_INVALID_ARGUMENT);
    desc.max_radius = 0.0;
    desc.min_share = 1.0;
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, 8, 4, 3, NULL, &s, NULL), PB_ERROR_INVALID_ARGUMENT);
    desc.min_share = 0.0;
    img[3 * 9 + 1] = NAN;
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, 8, 4, 3, NULL, &s, &err), PB_ERROR_NON_FINITE);
    TU_CHECK_CONTAINS(err.message, "(1, 1)");
    img[3 * 9 + 1] = -1.0f;
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_sky_sun_split(&desc, img, 8, 4, 3, NULL, &s, &err), PB_ERROR_NEGATIVE);
    TU_CHECK_CONTAINS(err.message, "negative");
}

int main(void)
{
    TU_RUN(test_disc_closed_form);
    TU_RUN(test_disc_small_sun_high_resolution);
    TU_RUN(test_disc_across_the_pole_and_the_seam);
    TU_RUN(test_soft_sky_has_no_sun);
    TU_RUN(test_detect_only_and_desc);
    TU_RUN(test_bad_input);
    return TU_EXIT();
}
