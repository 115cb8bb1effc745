// gltf_load.cpp - glTF 2.0 into a refl_scene through tinygltf (Debian's
// shared libtinygltf). The C API and the rules are in gltf_load.h.
//
// Inside, errors are thrown as LoadError and caught once at the C boundary,
// where every other exception (std::bad_alloc, anything tinygltf lets out) is
// turned into an error code too. Everything allocated lives in RAII holders
// until the scene is handed out, so every path is leak-free.
#include "gltf_load.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <sys/stat.h>

namespace {

// ---- errors ---------------------------------------------------------------

struct LoadError {
    refl_result code;
    std::string message;  // without the path
};

std::string format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char *fmt, ...) {
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return buf;
}

[[noreturn]] void fail(refl_result code, std::string message) {
    throw LoadError{code, std::move(message)};
}

void write_message(char *err, size_t err_size, const std::string &text) {
    if (!err || err_size == 0) return;
    size_t n = std::min(text.size(), err_size - 1);
    std::memcpy(err, text.data(), n);
    err[n] = '\0';
}

// ---- the file ---------------------------------------------------------------

const size_t kMaxFileBytes = size_t(1) << 31;  // tinygltf takes 32-bit sizes
const long long kDefaultMaxTexturePixels = 1LL << 24;  // 4096 x 4096: 256 MiB as float RGBA

std::vector<unsigned char> read_file(const char *path) {
    struct Closer { void operator()(FILE *f) const { std::fclose(f); } };
    // a device or pipe could stream without end (/dev/zero), a FIFO block
    // the open itself until a writer comes, a directory read as huge:
    // looked at before it is opened, and again (fstat) once it is
    struct stat st;
    if (stat(path, &st) == 0 && !S_ISREG(st.st_mode)) fail(REFL_ERROR_INVALID_SIZE, "not a regular file");
    std::unique_ptr<FILE, Closer> f(std::fopen(path, "rb"));
    if (!f) fail(REFL_ERROR_UNKNOWN_NAME, format("cannot open: %s", std::strerror(errno)));
    if (fstat(fileno(f.get()), &st) != 0 || !S_ISREG(st.st_mode))
        fail(REFL_ERROR_INVALID_SIZE, "not a regular file");
    if (uint64_t(st.st_size) > kMaxFileBytes) fail(REFL_ERROR_INVALID_SIZE, "file larger than 2 GiB");
    std::vector<unsigned char> data;
    data.reserve(size_t(st.st_size));
    unsigned char chunk[1 << 16];
    for (;;) {
        size_t n = std::fread(chunk, 1, sizeof chunk, f.get());
        data.insert(data.end(), chunk, chunk + n);
        if (data.size() > kMaxFileBytes) fail(REFL_ERROR_INVALID_SIZE, "file larger than 2 GiB");
        if (n < sizeof chunk) break;
    }
    if (std::ferror(f.get())) fail(REFL_ERROR_UNKNOWN_NAME, format("cannot read: %s", std::strerror(errno)));
    if (data.empty()) fail(REFL_ERROR_BAD_MESH, "empty file");
    return data;
}

// tinygltf's file callbacks for the files a glTF's URIs name (buffers,
// images): whether one exists by stat (tinygltf's own opens it, which
// blocks on a FIFO), and read_file's reading, so a URI naming a directory,
// FIFO or device is refused as the glTF file itself would be, not read
// without end or sized as huge.
bool uri_file_exists(const std::string &path, void *) {
    struct stat st;
    return stat(path.c_str(), &st) == 0;
}

bool read_uri_file(std::vector<unsigned char> *out, std::string *err, const std::string &path, void *) {
    try {
        *out = read_file(path.c_str());
        return true;
    } catch (const LoadError &e) {
        if (err) *err += path + ": " + e.message + "\n";
        return false;
    }
}

