/* Real spherical harmonics L = 0..4 (DESIGN.md §3): basis, equirect projection, irradiance,
 * ringing windows. See docs/sh.md for the derivations behind the choices below. */
#include "schnee/pb_sh.h"

#include "pb_file.h"
#include "schnee/pb_image.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PB_PI 3.14159265358979323846

/* Normalisation constants at full double precision (the 9-digit values of DESIGN.md §3). */
#define K00 0.28209479177387814 /* 1/(2√π) */
#define K1  0.4886025119029199  /* √(3/4π) */
#define K2A 1.0925484305920792  /* ½√(15/π) */
#define K2B 0.31539156525252005 /* ¼√(5/π) */
#define K2C 0.5462742152960396  /* ¼√(15/π) */
#define K3A 0.5900435899266435  /* ¼√(35/2π) */
#define K3B 2.890611442640554   /* ½√(105/π) */
#define K3C 0.4570457994644658  /* ¼√(21/2π) */
#define K3D 0.3731763325901154  /* ¼√(7/π) */
#define K3E 1.445305721320277   /* ¼√(105/π) */
#define K4A 2.5033429417967046  /* ¾√(35/π) */
#define K4B 1.7701307697799304  /* ¾√(35/2π) */
#define K4C 0.9461746957575601  /* ¾√(5/π) */
#define K4D 0.6690465435572892  /* ¾√(5/2π) */
#define K4E 0.10578554691520431 /* 3/(16√π) */
#define K4F 0.47308734787878004 /* ⅜√(5/π) */
#define K4G 0.6258357354491761  /* (3/16)√(35/π) */

void pb_sh_eval_basis(uint32_t max_band, const double dir[3], double *out)
{
    const double x = dir[0], y = dir[1], z = dir[2];
    out[0] = K00;
    if (max_band < 1) return;
    out[1] = K1 * y;
    out[2] = K1 * z;
    out[3] = K1 * x;
    if (max_band < 2) return;
    const double x2 = x * x, y2 = y * y, z2 = z * z;
    out[4] = K2A * x * y;
    out[5] = K2A * y * z;
    out[6] = K2B * (3.0 * z2 - 1.0);
    out[7] = K2A * x * z;
    out[8] = K2C * (x2 - y2);
    if (max_band < 3) return;
    out[9] = K3A * y * (3.0 * x2 - y2);
    out[10] = K3B * x * y * z;
    out[11] = K3C * y * (5.0 * z2 - 1.0);
    out[12] = K3D * z * (5.0 * z2 - 3.0);
    out[13] = K3C * x * (5.0 * z2 - 1.0);
    out[14] = K3E * z * (x2 - y2);
    out[15] = K3A * x * (x2 - 3.0 * y2);
    if (max_band < 4) return;
    out[16] = K4A * x * y * (x2 - y2);
    out[17] = K4B * y * z * (3.0 * x2 - y2);
    out[18] = K4C * x * y * (7.0 * z2 - 1.0);
    out[19] = K4D * y * z * (7.0 * z2 - 3.0);
    out[20] = K4E * (35.0 * z2 * z2 - 30.0 * z2 + 3.0);
    out[21] = K4D * x * z * (7.0 * z2 - 3.0);
    out[22] = K4F * (x2 - y2) * (7.0 * z2 - 1.0);
    out[23] = K4B * x * z * (x2 - 3.0 * y2);
    out[24] = K4G * (x2 * x2 - 6.0 * x2 * y2 + y2 * y2);
}

double pb_sh_lambert_band(uint32_t l)
{
    /* Â_l = 2π ∫₀¹ P_l(t) t dt (Ramamoorthi & Hanrahan 2001). */
    switch (l) {
    case 0: return PB_PI;
    case 1: return 2.0 * PB_PI / 3.0;
    case 2: return PB_PI / 4.0;
    case 3: return 0.0;
    case 4: return -PB_PI / 24.0;
    default: return 0.0;
    }
}

