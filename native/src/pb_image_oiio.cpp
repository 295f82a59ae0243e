// Float image I/O through OpenImageIO: the only C++ in the bake core, behind extern "C".
// No exception crosses the C boundary: every entry point catches and reports.
#include "schnee/pb_image.h"

#include "pb_file.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <string>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace
{

std::string lower_extension(const std::string &path)
{
    const size_t slash = path.find_last_of('/');
    const size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return std::string();
    std::string ext = path.substr(dot);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return (char)std::tolower(c); });
    return ext;
}

// Formats whose pixels we keep as 32-bit float; everything else is written as 8-bit.
bool is_float_format(const std::string &ext)
{
    return ext == ".exr" || ext == ".hdr" || ext == ".pfm" || ext == ".tif" || ext == ".tiff";
}

// The reader for a file, by content first (its magic bytes), else by extension. OpenImageIO's own
// fallback (when the extension's reader fails, try every reader in turn) is never used: on a large
// file some readers scan it whole (a 2 GB sparse file took minutes), and content decides anyway.
struct format_magic {
    const char *format;
    unsigned char bytes[4];
    size_t n;
};
const format_magic known_magics[] = {
    {"openexr", {0x76, 0x2f, 0x31, 0x01}, 4}, {"png", {0x89, 'P', 'N', 'G'}, 4},   {"jpeg", {0xff, 0xd8, 0xff, 0}, 3},
    {"tiff", {'I', 'I', 0x2a, 0x00}, 4},      {"tiff", {'M', 'M', 0x00, 0x2a}, 4}, {"hdr", {'#', '?', 0, 0}, 2},
    {"pnm", {'P', 'F', '\n', 0}, 3},          {"pnm", {'P', 'f', '\n', 0}, 3},
};

std::string format_for(const std::string &path, const unsigned char *head, size_t got)
{
    for (const format_magic &m : known_magics)
        if (got >= m.n && std::memcmp(head, m.bytes, m.n) == 0) return m.format;
    const std::string ext = lower_extension(path);
    return ext.empty() ? std::string() : ext.substr(1);
}

// The documented size limits (pb_image.h), checked before any pixel is allocated or read.
pb_result check_limits(const char *path, uint64_t w, uint64_t h, uint64_t c, pb_error *err)
{
    // Each factor is bounded before a product that could overflow is formed.
    if (w > PB_IMAGE_MAX_DIM || h > PB_IMAGE_MAX_DIM || c > PB_IMAGE_MAX_CHANNELS || w * h * c > PB_IMAGE_MAX_VALUES ||
        w * h * c > std::numeric_limits<size_t>::max() / sizeof(float))
        return pb_error_set(err, PB_ERROR_TOO_LARGE,
                            "image '%s' is too large: %llux%llu with %llu channel(s); the limits are %u pixels per "
                            "side, %u channels and %llu values (width x height x channels)",
                            path, (unsigned long long)w, (unsigned long long)h, (unsigned long long)c, PB_IMAGE_MAX_DIM,
                            PB_IMAGE_MAX_CHANNELS, (unsigned long long)PB_IMAGE_MAX_VALUES);
    return PB_SUCCESS;
}

// The size a PFM header ("PF" or "Pf", width, height, scale, whitespace-separated) claims, if the
// first bytes hold one: checked against the limits before OpenImageIO sees the file, because
// OpenImageIO 2.5 and later refuse PNM sides above 65535 themselves, with a different error.
bool pfm_header_size(const unsigned char *head, size_t got, uint64_t *w, uint64_t *h, uint64_t *c)
{
    if (got < 3 || head[0] != 'P' || (head[1] != 'F' && head[1] != 'f')) return false;
    *c = head[1] == 'F' ? 3 : 1;
    uint64_t dims[2] = {0, 0};
    size_t i = 2;
    for (uint64_t &d : dims) {
        const size_t start = i;
        while (i < got && std::isspace(head[i])) i++;
        if (i == start || i >= got || !std::isdigit(head[i])) return false;
        for (; i < got && std::isdigit(head[i]); i++) {
            if (d > (uint64_t)1 << 40) return false;
            d = d * 10 + (uint64_t)(head[i] - '0');
        }
        if (i >= got || !std::isspace(head[i])) return false;
    }
    *w = dims[0];
    *h = dims[1];
    return true;
}

