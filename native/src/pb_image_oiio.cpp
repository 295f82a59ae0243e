// Float image I/O through OpenImageIO: the only C++ in the bake core, behind extern "C".
// No exception crosses the C boundary: every entry point catches and reports.
#include "schnee/pb_image.h"

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

pb_result read_impl(const char *path, pb_image *out, pb_error *err)
{
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        std::string msg = OIIO::geterror();
        return pb_error_set(err, PB_ERROR_IO, "cannot open image '%s': %s", path,
                            msg.empty() ? "unknown OpenImageIO error" : msg.c_str());
    }
    const OIIO::ImageSpec &spec = in->spec();
    if (spec.deep)
        return pb_error_set(err, PB_ERROR_FORMAT, "image '%s' is a deep image; flat pixels are required", path);
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1)
        return pb_error_set(err, PB_ERROR_FORMAT, "image '%s' has unsupported size %dx%dx%d with %d channel(s)", path,
                            spec.width, spec.height, spec.depth, spec.nchannels);
    const uint64_t w = (uint64_t)spec.width, h = (uint64_t)spec.height, c = (uint64_t)spec.nchannels;
    // w, h, c < 2^31 each: w*h < 2^62 fits; then check the channel and byte products.
    const uint64_t pixels = w * h;
    if (pixels > std::numeric_limits<size_t>::max() / sizeof(float) / c)
        return pb_error_set(err, PB_ERROR_FORMAT, "image '%s' is too large (%dx%d, %d channels)", path, spec.width,
                            spec.height, spec.nchannels);
    const size_t count = (size_t)(pixels * c);
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