void pb_sh_irradiance(uint32_t max_band, const double *coeffs, const double n[3], double out_rgb[3])
{
    double y[PB_SH_MAX_COEFFS];
    if (max_band > PB_SH_MAX_BAND) max_band = PB_SH_MAX_BAND;
    pb_sh_eval_basis(max_band, n, y);
    out_rgb[0] = out_rgb[1] = out_rgb[2] = 0.0;
    for (uint32_t l = 0; l <= max_band; l++) {
        const double a = pb_sh_lambert_band(l);
        for (uint32_t i = l * l; i < (l + 1) * (l + 1); i++)
            for (int c = 0; c < 3; c++) out_rgb[c] += a * coeffs[i * 3 + c] * y[i];
    }
}

/* ---------------------------------------------------------------------------------------------- */
/* Projection                                                                                       */
/* ---------------------------------------------------------------------------------------------- */

void pb_sh_min_panorama_size(uint32_t max_band, uint32_t *min_width, uint32_t *min_height)
{
    /* Driscoll–Healy: a function band-limited to degree < B is determined by 2B × 2B equiangular
     * samples; here B = max_band + 1. With our pixel-centre sampling and exact solid angles this
     * keeps the discrete Gram matrix within 6.1 % of the identity for every band (docs/sh.md). */
    if (max_band > PB_SH_MAX_BAND) max_band = PB_SH_MAX_BAND;
    const uint32_t n = 2u * (max_band + 1u);
    if (min_width) *min_width = n;
    if (min_height) *min_height = n;
}