uint32_t le32(const unsigned char *p) {
    return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

// Checks the GLB container before tinygltf sees it; returns the byte count
// to hand over (the header's length).
size_t check_glb(const std::vector<unsigned char> &d) {
    const size_t size = d.size();
    if (size < 20) fail(REFL_ERROR_BAD_MESH, format("truncated GLB: %zu bytes, less than a header", size));
    uint32_t version = le32(&d[4]), length = le32(&d[8]);
    if (version != 2) fail(REFL_ERROR_UNSUPPORTED, format("GLB version %u (only 2 is supported)", version));
    if (length > size)
        fail(REFL_ERROR_BAD_MESH, format("truncated GLB: the header says %u bytes, the file has %zu", length, size));
    if (length < 20) fail(REFL_ERROR_BAD_MESH, format("corrupt GLB header: length %u", length));
    uint64_t json_len = le32(&d[12]);
    if (le32(&d[16]) != 0x4E4F534Au) fail(REFL_ERROR_BAD_MESH, "corrupt GLB: the first chunk is not JSON");
    if (json_len == 0 || 20 + json_len > length)
        fail(REFL_ERROR_BAD_MESH, format("corrupt or truncated GLB: JSON chunk of %llu bytes in a %u-byte file",
                                         (unsigned long long)json_len, length));
    uint64_t at = 20 + json_len;
    if (at < length) {
        if (at + 8 > length) fail(REFL_ERROR_BAD_MESH, "truncated GLB: partial chunk header after the JSON");
        uint64_t bin_len = le32(&d[at]);
        if (le32(&d[at + 4]) != 0x004E4942u) fail(REFL_ERROR_BAD_MESH, "corrupt GLB: the second chunk is not BIN");
        if (at + 8 + bin_len > length)
            fail(REFL_ERROR_BAD_MESH, format("truncated or corrupt GLB: BIN chunk of %llu bytes, %llu present",
                                             (unsigned long long)bin_len, (unsigned long long)(length - at - 8)));
    }
    return length;
}

std::string base_dir(const char *path) {
    std::string p(path);
    size_t slash = p.find_last_of('/');
    return slash == std::string::npos ? std::string() : p.substr(0, slash + 1);
}

// tinygltf's JSON parser recurses once per nesting level and keeps every
// value in a node of its own: a small file of deeply nested arrays overflows
// the stack, and a file of millions of tiny values takes many times its size
// in memory. So the JSON text is scanned first (outside strings: brackets
// for depth, brackets and commas for values) and refused beyond these
// limits, which no real glTF file comes near (its bulk data lives in buffers).
const int kMaxJsonDepth = 512;
const size_t kMaxJsonValues = size_t(1) << 24;

void check_json_shape(const unsigned char *p, size_t n) {
    int depth = 0;
    size_t values = 0;
    bool in_string = false;
    for (size_t i = 0; i < n; i++) {
        unsigned char c = p[i];
        if (in_string) {
            if (c == '\\') i++;
            else if (c == '"') in_string = false;
            continue;
        }
        if (c == '"') {
            in_string = true;
        } else if (c == '[' || c == '{') {
            if (++depth > kMaxJsonDepth)
                fail(REFL_ERROR_INVALID_SIZE, format("JSON nested deeper than %d arrays and objects (at byte %zu)",
                                                     kMaxJsonDepth, i));
            values++;
        } else if (c == ']' || c == '}') {
            depth -= depth > 0;
        } else if (c == ',') {
            values++;
        }
        if (values > kMaxJsonValues)
            fail(REFL_ERROR_INVALID_SIZE, format("JSON with more than %zu values", kMaxJsonValues));
    }
}

// ---- small math (double, column-major like refl_mat4) ------------------------

struct Mat {
    double m[16];
    static Mat identity() {
        Mat r{};
        r.m[0] = r.m[5] = r.m[10] = r.m[15] = 1;
        return r;
    }
    Mat operator*(const Mat &b) const {
        Mat r{};
        for (int c = 0; c < 4; c++)
            for (int row = 0; row < 4; row++) {
                double s = 0;
                for (int k = 0; k < 4; k++) s += m[k * 4 + row] * b.m[c * 4 + k];
                r.m[c * 4 + row] = s;
            }
        return r;
    }
    void apply(const double in[4], double out[3]) const {
        for (int row = 0; row < 3; row++)
            out[row] = m[row] * in[0] + m[4 + row] * in[1] + m[8 + row] * in[2] + m[12 + row] * in[3];
    }
    bool finite() const {
        for (double v : m)
            if (!std::isfinite(v)) return false;
        return true;
    }
};

Mat node_matrix(const tinygltf::Node &n, int index) {
    Mat r = Mat::identity();
    if (n.matrix.size() == 16) {
        for (int i = 0; i < 16; i++) r.m[i] = n.matrix[i];
    } else {
        if (!n.matrix.empty()) fail(REFL_ERROR_BAD_MESH, format("node %d: matrix of %zu numbers", index, n.matrix.size()));
        Mat t = Mat::identity(), rot = Mat::identity(), s = Mat::identity();
        if (n.translation.size() == 3) {
            t.m[12] = n.translation[0]; t.m[13] = n.translation[1]; t.m[14] = n.translation[2];
        } else if (!n.translation.empty()) {
            fail(REFL_ERROR_BAD_MESH, format("node %d: translation of %zu numbers", index, n.translation.size()));
        }
        if (n.rotation.size() == 4) {
            double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
            double len = std::sqrt(x * x + y * y + z * z + w * w);
            if (!(len > 0) || !std::isfinite(len))
                fail(REFL_ERROR_BAD_MESH, format("node %d: rotation is not a unit quaternion", index));
            x /= len; y /= len; z /= len; w /= len;
            rot.m[0] = 1 - 2 * (y * y + z * z); rot.m[1] = 2 * (x * y + z * w);     rot.m[2] = 2 * (x * z - y * w);
            rot.m[4] = 2 * (x * y - z * w);     rot.m[5] = 1 - 2 * (x * x + z * z); rot.m[6] = 2 * (y * z + x * w);
            rot.m[8] = 2 * (x * z + y * w);     rot.m[9] = 2 * (y * z - x * w);     rot.m[10] = 1 - 2 * (x * x + y * y);
        } else if (!n.rotation.empty()) {
            fail(REFL_ERROR_BAD_MESH, format("node %d: rotation of %zu numbers", index, n.rotation.size()));
        }
        if (n.scale.size() == 3) {
            s.m[0] = n.scale[0]; s.m[5] = n.scale[1]; s.m[10] = n.scale[2];
        } else if (!n.scale.empty()) {
            fail(REFL_ERROR_BAD_MESH, format("node %d: scale of %zu numbers", index, n.scale.size()));
        }
        r = t * rot * s;
    }
    if (!r.finite()) fail(REFL_ERROR_BAD_MESH, format("node %d: non-finite transform", index));
    return r;
}

// ---- accessors ------------------------------------------------------------------

const size_t kMaxCount = size_t(1) << 28;  // elements per accessor

// The renderers work in float and square coordinates (dot products,
// distances): beyond 1e18 a square overflows float's 3.4e38. Every world
// coordinate the loader hands out (vertices after their node's transform,
// light and camera positions) lies within it, else the load fails naming
// the node; every other double the file gives must fit a float.
const double kMaxCoordinate = 1e18;

bool fits_float(double v) { return std::isfinite(v) && std::fabs(v) <= double(FLT_MAX); }

// A bounds-checked view of one accessor: every element lies inside its
// bufferView, and the bufferView inside its buffer.
struct View {
    const unsigned char *base = nullptr;
    size_t stride = 0, count = 0;
    int ctype = 0, ncomp = 0, csize = 0;
    bool normalized = false;

    // Component c of element i, as the spec converts it (normalised
    // integers to [0, 1] or [-1, 1], others as their value).
    double get(size_t i, int c) const {
        const unsigned char *p = base + i * stride + size_t(c) * size_t(csize);
        switch (ctype) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: { float v; std::memcpy(&v, p, 4); return v; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
        case TINYGLTF_COMPONENT_TYPE_BYTE: {
            double v = (signed char)p[0];
            return normalized ? std::max(v / 127.0, -1.0) : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            uint16_t v; std::memcpy(&v, p, 2);
            return normalized ? v / 65535.0 : v;
        }
        case TINYGLTF_COMPONENT_TYPE_SHORT: {
            int16_t v; std::memcpy(&v, p, 2);
            return normalized ? std::max(v / 32767.0, -1.0) : double(v);
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t v; std::memcpy(&v, p, 4); return v; }
        default: return 0;
        }
    }
    uint32_t get_index(size_t i) const {
        const unsigned char *p = base + i * stride;
        if (ctype == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) return p[0];
        if (ctype == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) { uint16_t v; std::memcpy(&v, p, 2); return v; }
        uint32_t v; std::memcpy(&v, p, 4); return v;
    }
};

int component_size(int ctype) {
    switch (ctype) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT: case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;  // INT and DOUBLE are not glTF 2.0 vertex data
    }
}

