// image_io.cpp - images through OpenImageIO, behind the C API of image_io.h.
//
// Errors are thrown as IoError inside and caught once at each C entry point,
// with every other exception; buffers live in std::vector until they are
// copied out to the caller's allocator, so no path leaks.
//
// Two ways to build this file:
//   - plainly: the whole implementation; link with OpenImageIO.
//   - with REFL_IMAGE_IO_DLOPEN="path/to/libreflect_image_io.so": the
//     comparison and the free functions, and forwarders that load the
//     plain build, compiled as that shared library, on first use (dlopen;
//     a relative path is taken from the executable's directory, and the
//     environment variable REFL_IMAGE_IO_LIB, when set, replaces the
//     path). Programs that start many times, like the Criterion test binary
//     (which re-executes itself for every test), so avoid OpenImageIO's
//     start-up cost, about 0.3 s of CPU for its ~270 shared libraries, in
//     every process that does not touch an image.
#include "image_io.h"

#ifdef REFL_IMAGE_IO_DLOPEN
#include <dlfcn.h>
#include <unistd.h>
#else
#include <OpenImageIO/imageio.h>

#include <sys/stat.h>
#endif

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

namespace {

void write_message(char *err, size_t err_size, const std::string &text) {
    if (!err || err_size == 0) return;
    size_t n = std::min(text.size(), err_size - 1);
    std::memcpy(err, text.data(), n);
    err[n] = '\0';
}

const long long kMaxPixels = 1LL << 27;

void free_with(const refl_allocator *a, void *p) {
    if (!p) return;
    if (a && a->free) a->free(p, a->user);
    else std::free(p);
}

}  // namespace

// The entry points that need OpenImageIO, as the shared library exports them.
struct refl_image_io_table {
    int version;
    refl_result (*write)(const char *, int, int, int, const uint8_t *, const float *, char *, size_t);
    refl_result (*read)(const char *, refl_image *, const refl_allocator *, char *, size_t);
    refl_result (*read_rgba8)(const char *, int *, int *, uint8_t **, const refl_allocator *, char *, size_t);
    refl_result (*env_load)(const char *, refl_environment *, const refl_allocator *, char *, size_t);
};

#ifndef REFL_IMAGE_IO_DLOPEN
namespace {

struct IoError {
    refl_result code;
    std::string message;  // starts with the path
};

std::string format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char *fmt, ...) {
    char buf[1024];
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return buf;
}

[[noreturn]] void fail(refl_result code, const std::string &path, const std::string &what) {
    throw IoError{code, path + ": " + what};
}

std::string one_line(std::string s) {
    while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
    std::replace(s.begin(), s.end(), '\n', ' ');
    return s.empty() ? std::string("unknown error") : s;
}

// Runs f, turning every exception into a code and a message.
template <class F> refl_result guarded(const char *path, char *err, size_t err_size, F f) {
    if (err && err_size) err[0] = '\0';
    std::string p = path ? path : "(null)";
    try {
        f();
        return REFL_OK;
    } catch (const IoError &e) {
        write_message(err, err_size, e.message);
        return e.code;
    } catch (const std::bad_alloc &) {
        write_message(err, err_size, p + ": out of memory");
        return REFL_ERROR_OUT_OF_MEMORY;
    } catch (const std::exception &e) {
        write_message(err, err_size, p + ": " + one_line(e.what()));
        return REFL_ERROR_BAD_MESH;
    } catch (...) {
        write_message(err, err_size, p + ": unexpected error");
        return REFL_ERROR_BAD_MESH;
    }
}


std::string extension(const std::string &path) {
    size_t dot = path.find_last_of('.'), slash = path.find_last_of('/');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string e = path.substr(dot + 1);
    for (char &c : e) c = char(std::tolower((unsigned char)c));
    return e;
}

float srgb_to_linear(float c) {
    return c <= 0.04045f ? c / 12.92f : float(std::pow((double(c) + 0.055) / 1.055, 2.4));
}
float linear_to_srgb(float c) {
    return c <= 0.0031308f ? c * 12.92f : float(1.055 * std::pow(double(c), 1.0 / 2.4) - 0.055);
}