static const double pb_identity3_[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
static const double pb_blender_to_engine_[9] = {1, 0, 0, 0, 0, 1, 0, -1, 0};

/* Rotation of SH coefficients: M[i][j] = ∫ Y_i(R d) Y_j(d) dω, so that Σ_j M_ij Y_j(d) = Y_i(R d)
 * for every d (R orthogonal maps each band onto itself). The quadrature (5-point Gauss–Legendre in
 * z × 10 uniform φ) is exact for polynomials of degree ≤ 9 on the sphere, and Y_i(Rd)·Y_j(d) has
 * degree ≤ 8, so M is exact to rounding. Block-diagonal by band; other entries are left zero. */
static void pb_sh_rotation_matrix_(uint32_t max_band, const double r[9], double m[PB_SH_MAX_COEFFS][PB_SH_MAX_COEFFS])
{
    static const double gl_x[5] = {-0.90617984593866399280, -0.53846931010568309104, 0.0, 0.53846931010568309104,
                                   0.90617984593866399280};
    static const double gl_w[5] = {0.23692688505618908751, 0.47862867049936646804, 0.56888888888888888889,
                                   0.47862867049936646804, 0.23692688505618908751};
    enum { NPHI = 10 };
    memset(m, 0, sizeof(double) * PB_SH_MAX_COEFFS * PB_SH_MAX_COEFFS);
    for (int a = 0; a < 5; a++) {
        const double z = gl_x[a], s = sqrt(1.0 - z * z);
        for (int b = 0; b < NPHI; b++) {
            const double phi = 2.0 * PB_PI * b / NPHI;
            const double w = gl_w[a] * (2.0 * PB_PI / NPHI);
            const double d[3] = {s * cos(phi), s * sin(phi), z};
            double rd[3];
            for (int k = 0; k < 3; k++) rd[k] = r[k * 3 + 0] * d[0] + r[k * 3 + 1] * d[1] + r[k * 3 + 2] * d[2];
            double yd[PB_SH_MAX_COEFFS], yr[PB_SH_MAX_COEFFS];
            pb_sh_eval_basis(max_band, d, yd);
            pb_sh_eval_basis(max_band, rd, yr);
            for (uint32_t l = 0; l <= max_band; l++)
                for (uint32_t i = l * l; i < (l + 1) * (l + 1); i++)
                    for (uint32_t j = l * l; j < (l + 1) * (l + 1); j++) m[i][j] += w * yr[i] * yd[j];
        }
    }
}

static const char *const pb_channel_names_[3] = {"R", "G", "B"};

/* Validates desc and fills the derived sizes. */
static pb_result pb_sh_validate_(const pb_sh_project_desc *desc, const double *out, uint32_t *channels, size_t *stride,
                                 pb_error *err)
{
    if (!desc) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: desc is NULL");
    if (!out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: out is NULL");
    if (!desc->pixels) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: pixels is NULL");
    if (desc->max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: max_band %u is out of range (0..%d)",
                            desc->max_band, PB_SH_MAX_BAND);
    if ((unsigned)desc->negative > (unsigned)PB_NEGATIVE_ALLOW)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: unknown negative policy %d",
                            (int)desc->negative);
    const uint32_t ch = desc->channels ? desc->channels : 4u;
    if (ch < 3)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "SH projection: %u channel(s) per pixel; RGB (at least 3) is required", ch);
    if (desc->width == 0 || desc->height == 0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: empty panorama (%ux%u)", desc->width,
                            desc->height);
    uint32_t min_w, min_h;
    pb_sh_min_panorama_size(desc->max_band, &min_w, &min_h);
    if (desc->width < min_w || desc->height < min_h)
        return pb_error_set(err, PB_ERROR_TOO_SMALL,
                            "SH projection: a %ux%u panorama is too small for band L=%u; the minimum "
                            "is %ux%u (width x height, 2(L+1) samples per axis)",
                            desc->width, desc->height, desc->max_band, min_w, min_h);
    /* Row length and the last element touched must fit in size_t (the caller's buffer holds
     * (height-1)*stride + width*channels floats). */
    const size_t row = (size_t)desc->width * ch; /* both ≤ 2^32: fits 64-bit size_t */
    if (SIZE_MAX / ch < desc->width)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: width x channels overflows");
    size_t st = desc->row_stride ? desc->row_stride : row;
    if (st < row)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "SH projection: row_stride %zu is smaller than width x channels = %zu", st, row);
    if ((size_t)(desc->height - 1) > (SIZE_MAX - row) / st ||
        (size_t)(desc->height - 1) * st + row > SIZE_MAX / sizeof(float))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "SH projection: %u rows of stride %zu floats overflow the address space", desc->height, st);
    const double *r = desc->rotation;
    if (r) {
        for (int i = 0; i < 9; i++)
            if (!isfinite(r[i]))
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: rotation[%d] is not finite", i);
        /* Must be orthogonal: Y_i(R d) is only a band-l function (and d only a unit vector) then. */
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                const double dot =
                    r[0 * 3 + i] * r[0 * 3 + j] + r[1 * 3 + i] * r[1 * 3 + j] + r[2 * 3 + i] * r[2 * 3 + j];
                if (fabs(dot - (i == j ? 1.0 : 0.0)) > 1e-6)
                    return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                        "SH projection: rotation is not orthonormal (column %d . column "
                                        "%d = %.9g)",
                                        i, j, dot);
            }
    }
    *channels = ch;
    *stride = st;
    return PB_SUCCESS;
}

/* Finds the first offending pixel of a row whose sums came out non-finite (or had a negative),
 * and reports it. */
static pb_result pb_sh_report_pixel_(const float *p, uint32_t width, uint32_t ch, uint32_t y, bool want_nonfinite,
                                     pb_error *err)
{
    for (uint32_t x = 0; x < width; x++)
        for (uint32_t c = 0; c < 3; c++) {
            const float v = p[(size_t)x * ch + c];
            if (want_nonfinite && !isfinite(v)) {
                char text[32];
                return pb_error_set(err, PB_ERROR_NON_FINITE,
                                    "SH projection: non-finite radiance %s at pixel (x=%u, y=%u), "
                                    "channel %u (%s)",
                                    pb_format_double_(v, text, sizeof text), x, y, c, pb_channel_names_[c]);
            }
            if (!want_nonfinite && v < 0.0f)
                return pb_error_set(err, PB_ERROR_NEGATIVE,
                                    "SH projection: negative radiance %g at pixel (x=%u, y=%u), "
                                    "channel %u (%s); set the negative policy to clamp or allow to "
                                    "accept it",
                                    (double)v, x, y, c, pb_channel_names_[c]);
        }
    return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: internal error locating pixel");
}