// `what` names the use ("POSITION of primitive 0 of mesh 'x'") in messages;
// `ncomp_ok` lists the accepted component counts (types), ints; `index_data`
// restricts to unsigned, non-normalised scalars.
View view_accessor(const tinygltf::Model &model, int index, const std::string &what,
                   std::initializer_list<int> ncomp_ok, bool index_data) {
    const char *w = what.c_str();
    if (index < 0 || size_t(index) >= model.accessors.size())
        fail(REFL_ERROR_BAD_MESH, format("%s: accessor %d does not exist (%zu accessors)", w, index,
                                         model.accessors.size()));
    const tinygltf::Accessor &a = model.accessors[size_t(index)];
    if (a.sparse.isSparse)
        fail(REFL_ERROR_UNSUPPORTED, format("%s: accessor %d is sparse (not supported)", w, index));
    View v;
    v.ctype = a.componentType;
    v.csize = component_size(a.componentType);
    v.ncomp = tinygltf::GetNumComponentsInType(uint32_t(a.type));
    v.normalized = a.normalized;
    v.count = a.count;
    if (v.csize == 0)
        fail(REFL_ERROR_BAD_MESH, format("%s: accessor %d has component type %d", w, index, a.componentType));
    if (std::find(ncomp_ok.begin(), ncomp_ok.end(), v.ncomp) == ncomp_ok.end() ||
        (a.type != TINYGLTF_TYPE_SCALAR && a.type != TINYGLTF_TYPE_VEC2 && a.type != TINYGLTF_TYPE_VEC3 &&
         a.type != TINYGLTF_TYPE_VEC4))
        fail(REFL_ERROR_BAD_MESH, format("%s: accessor %d has the wrong type (%d components)", w, index, v.ncomp));
    if (index_data && (a.normalized || (v.ctype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
                                        v.ctype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
                                        v.ctype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)))
        fail(REFL_ERROR_BAD_MESH, format("%s: accessor %d: indices must be unsigned 8, 16 or 32-bit integers", w, index));
    if (a.normalized && (v.ctype == TINYGLTF_COMPONENT_TYPE_FLOAT || v.ctype == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
        fail(REFL_ERROR_BAD_MESH, format("%s: accessor %d: normalized float or 32-bit data", w, index));
    if (v.count == 0) fail(REFL_ERROR_BAD_MESH, format("%s: accessor %d has no elements", w, index));
    if (v.count > kMaxCount)
        fail(REFL_ERROR_INVALID_SIZE, format("%s: accessor %d: %zu elements is too many", w, index, v.count));
    if (a.bufferView < 0 || size_t(a.bufferView) >= model.bufferViews.size())
        fail(REFL_ERROR_BAD_MESH, format("%s: accessor %d: bufferView %d does not exist", w, index, a.bufferView));
    const tinygltf::BufferView &bv = model.bufferViews[size_t(a.bufferView)];
    if (bv.buffer < 0 || size_t(bv.buffer) >= model.buffers.size())
        fail(REFL_ERROR_BAD_MESH, format("%s: bufferView %d: buffer %d does not exist", w, a.bufferView, bv.buffer));
    const std::vector<unsigned char> &data = model.buffers[size_t(bv.buffer)].data;
    if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
        fail(REFL_ERROR_BAD_MESH, format("%s: bufferView %d (offset %zu, length %zu) lies outside buffer %d (%zu bytes)",
                                         w, a.bufferView, bv.byteOffset, bv.byteLength, bv.buffer, data.size()));
    size_t elem = size_t(v.csize) * size_t(v.ncomp);
    v.stride = bv.byteStride ? bv.byteStride : elem;
    if (v.stride < elem || v.stride > 1024)
        fail(REFL_ERROR_BAD_MESH, format("%s: bufferView %d: byteStride %zu for %zu-byte elements", w, a.bufferView,
                                         bv.byteStride, elem));
    size_t avail = a.byteOffset <= bv.byteLength ? bv.byteLength - a.byteOffset : 0;
    if (a.byteOffset > bv.byteLength || avail < elem || (v.count - 1) > (avail - elem) / v.stride)
        fail(REFL_ERROR_BAD_MESH,
             format("%s: accessor %d (offset %zu, %zu elements, stride %zu) overruns bufferView %d (%zu bytes)", w,
                    index, a.byteOffset, v.count, v.stride, a.bufferView, bv.byteLength));
    v.base = data.data() + bv.byteOffset + a.byteOffset;
    return v;
}

// ---- colours ------------------------------------------------------------------

float srgb_to_linear(double c) {
    return float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
}

double luminance(double r, double g, double b) { return 0.2126 * r + 0.7152 * g + 0.0722 * b; }

void copy_name(char (&dst)[32], const std::string &src) {
    size_t n = std::min(src.size(), sizeof dst - 1);
    std::memcpy(dst, src.data(), n);
    dst[n] = '\0';
}

double ext_number(const tinygltf::ExtensionMap &ext, const char *name, const char *key, double fallback,
                  bool *present = nullptr) {
    auto it = ext.find(name);
    if (present) *present = it != ext.end();
    if (it == ext.end() || !it->second.IsObject() || !it->second.Has(key)) return fallback;
    const tinygltf::Value &v = it->second.Get(key);
    return v.IsNumber() ? v.GetNumberAsDouble() : fallback;
}

// KHR_materials_volume on a glass, as the material model can hold it: Beer's
// law per channel, sigma_c = -ln(attenuationColor_c) / attenuationDistance
// per unit of length, while refl_material has one attenuation and a tint.
// The least absorbed channel's sigma becomes the attenuation (exact at every
// path length); the other channels' excess over it goes into the tint at the
// volume's nominal thickness (thicknessFactor): exact there, the same hue at
// other lengths. thicknessFactor 0 is thin-walled (no volume, no absorption).
// tint comes in as the base colour and leaves multiplied by the excess.
void volume_absorption(const tinygltf::Material &gm, const std::string &what, double tint[3], double *attenuation) {
    *attenuation = 0;
    auto it = gm.extensions.find("KHR_materials_volume");
    if (it == gm.extensions.end() || !it->second.IsObject()) return;
    double dist = ext_number(gm.extensions, "KHR_materials_volume", "attenuationDistance", INFINITY);
    double thickness = ext_number(gm.extensions, "KHR_materials_volume", "thicknessFactor", 0);
    if (!(dist > 0) || !std::isfinite(dist) || !(thickness > 0) || !std::isfinite(thickness)) return;
    double col[3] = {1, 1, 1};
    const tinygltf::Value &ac = it->second.Get("attenuationColor");
    if (ac.IsArray() && ac.ArrayLen() == 3)
        for (int k = 0; k < 3; k++)
            if (ac.Get(k).IsNumber() && std::isfinite(ac.Get(k).GetNumberAsDouble()))
                col[k] = std::min(std::max(ac.Get(k).GetNumberAsDouble(), 1e-4), 1.0);
    double sigma[3], least = INFINITY;
    for (int k = 0; k < 3; k++) {
        sigma[k] = -std::log(col[k]) / dist;
        least = std::min(least, sigma[k]);
    }
    if (!fits_float(least))
        fail(REFL_ERROR_BAD_MESH, format("%s: KHR_materials_volume: attenuation %g per unit (attenuationDistance %g) "
                                         "does not fit a float", what.c_str(), least, dist));
    for (int k = 0; k < 3; k++) tint[k] *= std::exp(-(sigma[k] - least) * thickness);
    *attenuation = least;
}

// Metallic-roughness surfaces whose mirror share is below this stay diffuse:
// a dielectric's 0.04 among them, which glTF shows mostly at grazing angles
// (Fresnel), where a constant mirror share would spread it over the surface.
const double kMinMirrorWeight = 0.05;

// ---- the loader ---------------------------------------------------------------

struct SceneDeleter { void operator()(refl_scene *s) const { refl_scene_destroy(s); } };
struct MeshDeleter { void operator()(refl_mesh *m) const { refl_mesh_destroy(m); } };

// tinygltf's image callback: keeps the encoded bytes, so that only the
// images a base colour texture uses are decoded (by tinygltf's own decoder),
// and a damaged image of an unused map does not fail the load. tinygltf
// hands over an image's bufferView without checking it against its buffer,
// so the sink checks that range before reading a byte of it (the model's
// buffers and bufferViews are parsed before its images).
typedef std::vector<std::vector<unsigned char>> RawImages;

struct ImageSink {
    const tinygltf::Model *model = nullptr;
    RawImages raw;
    std::string error;  // the first image whose bytes lie outside their buffer
};

// The width and height a PNG (IHDR) or baseline/progressive JPEG (SOFn)
// header gives, read before decoding so that a texture too large is refused
// before memory is spent on it; false for any other format.
bool image_size(const std::vector<unsigned char> &d, long long *w, long long *h) {
    static const unsigned char png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    auto be16 = [&](size_t i) { return (long long)(d[i] << 8 | d[i + 1]); };
    if (d.size() >= 24 && std::memcmp(d.data(), png, 8) == 0 && std::memcmp(&d[12], "IHDR", 4) == 0) {
        *w = be16(16) << 16 | be16(18);
        *h = be16(20) << 16 | be16(22);
        return true;
    }
    if (d.size() < 4 || d[0] != 0xFF || d[1] != 0xD8) return false;
    size_t i = 2;
    while (i + 4 <= d.size()) {
        if (d[i] != 0xFF) return false;
        unsigned char marker = d[i + 1];
        if (marker == 0xFF) { i++; continue; }  // fill byte
        size_t len = size_t(be16(i + 2));
        bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
        if (sof) {
            if (i + 9 > d.size()) return false;
            *h = be16(i + 5);
            *w = be16(i + 7);
            return true;
        }
        if (len < 2) return false;
        i += 2 + len;
    }
    return false;
}

bool defer_image(tinygltf::Image *image, const int index, std::string *, std::string *, int, int,
                 const unsigned char *bytes, int size, void *user) {
    ImageSink &sink = *static_cast<ImageSink *>(user);
    if (image && image->bufferView >= 0) {
        const tinygltf::Model &m = *sink.model;
        const size_t v = size_t(image->bufferView);
        if (v >= m.bufferViews.size() || m.bufferViews[v].buffer < 0 ||
            size_t(m.bufferViews[v].buffer) >= m.buffers.size()) {
            sink.error = format("image %d: bufferView %d or its buffer does not exist", index, image->bufferView);
            return false;
        }
        const tinygltf::BufferView &bv = m.bufferViews[v];
        const size_t have = m.buffers[size_t(bv.buffer)].data.size();
        if (bv.byteOffset > have || bv.byteLength > have - bv.byteOffset || bv.byteLength > size_t(INT32_MAX)) {
            sink.error = format("image %d: bufferView %d (byteOffset %zu, byteLength %zu) lies outside buffer %d "
                                "(%zu bytes)", index, image->bufferView, bv.byteOffset, bv.byteLength, bv.buffer, have);
            return false;
        }
    }
    if (index < 0 || index > (1 << 20) || size < 0 || (size > 0 && !bytes)) return false;
    if (size_t(index) >= sink.raw.size()) sink.raw.resize(size_t(index) + 1);
    sink.raw[size_t(index)].assign(bytes, bytes + size);
    return true;
}

class Loader {
public:
    Loader(const tinygltf::Model &model, const RawImages &raw_images, const refl_gltf_options &opt)
        : model_(model), raw_images_(raw_images), opt_(opt) {}

    std::unique_ptr<refl_scene, SceneDeleter> run(std::string &warnings);

private:
    const tinygltf::Model &model_;
    const RawImages &raw_images_;
    const refl_gltf_options &opt_;
    std::unique_ptr<refl_scene, SceneDeleter> scene_;
    std::string warnings_;
    std::map<int, int> image_texture_;             // glTF image -> scene texture
    std::vector<int> material_index_;              // glTF material -> scene material
    int default_material_ = -1;
    // what a scene mesh is made of: mode, indices, POSITION, NORMAL, TEXCOORD_n, COLOR_0
    struct PrimKey {
        std::array<int, 6> a;
        bool operator<(const PrimKey &o) const { return a < o.a; }
    };
    std::map<PrimKey, int> prim_mesh_;              // -> scene mesh, -1: skipped
    long long skipped_prims_ = 0, objects_ = 0;
    int skipped_mode_ = -1;
    std::vector<std::pair<int, float>> glass_;      // (material, attenuation) to rescale
    std::vector<char> seen_;                        // nodes visited
    int cameras_ = 0;                               // perspective camera nodes met
    std::map<std::string, int> ignored_;            // glTF feature the renderer ignores -> uses
    std::vector<std::array<double, 6>> mesh_bounds_; // scene mesh -> its vertices' lo xyz, hi xyz

    void warn(const std::string &w) { warnings_ += w; warnings_ += '\n'; }
    void check_extensions();
    void note_ignored_features();
    void add_materials();
    int texture_for(int gltf_texture, const std::string &what);
    int material_for(int gltf_material, const std::string &what);
    void emission(const tinygltf::Material &gm, const std::string &what, refl_material *m);
    int mesh_for(int mesh, int prim);
    int build_mesh(int mesh, int prim, const PrimKey &key, const std::string &texcoord_name);
    void traverse();
    void visit_node(int node, const Mat &world);
    void check_placement(int node, const Mat &world, int scene_mesh);
    void check_point(int node, const char *what, const double p[3]);
};

void Loader::check_extensions() {
    for (const std::string &e : model_.extensionsRequired) {
        bool ok = e.rfind("KHR_materials_", 0) == 0 || e == "KHR_texture_transform" || e == "KHR_lights_punctual" ||
                  e == "KHR_mesh_quantization" || e == "KHR_xmp" || e == "KHR_xmp_json_ld";
        if (!ok) fail(REFL_ERROR_UNSUPPORTED, format("requires extension %s, which this loader does not support", e.c_str()));
    }
}

int Loader::texture_for(int t, const std::string &what) {
    if (t < 0) return 0;
    if (size_t(t) >= model_.textures.size())
        fail(REFL_ERROR_BAD_MESH, format("%s: texture %d does not exist", what.c_str(), t));
    int src = model_.textures[size_t(t)].source;
    if (src < 0) {
        warn(format("%s: texture %d has no PNG/JPEG source; ignored", what.c_str(), t));
        return 0;
    }
    if (size_t(src) >= model_.images.size())
        fail(REFL_ERROR_BAD_MESH, format("%s: texture %d: image %d does not exist", what.c_str(), t, src));
    auto found = image_texture_.find(src);
    if (found != image_texture_.end()) return found->second;
    // decoded here, on first use (see defer_image)
    tinygltf::Image img;
    std::string derr, dwarn;
    const std::vector<unsigned char> *raw = size_t(src) < raw_images_.size() ? &raw_images_[size_t(src)] : nullptr;
    const long long limit = opt_.max_texture_pixels > 0 ? opt_.max_texture_pixels : kDefaultMaxTexturePixels;
    if (raw && !raw->empty()) {
        long long w = 0, h = 0;
        if (!image_size(*raw, &w, &h)) {
            warn(format("%s: image %d is neither PNG nor JPEG; texture ignored", what.c_str(), src));
            return image_texture_[src] = 0;
        }
        if (w * h > limit)
            fail(REFL_ERROR_INVALID_SIZE, format("%s: image %d is %lldx%lld, more than the texture limit of %lld "
                                                 "pixels (refl_gltf_options.max_texture_pixels)",
                                                 what.c_str(), src, w, h, limit));
    }
    if (!raw || raw->empty() || raw->size() > size_t(INT32_MAX) ||
        !tinygltf::LoadImageData(&img, src, &derr, &dwarn, 0, 0, raw->data(), int(raw->size()), nullptr)) {
        while (!derr.empty() && derr.back() == '\n') derr.pop_back();
        warn(format("%s: image %d cannot be decoded (%s); texture ignored", what.c_str(), src,
                    derr.empty() ? "no data" : derr.c_str()));
        return image_texture_[src] = 0;
    }
    int w = img.width, h = img.height, comp = img.component, bytes = img.bits / 8;
    if ((long long)w * h > limit)
        fail(REFL_ERROR_INVALID_SIZE, format("%s: image %d: %dx%d is too large", what.c_str(), src, w, h));
    if (comp < 1 || comp > 4 || (bytes != 1 && bytes != 2) ||
        img.image.size() != size_t(w) * size_t(h) * size_t(comp) * size_t(bytes))
        fail(REFL_ERROR_BAD_MESH, format("%s: image %d: inconsistent decoded size (%dx%d, %d channels, %d bits)",
                                         what.c_str(), src, w, h, comp, img.bits));
    float lut[256];
    for (int i = 0; i < 256; i++) lut[i] = srgb_to_linear(i / 255.0);
    size_t n = size_t(w) * size_t(h);
    std::vector<float> rgba(n * 4);
    const unsigned char *p = img.image.data();
    for (size_t i = 0; i < n; i++) {
        float c[4] = {0, 0, 0, 1};
        for (int k = 0; k < comp; k++) {
            const unsigned char *q = p + (i * size_t(comp) + size_t(k)) * size_t(bytes);
            bool alpha = (comp == 2 && k == 1) || k == 3;
            if (bytes == 1) c[k] = alpha ? q[0] / 255.0f : lut[q[0]];
            else {
                uint16_t v; std::memcpy(&v, q, 2);
                c[k] = alpha ? v / 65535.0f : srgb_to_linear(v / 65535.0);
            }
        }
        if (comp <= 2) { c[3] = comp == 2 ? c[1] : 1; c[1] = c[2] = c[0]; }
        std::memcpy(&rgba[i * 4], c, sizeof c);
    }
    int idx = refl_scene_add_texture(scene_.get(), w, h, rgba.data());
    if (idx < 0) fail(refl_result(idx), format("%s: image %d: refl_scene_add_texture failed: %s", what.c_str(), src,
                                               refl_result_string(refl_result(idx))));
    return image_texture_[src] = idx;
}

void Loader::add_materials() {
    for (size_t i = 0; i < model_.materials.size(); i++) {
        const tinygltf::Material &gm = model_.materials[i];
        const tinygltf::PbrMetallicRoughness &pbr = gm.pbrMetallicRoughness;
        std::string what = format("material %zu '%s'", i, gm.name.c_str());
        double base[4] = {1, 1, 1, 1};
        if (pbr.baseColorFactor.size() == 4)
            for (int k = 0; k < 4; k++) base[k] = pbr.baseColorFactor[size_t(k)];
        for (double &b : base) b = std::isfinite(b) ? std::min(std::max(b, 0.0), 1.0) : 1.0;
        double metallic = pbr.metallicFactor, roughness = pbr.roughnessFactor;
        bool has_transmission = false;
        double transmission = ext_number(gm.extensions, "KHR_materials_transmission", "transmissionFactor", 0,
                                         &has_transmission);

        refl_material m;
        std::memset(&m, 0, sizeof m);
        copy_name(m.name, gm.name);
        for (int k = 0; k < 4; k++) m.color[k] = float(base[k]);
        double mirror_weight = 0, reflectance = 1;
        if (std::isfinite(metallic) && std::isfinite(roughness)) {
            metallic = std::min(std::max(metallic, 0.0), 1.0);
            roughness = std::min(std::max(roughness, 0.0), 1.0);
            // see gltf_load.h: the sharp share of the specular lobe, at glTF's
            // normal-incidence reflectance (0.04 for the dielectric share)
            double metal_f0 = luminance(base[0], base[1], base[2]);
            double f0 = 0.04 * (1 - metallic) + metallic;
            mirror_weight = (1 - roughness) * (1 - roughness) * f0;
            reflectance = (0.04 * (1 - metallic) + metallic * metal_f0) / f0;
        }
        if (metallic >= 0.99 && roughness <= 0.05) {
            m.type = REFL_MIRROR;
            double lum = luminance(base[0], base[1], base[2]);
            m.reflectance = lum > 0 ? float(lum) : 1.0f;
        } else if (has_transmission && transmission > 0) {
            m.type = REFL_GLASS;
            double ior = ext_number(gm.extensions, "KHR_materials_ior", "ior", 1.5);
            if (std::isfinite(ior) && !fits_float(ior))
                fail(REFL_ERROR_BAD_MESH, format("%s: KHR_materials_ior.ior %g does not fit a float", what.c_str(), ior));
            m.ior = std::isfinite(ior) && ior >= 1 ? float(ior) : 1.5f;
            double tint[3] = {base[0], base[1], base[2]}, attenuation = 0;
            volume_absorption(gm, what, tint, &attenuation);
            for (int k = 0; k < 3; k++) m.tint[k] = float(tint[k]);
            m.attenuation = float(attenuation);
        } else if (mirror_weight >= kMinMirrorWeight) {
            m.type = REFL_PARTIAL;
            m.mirror_weight = float(mirror_weight);
            m.reflectance = reflectance > 0 ? float(reflectance) : 1e-6f;
            m.texture = texture_for(pbr.baseColorTexture.index, what);
        } else {
            m.type = REFL_DIFFUSE;
            m.texture = texture_for(pbr.baseColorTexture.index, what);
        }
        emission(gm, what, &m);
        int idx = refl_scene_add_material(scene_.get(), &m);
        if (idx < 0) fail(refl_result(idx), format("%s: refl_scene_add_material failed", what.c_str()));
        material_index_.push_back(idx);
        if (m.type == REFL_GLASS && m.attenuation > 0) glass_.emplace_back(idx, m.attenuation);
    }
}

// emissiveFactor times KHR_materials_emissive_strength, on the diffuse share
// (refl_material.emissive); mirrors and glass have none to add it to. An
// emissiveTexture is not drawn (a warning), and then neither is its factor.
void Loader::emission(const tinygltf::Material &gm, const std::string &what, refl_material *m) {
    // the factor scales the texture: without the texture it is no emission
    if (gm.emissiveFactor.size() != 3 || gm.emissiveTexture.index >= 0) return;
    double strength = ext_number(gm.extensions, "KHR_materials_emissive_strength", "emissiveStrength", 1);
    double e[3];
    for (int k = 0; k < 3; k++) {
        e[k] = gm.emissiveFactor[size_t(k)] * strength;
        if (!(e[k] > 0)) e[k] = 0;  // glTF's factors are >= 0
        if (!fits_float(e[k]))
            fail(REFL_ERROR_BAD_MESH, format("%s: emission %g does not fit a float", what.c_str(), e[k]));
    }
    if (e[0] == 0 && e[1] == 0 && e[2] == 0) return;
    if (m->type == REFL_MIRROR || m->type == REFL_GLASS) {
        warn(format("%s: emission on a %s is not drawn", what.c_str(), m->type == REFL_MIRROR ? "mirror" : "glass"));
        return;
    }
    for (int k = 0; k < 3; k++) m->emissive[k] = float(e[k]);
}

int Loader::material_for(int g, const std::string &what) {
    if (g >= 0) {
        if (size_t(g) >= material_index_.size())
            fail(REFL_ERROR_BAD_MESH, format("%s: material %d does not exist (%zu materials)", what.c_str(), g,
                                             material_index_.size()));
        return material_index_[size_t(g)];
    }
    if (default_material_ < 0) {
        refl_material m;
        std::memset(&m, 0, sizeof m);
        m.type = REFL_DIFFUSE;
        m.color[0] = m.color[1] = m.color[2] = m.color[3] = 1;
        copy_name(m.name, "default");
        default_material_ = refl_scene_add_material(scene_.get(), &m);
        if (default_material_ < 0) fail(refl_result(default_material_), "refl_scene_add_material failed");
    }
    return default_material_;
}

// The scene mesh of one primitive, or -1 when skipped. Primitives that read
// the same accessors share one scene mesh: glTF puts the material in the
// primitive, so instancing a shape with different materials repeats the
// accessors in several meshes.
int Loader::mesh_for(int mi, int pi) {
    const tinygltf::Mesh &gmesh = model_.meshes[size_t(mi)];
    const tinygltf::Primitive &prim = gmesh.primitives[size_t(pi)];
    auto attr = [&](const std::string &name) {
        auto it = prim.attributes.find(name);
        return it == prim.attributes.end() ? -1 : it->second;
    };
    int set = 0;  // the texture coordinate set of the base colour texture
    if (prim.material >= 0 && size_t(prim.material) < model_.materials.size())
        set = std::max(0, model_.materials[size_t(prim.material)].pbrMetallicRoughness.baseColorTexture.texCoord);
    std::string texcoord_name = format("TEXCOORD_%d", set);
    PrimKey key{{prim.mode, prim.indices, attr("POSITION"), attr("NORMAL"), attr(texcoord_name), attr("COLOR_0")}};
    auto found = prim_mesh_.find(key);
    if (found != prim_mesh_.end()) return found->second;
    return prim_mesh_[key] = build_mesh(mi, pi, key, texcoord_name);
}

int Loader::build_mesh(int mi, int pi, const PrimKey &key, const std::string &texcoord_name) {
    const tinygltf::Mesh &gmesh = model_.meshes[size_t(mi)];
    const tinygltf::Primitive &prim = gmesh.primitives[size_t(pi)];
    std::string what = format("primitive %d of mesh %d '%s'", pi, mi, gmesh.name.c_str());
    const char *w = what.c_str();

    int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        static const char *names[] = {"POINTS", "LINES", "LINE_LOOP", "LINE_STRIP"};
        if (mode > 6) fail(REFL_ERROR_BAD_MESH, format("%s: unknown primitive mode %d", w, mode));
        warn(format("%s: mode %s is not drawn; skipped", w, names[mode]));
        skipped_prims_++;
        skipped_mode_ = mode;
        return -1;
    }
    int pos_acc = key.a[2];
    if (pos_acc < 0) fail(REFL_ERROR_BAD_MESH, format("%s: no POSITION attribute", w));
    View pos = view_accessor(model_, pos_acc, "POSITION of " + what, {3}, false);
    size_t nv = pos.count;
    if (nv > size_t(INT32_MAX) / 4) fail(REFL_ERROR_INVALID_SIZE, format("%s: %zu vertices is too many", w, nv));
    std::vector<float> positions(nv * 3);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < nv; i++)
        for (int c = 0; c < 3; c++) {
            double v = pos.get(i, c);
            if (!std::isfinite(v)) fail(REFL_ERROR_BAD_MESH, format("%s: vertex %zu has a non-finite position", w, i));
            if (std::fabs(v) > kMaxCoordinate)
                fail(REFL_ERROR_BAD_MESH, format("%s: vertex %zu: POSITION %g is beyond +-%g", w, i, v, kMaxCoordinate));
            positions[i * 3 + size_t(c)] = float(v);
            lo[c] = std::min(lo[c], v);
            hi[c] = std::max(hi[c], v);
        }

    auto same_count = [&](const View &v, const char *name) {
        if (v.count != nv)
            fail(REFL_ERROR_BAD_MESH, format("%s: %s has %zu elements, POSITION %zu", w, name, v.count, nv));
    };
    std::vector<float> normals;
    if (int a = key.a[3]; a >= 0) {
        View v = view_accessor(model_, a, "NORMAL of " + what, {3}, false);
        same_count(v, "NORMAL");
        normals.resize(nv * 3);
        for (size_t i = 0; i < nv && !normals.empty(); i++) {
            double n[3] = {v.get(i, 0), v.get(i, 1), v.get(i, 2)};
            double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (!std::isfinite(len) || len < 1e-20) {
                warn(format("%s: normal %zu is zero or not finite; normals computed instead", w, i));
                normals.clear();
                break;
            }
            for (int c = 0; c < 3; c++) normals[i * 3 + size_t(c)] = float(n[c] / len);
        }
    }
    std::vector<float> texcoords;
    bool bad_values = false;
    if (int a = key.a[4]; a >= 0) {
        View v = view_accessor(model_, a, texcoord_name + " of " + what, {2}, false);
        same_count(v, "TEXCOORD");
        texcoords.resize(nv * 2);
        for (size_t i = 0; i < nv * 2; i++) {
            double t = v.get(i / 2, int(i % 2));
            if (!std::isfinite(t) || std::fabs(t) > 1e30) { t = 0; bad_values = true; }
            texcoords[i] = float(t);
        }
    }
    std::vector<float> colors;
    if (int a = key.a[5]; a >= 0) {
        View v = view_accessor(model_, a, "COLOR_0 of " + what, {3, 4}, false);
        same_count(v, "COLOR_0");
        colors.resize(nv * 4);
        for (size_t i = 0; i < nv; i++)
            for (int c = 0; c < 4; c++) {
                double x = c < v.ncomp ? v.get(i, c) : 1.0;
                if (!std::isfinite(x)) { x = 1; bad_values = true; }
                colors[i * 4 + size_t(c)] = float(std::min(std::max(x, 0.0), 1.0));
            }
    }
    if (bad_values) warn(format("%s: non-finite texture coordinates or colours replaced", w));

    std::vector<uint32_t> idx;
    size_t ni = nv;
    View iv;
    if (prim.indices >= 0) {
        iv = view_accessor(model_, prim.indices, "indices of " + what, {1}, true);
        ni = iv.count;
    }
    auto index_at = [&](size_t i) -> uint32_t {
        uint32_t k = prim.indices >= 0 ? iv.get_index(i) : uint32_t(i);
        if (k >= nv) fail(REFL_ERROR_BAD_MESH, format("%s: index %u out of range (%zu vertices)", w, k, nv));
        return k;
    };
    if (mode == TINYGLTF_MODE_TRIANGLES) {
        if (ni % 3 != 0) fail(REFL_ERROR_BAD_MESH, format("%s: %zu indices, not a multiple of 3", w, ni));
        idx.resize(ni);
        for (size_t i = 0; i < ni; i++) idx[i] = index_at(i);
    } else if (ni >= 3) {
        idx.reserve((ni - 2) * 3);
        for (size_t i = 0; i + 2 < ni; i++) {
            if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {  // spec: (i, i+1+i%2, i+2-i%2)
                idx.push_back(index_at(i));
                idx.push_back(index_at(i + 1 + i % 2));
                idx.push_back(index_at(i + 2 - i % 2));
            } else {  // fan: (i+1, i+2, 0)
                idx.push_back(index_at(i + 1));
                idx.push_back(index_at(i + 2));
                idx.push_back(index_at(0));
            }
        }
    }
    if (idx.empty()) {
        warn(format("%s: no triangles; skipped", w));
        return -1;
    }
    if (idx.size() > size_t(INT32_MAX)) fail(REFL_ERROR_INVALID_SIZE, format("%s: too many indices", w));

    refl_mesh_desc desc;
    std::memset(&desc, 0, sizeof desc);
    desc.positions = positions.data();
    desc.normals = normals.empty() ? nullptr : normals.data();
    desc.texcoords = texcoords.empty() ? nullptr : texcoords.data();
    desc.colors = colors.empty() ? nullptr : colors.data();
    desc.indices = idx.data();
    desc.vertex_count = int(nv);
    desc.index_count = int(idx.size());
    desc.allocator = opt_.allocator;
    refl_mesh *raw = nullptr;
    refl_result r = refl_mesh_create(&desc, &raw);
    std::unique_ptr<refl_mesh, MeshDeleter> mesh(raw);
    if (r != REFL_OK || !mesh) {
        fail(r != REFL_OK ? r : REFL_ERROR_BAD_MESH,
             format("%s: refl_mesh_create failed: %s", w, refl_result_string(r)));
    }
    int sm = refl_scene_add_mesh(scene_.get(), mesh.release());  // owns it, also on failure
    if (sm < 0) fail(refl_result(sm), format("%s: refl_scene_add_mesh failed", w));
    if (size_t(sm) >= mesh_bounds_.size()) mesh_bounds_.resize(size_t(sm) + 1);
    mesh_bounds_[size_t(sm)] = {{lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]}};
    return sm;
}