// The bytes of an image, a file (read with pread through a checked descriptor) or a buffer in
// memory: the header walks below read through it, so both readers apply the same checks.
struct byte_source {
    int fd = -1;                        // the file, or -1 for memory
    const unsigned char *mem = nullptr; // the buffer when fd < 0
    uint64_t size = 0;                  // bytes in the file or buffer

    // Reads n bytes at offset off, or fewer only at the end; EINTR is retried.
    bool read(uint64_t off, unsigned char *buf, size_t n, size_t *got) const
    {
        *got = 0;
        if (fd < 0) {
            if (off < size) *got = (size_t)std::min<uint64_t>(n, size - off);
            if (*got) std::memcpy(buf, mem + off, *got);
            return true;
        }
        while (*got < n) {
            const ssize_t r = pread(fd, buf + *got, n - *got, (off_t)(off + *got));
            if (r < 0 && errno == EINTR) continue;
            if (r < 0) return false;
            if (r == 0) break;
            *got += (size_t)r;
        }
        return true;
    }
};

uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

// Whether an attribute's declared size is the size OpenEXR will read for its type: OpenEXR reads
// a known fixed-size type's own size whatever the declared one says, a channel list up to its
// terminating empty name, a string vector by its inner lengths, a preview by its width x height;
// a declared size that disagrees would make OpenEXR read the rest of the header somewhere else than
// this walk does (a fuzzer file did exactly that to reach a 1.6 GB "attribute"). nullptr when it
// agrees, else the reason.
const char *exr_attribute_mismatch(const byte_source &src, const char *type, uint64_t at, uint64_t size,
                                   size_t max_name)
{
    static const struct {
        const char *type;
        uint64_t size;
    } fixed[] = {{"box2i", 16},
                 {"box2f", 16},
                 {"v2i", 8},
                 {"v2f", 8},
                 {"v2d", 16},
                 {"v3i", 12},
                 {"v3f", 12},
                 {"v3d", 24},
                 {"m33f", 36},
                 {"m33d", 72},
                 {"m44f", 64},
                 {"m44d", 128},
                 {"int", 4},
                 {"float", 4},
                 {"double", 8},
                 {"compression", 1},
                 {"lineOrder", 1},
                 {"envmap", 1},
                 {"tiledesc", 9},
                 {"rational", 8},
                 {"timecode", 8},
                 {"keycode", 28},
                 {"chromaticities", 32},
                 {"deepImageState", 1}};
    for (const auto &f : fixed)
        if (std::strcmp(type, f.type) == 0) return size == f.size ? nullptr : "its size is not its type's size";
    if (std::strcmp(type, "idmanifest") == 0) return "ID manifests are not read";
    if (std::strcmp(type, "floatvector") == 0) return size % 4 == 0 ? nullptr : "its size is not a multiple of 4";
    const bool chlist = std::strcmp(type, "chlist") == 0, strings = std::strcmp(type, "stringvector") == 0,
               preview = std::strcmp(type, "preview") == 0;
    if (!chlist && !strings && !preview) return nullptr; // read as exactly `size` bytes
    if (size > (1u << 20) && !preview) return "its value is larger than 1 MiB";
    std::string v((size_t)(preview ? std::min<uint64_t>(size, 8) : size), '\0');
    size_t got = 0;
    if (!src.read(at, (unsigned char *)&v[0], v.size(), &got) || got != v.size()) return "it is truncated";
    const unsigned char *b = (const unsigned char *)v.data();
    if (preview) {
        if (size < 8) return "its preview has no size";
        return size == 8 + 4 * (uint64_t)le32(b) * le32(b + 4) ? nullptr : "its preview's size disagrees";
    }
    size_t i = 0;
    while (i < v.size()) {
        if (chlist) {
            const void *z = std::memchr(b + i, 0, std::min(v.size() - i, max_name));
            if (!z) return "a channel name is not terminated";
            const size_t n = (size_t)((const unsigned char *)z - (b + i));
            if (n == 0) return i + 1 == v.size() ? nullptr : "its channel list ends before its size";
            i += n + 1 + 16;
        } else {
            if (v.size() - i < 4) return "a string is truncated";
            const uint64_t n = le32(b + i);
            if (n > v.size() - i - 4) return "a string is longer than the attribute";
            i += 4 + (size_t)n;
        }
    }
    return chlist ? "its channel list is not terminated" : (i == v.size() ? nullptr : "its strings overrun it");
}

