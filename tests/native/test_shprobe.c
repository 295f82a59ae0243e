/* .shprobe I/O: v1 bytes against DESIGN.md §4's table, v1/v2 round trips for L = 0..4, every
 * rejection case of the reader, atomic writes and grid lookup on cell boundaries.
 * Expected bytes are built here with explicit offsets from the table (not with the writer's code),
 * anchored by literal byte values (magic "SPHR", 1.0f = 00 00 80 3F). */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"
#include "testutil.h"

#include <dirent.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[256];

static void path_in_tmp(char *out, size_t n, const char *name) { snprintf(out, n, "%s/%s", tmpdir, name); }

static uint8_t *read_all(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc((size_t)n + 1);
    *size = fread(b, 1, (size_t)n, f);
    fclose(f);
    return b;
}

static void write_all(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    fwrite(data, 1, size, f);
    fclose(f);
}

/* Independent little-endian encoders for the expected bytes. */
static void le_u32(uint8_t *b, size_t off, uint32_t v)
{
    for (int i = 0; i < 4; i++) b[off + (size_t)i] = (uint8_t)(v >> (8 * i));
}

static void le_f32(uint8_t *b, size_t off, float f)
{
    union {
        float f;
        uint32_t u;
    } c = {f};
    le_u32(b, off, c.u);
}

static void le_i32(uint8_t *b, size_t off, int32_t v) { le_u32(b, off, (uint32_t)v); }

/* Count entries of tmpdir whose name contains ".tmp." (leftover temp files). */
static int count_temp_files(void)
{
    DIR *d = opendir(tmpdir);
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL)
        if (strstr(e->d_name, ".tmp.")) n++;
    if (d) closedir(d);
    return n;
}

/* A small sample file: P probes, band L, 3 x 2 x 2 grid, values derived from indices. */
static pb_shprobe *make_sample(uint32_t probes, uint32_t band, bool positions)
{
    const uint32_t dims[3] = {3, 2, 2};
    pb_shprobe *p = NULL;
    pb_error err = {0};
    if (pb_shprobe_create(probes, band, dims, positions, &p, &err) != PB_SUCCESS) return NULL;
    p->grid_origin[0] = -1.0f;
    p->grid_origin[1] = 0.5f;
    p->grid_origin[2] = 2.0f;
    p->grid_spacing = 0.5f;
    p->default_sh_scale = 1.25f;
    p->default_ambient = 0.1f;
    uint32_t count = pb_sh_count(band);
    for (uint32_t i = 0; i < probes; i++) {
        for (uint32_t k = 0; k < count * 3; k++)
            p->coeffs[(size_t)i * count * 3 + k] = (float)(i + 1) * 0.5f - (float)k * 0.03125f;
        p->probe_scale[i] = 1.0f + 0.25f * (float)i;
        p->probe_ambient[i] = 0.125f * (float)i;
        if (positions)
            for (int k = 0; k < 3; k++) p->positions[3 * i + (uint32_t)k] = (float)i - 0.75f * (float)k;
    }
    for (uint32_t j = 0; j < 12; j++) p->grid[j] = (j % 3 == 2) ? -1 : (int32_t)(j % probes);
    return p;
}