const long long kMaxObjects = 1000000;

void Loader::check_point(int ni, const char *what, const double p[3]) {
    for (int c = 0; c < 3; c++)
        if (!(std::fabs(p[c]) <= kMaxCoordinate))
            fail(REFL_ERROR_BAD_MESH, format("node %d '%s': %s (%g, %g, %g) is beyond +-%g", ni,
                                             model_.nodes[size_t(ni)].name.c_str(), what, p[0], p[1], p[2],
                                             kMaxCoordinate));
}

// The node's world transform must fit a float and keep the mesh's vertices
// (the corners of their box) within kMaxCoordinate.
void Loader::check_placement(int ni, const Mat &world, int sm) {
    const tinygltf::Node &node = model_.nodes[size_t(ni)];
    for (double v : world.m)
        if (!fits_float(v))
            fail(REFL_ERROR_BAD_MESH, format("node %d '%s': transform entry %g does not fit a float", ni,
                                             node.name.c_str(), v));
    const std::array<double, 6> &b = mesh_bounds_[size_t(sm)];
    for (int corner = 0; corner < 8; corner++) {
        double in[4] = {b[corner & 1 ? 3 : 0], b[corner & 2 ? 4 : 1], b[corner & 4 ? 5 : 2], 1}, out[3];
        world.apply(in, out);
        for (int c = 0; c < 3; c++)
            if (!(std::fabs(out[c]) <= kMaxCoordinate))
                fail(REFL_ERROR_BAD_MESH, format("node %d '%s': its transform puts mesh %d's vertices at %g, beyond "
                                                 "+-%g", ni, node.name.c_str(), node.mesh, out[c], kMaxCoordinate));
    }
}

