// gltf_fuzz.cpp - libFuzzer target for the glTF loader (tools/gltf_load.h):
// any bytes, as .glb or .gltf, must load or fail with a message, without a
// crash, a sanitizer report, a leak or a hang. `make fuzz` runs it
// (fuzz/run.sh builds the seed corpus from ../shared/assets).
//
// With GLTF_FUZZ_OUTCOMES set, it counts what the inputs it ran gave
// (loaded, or refused with which code) and prints the counts at exit:
//     GLTF_FUZZ_OUTCOMES=1 build/fuzz/gltf_fuzz -runs=0 build/fuzz/corpus
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>

#include "../tools/gltf_load.h"

namespace {

std::map<int, long> *outcomes;

void print_outcomes() {
    std::fprintf(stderr, "outcomes:");
    for (const auto &o : *outcomes)
        std::fprintf(stderr, " %s %ld;", o.first == REFL_OK ? "loaded" : refl_result_string(refl_result(o.first)),
                     o.second);
    std::fprintf(stderr, "\n");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    static bool count = std::getenv("GLTF_FUZZ_OUTCOMES") != nullptr;
    refl_scene *scene = nullptr;
    char err[512];
    // A name in a directory that does not exist: a .gltf's relative URIs
    // find no files, so every run depends on the bytes alone.
    refl_result r = refl_gltf_load_memory(data, size, "/nonexistent/fuzz.gltf", nullptr, &scene, err, sizeof err);
    if (r == REFL_OK) refl_scene_destroy(scene);
    if (count) {
        if (!outcomes) {
            outcomes = new std::map<int, long>;
            std::atexit(print_outcomes);
        }
        (*outcomes)[int(r)]++;
    }
    return 0;
}