static void test_v1_bytes_match_table(void)
{
    /* Band 1: v1 pads coefficients 4..8 with zeros and reads back as band 2. */
    pb_shprobe *p = make_sample(2, 1, false);
    TU_REQUIRE(p != NULL);
    char path[300];
    path_in_tmp(path, sizeof path, "v1.shprobe");
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_SUCCESS);
    size_t size = 0;
    uint8_t *got = read_all(path, &size);
    TU_REQUIRE(got != NULL);

    /* DESIGN.md §4: 48-byte header, 160 bytes per probe, then X*Y*Z int32. */
    size_t want_size = 48 + 2 * 160 + 12 * 4;
    TU_CHECK_EQ_INT(size, want_size);
    uint8_t *want = calloc(want_size, 1);
    le_u32(want, 0, 0x52485053u);
    le_u32(want, 4, 1);
    le_u32(want, 8, 2);
    le_u32(want, 12, 3);
    le_u32(want, 16, 2);
    le_u32(want, 20, 2);
    le_f32(want, 24, -1.0f);
    le_f32(want, 28, 0.5f);
    le_f32(want, 32, 2.0f);
    le_f32(want, 36, 0.5f);
    le_f32(want, 40, 1.25f);
    le_f32(want, 44, 0.1f);
    for (uint32_t i = 0; i < 2; i++) {
        size_t rec = 48 + 160 * (size_t)i;
        for (uint32_t k = 0; k < 4; k++) /* band 1: 4 coefficients, the rest stay zero */
            for (uint32_t c = 0; c < 3; c++)
                le_f32(want, rec + 16 * k + 4 * c, (float)(i + 1) * 0.5f - (float)(3 * k + c) * 0.03125f);
        le_f32(want, rec + 144, 1.0f + 0.25f * (float)i);
        le_f32(want, rec + 148, 0.125f * (float)i);
    }
    for (uint32_t j = 0; j < 12; j++) le_i32(want, 48 + 320 + 4 * (size_t)j, (j % 3 == 2) ? -1 : (int32_t)(j % 2));
    TU_CHECK(size == want_size && memcmp(got, want, want_size) == 0);
    for (size_t b = 0; b < size && b < want_size; b++)
        if (got[b] != want[b]) {
            TU_CHECK_EQ_INT(got[b], want[b]);
            printf("first differing byte at offset %zu\n", b);
            break;
        }
    /* Literal anchors independent of the encoders above. */
    static const uint8_t magic[4] = {0x53, 0x50, 0x48, 0x52};
    static const uint8_t one_f[4] = {0x00, 0x00, 0x80, 0x3F};
    static const uint8_t minus1[4] = {0xFF, 0xFF, 0xFF, 0xFF};
    TU_CHECK(memcmp(got, magic, 4) == 0);
    TU_CHECK(got[4] == 1 && got[5] == 0 && got[6] == 0 && got[7] == 0);
    TU_CHECK(memcmp(got + 48 + 144, one_f, 4) == 0);      /* probe 0 scale 1.0 */
    TU_CHECK(memcmp(got + 48 + 320 + 8, minus1, 4) == 0); /* grid cell 2 = -1 */

    pb_shprobe *r = NULL;
    TU_CHECK_EQ_INT(pb_shprobe_read(path, &r, &err), PB_SUCCESS);
    if (r) {
        TU_CHECK_EQ_INT(r->version, 1);
        TU_CHECK_EQ_INT(r->max_band, 2);
        TU_CHECK(r->positions == NULL);
        TU_CHECK_EQ_INT(r->coeffs[4 * 3], 0);    /* padded band 2 */
        TU_CHECK_EQ_INT(r->coeffs[27 + 0], 1.0); /* probe 1, coeff 0 red = 2*0.5 */
        TU_CHECK(r->grid_axes[0] == 1 && r->grid_axes[4] == 1 && r->grid_axes[8] == 1);
        TU_CHECK(r->validity[0] == 1.0f && r->validity[1] == 1.0f);
    }
    pb_shprobe_destroy(r);
    free(want);
    free(got);
    pb_shprobe_destroy(p);
}