void check_exists(const std::string &path) {
    struct stat st;
    if (stat(path.c_str(), &st) != 0) fail(REFL_ERROR_UNKNOWN_NAME, path, format("cannot open: %s", std::strerror(errno)));
    if (S_ISDIR(st.st_mode)) fail(REFL_ERROR_UNKNOWN_NAME, path, "cannot open: is a directory");
    // a FIFO blocks the open until a writer comes, a device streams without end
    if (!S_ISREG(st.st_mode)) fail(REFL_ERROR_UNKNOWN_NAME, path, "cannot open: not a regular file");
}

// PNG files are checked whole (every chunk present, every CRC right) before
// OpenImageIO sees them: its PNG reader, when libpng fails (a truncated
// file), longjmps past C++ destructors and leaks, and the check names the
// problem more exactly.
void check_png(const std::string &path) {
    struct Closer { void operator()(FILE *f) const { std::fclose(f); } };
    std::unique_ptr<FILE, Closer> f(std::fopen(path.c_str(), "rb"));
    if (!f) fail(REFL_ERROR_UNKNOWN_NAME, path, format("cannot open: %s", std::strerror(errno)));
    static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    unsigned char head[8];
    if (std::fread(head, 1, 8, f.get()) != 8 || std::memcmp(head, sig, 8) != 0) return;  // not a PNG
    std::vector<unsigned char> d(head, head + 8);
    unsigned char buf[1 << 16];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, f.get())) > 0) d.insert(d.end(), buf, buf + n);
    static uint32_t table[256];
    static bool have_table = [] {
        for (uint32_t i = 0; i < 256; i++) {
            uint32_t c = i;
            for (int k = 0; k < 8; k++) c = c & 1 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            table[i] = c;
        }
        return true;
    }();
    (void)have_table;
    auto be32 = [&](size_t at) {
        return uint32_t(d[at]) << 24 | uint32_t(d[at + 1]) << 16 | uint32_t(d[at + 2]) << 8 | uint32_t(d[at + 3]);
    };
    size_t at = 8;
    for (;;) {
        if (d.size() - at < 12)
            fail(REFL_ERROR_BAD_MESH, path, format("truncated PNG: %zu bytes, no IEND chunk", d.size()));
        uint32_t len = be32(at);
        char type[5] = {char(d[at + 4]), char(d[at + 5]), char(d[at + 6]), char(d[at + 7]), 0};
        for (char &c : type)
            if (c && !std::isalpha((unsigned char)c)) c = '?';
        if (len > 0x7FFFFFFFu || d.size() - at - 12 < len)
            fail(REFL_ERROR_BAD_MESH, path, format("truncated PNG: chunk '%s' at byte %zu needs %u bytes, %zu left",
                                                   type, at, len, d.size() - at - 12));
        uint32_t crc = 0xFFFFFFFFu;
        for (size_t i = at + 4; i < at + 8 + len; i++) crc = table[(crc ^ d[i]) & 0xFF] ^ (crc >> 8);
        if ((crc ^ 0xFFFFFFFFu) != be32(at + 8 + len))
            fail(REFL_ERROR_BAD_MESH, path, format("corrupt PNG: bad CRC in chunk '%s' at byte %zu", type, at));
        at += 12 + size_t(len);
        if (std::strcmp(type, "IEND") == 0) return;
    }
}

// The first subimage, all channels, as `type` (FLOAT or UINT8), with its spec.
struct Pixels {
    int width = 0, height = 0, channels = 0, alpha = -1;
    bool linear = true;  // float data, or a file that says it is linear
    std::vector<float> f;
    std::vector<uint8_t> b;
};