void Loader::visit_node(int root, const Mat &parent) {
    // Depth first, pre-order, with an explicit stack: deep hierarchies cannot
    // overflow the C stack, and a node reached twice (a cycle, or a node with
    // two parents: both invalid glTF) is visited once.
    struct Item { int node; Mat parent; };
    std::vector<Item> stack{{root, parent}};
    std::vector<char> &seen = seen_;
    while (!stack.empty()) {
        Item it = stack.back();
        stack.pop_back();
        int ni = it.node;
        if (ni < 0 || size_t(ni) >= model_.nodes.size())
            fail(REFL_ERROR_BAD_MESH, format("node %d does not exist (%zu nodes)", ni, model_.nodes.size()));
        if (seen[size_t(ni)]) {
            warn(format("node %d is reached twice (a cycle or two parents); visited once", ni));
            continue;
        }
        seen[size_t(ni)] = 1;
        const tinygltf::Node &node = model_.nodes[size_t(ni)];
        Mat world = it.parent * node_matrix(node, ni);
        if (!world.finite()) fail(REFL_ERROR_BAD_MESH, format("node %d: non-finite world transform", ni));

        if (node.mesh >= 0) {
            if (size_t(node.mesh) >= model_.meshes.size())
                fail(REFL_ERROR_BAD_MESH, format("node %d: mesh %d does not exist (%zu meshes)", ni, node.mesh,
                                                 model_.meshes.size()));
            const tinygltf::Mesh &gm = model_.meshes[size_t(node.mesh)];
            for (size_t p = 0; p < gm.primitives.size(); p++) {
                int sm = mesh_for(node.mesh, int(p));
                if (sm < 0) continue;
                if (++objects_ > kMaxObjects)
                    fail(REFL_ERROR_INVALID_SIZE, format("more than %lld objects", kMaxObjects));
                refl_object o;
                std::memset(&o, 0, sizeof o);
                o.mesh = sm;
                o.material = material_for(gm.primitives[p].material,
                                          format("primitive %zu of mesh %d '%s'", p, node.mesh, gm.name.c_str()));
                check_placement(ni, world, sm);
                for (int k = 0; k < 16; k++) o.transform.m[k] = float(world.m[k]);
                copy_name(o.name, !node.name.empty() ? node.name
                                  : !gm.name.empty() ? gm.name
                                                     : format("node %d", ni));
                if (int r = refl_scene_add_object(scene_.get(), &o); r < 0)
                    fail(refl_result(r), format("node %d: refl_scene_add_object failed: %s", ni,
                                                refl_result_string(refl_result(r))));
            }
        }
        if (node.camera >= 0) {
            if (size_t(node.camera) >= model_.cameras.size())
                fail(REFL_ERROR_BAD_MESH, format("node %d: camera %d does not exist", ni, node.camera));
            const tinygltf::Camera &cam = model_.cameras[size_t(node.camera)];
            if (cam.type != "perspective") ignored_["orthographic cameras"]++;
            // the opt_.camera-th perspective camera node, depth first
            if (cam.type == "perspective" && cameras_++ == opt_.camera) {
                static const double origin[4] = {0, 0, 0, 1}, fwd[4] = {0, 0, -1, 0}, up[4] = {0, 1, 0, 0};
                double e[3], f[3], u[3];
                world.apply(origin, e);
                world.apply(fwd, f);
                world.apply(up, u);
                double fl = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
                double ul = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
                if (fl > 0 && ul > 0 && std::isfinite(fl) && std::isfinite(ul)) {
                    check_point(ni, "camera position", e);
                    refl_view &v = scene_->camera;
                    std::memset(&v, 0, sizeof v);
                    v.eye = {float(e[0]), float(e[1]), float(e[2])};
                    v.target = {float(e[0] + f[0] / fl), float(e[1] + f[1] / fl), float(e[2] + f[2] / fl)};
                    v.up = {float(u[0] / ul), float(u[1] / ul), float(u[2] / ul)};
                    double yfov = cam.perspective.yfov;
                    if (std::isfinite(yfov) && yfov > 0 && yfov < 3.1) v.fovy_degrees = float(yfov * 180.0 / M_PI);
                    scene_->has_camera = 1;
                } else {
                    warn(format("node %d: camera with a degenerate transform; ignored", ni));
                }
            }
        }
        auto lp = node.extensions.find("KHR_lights_punctual");
        if (lp != node.extensions.end() && lp->second.IsObject() && lp->second.Get("light").IsNumber()) {
            int li = lp->second.Get("light").GetNumberAsInt();
            if (li < 0 || size_t(li) >= model_.lights.size())
                fail(REFL_ERROR_BAD_MESH, format("node %d: light %d does not exist", ni, li));
            const tinygltf::Light &gl = model_.lights[size_t(li)];
            refl_light l;
            std::memset(&l, 0, sizeof l);
            double col[3] = {1, 1, 1};
            if (gl.color.size() == 3) col[0] = gl.color[0], col[1] = gl.color[1], col[2] = gl.color[2];
            double inten = std::isfinite(gl.intensity) && gl.intensity >= 0 ? gl.intensity : 1.0;
            for (int k = 0; k < 3; k++) {
                double c = std::isfinite(col[k]) ? std::max(col[k], 0.0) * inten : inten;
                if (!fits_float(c))
                    fail(REFL_ERROR_BAD_MESH, format("node %d: light %d: color x intensity %g does not fit a float", ni,
                                                     li, c));
                l.color[k] = float(c);
            }
            double p[3];
            static const double origin[4] = {0, 0, 0, 1}, fwd[4] = {0, 0, -1, 0};
            if (gl.type == "directional") {
                world.apply(fwd, p);
                double len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
                if (!(len > 0) || !std::isfinite(len)) fail(REFL_ERROR_BAD_MESH, format("node %d: degenerate light direction", ni));
                l.type = REFL_LIGHT_DIRECTIONAL;
                l.direction = {float(p[0] / len), float(p[1] / len), float(p[2] / len)};
            } else {
                if (gl.type != "point" && gl.type != "spot")
                    warn(format("light %d: unknown type '%s', used as a point light", li, gl.type.c_str()));
                world.apply(origin, p);
                check_point(ni, "light position", p);
                l.type = REFL_LIGHT_POINT;
                l.position = {float(p[0]), float(p[1]), float(p[2])};
            }
            if (refl_scene_add_light(scene_.get(), &l) < 0)
                fail(REFL_ERROR_OUT_OF_MEMORY, format("node %d: refl_scene_add_light failed", ni));
        }
        // children pushed in reverse, so they pop in file order
        for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.push_back({*c, world});
    }
}