static void check_equal(const pb_shprobe *a, const pb_shprobe *b, uint32_t band)
{
    TU_CHECK_EQ_INT(b->probe_count, a->probe_count);
    TU_CHECK_EQ_INT(b->max_band, band);
    for (int i = 0; i < 3; i++) {
        TU_CHECK_EQ_INT(b->grid_dims[i], a->grid_dims[i]);
        TU_CHECK(b->grid_origin[i] == a->grid_origin[i]);
    }
    TU_CHECK(b->grid_spacing == a->grid_spacing);
    TU_CHECK(b->default_sh_scale == a->default_sh_scale);
    TU_CHECK(b->default_ambient == a->default_ambient);
    uint32_t ca = pb_sh_count(a->max_band), cb = pb_sh_count(b->max_band);
    bool coeffs_ok = true;
    for (uint32_t i = 0; i < a->probe_count; i++)
        for (uint32_t k = 0; k < cb * 3; k++) {
            float want = k < ca * 3 ? a->coeffs[(size_t)i * ca * 3 + k] : 0.0f;
            if (b->coeffs[(size_t)i * cb * 3 + k] != want) coeffs_ok = false;
        }
    TU_CHECK(coeffs_ok);
    for (uint32_t i = 0; i < a->probe_count; i++) {
        TU_CHECK(b->probe_scale[i] == a->probe_scale[i]);
        TU_CHECK(b->probe_ambient[i] == a->probe_ambient[i]);
        TU_CHECK(b->validity[i] == a->validity[i]);
    }
    TU_CHECK((a->positions == NULL) == (b->positions == NULL));
    if (a->positions && b->positions)
        TU_CHECK(memcmp(a->positions, b->positions, 3 * sizeof(float) * a->probe_count) == 0);
    TU_CHECK(memcmp(a->grid, b->grid, 12 * sizeof(int32_t)) == 0);
}

static void test_round_trips(void)
{
    char path[300];
    path_in_tmp(path, sizeof path, "rt.shprobe");
    for (uint32_t band = 0; band <= 4; band++)
        for (int variant = 0; variant < 3; variant++) {
            /* variant 0: auto version, 1: positions (forces v2), 2: explicit v2 + validity + axes */
            pb_shprobe *p = make_sample(3, band, variant == 1);
            TU_REQUIRE(p != NULL);
            if (variant == 2) {
                p->version = 2;
                p->validity[1] = 0.25f;
                static const float axes[9] = {0, 0, 1, 1, 0, 0, 0, 1, 0};
                memcpy(p->grid_axes, axes, sizeof axes);
            }
            uint32_t want_version = (band <= 2 && variant == 0) ? 1 : 2;
            pb_error err = {0};
            TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_SUCCESS);
            pb_shprobe *r = NULL;
            TU_CHECK_EQ_INT(pb_shprobe_read(path, &r, &err), PB_SUCCESS);
            if (err.code) printf("band %u variant %d: %s\n", band, variant, err.message);
            if (r) {
                TU_CHECK_EQ_INT(r->version, want_version);
                check_equal(p, r, want_version == 1 ? 2 : band);
                TU_CHECK(memcmp(r->grid_axes, p->grid_axes, sizeof p->grid_axes) == 0);
                /* v2 size: 96 + P*(C+1)*16 (+ P*16 positions) + cells*4 (docs/shprobe-format.md). */
                size_t size = 0;
                uint8_t *bytes = read_all(path, &size);
                size_t want = want_version == 1
                                  ? 48 + 3 * 160 + 48
                                  : 96 + 3 * (pb_sh_count(band) + 1) * 16 + (variant == 1 ? 3 * 16 : 0) + 48;
                TU_CHECK_EQ_INT(size, want);
                pb_shprobe hdr;
                TU_CHECK_EQ_INT(pb_shprobe_read_header(path, &hdr, &err), PB_SUCCESS);
                TU_CHECK_EQ_INT(hdr.version, want_version);
                TU_CHECK_EQ_INT(hdr.probe_count, 3);
                TU_CHECK_EQ_INT(hdr.max_band, r->max_band);
                TU_CHECK(hdr.coeffs == NULL && hdr.grid == NULL && hdr.positions == NULL);
                TU_CHECK(hdr.grid_spacing == 0.5f && hdr.default_sh_scale == 1.25f);
                /* Memory reader agrees with the file reader. */
                pb_shprobe *m = NULL;
                TU_CHECK_EQ_INT(pb_shprobe_read_memory(bytes, size, &m, &err), PB_SUCCESS);
                if (m) check_equal(r, m, r->max_band);
                pb_shprobe_destroy(m);
                free(bytes);
            }
            pb_shprobe_destroy(r);
            pb_shprobe_destroy(p);
        }
}

