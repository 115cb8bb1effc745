# reflect.h + rast.h -- GNU make.
#
#   make            amalgamator, headers, C and C++ compile checks, tests, bench, examples
#   make headers    regenerate rast.h (and reflect.h) from src/
#   make test       install packages, check headers, run the tests (plain, portable, ASan/UBSan)
#   make fuzz       install packages, fuzz the glTF loader for FUZZ_SECONDS (clang, libFuzzer)
#   make bench      install packages, run the rasteriser, ray and method benchmarks -> out/
#   make demo       install packages, render every scene with every method and the chart -> out/
#   make deps       install the Debian packages the project needs (tools/deps.sh)
#   make clean
#
# rast.h and reflect.h are generated from src/ by `make headers` (and `make`,
# which runs it first). The amalgamator writes a header only when its bytes
# change, so a `make` with nothing changed rebuilds nothing. Everything else
# builds against the shipped headers; `make check-headers` tells when they
# are stale. Every object records what it includes (-MMD), so anything that
# includes a header rebuilds when that header changes.
#
# Each implementation is compiled once per configuration and linked wherever
# it is needed: tests/rast_impl.c and tests/reflect_impl.c, plain in
# build/tests/ (the test binary, the benchmarks, the `reflect` command),
# sanitized in build/asan/tests/ (the sanitized test binary), and rast.h in
# plain C without threads in build/portable/ (the rasteriser's tests again).
# Besides these, only the C and C++ compile checks compile the
# implementations (at -O0: they are never run), and each example in
# examples/, a self-contained program that defines the IMPLEMENTATION macros
# as a user's would.
#
# Build outputs mirror the source tree: tests/reflect/test_bvh.c compiles to
# build/tests/reflect/test_bvh.o, and to build/asan/tests/reflect/test_bvh.o
# sanitized.

SHELL := /bin/bash

CC  ?= cc
CXX ?= c++
CFLAGS   = -std=c99 -O2 -g -Wall -Wextra -Werror -pthread
CXXFLAGS = -std=c++11 -O2 -g -Wall -Wextra -Werror -pthread
DEPFLAGS  = -MMD -MP
LDLIBS    = -lm -pthread
# Headless GL through EGL on Mesa's llvmpipe, for the GL peer in the tests and
# the benchmark: libEGL (libegl-dev) and libGL (libgl-dev). Both are GLVND
# dispatchers; libGL exports every desktop GL entry point.
GL_LIBS   = -lEGL -lGL
TEST_LIBS = -lcriterion $(GL_LIBS) $(LDLIBS)

ASAN_CFLAGS = -std=c99 -O1 -g -Wall -Wextra -Werror -pthread \
              -fsanitize=address,undefined -fno-omit-frame-pointer
ASAN_ENV = ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$(CURDIR)/tests/lsan.supp \
           UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
CRITERION_FLAGS = --jobs 2
# The sanitized run leaves out the tests listed in tests/sanitized_skip.txt
# (the file says why and how the list was chosen), read by the test
# binaries' main (tests/rast/test_main.c).
ASAN_SKIP_FILE = tests/sanitized_skip.txt
# Builds started by `make`, `make test`, `bench`, `demo` and `fuzz` use every
# core (JOBS) unless the caller chose with -j.
JOBS ?= $(shell nproc 2>/dev/null || echo 1)
PARALLEL = $(if $(filter -j% j%,$(MAKEFLAGS)),,-j$(JOBS))
# Seconds per test run (plain, then sanitized), so `make test` stays bounded.
TEST_TIMEOUT = 450
ASAN_TEST_TIMEOUT = 900

# ---- modules, in amalgamation order (edit here when adding a module) ----

RAST_PUBLIC = src/rast/api.h
RAST_IMPL   = src/rast/internal.h \
              src/rast/threads.c \
              src/rast/context.c \
              src/rast/texture.c \
              src/rast/setup.c \
              src/rast/fragment.c \
              src/rast/raster.c \
              src/rast/bin.c