// The OpenEXR header structure (every part's attributes), walked before OpenEXR sees the file.
// OpenEXR allocates each attribute's announced size before reading it (an 840-byte file announcing
// a 270 MB attribute made the sky fuzzer run out of memory), and sizes its chunk offset tables from
// the dataWindow and tiles; so: every attribute must fit in the file, every part's dataWindow and
// tile size must be within the limits, and the offset tables those announce (8 bytes per chunk,
// stored in the file) must fit in the file too. Layout: magic, version (flags 0x200 tiled, 0x400
// long names, 0x800 non-image / deep, 0x1000 multi-part), then headers of attributes
// (name\0 type\0 int32 size, value) each ended by an empty name; multi-part files end the list of
// headers with an empty header.
pb_result exr_check_header(const byte_source &src, const char *path, pb_error *err)
{
    const uint64_t size = src.size;
    const uint64_t max_attributes = 1u << 16;
    unsigned char v[8];
    size_t got = 0;
    if (!src.read(0, v, sizeof v, &got)) return pb_error_set(err, PB_ERROR_IO, "%s: cannot read", path);
    if (got < sizeof v) return pb_error_set(err, PB_ERROR_FORMAT, "%s: truncated OpenEXR header", path);
    const uint32_t flags = (uint32_t)v[5] << 8 | (uint32_t)v[6] << 16 | (uint32_t)v[7] << 24;
    if (v[4] != 2)
        return pb_error_set(err, PB_ERROR_FORMAT, "%s: OpenEXR file version %u is not supported (only 2)", path,
                            (unsigned)v[4]);
    if (flags & 0x800)
        return pb_error_set(err, PB_ERROR_FORMAT, "image '%s' is a deep image; flat pixels are required", path);
    const bool multipart = (flags & 0x1000) != 0;
    const size_t max_name = (flags & 0x400) ? 256 : 32; // including the terminating zero
    uint64_t off = 8, attributes = 0, chunks_total = 0;
    for (int part = 0;; part++) {
        int64_t dw[4] = {0, 0, -1, -1};
        uint64_t tile_x = 0, tile_y = 0;
        bool have_dw = false, empty = true;
        for (;;) {
            // name\0 type\0 size: at most 2 * max_name + 4 bytes.
            unsigned char buf[2 * 256 + 4];
            if (!src.read(off, buf, 2 * max_name + 4, &got))
                return pb_error_set(err, PB_ERROR_IO, "%s: cannot read", path);
            if (got == 0) return pb_error_set(err, PB_ERROR_FORMAT, "%s: truncated OpenEXR header", path);
            if (buf[0] == 0) { // end of this header
                off += 1;
                break;
            }
            empty = false;
            if (++attributes > max_attributes)
                return pb_error_set(err, PB_ERROR_FORMAT, "%s: more than %llu OpenEXR header attributes", path,
                                    (unsigned long long)max_attributes);
            const unsigned char *name_end = (const unsigned char *)std::memchr(buf, 0, std::min(got, max_name));
            if (!name_end) return pb_error_set(err, PB_ERROR_FORMAT, "%s: malformed OpenEXR attribute name", path);
            const size_t type_at = (size_t)(name_end - buf) + 1;
            const unsigned char *type_end =
                type_at < got ? (const unsigned char *)std::memchr(buf + type_at, 0, std::min(got - type_at, max_name))
                              : nullptr;
            if (!type_end) return pb_error_set(err, PB_ERROR_FORMAT, "%s: malformed OpenEXR attribute type", path);
            const size_t size_at = (size_t)(type_end - buf) + 1;
            if (size_at + 4 > got) return pb_error_set(err, PB_ERROR_FORMAT, "%s: truncated OpenEXR header", path);
            const int32_t asize = (int32_t)((uint32_t)buf[size_at] | (uint32_t)buf[size_at + 1] << 8 |
                                            (uint32_t)buf[size_at + 2] << 16 | (uint32_t)buf[size_at + 3] << 24);
            const uint64_t value_at = off + size_at + 4;
            if (asize < 0 || value_at + (uint64_t)asize > size)
                return pb_error_set(err, PB_ERROR_FORMAT,
                                    "%s: OpenEXR attribute at offset %llu announces %lld bytes, past the end of the "
                                    "%llu-byte file",
                                    path, (unsigned long long)off, (long long)asize, (unsigned long long)size);
            const char *name = (const char *)buf;
            const char *type = (const char *)buf + type_at;
            if (const char *why = exr_attribute_mismatch(src, type, value_at, (uint64_t)asize, max_name))
                return pb_error_set(err, PB_ERROR_FORMAT,
                                    "%s: OpenEXR attribute at offset %llu (type %.32s, %lld bytes) is malformed: %s",
                                    path, (unsigned long long)off, type, (long long)asize, why);
            unsigned char value[16];
            if ((std::strcmp(name, "dataWindow") == 0 && std::strcmp(type, "box2i") == 0 && asize == 16) ||
                (std::strcmp(name, "tiles") == 0 && std::strcmp(type, "tiledesc") == 0 && asize == 9)) {
                if (!src.read(value_at, value, (size_t)asize, &got) || got != (size_t)asize)
                    return pb_error_set(err, PB_ERROR_IO, "%s: cannot read", path);
                int32_t f[4] = {0, 0, 0, 0};
                for (int i = 0; i < 4 && 4 * i + 4 <= asize; i++) f[i] = (int32_t)le32(value + 4 * i);
                if (asize == 16) {
                    for (int i = 0; i < 4; i++) dw[i] = f[i];
                    have_dw = true;
                } else {
                    tile_x = (uint32_t)f[0];
                    tile_y = (uint32_t)f[1];
                }
            }
            off = value_at + (uint64_t)asize;
        }
        if (multipart && empty) break; // the empty header that ends a multi-part file's list
        if (!have_dw) return pb_error_set(err, PB_ERROR_FORMAT, "%s: OpenEXR part %d has no dataWindow", path, part);
        const int64_t w = dw[2] - dw[0] + 1, h = dw[3] - dw[1] + 1;
        if (w <= 0 || h <= 0)
            return pb_error_set(err, PB_ERROR_FORMAT, "%s: OpenEXR part %d has an empty dataWindow", path, part);
        pb_result r = check_limits(path, (uint64_t)w, (uint64_t)h, 1, err);
        if (r != PB_SUCCESS) return r;
        // The level-0 chunk count (a lower bound of the offset table; scan-line chunks hold at most
        // 256 lines, DWAB's maximum). Mip/rip levels only add chunks.
        uint64_t chunks = ((uint64_t)h + 255) / 256;
        if ((flags & 0x200) || tile_x || tile_y) {
            if (tile_x == 0 || tile_y == 0 || tile_x > PB_IMAGE_MAX_DIM || tile_y > PB_IMAGE_MAX_DIM)
                return pb_error_set(err, PB_ERROR_FORMAT, "%s: OpenEXR part %d has tiles of %llux%llu pixels", path,
                                    part, (unsigned long long)tile_x, (unsigned long long)tile_y);
            chunks = (((uint64_t)w + tile_x - 1) / tile_x) * (((uint64_t)h + tile_y - 1) / tile_y);
        }
        chunks_total += chunks;
        if (chunks_total * 8 > size)
            return pb_error_set(err, PB_ERROR_FORMAT,
                                "%s: the OpenEXR header announces at least %llu chunks, whose offset table alone "
                                "is larger than the %llu-byte file",
                                path, (unsigned long long)chunks_total, (unsigned long long)size);
        if (!multipart) break;
    }
    return PB_SUCCESS;
}