Pixels read_pixels(const std::string &path, OIIO::TypeDesc type) {
    check_exists(path);
    check_png(path);
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);  // alpha as stored, never premultiplied
    auto in = OIIO::ImageInput::open(path, &config);
    if (!in) fail(REFL_ERROR_BAD_MESH, path, "cannot read: " + one_line(OIIO::geterror()));
    const OIIO::ImageSpec &spec = in->spec();
    Pixels px;
    px.width = spec.width;
    px.height = spec.height;
    px.channels = spec.nchannels;
    px.alpha = spec.alpha_channel;
    if (px.width <= 0 || px.height <= 0 || px.channels <= 0 || spec.depth > 1 ||
        (long long)px.width * px.height > kMaxPixels || px.channels > 64) {
        fail(REFL_ERROR_INVALID_SIZE, path,
             format("unsupported size %dx%d with %d channels", px.width, px.height, px.channels));
    }
    std::string cs = spec.get_string_attribute("oiio:ColorSpace");
    bool is_float = spec.format.basetype == OIIO::TypeDesc::FLOAT || spec.format.basetype == OIIO::TypeDesc::HALF ||
                    spec.format.basetype == OIIO::TypeDesc::DOUBLE;
    std::string lcs = cs;
    for (char &c : lcs) c = char(std::tolower((unsigned char)c));
    px.linear = is_float || lcs == "linear" || lcs == "scene_linear" || lcs == "lin_srgb";
    size_t n = size_t(px.width) * size_t(px.height) * size_t(px.channels);
    void *data;
    if (type == OIIO::TypeDesc::FLOAT) { px.f.resize(n); data = px.f.data(); }
    else { px.b.resize(n); data = px.b.data(); }
    if (!in->read_image(0, 0, 0, px.channels, type, data)) {
        std::string e = in->geterror();
        in->close();
        fail(REFL_ERROR_BAD_MESH, path, "corrupt or truncated: " + one_line(e));
    }
    in->close();
    return px;
}

// Channel c (0..3 of RGBA) of pixel i from a px.channels-channel buffer.
template <class T> void to_rgba(const Pixels &px, const T *src, T one, T *dst, size_t count) {
    const int nc = px.channels;
    int a = px.alpha >= 0 && px.alpha < nc ? px.alpha : (nc == 2 ? 1 : nc >= 4 ? 3 : -1);
    int colour = nc >= 3 ? 3 : 1;
    for (size_t i = 0; i < count; i++) {
        const T *s = src + i * size_t(nc);
        T *d = dst + i * 4;
        if (colour == 3) { d[0] = s[0]; d[1] = s[1]; d[2] = s[2]; }
        else d[0] = d[1] = d[2] = s[0];
        d[3] = a >= 0 ? s[a] : one;
    }
}

template <class T> T *copy_out(const std::vector<T> &v, const refl_allocator *a) {
    size_t bytes = v.size() * sizeof(T);
    void *p = a && a->alloc ? a->alloc(bytes, a->user) : std::malloc(bytes);
    if (!p) throw std::bad_alloc();
    std::memcpy(p, v.data(), bytes);
    return static_cast<T *>(p);
}

std::vector<float> read_linear_rgba(const std::string &path, int *w, int *h) {
    Pixels px = read_pixels(path, OIIO::TypeDesc::FLOAT);
    size_t count = size_t(px.width) * size_t(px.height);
    std::vector<float> rgba(count * 4);
    to_rgba(px, px.f.data(), 1.0f, rgba.data(), count);
    for (size_t i = 0; i < count; i++)
        for (int c = 0; c < 4; c++) {
            float &v = rgba[i * 4 + size_t(c)];
            if (!std::isfinite(v)) v = 0;
            else if (c < 3 && !px.linear) v = srgb_to_linear(v);
        }
    *w = px.width;
    *h = px.height;
    return rgba;
}

}  // namespace