static void test_write_rejects(void)
{
    char path[300];
    path_in_tmp(path, sizeof path, "bad.shprobe");
    pb_error err = {0};
    pb_shprobe *p = make_sample(2, 3, false);
    TU_REQUIRE(p != NULL);
    p->version = 1;
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "version 1 cannot hold max band > 2");
    pb_shprobe_destroy(p);

    struct {
        const char *what;
        int field;
        pb_result code;
        const char *needle;
    } cases[] = {
        {"spacing 0", 0, PB_ERROR_INVALID_ARGUMENT, "grid spacing is 0 (offset 36)"},
        {"NaN coeff", 1, PB_ERROR_NON_FINITE, "probe 1 coefficient 2 green is nan"},
        {"grid entry = count", 2, PB_ERROR_INVALID_ARGUMENT, "grid cell (1, 1, 0) holds 2"},
        {"grid entry -2", 3, PB_ERROR_INVALID_ARGUMENT, "holds -2"},
        {"version 7", 4, PB_ERROR_INVALID_ARGUMENT, "unknown version 7"},
        {"Inf ambient", 5, PB_ERROR_NON_FINITE, "probe 0 ambient is inf"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        p = make_sample(2, 2, false);
        TU_REQUIRE(p != NULL);
        switch (cases[c].field) {
        case 0: p->grid_spacing = 0; break;
        case 1: p->coeffs[27 + 2 * 3 + 1] = NAN; break;
        case 2: p->grid[4] = 2; break;
        case 3: p->grid[0] = -2; break;
        case 4: p->version = 7; break;
        case 5: p->probe_ambient[0] = INFINITY; break;
        }
        memset(&err, 0, sizeof err);
        TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), cases[c].code);
        TU_CHECK_CONTAINS(err.message, cases[c].needle);
        TU_CHECK_CONTAINS(err.message, path);
        TU_CHECK(access(path, F_OK) != 0); /* nothing written */
        pb_shprobe_destroy(p);
    }
    TU_CHECK_EQ_INT(count_temp_files(), 0);

    /* create: band, dims and overflow */
    const uint32_t zero_dims[3] = {2, 0, 2}, huge[3] = {0xFFFFFFFFu, 0xFFFFFFFFu, 0xFFFFFFFFu};
    const uint32_t ok_dims[3] = {1, 1, 1};
    pb_shprobe *q = NULL;
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_create(1, 5, ok_dims, false, &q, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "max band 5");
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_create(1, 2, zero_dims, false, &q, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "grid dim Y is 0");
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_create(1, 2, huge, false, &q, &err), PB_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(err.message, "overflow");
    TU_CHECK(q == NULL);
}

/* Reader rejections: each case patches a valid v1 or v2 image and expects code + message. */
typedef struct reject_case {
    int version;    /* which base image */
    size_t offset;  /* byte offset to patch (SIZE_MAX = none) */
    uint32_t value; /* u32 written there */
    long resize;    /* bytes added to (or removed from) the end */
    pb_result code;
    const char *needle;
} reject_case;