// The PNG chunk list (length, type, data, CRC), walked before libpng sees it: libpng allocates a
// chunk's announced length before reading it (a 619-byte file announcing a 1.9 GB tEXt chunk made
// the sky fuzzer run out of memory), so every chunk must fit in the file.
pb_result png_check_chunks(const byte_source &src, const char *path, pb_error *err)
{
    const uint64_t size = src.size;
    uint64_t off = 8;
    for (uint32_t n = 0; off < size; n++) {
        unsigned char h[8];
        size_t got = 0;
        if (n >= (1u << 20)) return pb_error_set(err, PB_ERROR_FORMAT, "%s: more than %u PNG chunks", path, 1u << 20);
        if (!src.read(off, h, sizeof h, &got)) return pb_error_set(err, PB_ERROR_IO, "%s: cannot read", path);
        if (got < sizeof h) return pb_error_set(err, PB_ERROR_FORMAT, "%s: truncated PNG chunk", path);
        const uint64_t len = (uint64_t)h[0] << 24 | (uint64_t)h[1] << 16 | (uint64_t)h[2] << 8 | h[3];
        if (len > 0x7fffffffu || off + 12 + len > size)
            return pb_error_set(err, PB_ERROR_FORMAT,
                                "%s: PNG chunk at offset %llu announces %llu bytes, past the end of the %llu-byte "
                                "file",
                                path, (unsigned long long)off, (unsigned long long)len, (unsigned long long)size);
        if (std::memcmp(h + 4, "IEND", 4) == 0) return PB_SUCCESS;
        off += 12 + len;
    }
    return pb_error_set(err, PB_ERROR_FORMAT, "%s: PNG file without an IEND chunk", path);
}