extern "C" {

refl_result refl_image_write(const char *path, int width, int height, int channels, const uint8_t *rgba8,
                             const float *rgbaf, char *err, size_t err_size) {
    return guarded(path, err, err_size, [&] {
        std::string p = path ? path : "(null)";
        if (!path || (!rgba8) == (!rgbaf))
            fail(REFL_ERROR_INVALID_ARGUMENT, p, "refl_image_write needs a path and exactly one of rgba8, rgbaf");
        if (channels < 1 || channels > 4)
            fail(REFL_ERROR_INVALID_ARGUMENT, p, format("%d channels (1 to 4)", channels));
        if (width <= 0 || height <= 0 || (long long)width * height > kMaxPixels)
            fail(REFL_ERROR_INVALID_SIZE, p, format("invalid size %dx%d", width, height));
        std::string ext = extension(p);
        bool want_float = ext == "exr" || ext == "hdr" || ext == "pfm";
        auto out = OIIO::ImageOutput::create(p);
        if (!out) fail(REFL_ERROR_UNKNOWN_NAME, p, "no image format for this name: " + one_line(OIIO::geterror()));
        size_t count = size_t(width) * size_t(height), n = count * size_t(channels);
        int colour = channels >= 3 ? 3 : 1;  // channels that are colour (the rest is alpha)
        std::vector<float> f;
        std::vector<uint8_t> b;
        if (want_float) {
            if (rgbaf) f.assign(rgbaf, rgbaf + n);
            else {
                f.resize(n);
                for (size_t i = 0; i < n; i++) {
                    float v = rgba8[i] / 255.0f;
                    f[i] = int(i % size_t(channels)) < colour ? srgb_to_linear(v) : v;
                }
            }
        } else {
            if (rgba8) b.assign(rgba8, rgba8 + n);
            else {
                b.resize(n);
                for (size_t i = 0; i < n; i++) {
                    float v = rgbaf[i];
                    if (!std::isfinite(v)) v = 0;
                    v = std::min(std::max(v, 0.0f), 1.0f);
                    if (int(i % size_t(channels)) < colour) v = linear_to_srgb(v);
                    b[i] = uint8_t(std::lround(v * 255.0f));
                }
            }
        }
        if (ext == "hdr" && channels != 3) {  // Radiance RGBE holds RGB only: grey expanded, alpha dropped
            std::vector<float> rgb(count * 3);
            for (size_t i = 0; i < count; i++)
                for (int c = 0; c < 3; c++) rgb[i * 3 + size_t(c)] = f[i * size_t(channels) + size_t(colour == 3 ? c : 0)];
            f.swap(rgb);
            channels = 3;
        }
        OIIO::ImageSpec spec(width, height, channels, want_float ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8);
        static const char *names[4][4] = {{"Y"}, {"Y", "A"}, {"R", "G", "B"}, {"R", "G", "B", "A"}};
        spec.channelnames.clear();
        for (int c = 0; c < channels; c++) spec.channelnames.push_back(names[channels - 1][c]);
        spec.alpha_channel = channels == 2 ? 1 : channels == 4 ? 3 : -1;
        spec.attribute("oiio:UnassociatedAlpha", 1);
        spec.attribute("oiio:ColorSpace", want_float ? "Linear" : "sRGB");
        if (!out->open(p, spec)) fail(REFL_ERROR_UNKNOWN_NAME, p, "cannot write: " + one_line(out->geterror()));
        bool ok = want_float ? out->write_image(OIIO::TypeDesc::FLOAT, f.data())
                             : out->write_image(OIIO::TypeDesc::UINT8, b.data());
        std::string e = ok ? std::string() : out->geterror();
        if (!out->close() && ok) { ok = false; e = out->geterror(); }
        if (!ok) fail(REFL_ERROR_UNKNOWN_NAME, p, "cannot write: " + one_line(e));
    });
}

refl_result refl_image_read(const char *path, refl_image *out, const refl_allocator *a, char *err,
                            size_t err_size) {
    if (out) std::memset(out, 0, sizeof *out);
    return guarded(path, err, err_size, [&] {
        if (!path || !out) fail(REFL_ERROR_INVALID_ARGUMENT, path ? path : "(null)", "refl_image_read needs a path and out");
        int w, h;
        std::vector<float> rgba = read_linear_rgba(path, &w, &h);
        out->pixels = copy_out(rgba, a);
        out->width = w;
        out->height = h;
    });
}

refl_result refl_image_read_rgba8(const char *path, int *width, int *height, uint8_t **rgba8,
                                  const refl_allocator *a, char *err, size_t err_size) {
    if (width) *width = 0;
    if (height) *height = 0;
    if (rgba8) *rgba8 = nullptr;
    return guarded(path, err, err_size, [&] {
        if (!path || !width || !height || !rgba8)
            fail(REFL_ERROR_INVALID_ARGUMENT, path ? path : "(null)", "refl_image_read_rgba8: NULL argument");
        Pixels px = read_pixels(path, OIIO::TypeDesc::UINT8);
        size_t count = size_t(px.width) * size_t(px.height);
        std::vector<uint8_t> rgba(count * 4);
        to_rgba(px, px.b.data(), uint8_t(255), rgba.data(), count);
        *rgba8 = copy_out(rgba, a);
        *width = px.width;
        *height = px.height;
    });
}

refl_result refl_env_load(const char *path_or_pattern, refl_environment *out, const refl_allocator *a, char *err,
                          size_t err_size) {
    if (out) std::memset(out, 0, sizeof *out);
    return guarded(path_or_pattern, err, err_size, [&] {
        if (!path_or_pattern || !out)
            fail(REFL_ERROR_INVALID_ARGUMENT, path_or_pattern ? path_or_pattern : "(null)",
                 "refl_env_load needs a path and out");
        std::string pattern = path_or_pattern;
        size_t at = pattern.find("%s");
        if (at == std::string::npos) {
            int w, h;
            std::vector<float> rgba = read_linear_rgba(pattern, &w, &h);
            if (w != 2 * h)
                fail(REFL_ERROR_INVALID_SIZE, pattern,
                     format("an equirectangular map must be twice as wide as high, not %dx%d", w, h));
            out->image.pixels = copy_out(rgba, a);
            out->image.width = w;
            out->image.height = h;
            out->type = REFL_ENV_EQUIRECT;
            return;
        }
        static const char *faces[6] = {"px", "nx", "py", "ny", "pz", "nz"};
        std::vector<float> data[6];
        int size = 0;
        for (int f = 0; f < 6; f++) {
            std::string name = pattern.substr(0, at) + faces[f] + pattern.substr(at + 2);
            int w, h;
            data[f] = read_linear_rgba(name, &w, &h);
            if (w != h) fail(REFL_ERROR_INVALID_SIZE, name, format("a cube face must be square, not %dx%d", w, h));
            if (f > 0 && w != size)
                fail(REFL_ERROR_INVALID_SIZE, name, format("face is %dx%d, the first face %dx%d", w, h, size, size));
            size = w;
        }
        refl_environment env;
        std::memset(&env, 0, sizeof env);
        env.type = REFL_ENV_CUBE;
        try {
            for (int f = 0; f < 6; f++) {
                env.faces[f].pixels = copy_out(data[f], a);
                env.faces[f].width = env.faces[f].height = size;
            }
        } catch (...) {
            refl_env_free(&env, a);
            throw;
        }
        *out = env;
    });
}

const refl_image_io_table *refl_image_io_table_v1(void) {
    static const refl_image_io_table table = {1, refl_image_write, refl_image_read, refl_image_read_rgba8,
                                              refl_env_load};
    return &table;
}

}  // extern "C"