void Loader::traverse() {
    seen_.assign(model_.nodes.size(), 0);
    std::vector<int> roots;
    if (!model_.scenes.empty()) {
        int s = model_.defaultScene;
        if (s < 0 || size_t(s) >= model_.scenes.size()) {
            if (s >= 0) warn(format("default scene %d does not exist; scene 0 used", s));
            s = 0;
        }
        roots = model_.scenes[size_t(s)].nodes;
    } else {
        // no scenes: every node that is nobody's child
        std::vector<char> child(model_.nodes.size(), 0);
        for (const tinygltf::Node &n : model_.nodes)
            for (int c : n.children)
                if (c >= 0 && size_t(c) < child.size()) child[size_t(c)] = 1;
        for (size_t i = 0; i < child.size(); i++)
            if (!child[i]) roots.push_back(int(i));
    }
    for (int r : roots) visit_node(r, Mat::identity());
}

// One warning per glTF feature the scene uses and the renderer does not draw,
// with how often it is used.
void Loader::note_ignored_features() {
    static const char *const drawn_material_ext[] = {"KHR_materials_transmission", "KHR_materials_ior",
                                                     "KHR_materials_volume", "KHR_materials_emissive_strength"};
    auto texture_transform = [&](const tinygltf::ExtensionMap &ext) {
        if (ext.count("KHR_texture_transform")) ignored_["KHR_texture_transform"]++;
    };
    for (const tinygltf::Material &gm : model_.materials) {
        if (gm.alphaMode == "MASK" || gm.alphaMode == "BLEND") ignored_["alphaMode " + gm.alphaMode + " (drawn opaque)"]++;
        if (gm.normalTexture.index >= 0) ignored_["normalTexture"]++;
        if (gm.occlusionTexture.index >= 0) ignored_["occlusionTexture"]++;
        if (gm.emissiveTexture.index >= 0) ignored_["emissiveTexture"]++;
        if (gm.pbrMetallicRoughness.metallicRoughnessTexture.index >= 0) ignored_["metallicRoughnessTexture"]++;
        texture_transform(gm.pbrMetallicRoughness.baseColorTexture.extensions);
        for (const auto &e : gm.extensions)
            if (std::find(std::begin(drawn_material_ext), std::end(drawn_material_ext), e.first) ==
                std::end(drawn_material_ext))
                ignored_[e.first]++;
    }
    for (const tinygltf::Sampler &sm : model_.samplers)
        if ((sm.wrapS != -1 && sm.wrapS != TINYGLTF_TEXTURE_WRAP_REPEAT) ||
            (sm.wrapT != -1 && sm.wrapT != TINYGLTF_TEXTURE_WRAP_REPEAT))
            ignored_["sampler wrap modes other than REPEAT"]++;
    for (const tinygltf::Mesh &gm : model_.meshes)
        for (const tinygltf::Primitive &p : gm.primitives)
            if (!p.targets.empty()) ignored_["morph targets (the rest pose is drawn)"]++;
    if (!model_.skins.empty()) ignored_["skins (the rest pose is drawn)"] += int(model_.skins.size());
    if (!model_.animations.empty()) ignored_["animations"] += int(model_.animations.size());
    for (const auto &f : ignored_) warn(format("not drawn: %s (%d use%s)", f.first.c_str(), f.second, f.second == 1 ? "" : "s"));
}