// Closes the descriptor (and the FILE wrapping it) on every path out of read_impl.
struct file_guard {
    int fd = -1;
    FILE *file = nullptr;
    ~file_guard()
    {
        if (file)
            std::fclose(file);
        else if (fd >= 0)
            close(fd);
    }
};

// The checks both readers share, before OpenImageIO sees a byte: the size, the format (by content,
// else by the extension of `path`), and the header walks of EXR, PNG and PFM. `path` names the
// image in messages (a file's path, or the caller's name for a buffer).
pb_result check_source(const byte_source &src, const char *path, std::string *format, pb_error *err)
{
    if (src.size == 0) return pb_error_set(err, PB_ERROR_FORMAT, "%s: empty file, not an image", path);
    if (src.size > PB_IMAGE_MAX_FILE_BYTES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%s: %llu bytes is above the image file limit of %llu bytes", path,
                            (unsigned long long)src.size, (unsigned long long)PB_IMAGE_MAX_FILE_BYTES);
    unsigned char head[64] = {0};
    size_t got = 0;
    if (!src.read(0, head, sizeof head, &got))
        return pb_error_set(err, PB_ERROR_IO, "%s: cannot read: %s", path, std::strerror(errno));
    *format = format_for(path, head, got);
    pb_result r = PB_SUCCESS;
    uint64_t pfm_w, pfm_h, pfm_c;
    if (*format == "openexr") r = exr_check_header(src, path, err);
    if (*format == "png") r = png_check_chunks(src, path, err);
    if (*format == "pnm" && pfm_header_size(head, got, &pfm_w, &pfm_h, &pfm_c))
        r = check_limits(path, pfm_w, pfm_h, pfm_c, err);
    return r;
}