pb_result pb_sh_project_equirect(const pb_sh_project_desc *desc, double *out, pb_error *err)
{
    uint32_t ch = 0;
    size_t stride = 0;
    pb_result res = pb_sh_validate_(desc, out, &ch, &stride, err);
    if (res != PB_SUCCESS) return res;

    const uint32_t L = desc->max_band, W = desc->width, H = desc->height;
    const uint32_t count = pb_sh_count(L);
    const uint32_t ntrig = 2 * L + 1; /* cos(kφ) k=0..L, sin(kφ) k=1..L */

    /* Separable evaluation. In the canonical frame (the Cycles direction d itself), the basis is
     * Y_lm(d) = N_lm P_l^|m|(cos θ) trig(|m| φ): per row, Σ_i L(i) trig(kφ_i) over columns, then per
     * (l, m) a row factor. The result c_j = Σ_p w_p L_p Y_j(d_p) is mapped to the output space with
     * M_ij = ∫ Y_i(R d) Y_j(d): Σ_j M_ij c_j = Σ_p w_p L_p Y_i(R d_p) exactly, i.e. the basis is
     * evaluated at the converted direction R d_p (never a coefficient permutation). */
    double *trig = malloc(sizeof(double) * (size_t)ntrig * W);
    double *rowbuf = malloc(sizeof(double) * 3u * W);
    if (!trig || !rowbuf) {
        free(trig);
        free(rowbuf);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "SH projection: out of memory for %ux%u tables", W, ntrig);
    }
    for (uint32_t i = 0; i < W; i++) {
        const double phi = PB_PI - 2.0 * PB_PI * (i + 0.5) / W;
        trig[i] = 1.0;
        for (uint32_t k = 1; k <= L; k++) {
            trig[(size_t)(2 * k - 1) * W + i] = cos(k * phi);
            trig[(size_t)(2 * k) * W + i] = sin(k * phi);
        }
    }

    double canon[PB_SH_MAX_COEFFS][3];
    memset(canon, 0, sizeof canon);
    const double dphi = 2.0 * PB_PI / W;
    const bool clamp = desc->negative == PB_NEGATIVE_CLAMP;
    const bool reject_negative = desc->negative == PB_NEGATIVE_ERROR;
    double cos_top = 1.0;
    for (uint32_t y = 0; y < H; y++) {
        const float *p = desc->pixels + (size_t)y * stride;
        const double cos_bottom = (y + 1 == H) ? -1.0 : cos(PB_PI * (y + 1) / H);
        const double w = dphi * (cos_top - cos_bottom);
        const double theta = PB_PI * (y + 0.5) / H;
        cos_top = cos_bottom;

        /* De-interleave to double; track non-finite (via the sum) and the row minimum. */
        double *r0 = rowbuf, *r1 = rowbuf + W, *r2 = rowbuf + 2 * (size_t)W;
        double sum = 0.0, mn = 0.0;
        for (uint32_t i = 0; i < W; i++) {
            const float *q = p + (size_t)i * ch;
            double a = q[0], b = q[1], c = q[2];
            sum += a + b + c;
            mn = a < mn ? a : mn;
            mn = b < mn ? b : mn;
            mn = c < mn ? c : mn;
            if (clamp) {
                a = a < 0.0 ? 0.0 : a;
                b = b < 0.0 ? 0.0 : b;
                c = c < 0.0 ? 0.0 : c;
            }
            r0[i] = a;
            r1[i] = b;
            r2[i] = c;
        }
        /* Finite floats cannot overflow a double sum, so a non-finite sum means a non-finite pixel. */
        if (!isfinite(sum) || (reject_negative && mn < 0.0)) {
            res = pb_sh_report_pixel_(p, W, ch, y, !isfinite(sum), err);
            break;
        }

        /* Column sums against each trig table; 2 accumulators per channel for ILP. */
        double s[2 * PB_SH_MAX_BAND + 1][3];
        for (uint32_t t = 0; t < ntrig; t++) {
            const double *tr = trig + (size_t)t * W;
            double a0 = 0, a1 = 0, b0 = 0, b1 = 0, c0 = 0, c1 = 0;
            uint32_t i = 0;
            for (; i + 1 < W; i += 2) {
                a0 += r0[i] * tr[i];
                b0 += r1[i] * tr[i];
                c0 += r2[i] * tr[i];
                a1 += r0[i + 1] * tr[i + 1];
                b1 += r1[i + 1] * tr[i + 1];
                c1 += r2[i + 1] * tr[i + 1];
            }
            if (i < W) {
                a0 += r0[i] * tr[i];
                b0 += r1[i] * tr[i];
                c0 += r2[i] * tr[i];
            }
            s[t][0] = a0 + a1;
            s[t][1] = b0 + b1;
            s[t][2] = c0 + c1;
        }

        /* Row factors N_lm P_l^|m|(cos θ): the basis at φ0 where trig(|m|φ0) = 1 (φ0 = 0 for
         * m ≥ 0, π/(2|m|) for m < 0), so they come from pb_sh_eval_basis itself. */
        double f[PB_SH_MAX_COEFFS];
        {
            const double st = sin(theta), ct = cos(theta);
            double yb[PB_SH_MAX_COEFFS];
            const double d0[3] = {st, 0.0, ct};
            pb_sh_eval_basis(L, d0, yb);
            for (uint32_t l = 0; l <= L; l++)
                for (uint32_t m = 0; m <= l; m++) f[l * l + l + m] = yb[l * l + l + m];
            for (uint32_t m = 1; m <= L; m++) {
                const double phi0 = PB_PI / (2.0 * m);
                const double dm[3] = {st * cos(phi0), st * sin(phi0), ct};
                pb_sh_eval_basis(L, dm, yb);
                for (uint32_t l = m; l <= L; l++) f[l * l + l - m] = yb[l * l + l - m];
            }
        }
        for (uint32_t l = 0; l <= L; l++)
            for (int m = -(int)l; m <= (int)l; m++) {
                const uint32_t j = (uint32_t)((int)(l * l + l) + m);
                const uint32_t t = m == 0 ? 0u : m > 0 ? 2u * (uint32_t)m - 1u : 2u * (uint32_t)(-m);
                const double g = w * f[j];
                for (int c = 0; c < 3; c++) canon[j][c] += g * s[t][c];
            }
    }
    free(trig);
    free(rowbuf);
    if (res != PB_SUCCESS) return res;

    const double *rot = desc->rotation ? desc->rotation : pb_blender_to_engine_;
    if (memcmp(rot, pb_identity3_, sizeof pb_identity3_) == 0) {
        for (uint32_t i = 0; i < count; i++)
            for (int c = 0; c < 3; c++) out[i * 3 + c] = canon[i][c];
        return PB_SUCCESS;
    }
    double m[PB_SH_MAX_COEFFS][PB_SH_MAX_COEFFS];
    pb_sh_rotation_matrix_(L, rot, m);
    for (uint32_t l = 0; l <= L; l++)
        for (uint32_t i = l * l; i < (l + 1) * (l + 1); i++)
            for (int c = 0; c < 3; c++) {
                double acc = 0.0;
                for (uint32_t j = l * l; j < (l + 1) * (l + 1); j++) acc += m[i][j] * canon[j][c];
                out[i * 3 + c] = acc;
            }
    return PB_SUCCESS;
}