#else  // REFL_IMAGE_IO_DLOPEN: forwarders to the shared library

namespace {

const refl_image_io_table *io_table(std::string *why) {
    static std::string error;
    static const refl_image_io_table *table = [] () -> const refl_image_io_table * {
        const char *env = std::getenv("REFL_IMAGE_IO_LIB");
        std::string lib = env && *env ? env : REFL_IMAGE_IO_DLOPEN;
        if (!(env && *env) && !lib.empty() && lib[0] != '/') {
            char exe[4096];
            ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
            if (n > 0) {
                std::string dir(exe, size_t(n));
                lib = dir.substr(0, dir.find_last_of('/') + 1) + lib;
            }
        }
        void *h = dlopen(lib.c_str(), RTLD_NOW | RTLD_LOCAL);
        if (!h) {
            const char *e = dlerror();
            error = "cannot load " + lib + ": " + (e ? e : "dlopen failed");
            return nullptr;
        }
        typedef const refl_image_io_table *(*get_fn)(void);
        get_fn get = reinterpret_cast<get_fn>(dlsym(h, "refl_image_io_table_v1"));
        const refl_image_io_table *t = get ? get() : nullptr;
        if (!t || t->version != 1) {
            error = lib + ": no refl_image_io_table_v1 of version 1";
            return nullptr;  // h stays loaded: harmless
        }
        return t;
    }();
    if (!table && why) *why = error;
    return table;
}

refl_result unavailable(const char *path, char *err, size_t err_size, const std::string &why) {
    write_message(err, err_size, std::string(path ? path : "(null)") + ": image I/O is not available: " + why);
    return REFL_ERROR_UNSUPPORTED;
}

}  // namespace