std::unique_ptr<refl_scene, SceneDeleter> Loader::run(std::string &warnings) {
    check_extensions();
    refl_scene *raw = nullptr;
    refl_result r = refl_scene_create(&opt_.allocator, &raw);
    scene_.reset(raw);
    if (r != REFL_OK || !scene_) fail(r != REFL_OK ? r : REFL_ERROR_OUT_OF_MEMORY, "refl_scene_create failed");
    add_materials();
    traverse();
    if (opt_.camera_count) *opt_.camera_count = cameras_;
    if (opt_.camera > 0 && opt_.camera >= cameras_)
        fail(REFL_ERROR_INVALID_ARGUMENT, format("camera %d does not exist: the scene has %d perspective camera%s",
                                                 opt_.camera, cameras_, cameras_ == 1 ? "" : "s"));
    note_ignored_features();
    if (scene_->object_count == 0) {
        if (skipped_prims_ > 0) {
            static const char *names[] = {"POINTS", "LINES", "LINE_LOOP", "LINE_STRIP"};
            fail(REFL_ERROR_UNSUPPORTED,
                 format("no triangles: the scene has only %s primitives (%lld skipped), which are not supported",
                        names[skipped_mode_], skipped_prims_));
        }
        fail(REFL_ERROR_BAD_MESH, "no triangles: the scene has no mesh primitives");
    }
    if (opt_.normalize_size > 0 && std::isfinite(opt_.normalize_size)) {
        refl_vec3 lo, hi;
        refl_scene_bounds(scene_.get(), &lo, &hi);
        double dx = double(hi.x) - lo.x, dy = double(hi.y) - lo.y, dz = double(hi.z) - lo.z;
        double diag = std::sqrt(dx * dx + dy * dy + dz * dz);
        refl_scene_normalize(scene_.get(), opt_.normalize_size);
        // attenuation is per unit of world length: a scale s divides it by s
        if (diag > 0 && std::isfinite(diag))
            for (auto &g : glass_) {
                double att = double(g.second) * diag / opt_.normalize_size;
                if (!fits_float(att))
                    fail(REFL_ERROR_BAD_MESH, format("material %d: attenuation %g after normalising does not fit a "
                                                     "float", g.first, att));
                scene_->materials[g.first].attenuation = float(att);
            }
    }
    warnings = std::move(warnings_);
    return std::move(scene_);
}