# reflect.h gets the same treatment; it is skipped while src/reflect/api.h
# does not exist. internal.h comes first and declares whatever one module
# takes from another, so the modules after it may come in any order
# (alphabetical here); SBC's private headers come right after it.
REFLECT_PUBLIC = src/reflect/api.h
REFLECT_IMPL   = src/reflect/internal.h \
                 src/reflect/cam_sbc_internal.h \
                 src/reflect/sbc_internal.h \
                 src/reflect/auto_model.c \
                 src/reflect/base_pass.c \
                 src/reflect/bvh.c \
                 src/reflect/cam_c3rc.c \
                 src/reflect/cam_graph.c \
                 src/reflect/cam_sbc.c \
                 src/reflect/cam_sbc_fit.c \
                 src/reflect/cam_sbc_morph.c \
                 src/reflect/cam_sbc_raylist.c \
                 src/reflect/cam_spoc.c \
                 src/reflect/gbuffer.c \
                 src/reflect/gl_hooks.c \
                 src/reflect/greedy_path.c \
                 src/reflect/impostor.c \
                 src/reflect/kdtree.c \
                 src/reflect/lem_infer.c \
                 src/reflect/lens_tess.c \
                 src/reflect/light_volume.c \
                 src/reflect/m_auto.c \
                 src/reflect/m_c3rc.c \
                 src/reflect/m_envmap.c \
                 src/reflect/m_graphcam.c \
                 src/reflect/m_layered_em.c \
                 src/reflect/m_planar.c \
                 src/reflect/m_raytrace.c \
                 src/reflect/m_sbc.c \
                 src/reflect/m_spoc.c \
                 src/reflect/math.c \
                 src/reflect/mesh.c \
                 src/reflect/metrics.c \
                 src/reflect/planar_faces.c \
                 src/reflect/render.c \
                 src/reflect/result.c \
                 src/reflect/sbc_draw.c \
                 src/reflect/sbc_groups.c \
                 src/reflect/sbc_measure.c \
                 src/reflect/sbc_project.c \
                 src/reflect/sbc_raymap.c \
                 src/reflect/sbc_resolve.c \
                 src/reflect/scene.c \
                 src/reflect/shade.c \
                 src/reflect/shadow.c \
                 src/reflect/shapes.c \
                 src/reflect/trace.c
HAVE_REFLECT   = $(wildcard $(REFLECT_PUBLIC))

AMALGAMATE = build/amalgamate
# $(call amalgamate,OUT,NAME,PUBLIC,MACRO,IMPL)
amalgamate = $(AMALGAMATE) -o $(1) --banner $(2) --public $(3) --impl $(4) $(5)

# ---- what gets built ----

# The tests, one folder per subject: the rasteriser's, reflect.h's, and
# those of the adapters and bench code in tools/ and bench/.
RAST_TEST_SRCS    = $(sort $(wildcard tests/rast/test_*.c))
REFLECT_TEST_SRCS = $(sort $(wildcard tests/reflect/test_*.c))
TOOLS_TEST_SRCS   = $(sort $(wildcard tests/tools/test_*.c))
TEST_SRCS         = $(RAST_TEST_SRCS) $(REFLECT_TEST_SRCS) $(TOOLS_TEST_SRCS)

# The implementations, once per configuration (see the top of this file).
RAST_IMPL_OBJ     = build/tests/rast_impl.o
REFLECT_IMPL_OBJ  = build/tests/reflect_impl.o
IMPL_OBJS         = $(RAST_IMPL_OBJ) $(REFLECT_IMPL_OBJ)
ASAN_IMPL_OBJS    = build/asan/tests/rast_impl.o build/asan/tests/reflect_impl.o
PORTABLE_IMPL_OBJ = build/portable/rast_impl.o

TEST_BIN       = build/tests/rast_tests
ASAN_TEST_BIN  = build/asan/rast_tests
TEST_OBJS      = $(TEST_SRCS:%.c=build/%.o) $(IMPL_OBJS)
ASAN_TEST_OBJS = $(TEST_SRCS:%.c=build/asan/%.o) $(ASAN_IMPL_OBJS)
# The rasteriser's own tests (tests/rast/) again against an implementation
# in plain C without threads (RAST_NO_SIMD, RAST_NO_THREADS): the scalar
# paths that SSE2 machines never take must give the same answers.
PORTABLE_TEST_BIN  = build/portable/rast_tests
PORTABLE_TEST_OBJS = $(RAST_TEST_SRCS:%.c=build/%.o) $(PORTABLE_IMPL_OBJ)

