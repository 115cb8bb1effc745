// gltf_fuzz.cpp - libFuzzer target for the glTF loader (tools/gltf_load.h):
// any bytes, as .glb or .gltf, must load or fail with a message, without a
// crash, a sanitizer report, a leak or a hang. `make fuzz` runs it
// (fuzz/run.sh builds the seed corpus from ../shared/assets).
//
// With GLTF_FUZZ_OUTCOMES set, it counts what the inputs it ran gave
// (loaded, or refused: the code and the message's start) and prints the
// counts at exit:
//     GLTF_FUZZ_OUTCOMES=1 build/fuzz/gltf_fuzz -runs=0 build/fuzz/corpus
#include <cstddef>
#include <cstdint>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>

#include "../tools/gltf_load.h"

namespace {

const char kName[] = "/nonexistent/fuzz.gltf";

// outcome -> count; an outcome is "loaded", or the code and the start of
// the message with its numbers as '#' (one reason, whatever the numbers)
std::map<std::string, long> *outcomes;

const char *code_name(refl_result r) {
    switch (r) {
    case REFL_OK: return "loaded";
    case REFL_ERROR_BAD_MESH: return "BAD_MESH";
    case REFL_ERROR_UNSUPPORTED: return "UNSUPPORTED";
    case REFL_ERROR_INVALID_SIZE: return "INVALID_SIZE";
    case REFL_ERROR_OUT_OF_MEMORY: return "OUT_OF_MEMORY";
    case REFL_ERROR_UNKNOWN_NAME: return "UNKNOWN_NAME";
    case REFL_ERROR_INVALID_ARGUMENT: return "INVALID_ARGUMENT";
    default: return "other";
    }
}

void print_outcomes() {
    std::fprintf(stderr, "outcomes:\n");
    for (const auto &o : *outcomes) std::fprintf(stderr, "%8ld  %s\n", o.second, o.first.c_str());
}

void count(refl_result r, const char *err) {
    if (!outcomes) {
        outcomes = new std::map<std::string, long>;
        std::atexit(print_outcomes);
    }
    std::string key = code_name(r);
    if (r != REFL_OK) {
        key += ": ";
        const char *m = err + (std::strncmp(err, kName, sizeof kName - 1) == 0 ? sizeof kName + 1 : 0);
        for (int n = 0; *m && n < 48; m++, n++) key += std::isdigit((unsigned char)*m) ? '#' : *m;
    }
    (*outcomes)[key]++;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    static bool counting = std::getenv("GLTF_FUZZ_OUTCOMES") != nullptr;
    refl_scene *scene = nullptr;
    char err[512];
    // A name in a directory that does not exist: a .gltf's relative URIs
    // find no files, so every run depends on the bytes alone.
    refl_result r = refl_gltf_load_memory(data, size, kName, nullptr, &scene, err, sizeof err);
    if (r == REFL_OK) refl_scene_destroy(scene);
    if (counting) count(r, err);
    return 0;
}