refl_result load(const char *path, const unsigned char *bytes, size_t size, const refl_gltf_options &opt,
                 refl_scene **out, std::string &warnings) {
    std::vector<unsigned char> data;
    if (bytes) {
        if (size == 0) fail(REFL_ERROR_BAD_MESH, "empty file");
        if (size > kMaxFileBytes) fail(REFL_ERROR_INVALID_SIZE, "file larger than 2 GiB");
        data.assign(bytes, bytes + size);
    } else {
        data = read_file(path);
    }
    tinygltf::TinyGLTF gltf;
    tinygltf::Model model;
    ImageSink images;
    images.model = &model;
    gltf.SetImageLoader(defer_image, &images);
    tinygltf::FsCallbacks fs = {&uri_file_exists, &tinygltf::ExpandFilePath, &read_uri_file,
                                &tinygltf::WriteWholeFile, nullptr};
    gltf.SetFsCallbacks(fs);
    std::string terr, twarn;
    bool ok;
    if (data.size() >= 4 && std::memcmp(data.data(), "glTF", 4) == 0) {
        size_t n = check_glb(data);
        check_json_shape(&data[20], le32(&data[12]));
        ok = gltf.LoadBinaryFromMemory(&model, &terr, &twarn, data.data(), unsigned(n), base_dir(path));
    } else {
        check_json_shape(data.data(), data.size());
        ok = gltf.LoadASCIIFromString(&model, &terr, &twarn, reinterpret_cast<const char *>(data.data()),
                                      unsigned(data.size()), base_dir(path));
    }
    data = std::vector<unsigned char>();  // the model holds copies now
    // tinygltf's messages can span lines; keep them on one
    auto one_line = [](std::string s) {
        while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
        std::replace(s.begin(), s.end(), '\n', ' ');
        return s;
    };
    if (!images.error.empty()) fail(REFL_ERROR_BAD_MESH, images.error);
    if (!ok) fail(REFL_ERROR_BAD_MESH, "tinygltf: " + one_line(terr.empty() ? "cannot parse the file" : terr));
    if (!terr.empty()) warnings += "tinygltf: " + one_line(terr) + "\n";
    if (!twarn.empty()) warnings += "tinygltf: " + one_line(twarn) + "\n";
    Loader loader(model, images.raw, opt);
    std::string w;
    std::unique_ptr<refl_scene, SceneDeleter> scene = loader.run(w);
    warnings += w;
    *out = scene.release();
    return REFL_OK;
}

refl_result load_c(const char *path, const void *bytes, size_t size, const refl_gltf_options *opt,
                   refl_scene **out_scene, char *err, size_t err_size) {
    if (err && err_size) err[0] = '\0';
    if (out_scene) *out_scene = nullptr;
    if (!path || !out_scene) {
        write_message(err, err_size, "refl_gltf_load: path (or name) and out_scene are required");
        return REFL_ERROR_INVALID_ARGUMENT;
    }
    refl_gltf_options defaults;
    std::memset(&defaults, 0, sizeof defaults);
    try {
        std::string warnings;
        const unsigned char *b = static_cast<const unsigned char *>(bytes);
        refl_result r = load(path, b, size, opt ? *opt : defaults, out_scene, warnings);
        // prefix every warning line with the path
        std::string text;
        size_t at = 0;
        while (at < warnings.size()) {
            size_t end = warnings.find('\n', at);
            if (end == std::string::npos) end = warnings.size();
            text += std::string(path) + ": " + warnings.substr(at, end - at) + "\n";
            at = end + 1;
        }
        write_message(err, err_size, text);
        return r;
    } catch (const LoadError &e) {
        write_message(err, err_size, std::string(path) + ": " + e.message);
        return e.code;
    } catch (const std::bad_alloc &) {
        write_message(err, err_size, std::string(path) + ": out of memory");
        return REFL_ERROR_OUT_OF_MEMORY;
    } catch (const std::exception &e) {
        write_message(err, err_size, std::string(path) + ": " + e.what());
        return REFL_ERROR_BAD_MESH;
    } catch (...) {
        write_message(err, err_size, std::string(path) + ": unexpected error");
        return REFL_ERROR_BAD_MESH;
    }
}

}  // namespace

extern "C" refl_result refl_gltf_load(const char *path, const refl_gltf_options *opt, refl_scene **out_scene,
                                      char *err, size_t err_size) {
    return load_c(path, nullptr, 0, opt, out_scene, err, err_size);
}

extern "C" refl_result refl_gltf_load_memory(const void *data, size_t size, const char *name,
                                             const refl_gltf_options *opt, refl_scene **out_scene, char *err,
                                             size_t err_size) {
    if (!data) {
        if (err && err_size) write_message(err, err_size, "refl_gltf_load_memory: data is NULL");
        if (out_scene) *out_scene = nullptr;
        return REFL_ERROR_INVALID_ARGUMENT;
    }
    return load_c(name, data, size, opt, out_scene, err, err_size);
}