extern "C" {

refl_result refl_image_write(const char *path, int width, int height, int channels, const uint8_t *rgba8,
                             const float *rgbaf, char *err, size_t err_size) {
    std::string why;
    const refl_image_io_table *t = io_table(&why);
    return t ? t->write(path, width, height, channels, rgba8, rgbaf, err, err_size)
             : unavailable(path, err, err_size, why);
}

refl_result refl_image_read(const char *path, refl_image *out, const refl_allocator *a, char *err,
                            size_t err_size) {
    std::string why;
    const refl_image_io_table *t = io_table(&why);
    if (out) std::memset(out, 0, sizeof *out);
    return t ? t->read(path, out, a, err, err_size) : unavailable(path, err, err_size, why);
}

refl_result refl_image_read_rgba8(const char *path, int *width, int *height, uint8_t **rgba8,
                                  const refl_allocator *a, char *err, size_t err_size) {
    std::string why;
    const refl_image_io_table *t = io_table(&why);
    if (width) *width = 0;
    if (height) *height = 0;
    if (rgba8) *rgba8 = nullptr;
    return t ? t->read_rgba8(path, width, height, rgba8, a, err, err_size) : unavailable(path, err, err_size, why);
}

refl_result refl_env_load(const char *path_or_pattern, refl_environment *out, const refl_allocator *a, char *err,
                          size_t err_size) {
    std::string why;
    const refl_image_io_table *t = io_table(&why);
    if (out) std::memset(out, 0, sizeof *out);
    return t ? t->env_load(path_or_pattern, out, a, err, err_size) : unavailable(path_or_pattern, err, err_size, why);
}

}  // extern "C"

#endif  // REFL_IMAGE_IO_DLOPEN

// ---- both builds: no OpenImageIO needed ----------------------------------------

extern "C" {

void refl_image_free(refl_image *image, const refl_allocator *a) {
    if (!image) return;
    free_with(a, image->pixels);
    std::memset(image, 0, sizeof *image);
}

void refl_env_free(refl_environment *env, const refl_allocator *a) {
    if (!env) return;
    refl_image_free(&env->image, a);
    for (refl_image &f : env->faces) refl_image_free(&f, a);
    std::memset(env, 0, sizeof *env);
}

refl_result refl_image_compare(const uint8_t *a, const uint8_t *b, int width, int height, double threshold,
                               refl_image_diff *out) {
    if (out) std::memset(out, 0, sizeof *out);
    if (!a || !b || !out) return REFL_ERROR_INVALID_ARGUMENT;
    if (width <= 0 || height <= 0 || (long long)width * height > kMaxPixels) return REFL_ERROR_INVALID_SIZE;
    size_t count = size_t(width) * size_t(height);
    double sum = 0;
    int max_diff = 0;
    long long over = 0;
    for (size_t i = 0; i < count; i++) {
        int worst = 0;
        for (int c = 0; c < 3; c++) {
            int d = std::abs(int(a[i * 4 + size_t(c)]) - int(b[i * 4 + size_t(c)]));
            sum += double(d) * d;
            worst = std::max(worst, d);
        }
        max_diff = std::max(max_diff, worst);
        if (worst / 255.0 > threshold) over++;
    }
    out->rmse = std::sqrt(sum / (3.0 * double(count))) / 255.0;
    out->psnr = out->rmse > 0 ? 20.0 * std::log10(1.0 / out->rmse) : INFINITY;
    out->max_error = max_diff / 255.0;
    out->pixels_over = over;
    out->fraction_over = double(over) / double(count);
    return REFL_OK;
}

refl_result refl_image_compare_files(const char *path_a, const char *path_b, double threshold,
                                     refl_image_diff *out, char *err, size_t err_size) {
    if (out) std::memset(out, 0, sizeof *out);
    int wa = 0, ha = 0, wb = 0, hb = 0;
    uint8_t *a = nullptr, *b = nullptr;
    refl_result r = refl_image_read_rgba8(path_a, &wa, &ha, &a, nullptr, err, err_size);
    if (r == REFL_OK) r = refl_image_read_rgba8(path_b, &wb, &hb, &b, nullptr, err, err_size);
    if (r == REFL_OK && (wa != wb || ha != hb)) {
        char msg[1024];
        std::snprintf(msg, sizeof msg, "%s: %dx%d, but %s is %dx%d", path_b, wb, hb, path_a, wa, ha);
        write_message(err, err_size, msg);
        r = REFL_ERROR_INVALID_SIZE;
    }
    if (r == REFL_OK) r = refl_image_compare(a, b, wa, ha, threshold, out);
    std::free(a);
    std::free(b);
    return r;
}

}  // extern "C"