static void test_read_rejects(void)
{
    pb_shprobe *p1 = make_sample(2, 2, false), *p2 = make_sample(2, 3, true);
    TU_REQUIRE(p1 && p2);
    char path1[300], path2[300];
    path_in_tmp(path1, sizeof path1, "base1.shprobe");
    path_in_tmp(path2, sizeof path2, "base2.shprobe");
    pb_error err = {0};
    TU_REQUIRE(pb_shprobe_write(path1, p1, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_shprobe_write(path2, p2, &err) == PB_SUCCESS);
    size_t n1, n2;
    uint8_t *b1 = read_all(path1, &n1), *b2 = read_all(path2, &n2);
    TU_REQUIRE(b1 && b2 && n1 == 48 + 320 + 48 && n2 == 96 + 2 * 17 * 16 + 32 + 48);
    const uint32_t nan_bits = 0x7FC00000u, inf_bits = 0x7F800000u, two_bits = 0x40000000u;
    const uint32_t neg_half = 0xBF000000u;
    /* v1 offsets: records at 48 (160 each), grid at 368. v2 (band 3, positions): records at 96
     * (17*16 = 272 each), positions at 640, grid at 672. */
    const reject_case cases[] = {
        {1, SIZE_MAX, 0, -(long)n1, PB_ERROR_FORMAT, "truncated: 0 bytes, the magic at offset 0"},
        {1, SIZE_MAX, 0, 3 - (long)n1, PB_ERROR_FORMAT, "truncated: 3 bytes"},
        {1, 0, 0x52504853u, 0, PB_ERROR_FORMAT, "not a .shprobe file (bad magic: it does not start with \"SPHR\""},
        {1, SIZE_MAX, 0, 6 - (long)n1, PB_ERROR_FORMAT, "the version at offset 4"},
        {1, 4, 5, 0, PB_ERROR_FORMAT, "unknown version 5 at offset 4; this reader knows versions 1, 2, 3 and 4"},
        {1, 4, 0, 0, PB_ERROR_FORMAT, "unknown version 0 at offset 4"},
        {1, SIZE_MAX, 0, 47 - (long)n1, PB_ERROR_FORMAT, "the version 1 header needs 48"},
        {1, SIZE_MAX, 0, -1, PB_ERROR_FORMAT, "truncated: 415 bytes, but 2 probes"},
        {1, SIZE_MAX, 0, 1, PB_ERROR_FORMAT, "1 bytes of trailing data after the grid, which ends at offset 416"},
        {1, 8, 0xFFFFFFFFu, 0, PB_ERROR_TOO_LARGE, "probe count 4294967295 (offset 8) is above the limit of 16777216"},
        {1, 8, (1u << 24) + 1u, 0, PB_ERROR_TOO_LARGE, "probe count 16777217 (offset 8) is above the limit"},
        {1, 8, 1u << 24, 0, PB_ERROR_FORMAT, "truncated: 416 bytes, but 16777216 probes"}, /* at the limit */
        {1, 12, 0xFFFFFFFFu, 0, PB_ERROR_TOO_LARGE, "grid 4294967295 x 2 x 2 = 17179869180 cells (offset 12) is above"},
        {1, 12, 1u << 26, 0, PB_ERROR_FORMAT, "truncated"}, /* 2^26 x 2 x 2 = 2^28 cells: at the limit */
        {1, 12, (1u << 26) + 1u, 0, PB_ERROR_TOO_LARGE, "268435460 cells (offset 12) is above the limit of 268435456"},
        {1, 16, 0, 0, PB_ERROR_FORMAT, "grid dim Y at offset 16 is 0"},
        {1, 24, nan_bits, 0, PB_ERROR_NON_FINITE, "grid origin[0] is nan (offset 24)"},
        {1, 36, inf_bits, 0, PB_ERROR_NON_FINITE, "grid spacing is inf (offset 36)"},
        {1, 36, 0, 0, PB_ERROR_FORMAT, "grid spacing is 0 (offset 36); it must be > 0"},
        {1, 36, neg_half, 0, PB_ERROR_FORMAT, "grid spacing is -0.5 (offset 36)"},
        {1, 40, nan_bits, 0, PB_ERROR_NON_FINITE, "default SH scale is nan (offset 40)"},
        {1, 44, inf_bits, 0, PB_ERROR_NON_FINITE, "default ambient is inf (offset 44)"},
        {1, 48 + 160 + 16 * 8 + 8, nan_bits, 0, PB_ERROR_NON_FINITE, "probe 1 coefficient 8 blue is nan (offset 344)"},
        {1, 48 + 144, inf_bits, 0, PB_ERROR_NON_FINITE, "probe 0 scale is inf (offset 192)"},
        {1, 48 + 160 + 148, nan_bits, 0, PB_ERROR_NON_FINITE, "probe 1 ambient is nan (offset 356)"},
        {1, 368 + 4 * 5, 2, 0, PB_ERROR_FORMAT, "grid cell (2, 1, 0) holds 2 (offset 388)"},
        {1, 368 + 4 * 11, 0xFFFFFFFEu, 0, PB_ERROR_FORMAT, "grid cell (2, 1, 1) holds -2 (offset 412)"},
        {1, 368, 0x7FFFFFFFu, 0, PB_ERROR_FORMAT, "holds 2147483647"},
        {2, 12, 5, 0, PB_ERROR_FORMAT, "max band 5 at offset 12 is out of range 0..4"},
        {2, 16, 3, 0, PB_ERROR_FORMAT, "unknown flags 0x3 at offset 16"},
        {2, 16, 0, 0, PB_ERROR_FORMAT, "trailing data"}, /* positions flag cleared */
        {2, 52, 0x3F800000u, 0, PB_ERROR_FORMAT, "grid axes are not orthonormal: axis 0 . axis 0 = 2"},
        {2, 48, nan_bits, 0, PB_ERROR_NON_FINITE, "grid axes[0] is nan (offset 48)"},
        {2, 48, 0, 0, PB_ERROR_FORMAT, "grid axes are not orthonormal"},
        {2, 44, 0, 0, PB_ERROR_FORMAT, "grid spacing is 0 (offset 44)"},
        {2, 96 + 272 + 16 * 15 + 4, inf_bits, 0, PB_ERROR_NON_FINITE,
         "probe 1 coefficient 15 green is inf (offset 612)"},
        {2, 96 + 16 * 16 + 8, two_bits, 0, PB_ERROR_FORMAT, "probe 0 validity is 2 (offset 360); it must be in [0, 1]"},
        {2, 96 + 16 * 16 + 8, nan_bits, 0, PB_ERROR_NON_FINITE, "probe 0 validity is nan"},
        {2, 640 + 16 + 8, inf_bits, 0, PB_ERROR_NON_FINITE, "probe 1 position[2] is inf (offset 664)"},
        {2, 672 + 4, 7, 0, PB_ERROR_FORMAT, "grid cell (1, 0, 0) holds 7 (offset 676)"},
        {2, SIZE_MAX, 0, -4, PB_ERROR_FORMAT, "truncated"},
        {2, SIZE_MAX, 0, 95 - (long)n2, PB_ERROR_FORMAT, "the version 2 header needs 96"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        const reject_case *k = &cases[c];
        const uint8_t *base = k->version == 1 ? b1 : b2;
        size_t n = k->version == 1 ? n1 : n2;
        size_t size = (size_t)((long)n + k->resize);
        uint8_t *buf = calloc(size + 1, 1);
        memcpy(buf, base, size < n ? size : n);
        if (k->offset != SIZE_MAX) le_u32(buf, k->offset, k->value);
        pb_shprobe *out = (pb_shprobe *)(uintptr_t)1;
        memset(&err, 0, sizeof err);
        pb_result r = pb_shprobe_read_memory(buf, size, &out, &err);
        TU_CHECK_EQ_INT(r, k->code);
        TU_CHECK_CONTAINS(err.message, k->needle);
        TU_CHECK(out == NULL);
        if (r != k->code || !strstr(err.message, k->needle)) printf("case %zu: %s\n", c, err.message);
        free(buf);
    }
    /* Size products: X*Y*Z = 2^93 overflows 64 bits; X*Y*Z = 2^63 fits but 4 bytes per cell do not. */
    for (int big_z = 0; big_z < 2; big_z++) {
        uint8_t *buf = malloc(n1);
        memcpy(buf, b1, n1);
        le_u32(buf, 12, 0x80000000u);
        le_u32(buf, 16, 0x80000000u);
        if (big_z) le_u32(buf, 20, 0x80000000u);
        pb_shprobe *out = NULL;
        memset(&err, 0, sizeof err);
        TU_CHECK_EQ_INT(pb_shprobe_read_memory(buf, n1, &out, &err), big_z ? PB_ERROR_FORMAT : PB_ERROR_TOO_LARGE);
        TU_CHECK_CONTAINS(err.message, big_z ? "grid dims 2147483648 x 2147483648 x 2147483648 overflow"
                                             : "grid 2147483648 x 2147483648 x 2 = 9223372036854775808 cells");
        TU_CHECK(out == NULL);
        free(buf);
    }
    /* The file readers put the path in front, and read_header checks the size against the file. */
    char trunc[300];
    path_in_tmp(trunc, sizeof trunc, "trunc.shprobe");
    write_all(trunc, b2, n2 - 1);
    pb_shprobe hdr, *out = NULL;
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_read_header(trunc, &hdr, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, trunc);
    TU_CHECK_CONTAINS(err.message, "truncated");
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_read(trunc, &out, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "trunc.shprobe: truncated");
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_read(tmpdir, &out, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, "not a regular file");
    char missing[300];
    path_in_tmp(missing, sizeof missing, "missing.shprobe");
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_read(missing, &out, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, "missing.shprobe: cannot open");
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_read_header(missing, &hdr, &err), PB_ERROR_IO);
    unlink(trunc);
    free(b1);
    free(b2);
    pb_shprobe_destroy(p1);
    pb_shprobe_destroy(p2);
}

static void test_atomic_write(void)
{
    char path[300];
    path_in_tmp(path, sizeof path, "atomic.shprobe");
    pb_error err = {0};
    pb_shprobe *p = make_sample(2, 2, false);
    TU_REQUIRE(p != NULL);
    TU_REQUIRE(pb_shprobe_write(path, p, &err) == PB_SUCCESS);
    size_t n0, n1;
    uint8_t *before = read_all(path, &n0);

    /* 1. Invalid data: refused before anything is written; the old file is untouched. */
    p->coeffs[0] = NAN;
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_ERROR_NON_FINITE);
    p->coeffs[0] = 7.0f;
    /* 2. The target is a non-empty directory: refused before a temp file is made (issue 14). */
    char dir_target[300], inner[320];
    path_in_tmp(dir_target, sizeof dir_target, "occupied");
    mkdir(dir_target, 0755);
    snprintf(inner, sizeof inner, "%s/keep", dir_target);
    write_all(inner, "x", 1);
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_write(dir_target, p, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "occupied: it exists and is a directory, not a .shprobe file");
    TU_CHECK_EQ_INT(count_temp_files(), 0);
    /* 3. The folder does not exist: no temp file can be created. */
    char bad[300];
    path_in_tmp(bad, sizeof bad, "no/such/dir/x.shprobe");
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_write(bad, p, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, "cannot create a temporary file next to it");
    /* 4. A read-only folder (skipped as root, who may write anyway). */
    if (geteuid() != 0) {
        char ro[300], ro_file[320];
        path_in_tmp(ro, sizeof ro, "readonly");
        mkdir(ro, 0755);
        snprintf(ro_file, sizeof ro_file, "%s/x.shprobe", ro);
        chmod(ro, 0555);
        memset(&err, 0, sizeof err);
        TU_CHECK_EQ_INT(pb_shprobe_write(ro_file, p, &err), PB_ERROR_IO);
        TU_CHECK_CONTAINS(err.message, "Permission denied");
        chmod(ro, 0755);
        rmdir(ro);
    }
    uint8_t *after = read_all(path, &n1);
    TU_CHECK(n0 == n1 && memcmp(before, after, n0) == 0);
    TU_CHECK_EQ_INT(count_temp_files(), 0);
    struct stat st;
    TU_CHECK(stat(path, &st) == 0 && (st.st_mode & 0777) == 0644);
    unlink(inner);
    rmdir(dir_target);
    free(before);
    free(after);
    pb_shprobe_destroy(p);
}