// Decodes the checked image through `proxy` (where the format's reader takes one; a file's reader
// that does not opens `path` itself, a buffer's fails), checking the spec against the documented
// limits before any pixel is read or allocated.
pb_result decode(const char *path, const std::string &format, OIIO::Filesystem::IOProxy *proxy, bool proxy_only,
                 pb_image *out, pb_error *err)
{
    auto in = format.empty() ? nullptr : OIIO::ImageInput::create(format, false);
    if (!in) {
        (void)OIIO::geterror(); // clear OpenImageIO's per-thread error
        return pb_error_set(err, PB_ERROR_FORMAT,
                            "%s: not a known image format (the content is not EXR, HDR, PNG, JPEG, TIFF or PFM, "
                            "and OpenImageIO has no reader for the extension '%s')",
                            path, format.c_str());
    }
    if (proxy_only && !in->supports("ioproxy"))
        return pb_error_set(err, PB_ERROR_FORMAT, "%s: OpenImageIO's %s reader cannot read from memory", path,
                            format.c_str());
    if (in->supports("ioproxy") && !in->set_ioproxy(proxy))
        return pb_error_set(err, PB_ERROR_IO, "%s: cannot read through OpenImageIO", path);
    OIIO::ImageSpec spec;
    if (!in->open(path, spec)) {
        std::string msg = in->geterror();
        return pb_error_set(err, PB_ERROR_FORMAT, "%s: cannot read as %s: %s", path, format.c_str(),
                            msg.empty() ? "unknown OpenImageIO error" : msg.c_str());
    }
    if (spec.deep)
        return pb_error_set(err, PB_ERROR_FORMAT, "image '%s' is a deep image; flat pixels are required", path);
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1)
        return pb_error_set(err, PB_ERROR_FORMAT, "image '%s' has unsupported size %dx%dx%d with %d channel(s)", path,
                            spec.width, spec.height, spec.depth, spec.nchannels);
    const uint64_t w = (uint64_t)spec.width, h = (uint64_t)spec.height, c = (uint64_t)spec.nchannels;
    pb_result r = check_limits(path, w, h, c, err);
    if (r != PB_SUCCESS) return r;
    const size_t count = (size_t)(w * h * c);
    float *data = static_cast<float *>(std::malloc(count * sizeof(float)));
    if (!data)
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory reading '%s' (%dx%d, %d channels)", path,
                            spec.width, spec.height, spec.nchannels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, data)) {
        std::string msg = in->geterror();
        std::free(data);
        return pb_error_set(err, PB_ERROR_IO, "cannot read pixels of '%s': %s", path,
                            msg.empty() ? "unknown OpenImageIO error" : msg.c_str());
    }
    in->close();
    out->width = (uint32_t)spec.width;
    out->height = (uint32_t)spec.height;
    out->channels = (uint32_t)spec.nchannels;
    out->pixels = data;
    return PB_SUCCESS;
}

pb_result read_impl(const char *path, pb_image *out, pb_error *err)
{
    // 1. The file: a regular file opened without blocking, of a plausible size, its header checked.
    file_guard g;
    byte_source src;
    pb_result r = pb_open_regular_(path, "an image", &g.fd, &src.size, err);
    if (r != PB_SUCCESS) return r;
    src.fd = g.fd;
    std::string format;
    r = check_source(src, path, &format, err);
    if (r != PB_SUCCESS) return r;
    if (lseek(g.fd, 0, SEEK_SET) != 0)
        return pb_error_set(err, PB_ERROR_IO, "%s: cannot seek: %s", path, std::strerror(errno));
    // 2. OpenImageIO reads through our checked descriptor where the reader supports it (all the
    // formats above do), so the file cannot be swapped for a FIFO or device after the check. The
    // proxy outlives the reader (declared before it), the FILE outlives both.
    g.file = fdopen(g.fd, "rb");
    if (!g.file) return pb_error_set(err, PB_ERROR_IO, "%s: cannot read: %s", path, std::strerror(errno));
    OIIO::Filesystem::IOFile proxy(g.file, OIIO::Filesystem::IOProxy::Read);
    return decode(path, format, &proxy, false, out, err);
}

pb_result read_memory_impl(const void *data, size_t size, const char *name, pb_image *out, pb_error *err)
{
    byte_source src;
    src.mem = static_cast<const unsigned char *>(data);
    src.size = size;
    std::string format;
    pb_result r = check_source(src, name, &format, err);
    if (r != PB_SUCCESS) return r;
    OIIO::Filesystem::IOMemReader proxy(data, size);
    return decode(name, format, &proxy, true, out, err);
}