pb_result pb_sh_project_file(const char *path, const pb_sh_project_desc *desc, double *out, pb_error *err)
{
    if (!path) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: path is NULL");
    if (!out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH projection: out is NULL");
    pb_image img = {0};
    pb_result res = pb_image_read(path, &img, err);
    if (res != PB_SUCCESS) return res;
    if (img.channels < 3) {
        res = pb_error_set(err, PB_ERROR_FORMAT, "SH projection: '%s' has %u channel(s); an RGB panorama is required",
                           path, img.channels);
        pb_image_free(&img);
        return res;
    }
    pb_sh_project_desc d = {0};
    if (desc) d = *desc;
    d.pixels = img.pixels;
    d.width = img.width;
    d.height = img.height;
    d.channels = img.channels;
    d.row_stride = 0;
    pb_error local = {0};
    res = pb_sh_project_equirect(&d, out, &local);
    if (res != PB_SUCCESS) pb_error_set(err, res, "%s: %s", path, local.message);
    pb_image_free(&img);
    return res;
}

/* ---------------------------------------------------------------------------------------------- */
/* Ringing windows                                                                                  */
/* ---------------------------------------------------------------------------------------------- */

static double pb_sh_window_factor_(pb_sh_window_kind kind, double strength, uint32_t l)
{
    if (l == 0) return 1.0;
    switch (kind) {
    case PB_SH_WINDOW_SINC4: {
        /* Filament (cmgen): sinc window scaled so it reaches 0 at band `strength`, to the 4th power. */
        if ((double)l >= strength) return 0.0;
        const double x = PB_PI * l / strength;
        const double s = sin(x) / x;
        return s * s * s * s;
    }
    case PB_SH_WINDOW_LAPLACIAN: {
        /* Sloan 2017: minimise ∫|f − g|² + λ∫|Δg|²  →  band l scaled by 1/(1 + λ l²(l+1)²). */
        const double ll = (double)l * (l + 1);
        return 1.0 / (1.0 + strength * ll * ll);
    }
    default: return 1.0;
    }
}

/* Dense sample set for the minimum search: a Fibonacci sphere, basis precomputed. */
enum { PB_SH_MIN_SAMPLES = 2048, PB_SH_MIN_REFINE = 6 };

typedef struct pb_sh_minsearch {
    uint32_t max_band;
    double *basis; /* PB_SH_MIN_SAMPLES × count */
    double dirs[PB_SH_MIN_SAMPLES][3];
} pb_sh_minsearch;

static double pb_sh_eval_channel_(uint32_t max_band, const double *irr_coeffs, int c, const double d[3])
{
    double y[PB_SH_MAX_COEFFS];
    pb_sh_eval_basis(max_band, d, y);
    double e = 0.0;
    for (uint32_t i = 0; i < pb_sh_count(max_band); i++) e += irr_coeffs[i * 3 + c] * y[i];
    return e;
}

static void pb_sh_dir_from_angles_(double theta, double phi, double d[3])
{
    d[0] = sin(theta) * cos(phi);
    d[1] = sin(theta) * sin(phi);
    d[2] = cos(theta);
}

/* Minimum over the sphere of Σ_i k_i Y_i (k = irradiance coefficients A_l L_lm) per channel: dense
 * samples, then a shrinking-step pattern search around the best few samples. */
static void pb_sh_min_over_sphere_(const pb_sh_minsearch *ms, const double *k, double out[3])
{
    const uint32_t L = ms->max_band, count = pb_sh_count(L);
    for (int c = 0; c < 3; c++) {
        int best[PB_SH_MIN_REFINE];
        double bestv[PB_SH_MIN_REFINE];
        for (int b = 0; b < PB_SH_MIN_REFINE; b++) {
            best[b] = -1;
            bestv[b] = DBL_MAX;
        }
        for (int s = 0; s < PB_SH_MIN_SAMPLES; s++) {
            const double *y = ms->basis + (size_t)s * count;
            double e = 0.0;
            for (uint32_t i = 0; i < count; i++) e += k[i * 3 + c] * y[i];
            if (e < bestv[PB_SH_MIN_REFINE - 1]) {
                int b = PB_SH_MIN_REFINE - 1;
                while (b > 0 && bestv[b - 1] > e) {
                    bestv[b] = bestv[b - 1];
                    best[b] = best[b - 1];
                    b--;
                }
                bestv[b] = e;
                best[b] = s;
            }
        }
        double mn = bestv[0];
        for (int b = 0; b < PB_SH_MIN_REFINE && best[b] >= 0; b++) {
            const double *d0 = ms->dirs[best[b]];
            double th = acos(fmax(-1.0, fmin(1.0, d0[2]))), ph = atan2(d0[1], d0[0]);
            double v = bestv[b];
            /* Start near the sample spacing (~0.08 rad) and shrink to 1e-9 rad. Working in (θ, φ)
             * is fine away from the poles; near a pole the φ steps are scaled by 1/sin θ capped. */
            for (double step = 0.1; step > 1e-9;) {
                const double sp = step / fmax(sin(th), 0.05);
                const double cand[4][2] = {{th + step, ph}, {th - step, ph}, {th, ph + sp}, {th, ph - sp}};
                bool moved = false;
                for (int q = 0; q < 4; q++) {
                    double d[3];
                    pb_sh_dir_from_angles_(cand[q][0], cand[q][1], d);
                    const double e = pb_sh_eval_channel_(L, k, c, d);
                    if (e < v) {
                        v = e;
                        th = cand[q][0];
                        ph = cand[q][1];
                        moved = true;
                        break;
                    }
                }
                if (!moved) step *= 0.5;
            }
            mn = fmin(mn, v);
        }
        out[c] = mn;
    }
}

static void pb_sh_windowed_irradiance_coeffs_(uint32_t L, pb_sh_window_kind kind, double strength, const double *coeffs,
                                              double *k)
{
    for (uint32_t l = 0; l <= L; l++) {
        const double f = pb_sh_window_factor_(kind, strength, l) * pb_sh_lambert_band(l);
        for (uint32_t i = l * l; i < (l + 1) * (l + 1); i++)
            for (int c = 0; c < 3; c++) k[i * 3 + c] = f * coeffs[i * 3 + c];
    }
}

static double pb_min3_(const double v[3]) { return fmin(v[0], fmin(v[1], v[2])); }

pb_result pb_sh_window(uint32_t max_band, pb_sh_window_kind kind, double strength, double *coeffs,
                       double min_irradiance[3], pb_error *err)
{
    if (!coeffs) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH window: coeffs is NULL");
    if (max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH window: max_band %u is out of range (0..%d)", max_band,
                            PB_SH_MAX_BAND);
    if (kind != PB_SH_WINDOW_NONE && kind != PB_SH_WINDOW_SINC4 && kind != PB_SH_WINDOW_LAPLACIAN)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "SH window: unknown window kind %d", (int)kind);
    if (!isfinite(strength) || strength < 0.0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "SH window: strength %g must be finite and >= 0 (0 = automatic)", strength);
    const uint32_t count = pb_sh_count(max_band);
    for (uint32_t i = 0; i < count * 3; i++)
        if (!isfinite(coeffs[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "SH window: coefficient %u channel %u is %g", i / 3, i % 3,
                                coeffs[i]);

    const bool need_min = min_irradiance != NULL || (kind != PB_SH_WINDOW_NONE && strength == 0.0);
    pb_sh_minsearch *ms = NULL;
    if (need_min) {
        ms = malloc(sizeof *ms);
        double *basis = malloc(sizeof(double) * PB_SH_MIN_SAMPLES * count);
        if (!ms || !basis) {
            free(ms);
            free(basis);
            return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "SH window: out of memory");
        }
        ms->max_band = max_band;
        ms->basis = basis;
        const double golden = PB_PI * (3.0 - sqrt(5.0));
        for (int s = 0; s < PB_SH_MIN_SAMPLES; s++) {
            const double z = 1.0 - (2.0 * s + 1.0) / PB_SH_MIN_SAMPLES;
            const double r = sqrt(1.0 - z * z), a = golden * s;
            ms->dirs[s][0] = r * cos(a);
            ms->dirs[s][1] = r * sin(a);
            ms->dirs[s][2] = z;
            pb_sh_eval_basis(max_band, ms->dirs[s], basis + (size_t)s * count);
        }
    }

    double k[PB_SH_MAX_COEFFS * 3];
    double mn[3] = {0, 0, 0};
    pb_result res = PB_SUCCESS;
    if (kind != PB_SH_WINDOW_NONE && strength == 0.0) {
        /* Automatic: the weakest window (largest sinc cutoff / smallest λ) whose irradiance is ≥ 0
         * everywhere. Bisection keeps the feasible end, so the result is never slightly negative. */
        pb_sh_windowed_irradiance_coeffs_(max_band, PB_SH_WINDOW_NONE, 0.0, coeffs, k);
        pb_sh_min_over_sphere_(ms, k, mn);
        if (pb_min3_(mn) >= 0.0) {
            kind = PB_SH_WINDOW_NONE; /* nothing to fix: the smallest window is no window */
        } else if (max_band == 0 || coeffs[0] < 0.0 || coeffs[1] < 0.0 || coeffs[2] < 0.0) {
            /* Only the DC term survives the strongest window; a negative DC cannot be fixed. */
            res = pb_error_set(err, PB_ERROR_NEGATIVE,
                               "SH window: the DC term is negative (%g, %g, %g); no window makes the "
                               "irradiance non-negative",
                               coeffs[0], coeffs[1], coeffs[2]);
        } else {
            /* feasible / infeasible ends of the strength interval */
            double good, bad;
            if (kind == PB_SH_WINDOW_SINC4) {
                good = 1.0; /* cutoff 1 keeps only band 0 */
                bad = 1e6;  /* ~identity */
            } else {
                bad = 0.0;
                good = 1e-6;
                for (;;) {
                    pb_sh_windowed_irradiance_coeffs_(max_band, kind, good, coeffs, k);
                    pb_sh_min_over_sphere_(ms, k, mn);
                    if (pb_min3_(mn) >= 0.0 || good > 1e12) break;
                    bad = good;
                    good *= 4.0;
                }
            }
            for (int it = 0; it < 60 && fabs(good - bad) > 1e-6 * fabs(good); it++) {
                const double mid = kind == PB_SH_WINDOW_SINC4 || bad == 0.0 ? 0.5 * (good + bad) : sqrt(good * bad);
                pb_sh_windowed_irradiance_coeffs_(max_band, kind, mid, coeffs, k);
                pb_sh_min_over_sphere_(ms, k, mn);
                if (pb_min3_(mn) >= 0.0)
                    good = mid;
                else
                    bad = mid;
            }
            strength = good;
        }
    }
    if (res == PB_SUCCESS) {
        for (uint32_t l = 0; l <= max_band; l++) {
            const double f = kind == PB_SH_WINDOW_NONE ? 1.0 : pb_sh_window_factor_(kind, strength, l);
            for (uint32_t i = l * l; i < (l + 1) * (l + 1); i++)
                for (int c = 0; c < 3; c++) coeffs[i * 3 + c] *= f;
        }
        if (min_irradiance) {
            pb_sh_windowed_irradiance_coeffs_(max_band, PB_SH_WINDOW_NONE, 0.0, coeffs, k);
            pb_sh_min_over_sphere_(ms, k, min_irradiance);
        }
    }
    if (ms) free(ms->basis);
    free(ms);
    return res;
}