static void test_lookup(void)
{
    /* Grid 3 x 2 x 2, origin (-1, 0.5, 2), spacing 0.5: cell (x,y,z) spans
     * [-1 + 0.5x, -0.5 + 0.5x) x [0.5 + 0.5y, 1 + 0.5y) x [2 + 0.5z, 2.5 + 0.5z). */
    pb_shprobe *p = make_sample(2, 2, false);
    TU_REQUIRE(p != NULL);
    for (int j = 0; j < 12; j++) p->grid[j] = (j == 7) ? -1 : (int32_t)(j % 2);
    const struct {
        float x, y, z;
        int32_t want;
    } pts[] = {
        {-1.0f, 0.5f, 2.0f, 0},                                         /* min corner belongs to cell 0 */
        {-0.5f, 0.5f, 2.0f, 1},                                         /* face x = -0.5 belongs to cell x=1 (flat 1) */
        {-0.50001f, 0.5f, 2.0f, 0},  {0.49999f, 1.49999f, 2.99999f, 1}, /* last cell (2,1,1), flat 11 */
        {0.5f, 1.0f, 2.5f, -1},                                         /* max face x = 0.5 is outside */
        {0.0f, 1.5f, 2.5f, -1},                                         /* max face y */
        {0.0f, 1.0f, 3.0f, -1},                                         /* max face z */
        {-1.00001f, 0.7f, 2.2f, -1},                                    /* just below the min corner */
        {-0.25f, 1.25f, 2.25f, 0},                                      /* cell (1,1,0): flat 1 + 3 = 4 -> 4 % 2 = 0 */
        {0.25f, 0.75f, 2.75f, 0},                                       /* cell (2,0,1): flat 2 + 6 = 8 -> 0 */
        {-0.75f, 0.75f, 2.75f, 0},                                      /* cell (0,0,1): flat 6 -> 0 */
        {-0.25f, 0.75f, 2.75f, -1},                                     /* cell (1,0,1): flat 7 is empty */
        {NAN, 1.0f, 2.2f, -1},       {INFINITY, 1.0f, 2.2f, -1},
    };
    float pt[3];
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; i++) {
        pt[0] = pts[i].x;
        pt[1] = pts[i].y;
        pt[2] = pts[i].z;
        int32_t want = pts[i].want;
        int32_t got = pb_shprobe_lookup(p, pt);
        if (got != want) printf("point %zu\n", i);
        TU_CHECK_EQ_INT(got, want);
    }
    /* Rotated axes: grid X along engine +Z, grid Y along engine +X, grid Z along engine +Y.
     * Point origin + (0.25 engine x, 0.75 engine y, 1.25 engine z) -> grid (2, 0, 1), flat 8. */
    static const float axes[9] = {0, 0, 1, 1, 0, 0, 0, 1, 0};
    memcpy(p->grid_axes, axes, sizeof axes);
    p->grid[8] = 1;
    pt[0] = -1.0f + 0.25f;
    pt[1] = 0.5f + 0.75f;
    pt[2] = 2.0f + 1.25f;
    TU_CHECK_EQ_INT(pb_shprobe_lookup(p, pt), 1);
    pt[2] = 2.0f + 1.5f; /* grid x = 3 = dims: outside */
    TU_CHECK_EQ_INT(pb_shprobe_lookup(p, pt), -1);
    TU_CHECK_EQ_INT(pb_shprobe_lookup(NULL, pt), -1);
    pb_shprobe_destroy(p);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/schnee_shprobe_XXXXXX");
    if (!mkdtemp(tmpdir)) return 2;
    TU_RUN(test_v1_bytes_match_table);
    TU_RUN(test_round_trips);
    TU_RUN(test_write_rejects);
    TU_RUN(test_read_rejects);
    TU_RUN(test_atomic_write);
    TU_RUN(test_lookup);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    return TU_EXIT();
}