pb_result write_impl(const char *path, uint32_t width, uint32_t height, uint32_t channels, const float *pixels,
                     pb_error *err)
{
    const std::string target(path);
    const std::string ext = lower_extension(target);
    auto out = OIIO::ImageOutput::create(target);
    if (!out) {
        std::string msg = OIIO::geterror();
        return pb_error_set(err, PB_ERROR_IO, "no image writer for '%s' (extension '%s'): %s", path, ext.c_str(),
                            msg.empty() ? "unknown OpenImageIO error" : msg.c_str());
    }
    // A temporary file in the same folder (so rename() is atomic), keeping the extension.
    const size_t slash = target.find_last_of('/');
    const std::string dir = slash == std::string::npos ? std::string() : target.substr(0, slash + 1);
    const std::string base = slash == std::string::npos ? target : target.substr(slash + 1);
    std::string tmpl = dir + "." + base + ".tmp-XXXXXX" + ext;
    const int fd = mkstemps(&tmpl[0], (int)ext.size());
    if (fd < 0)
        return pb_error_set(err, PB_ERROR_IO, "cannot create a temporary file next to '%s': %s", path,
                            std::strerror(errno));
    // mkstemps creates mode 0600; give the result ordinary permissions.
    (void)fchmod(fd, 0644);
    close(fd);

    OIIO::ImageSpec spec((int)width, (int)height, (int)channels,
                         is_float_format(ext) ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
    bool ok = out->open(tmpl, spec);
    if (ok) ok = out->write_image(OIIO::TypeDesc::FLOAT, pixels);
    if (ok) ok = out->close();
    if (!ok) {
        std::string msg = out->geterror();
        std::remove(tmpl.c_str());
        return pb_error_set(err, PB_ERROR_IO, "cannot write image '%s': %s", path,
                            msg.empty() ? "unknown OpenImageIO error" : msg.c_str());
    }
    out.reset();
    if (std::rename(tmpl.c_str(), path) != 0) {
        const int e = errno;
        std::remove(tmpl.c_str());
        return pb_error_set(err, PB_ERROR_IO, "cannot rename '%s' to '%s': %s", tmpl.c_str(), path, std::strerror(e));
    }
    return PB_SUCCESS;
}

} // namespace

extern "C" pb_result pb_image_read(const char *path, pb_image *out, pb_error *err)
{
    if (!out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_image_read: out is NULL");
    *out = pb_image{};
    if (!path || !*path) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_image_read: empty path");
    try {
        return read_impl(path, out, err);
    } catch (const std::bad_alloc &) {
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory reading '%s'", path);
    } catch (const std::exception &e) {
        return pb_error_set(err, PB_ERROR_IO, "cannot read image '%s': %s", path, e.what());
    } catch (...) {
        return pb_error_set(err, PB_ERROR_IO, "cannot read image '%s': unknown exception", path);
    }
}

extern "C" pb_result pb_image_read_memory(const void *data, size_t size, const char *name, pb_image *out, pb_error *err)
{
    if (!out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_image_read_memory: out is NULL");
    *out = pb_image{};
    if (!name || !*name) name = "(image in memory)";
    if (!data && size) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "%s: data is NULL", name);
    try {
        return read_memory_impl(data, size, name, out, err);
    } catch (const std::bad_alloc &) {
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory reading '%s'", name);
    } catch (const std::exception &e) {
        return pb_error_set(err, PB_ERROR_IO, "cannot read image '%s': %s", name, e.what());
    } catch (...) {
        return pb_error_set(err, PB_ERROR_IO, "cannot read image '%s': unknown exception", name);
    }
}

extern "C" pb_result pb_image_write(const char *path, uint32_t width, uint32_t height, uint32_t channels,
                                    const float *pixels, pb_error *err)
{
    if (!path || !*path) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_image_write: empty path");
    if (!pixels) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_image_write: pixels is NULL");
    if (width == 0 || height == 0 || channels == 0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_image_write: empty image %ux%u with %u channel(s)",
                            width, height, channels);
    const uint32_t int_max = (uint32_t)std::numeric_limits<int>::max();
    if (width > int_max || height > int_max || channels > int_max ||
        (uint64_t)width * height > std::numeric_limits<size_t>::max() / sizeof(float) / channels)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_image_write: image size %ux%u x %u overflows", width,
                            height, channels);
    try {
        return write_impl(path, width, height, channels, pixels, err);
    } catch (const std::bad_alloc &) {
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory writing '%s'", path);
    } catch (const std::exception &e) {
        return pb_error_set(err, PB_ERROR_IO, "cannot write image '%s': %s", path, e.what());
    } catch (...) {
        return pb_error_set(err, PB_ERROR_IO, "cannot write image '%s': unknown exception", path);
    }
}

extern "C" void pb_image_free(pb_image *image)
{
    if (!image) return;
    std::free(image->pixels);
    *image = pb_image{};
}