REFLECT_BIN = build/bin/reflect
BENCH_BIN  = build/bench/bench_rast
BENCH_OBJS = build/bench/bench_rast.o $(RAST_IMPL_OBJ)
# refl_bvh against Embree (bench/embree_peer.c), rays per second
BENCH_RAYS_BIN  = build/bench/bench_rays
BENCH_RAYS_OBJS = build/bench/bench_rays.o build/bench/embree_peer.o $(IMPL_OBJS)

# Each example is one self-contained program (it defines RAST_IMPLEMENTATION).
EXAMPLES = $(patsubst examples/%.c,build/examples/%,$(sort $(wildcard examples/*.c)))

COMPILE_CHECKS = build/check/compile_check.o build/check/compile_check_cpp.o
# Compiled, never run: -O0 keeps them cheap.
CHECK_CFLAGS   = -std=c99 -O0 -Wall -Wextra -Werror -pthread
CHECK_CXXFLAGS = -std=c++11 -O0 -Wall -Wextra -Werror -pthread

.PHONY: all build-all headers check-headers compile-check deps test bench demo clean

all: headers
	@$(MAKE) --no-print-directory $(PARALLEL) build-all

build-all: compile-check $(TEST_BIN) $(PORTABLE_TEST_BIN) $(BENCH_BIN) $(BENCH_RAYS_BIN) $(EXAMPLES) $(REFLECT_BIN) $(REFLECT_GL_BIN)

# ---- headers ----

$(AMALGAMATE): tools/amalgamate.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) -o $@ $<

headers: $(AMALGAMATE)
	$(call amalgamate,rast.h,rast.h,$(RAST_PUBLIC),RAST_IMPLEMENTATION,$(RAST_IMPL))
ifneq ($(HAVE_REFLECT),)
	$(call amalgamate,reflect.h,reflect.h --keep rast.h,$(REFLECT_PUBLIC),REFL_IMPLEMENTATION,$(REFLECT_IMPL))
endif

check-headers: $(AMALGAMATE)
	@mkdir -p build/gen
	@$(call amalgamate,build/gen/rast.h,rast.h,$(RAST_PUBLIC),RAST_IMPLEMENTATION,$(RAST_IMPL))
	@cmp -s build/gen/rast.h rast.h || \
	  { echo "rast.h differs from src/: run 'make headers' and commit it" >&2; exit 1; }
ifneq ($(HAVE_REFLECT),)
	@$(call amalgamate,build/gen/reflect.h,reflect.h --keep rast.h,$(REFLECT_PUBLIC),REFL_IMPLEMENTATION,$(REFLECT_IMPL))
	@cmp -s build/gen/reflect.h reflect.h || \
	  { echo "reflect.h differs from src/: run 'make headers' and commit it" >&2; exit 1; }
endif
	@echo "headers match src/"

# Only when rast.h is absent (a checkout always has it).
rast.h:
	@echo "rast.h is missing: run 'make headers'" >&2; exit 1

# ---- compiling: every object records its includes in a .d file ----

compile-check: $(COMPILE_CHECKS)

build/check/compile_check.o: tests/compile_check.c | rast.h
	@mkdir -p $(@D)
	$(CC) $(CHECK_CFLAGS) $(DEPFLAGS) -c $< -o $@

build/check/compile_check_cpp.o: tests/compile_check.cpp | rast.h
	@mkdir -p $(@D)
	$(CXX) $(CHECK_CXXFLAGS) $(DEPFLAGS) -c $< -o $@

build/tests/%.o: tests/%.c | rast.h
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(DEPFLAGS) -c $< -o $@

$(PORTABLE_IMPL_OBJ): tests/rast_impl.c | rast.h
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) -DRAST_NO_SIMD -DRAST_NO_THREADS $(DEPFLAGS) -c $< -o $@

build/asan/tests/%.o: tests/%.c | rast.h
	@mkdir -p $(@D)
	$(CC) $(ASAN_CFLAGS) $(DEPFLAGS) -c $< -o $@

build/bench/%.o: bench/%.c | rast.h
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(DEPFLAGS) -c $< -o $@

build/asan/bench/%.o: bench/%.c | rast.h
	@mkdir -p $(@D)
	$(CC) $(ASAN_CFLAGS) $(DEPFLAGS) -c $< -o $@

build/examples/%: examples/%.c | rast.h
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(DEPFLAGS) $< -o $@ $(LDLIBS)

$(TEST_BIN): $(TEST_OBJS)
	$(CC) $(CFLAGS) $^ -o $@ $(TEST_LIBS)

$(PORTABLE_TEST_BIN): $(PORTABLE_TEST_OBJS)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $^ -o $@ -lcriterion $(GL_LIBS) $(LDLIBS)

$(ASAN_TEST_BIN): $(ASAN_TEST_OBJS)
	$(CC) $(ASAN_CFLAGS) $^ -o $@ $(TEST_LIBS)

$(BENCH_BIN): $(BENCH_OBJS)
	$(CC) $(CFLAGS) $^ -o $@ $(GL_LIBS) $(LDLIBS)

$(BENCH_RAYS_BIN): $(BENCH_RAYS_OBJS) build/tools/gltf_load.o
	$(CC) $(CFLAGS) $^ -o $@ -lembree3 $(TINYGLTF_LIBS) -lstdc++ $(LDLIBS)

# The test binaries compare refl_bvh with Embree (tests/tools/test_embree.c)
# and with the uniform grid (tests/tools/test_grid_peer.c), and check the
# bench's cost lines (tests/tools/test_bench_cost_fit.c).
$(TEST_BIN): build/bench/embree_peer.o build/bench/cost_fit.o build/bench/grid_peer.o
$(ASAN_TEST_BIN): build/asan/bench/embree_peer.o build/asan/bench/cost_fit.o build/asan/bench/grid_peer.o
TEST_LIBS += -lembree3

DEPFILES = $(COMPILE_CHECKS:.o=.d) $(TEST_OBJS:.o=.d) $(ASAN_TEST_OBJS:.o=.d) $(PORTABLE_IMPL_OBJ:.o=.d) \
           $(BENCH_OBJS:.o=.d) $(BENCH_RAYS_OBJS:.o=.d) build/asan/bench/embree_peer.d build/bench/cost_fit.d \
           build/asan/bench/cost_fit.d build/bench/grid_peer.d build/asan/bench/grid_peer.d $(EXAMPLES:=.d)
-include $(DEPFILES)

# ---- packages ----

deps:
	@bash tools/deps.sh

# ---- tools: begin ----
# The C++ adapters in tools/ with C APIs (DESIGN.md section 7): gltf_load
# over tinygltf (Debian's shared libtinygltf, so no JSON or stb code is
# compiled here) and image_io over OpenImageIO. The test binaries link them.
#
# image_io.cpp compiles two ways. Plainly (image_io_oiio.o) it is the whole
# implementation, linked with OpenImageIO: the shared library below, and
# what a program that starts once (the `reflect` command) links, with
# REFLECT_TOOLS_OBJS and REFLECT_TOOLS_LIBS. With REFL_IMAGE_IO_DLOPEN
# (image_io.o) it is a small front that loads that library on the first
# image call; the test binaries link this one. Linked directly,
# OpenImageIO's ~270 shared libraries would cost every test about 0.3 s of
# CPU, because Criterion re-executes the binary for each test.
#
# -fno-var-tracking: tinygltf's large inline types (Model's destructor alone
# is 100 KB of instrumented code) make GCC's variable tracking the slowest
# part of the build; line numbers in backtraces are kept.
TOOLS_CXXFLAGS      = -std=c++17 -O2 -g -fno-var-tracking -Wall -Wextra -Werror -pthread
ASAN_TOOLS_CXXFLAGS = -std=c++17 -O1 -g -fno-var-tracking -Wall -Wextra -Werror -pthread \
                      -fsanitize=address,undefined -fno-omit-frame-pointer
TINYGLTF_LIBS := $(or $(shell pkg-config --libs tinygltf 2>/dev/null),-ltinygltf)
OIIO_CFLAGS   := $(shell pkg-config --cflags OpenImageIO 2>/dev/null)
OIIO_LIBS     := $(or $(shell pkg-config --libs OpenImageIO 2>/dev/null),-lOpenImageIO -lOpenImageIO_Util)
TOOLS_LIBS     = $(TINYGLTF_LIBS) -ldl -lstdc++

TOOLS_OBJS        = build/tools/gltf_load.o build/tools/image_io.o
ASAN_TOOLS_OBJS   = build/asan/tools/gltf_load.o build/asan/tools/image_io.o
IMAGE_IO_LIB      = build/tools/libreflect_image_io.so
ASAN_IMAGE_IO_LIB = build/asan/tools/libreflect_image_io.so
REFLECT_TOOLS_OBJS = build/tools/gltf_load.o build/tools/image_io_oiio.o
REFLECT_TOOLS_LIBS = $(TINYGLTF_LIBS) $(OIIO_LIBS) -lstdc++

build/tools/gltf_load.o: tools/gltf_load.cpp | rast.h
	@mkdir -p $(@D)
	$(CXX) $(TOOLS_CXXFLAGS) $(DEPFLAGS) -c $< -o $@

build/asan/tools/gltf_load.o: tools/gltf_load.cpp | rast.h
	@mkdir -p $(@D)
	$(CXX) $(ASAN_TOOLS_CXXFLAGS) $(DEPFLAGS) -c $< -o $@

# the library's path from the test binary's directory: build/tests/ -> build/tools/
build/tools/image_io.o: tools/image_io.cpp | rast.h
	@mkdir -p $(@D)
	$(CXX) $(TOOLS_CXXFLAGS) $(DEPFLAGS) -DREFL_IMAGE_IO_DLOPEN='"../tools/libreflect_image_io.so"' -c $< -o $@

# build/asan/ -> build/asan/tools/
build/asan/tools/image_io.o: tools/image_io.cpp | rast.h
	@mkdir -p $(@D)
	$(CXX) $(ASAN_TOOLS_CXXFLAGS) $(DEPFLAGS) -DREFL_IMAGE_IO_DLOPEN='"tools/libreflect_image_io.so"' -c $< -o $@

build/tools/image_io_oiio.o: tools/image_io.cpp | rast.h
	@mkdir -p $(@D)
	$(CXX) $(TOOLS_CXXFLAGS) $(DEPFLAGS) $(OIIO_CFLAGS) -fPIC -c $< -o $@

build/asan/tools/image_io_oiio.o: tools/image_io.cpp | rast.h
	@mkdir -p $(@D)
	$(CXX) $(ASAN_TOOLS_CXXFLAGS) $(DEPFLAGS) $(OIIO_CFLAGS) -fPIC -c $< -o $@

$(IMAGE_IO_LIB): build/tools/image_io_oiio.o
	$(CXX) $(TOOLS_CXXFLAGS) -shared $< -o $@ $(OIIO_LIBS) -Wl,-Bsymbolic

$(ASAN_IMAGE_IO_LIB): build/asan/tools/image_io_oiio.o
	$(CXX) $(ASAN_TOOLS_CXXFLAGS) -shared $< -o $@ $(OIIO_LIBS) -Wl,-Bsymbolic

# Extra prerequisites of the test binaries (their link rules use $^); the
# libraries are order-only: built first, never linked.
$(TEST_BIN): $(TOOLS_OBJS) | $(IMAGE_IO_LIB)
$(ASAN_TEST_BIN): $(ASAN_TOOLS_OBJS) | $(ASAN_IMAGE_IO_LIB)
TEST_LIBS += $(TOOLS_LIBS)

-include $(TOOLS_OBJS:.o=.d) $(ASAN_TOOLS_OBJS:.o=.d) build/tools/image_io_oiio.d build/asan/tools/image_io_oiio.d
# ---- tools: end ----

# ---- fuzzing ----
# fuzz/gltf_fuzz.cpp feeds libFuzzer's inputs to the glTF loader and
# fuzz/render_fuzz.c to the scene and render API, compiled with clang under
# ASan/UBSan (Debian: clang and libclang-rt-14-dev). `make fuzz` runs each
# for FUZZ_SECONDS; `make test` runs the loader's for 60 seconds when clang
# can build it (fuzz/run.sh --available), else says it skipped. The render
# target stays out of `make test`: some of its inputs take over a minute
# under the sanitizers and the coverage instrumentation. Its implementation
# leaves LAYERED_EM's shell-frame search out of the coverage
# (fuzz/render_coverage_ignore.txt), whose traced comparisons made a
# 12x12 frame's first run 1.6 to 1.8 times as long.
FUZZ_CC      ?= clang
FUZZ_CXX     ?= clang++
FUZZ_SAN      = -fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer
FUZZ_FLAGS    = -O1 -g -pthread -fsanitize=fuzzer-no-link $(FUZZ_SAN)
FUZZ_BIN      = build/fuzz/gltf_fuzz
FUZZ_OBJS     = build/fuzz/gltf_fuzz.o build/fuzz/gltf_load.o build/fuzz/gltf/reflect_impl.o build/fuzz/gltf/rast_impl.o
RENDER_FUZZ_BIN  = build/fuzz/render_fuzz
RENDER_FUZZ_OBJS = build/fuzz/render_fuzz.o build/fuzz/reflect_impl.o build/fuzz/rast_impl.o
FUZZ_SECONDS  = 600

build/fuzz/render_fuzz.o: fuzz/render_fuzz.c | rast.h
	@mkdir -p $(@D)
	$(FUZZ_CC) -std=c99 $(FUZZ_FLAGS) $(DEPFLAGS) -c $< -o $@

$(RENDER_FUZZ_BIN): $(RENDER_FUZZ_OBJS)
	$(FUZZ_CC) -fsanitize=fuzzer $(FUZZ_SAN) -pthread $^ -o $@ -lm

build/fuzz/gltf_fuzz.o: fuzz/gltf_fuzz.cpp | rast.h
	@mkdir -p $(@D)
	$(FUZZ_CXX) -std=c++17 $(FUZZ_FLAGS) $(DEPFLAGS) -c $< -o $@

build/fuzz/gltf_load.o: tools/gltf_load.cpp | rast.h
	@mkdir -p $(@D)
	$(FUZZ_CXX) -std=c++17 $(FUZZ_FLAGS) $(DEPFLAGS) -c $< -o $@

build/fuzz/%_impl.o: tests/%_impl.c fuzz/render_coverage_ignore.txt | rast.h
	@mkdir -p $(@D)
	$(FUZZ_CC) -std=c99 $(FUZZ_FLAGS) -fsanitize-coverage-ignorelist=fuzz/render_coverage_ignore.txt $(DEPFLAGS) -c $< -o $@

# The glTF target's implementations: sanitized, but at -O0 and without the
# fuzzer's coverage, which is the loader's to guide; they compile in about a
# sixth of the time, and `make test` builds them.
build/fuzz/gltf/%_impl.o: tests/%_impl.c | rast.h
	@mkdir -p $(@D)
	$(FUZZ_CC) -std=c99 -O0 -g -pthread $(FUZZ_SAN) $(DEPFLAGS) -c $< -o $@

$(FUZZ_BIN): $(FUZZ_OBJS)
	$(FUZZ_CXX) -fsanitize=fuzzer $(FUZZ_SAN) -pthread $^ -o $@ $(TINYGLTF_LIBS) -lm

.PHONY: fuzz fuzz-short
fuzz: deps
	@$(MAKE) --no-print-directory $(PARALLEL) $(FUZZ_BIN) $(RENDER_FUZZ_BIN)
	bash fuzz/run.sh $(FUZZ_BIN) $(FUZZ_SECONDS)
	bash fuzz/run.sh $(RENDER_FUZZ_BIN) $(FUZZ_SECONDS)

fuzz-short:
	@if bash fuzz/run.sh --available; then \
	  $(MAKE) --no-print-directory $(PARALLEL) $(FUZZ_BIN) && bash fuzz/run.sh $(FUZZ_BIN) 60; \
	else echo "fuzz: $(FUZZ_CXX) cannot build a libFuzzer target (Debian: clang libclang-rt-14-dev); skipped"; fi

-include $(FUZZ_OBJS:.o=.d) $(RENDER_FUZZ_OBJS:.o=.d)

# ---- the reflect command ----

# One file per command (tools/reflect*.c) over the shared implementations;
# `reflect bench` (tools/reflect_bench.c) runs Embree through bench/embree_peer.c.
REFLECT_OBJS = build/tools/reflect.o build/tools/reflect_bench.o build/tools/reflect_bench_c3rc.o \
               build/tools/reflect_bench_sbc.o build/tools/reflect_bench_sbc_sweep.o build/tools/reflect_bench_path.o \
               build/tools/reflect_path.o build/tools/reflect_bench_graphcam.o build/tools/reflect_report.o \
               build/tools/reflect_bench_auto.o build/tools/reflect_bench_spoc.o build/tools/reflect_bench_lem.o
REFLECT_BENCH_OBJS = build/bench/embree_peer.o build/bench/cost_fit.o build/bench/grid_peer.o

$(REFLECT_OBJS): build/tools/%.o: tools/%.c | rast.h reflect.h
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(DEPFLAGS) -c $< -o $@

$(REFLECT_BIN): $(REFLECT_OBJS) $(REFLECT_BENCH_OBJS) $(REFLECT_TOOLS_OBJS) $(IMPL_OBJS)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $^ -o $@ $(REFLECT_TOOLS_LIBS) -lembree3 $(EGL_LIBS) $(LDLIBS)
-include $(REFLECT_OBJS:.o=.d)

# ---- the GL path ----

# The GL host (tools/reflect_gl*.c): an EGL context whose GL entry points are
# loaded through eglGetProcAddress, so it links libEGL alone. reflect_gl is
# the GL path's checks as a program that needs nothing else (run on a bare
# GPU machine by tools/gl_device_check.sh); the tests and `reflect` link the
# host too.
REFLECT_GL_BIN  = build/bin/reflect_gl
REFLECT_GL_OBJS = build/tools/reflect_gl.o build/tools/reflect_gl_frame.o build/tools/reflect_gl_bench.o \
                  build/tools/reflect_gl_c3rc.o build/tools/reflect_gl_sbc.o build/tools/reflect_gl_impostor.o \
                  build/tools/reflect_gl_lem.o
ASAN_GL_OBJS    = $(patsubst build/%,build/asan/%,$(REFLECT_GL_OBJS))
EGL_LIBS        = -lEGL

$(REFLECT_GL_OBJS) build/tools/reflect_gl_main.o: build/tools/%.o: tools/%.c | rast.h reflect.h
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $(DEPFLAGS) -c $< -o $@

$(ASAN_GL_OBJS): build/asan/tools/%.o: tools/%.c | rast.h reflect.h
	@mkdir -p $(@D)
	$(CC) $(ASAN_CFLAGS) $(DEPFLAGS) -c $< -o $@

$(REFLECT_GL_BIN): build/tools/reflect_gl_main.o $(REFLECT_GL_OBJS) $(IMPL_OBJS)
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) $^ -o $@ $(EGL_LIBS) $(LDLIBS)

$(TEST_BIN) $(REFLECT_BIN): $(REFLECT_GL_OBJS)
$(ASAN_TEST_BIN): $(ASAN_GL_OBJS)
-include $(REFLECT_GL_OBJS:.o=.d) build/tools/reflect_gl_main.d $(ASAN_GL_OBJS:.o=.d)

# ---- running ----

# The sanitized run also fails on reports that do not fail a test by
# themselves: leaks are found when a test's process exits, after Criterion
# has counted the test as passed. Third-party leaks: tests/lsan.supp.
#
# The five runs go two at a time (make -j2 -O: each run's output is printed
# whole when it ends): the CLI's checks and the fuzzer are one process
# each, so beside them another run keeps the second core busy. The two
# implementation objects take longest to compile, so they start first
# rather than leave one core to finish them alone.
test: deps
	@$(MAKE) --no-print-directory check-headers
	@$(MAKE) --no-print-directory $(PARALLEL) build/asan/tests/reflect_impl.o $(REFLECT_IMPL_OBJ) compile-check $(TEST_BIN) $(PORTABLE_TEST_BIN) $(ASAN_TEST_BIN) $(REFLECT_BIN) $(REFLECT_GL_BIN)
	@$(MAKE) --no-print-directory -j2 -O test-cli fuzz-short test-report test-plain test-sanitized

.PHONY: test-cli test-report test-plain test-sanitized
test-cli:
	bash tests/cli_test.sh $(REFLECT_BIN)

test-report:
	bash tests/report_test.sh $(REFLECT_BIN)

test-plain:
	@rm -rf build/tests/digest build/portable/digest; mkdir -p build/tests/digest build/portable/digest
	RAST_TEST_DIGEST_DIR=build/tests/digest timeout -k 10 $(TEST_TIMEOUT) $(TEST_BIN) $(CRITERION_FLAGS)
	RAST_TEST_NO_THREADS=1 RAST_TEST_DIGEST_DIR=build/portable/digest \
	  timeout -k 10 $(TEST_TIMEOUT) $(PORTABLE_TEST_BIN) $(CRITERION_FLAGS)
	diff -r build/tests/digest build/portable/digest || \
	  { echo "the plain C (RAST_NO_SIMD) build renders other bytes than the SSE2 one" >&2; exit 1; }

test-sanitized:
	set -o pipefail; $(ASAN_ENV) RAST_TEST_SKIP_FILE=$(ASAN_SKIP_FILE) timeout -k 10 $(ASAN_TEST_TIMEOUT) $(ASAN_TEST_BIN) $(CRITERION_FLAGS) 2>&1 \
	  | tee build/asan/rast_tests.log
	@if grep -qE 'ERROR: (Address|Leak)Sanitizer|runtime error:' build/asan/rast_tests.log; then \
	  echo "sanitizer reports in the sanitized test run (see above, or build/asan/rast_tests.log)" >&2; \
	  exit 1; fi

# The rasteriser against llvmpipe, refl_bvh against Embree, then every
# method against the ray-traced reference (`reflect bench`: CSV and charts
# in out/bench/; `reflect bench --full` runs every scene and size).
bench: deps
	@$(MAKE) --no-print-directory $(PARALLEL) $(BENCH_BIN) $(BENCH_RAYS_BIN) $(REFLECT_BIN)
	@mkdir -p out
	$(BENCH_BIN) --csv out/bench_rast.csv
	$(BENCH_RAYS_BIN) --csv out/bench_rays.csv
	if [ -f ../shared/assets/xyzrgb_dragon_100k.glb ]; then \
	  $(BENCH_RAYS_BIN) --asset ../shared/assets/xyzrgb_dragon_100k.glb --csv out/bench_rays_dragon.csv; fi
	$(REFLECT_BIN) bench --out out/bench

# The demo: every built-in scene through the `reflect` command with every
# method built so far (and SBC with its ray-traced fallback on the default
# scene), the speed-against-accuracy chart of the default scene (a quick
# `reflect bench`), and the rasteriser's own demo picture. LAYERED_EM
# infers its maps every frame (seconds per 10^5 pixels), so it renders at
# 320x240.
DEMO_SCENES  = default mirror-room concave glass maze teapots hybrid
DEMO_METHODS = direct raytrace envmap planar c3rc sbc spoc graphcam layered-em auto
demo: deps
	@$(MAKE) --no-print-directory $(PARALLEL) build/examples/rast_demo $(REFLECT_BIN)
	@mkdir -p out
	@for s in $(DEMO_SCENES); do for m in $(DEMO_METHODS); do \
	  size=960x720; [ $$m = layered-em ] && size=320x240; \
	  echo "$(REFLECT_BIN) render --builtin $$s --method $$m --size $$size --out out/$$s-$$m.png"; \
	  $(REFLECT_BIN) render --builtin $$s --method $$m --size $$size --out out/$$s-$$m.png || exit 1; \
	done; done
	$(REFLECT_BIN) render --builtin default --method sbc --trace-fallback --size 960x720 --out out/default-sbc-fallback.png
	$(REFLECT_BIN) bench --repeats 1 --out out/bench
	build/examples/rast_demo out/rast_demo.ppm
	oiiotool out/rast_demo.ppm -o out/rast_demo.png
	@echo "wrote out/*.png, out/bench/bench.csv and the charts out/bench/*.png"

clean:
	rm -rf build out
