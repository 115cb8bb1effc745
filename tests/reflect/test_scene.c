/* Scenes, the built-in named scenes and the DIRECT method: ownership and
   errors, the properties each named scene promises, the stencil ids and
   colours of the base pass, determinism across threads, and the golden
   image of the default scene. */
#include <criterion/criterion.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../../reflect.h"
#include "../test_util.h"
#include "refl_test_util.h"

#define GOLDEN "tests/golden/direct_default_160x120.ppm"


static refl_frame *render(const refl_scene *s, int w, int h, int threads) {
    refl_frame *f = NULL;
    refl_view v = s->camera;
    refl_render_desc d;
    v.width = w;
    v.height = h;
    memset(&d, 0, sizeof d);
    d.threads = threads;
    cr_assert_eq(refl_frame_create(w, h, NULL, &f), REFL_OK);
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_OK);
    return f;
}

static int object_named(const refl_scene *s, const char *name) {
    int i;
    for (i = 0; i < s->object_count; ++i)
        if (!strcmp(s->objects[i].name, name)) return i;
    return -1;
}

Test(refl_scene, every_builtin_builds_and_unknown_names_fail) {
    const char *const *names = refl_builtin_names();
    refl_scene *s = (refl_scene *)1;
    int n = 0;
    for (; names[n]; ++n) {
        int i, reflectors = 0;
        cr_assert_eq(refl_scene_builtin(names[n], NULL, &s), REFL_OK, "%s", names[n]);
        cr_assert(s->object_count >= 2 && s->has_camera, "%s", names[n]);
        for (i = 0; i < s->object_count; ++i)
            reflectors += s->materials[s->objects[i].material].type != REFL_DIFFUSE;
        cr_assert(reflectors >= 1, "%s has no reflector", names[n]);
        refl_scene_destroy(s);
    }
    cr_assert_eq(n, 7);
    cr_assert_eq(refl_scene_builtin("no-such-scene", NULL, &s), REFL_ERROR_UNKNOWN_NAME);
    cr_assert_null(s);
    cr_assert_eq(refl_scene_builtin(NULL, NULL, &s), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert_eq(refl_scene_builtin("default", NULL, NULL), REFL_ERROR_INVALID_ARGUMENT);
}

/* The default scene promises a diffuse object touching the mirror teapot:
   some teapot vertex lies within 0.05 of the sphere's surface (vertices
   are about 0.2 apart at the default tessellation, so the surfaces meet),
   and none lies deep inside the sphere. */
Test(refl_scene, default_scene_has_an_object_touching_the_mirror) {
    refl_scene *s;
    int t, sp, v;
    float best = 1e30f;
    refl_vec3 c;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    t = object_named(s, "teapot");
    sp = object_named(s, "sphere");
    cr_assert(t >= 0 && sp >= 0);
    cr_assert_eq(s->materials[s->objects[t].material].type, REFL_MIRROR);
    c = refl_mat4_point(s->objects[sp].transform, refl_v3(0, 0, 0));
    for (v = 0; v < s->meshes[s->objects[t].mesh]->vertex_count; ++v) {
        const float *p = s->meshes[s->objects[t].mesh]->positions + 3 * v;
        refl_vec3 w = refl_mat4_point(s->objects[t].transform, refl_v3(p[0], p[1], p[2]));
        float d = refl_v3_length(refl_v3_sub(w, c)) - 0.7f;
        if (d < best) best = d;
    }
    cr_assert(best < 0.05f && best > -0.1f, "sphere surface %g from the teapot", best);
    refl_scene_destroy(s);
}

/* The concave scene's ball sits at the mirror's focus: half the radius in
   front of the bowl's deepest point. */
Test(refl_scene, concave_scene_ball_at_the_focus) {
    refl_scene *s;
    int bowl, ball;
    refl_vec3 lo, hi, c;
    cr_assert_eq(refl_scene_builtin("concave", NULL, &s), REFL_OK);
    bowl = object_named(s, "concave mirror");
    ball = object_named(s, "ball at focus");
    cr_assert(bowl >= 0 && ball >= 0);
    refl_mesh_bounds(s->meshes[s->objects[bowl].mesh], &lo, &hi);
    c = refl_mat4_point(s->objects[ball].transform, refl_v3(0, 0, 0));
    /* bowl: radius 3 centred at (0, 3, 0) opening to +z, deepest at z = -3 */
    cr_assert_float_eq(lo.z, -3.0f, 0.01f);
    cr_assert_float_eq(c.z - (lo.z + s->objects[bowl].transform.m[14]), 1.5f, 0.01f);
    refl_scene_destroy(s);
}

Test(refl_scene, ownership_and_bad_input) {
    refl_scene *s;
    refl_mesh *m = NULL;
    refl_material mat;
    refl_object o;
    float px[4] = {1, 0, 0, 1};
    cr_assert_eq(refl_scene_create(NULL, &s), REFL_OK);
    memset(&mat, 0, sizeof mat);
    mat.texture = 1; /* no texture yet */
    cr_assert_lt(refl_scene_add_material(s, &mat), 0);
    cr_assert_eq(refl_scene_add_texture(s, 1, 1, px), 1); /* the id materials take */
    cr_assert_eq(refl_scene_add_material(s, &mat), 0);
    cr_assert_lt(refl_scene_add_texture(s, 0, 1, px), 0);
    cr_assert_eq(refl_mesh_box(refl_v3(1, 1, 1), NULL, &m), REFL_OK);
    cr_assert_eq(refl_scene_add_mesh(s, m), 0);
    memset(&o, 0, sizeof o);
    o.transform = refl_mat4_identity();
    o.mesh = 1; /* out of range */
    cr_assert_lt(refl_scene_add_object(s, &o), 0);
    o.mesh = 0;
    o.transform.m[5] = NAN;
    cr_assert_lt(refl_scene_add_object(s, &o), 0);
    o.transform = refl_mat4_identity();
    cr_assert_eq(refl_scene_add_object(s, &o), 0);
    cr_assert_lt(refl_scene_add_mesh(s, NULL), 0);
    refl_scene_destroy(s); /* frees the mesh and the texture (ASan checks) */
}

/* Every allocation of building and rendering a scene may fail: each run
   returns an error or succeeds, and nothing leaks. */
Test(refl_scene, allocation_failure_leaks_nothing) {
    refl_render_desc d = tu_refl_desc(REFL_METHOD_DEFAULT, 2);
    tu_refl_failed_runs runs = tu_refl_default_allocation_failures(&d, 2000);
    cr_assert(runs.scene_failed && runs.runs > 10, "only %ld allocations seen", runs.runs);
}

/* DIRECT: diffuse objects shaded, mirrors transparent black with their id
   + 1 in the stencil, diffuse pixels id 0, the environment where nothing
   was drawn. */
Test(refl_scene, direct_stencil_ids_colours_and_background) {
    refl_scene *s;
    refl_frame *f;
    int t, i, mirror_px = 0, sky_px = 0, diffuse_px = 0;
    uint8_t sky[3];
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    t = object_named(s, "teapot");
    for (i = 0; i < 3; ++i) sky[i] = (uint8_t)(s->environment.color[i] * 255.0f + 0.5f);
    f = render(s, 160, 120, 2);
    for (i = 0; i < 160 * 120; ++i) {
        int c[4];
        tu_pixel8(f, (size_t)i, c);
        if (f->stencil[i]) {
            cr_assert_eq(f->stencil[i], t + 1);
            cr_assert(c[0] == 0 && c[1] == 0 && c[2] == 0 && c[3] == 255); /* mirrors: black, opaque */
            ++mirror_px;
        } else if (f->depth[i] >= 1.0f) {
            cr_assert(c[0] == sky[0] && c[1] == sky[1] && c[2] == sky[2] && c[3] == 255, "pixel %d", i);
            ++sky_px;
        } else {
            cr_assert_eq(c[3], 255);
            ++diffuse_px;
        }
    }
    cr_assert(mirror_px > 500 && sky_px > 500 && diffuse_px > 500, "%d %d %d", mirror_px, sky_px, diffuse_px);
    cr_assert_eq(f->stats.reflectors, 1);
    cr_assert_eq(f->stats.triangles, refl_scene_triangles(s));
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

Test(refl_scene, direct_is_identical_for_any_thread_count) {
    refl_scene *s;
    refl_frame *a, *b;
    int threads[3] = {1, 3, 8}, i;
    cr_assert_eq(refl_scene_builtin("mirror-room", NULL, &s), REFL_OK);
    a = render(s, 200, 150, 2);
    for (i = 0; i < 3; ++i) {
        b = render(s, 200, 150, threads[i]);
        cr_assert_eq(tu_first_diff(a->rgba, b->rgba, (200 * 150 * 4) * sizeof(float)), -1, "threads %d", threads[i]);
        cr_assert_eq(tu_first_diff(a->depth, b->depth, 200 * 150 * sizeof(float)), -1);
        cr_assert_eq(tu_first_diff(a->stencil, b->stencil, 200 * 150), -1);
        refl_frame_destroy(b);
    }
    refl_frame_destroy(a);
    refl_scene_destroy(s);
}

Test(refl_scene, render_rejects_bad_input) {
    refl_scene *s;
    refl_frame *f;
    refl_view v;
    refl_render_desc d;
    cr_assert_eq(refl_scene_builtin("glass", NULL, &s), REFL_OK);
    cr_assert_eq(refl_frame_create(64, 48, NULL, &f), REFL_OK);
    v = s->camera;
    v.width = 64;
    v.height = 48;
    memset(&d, 0, sizeof d);
    cr_assert_eq(refl_render(NULL, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.method = REFL_METHOD_COUNT;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    d.method = REFL_DIRECT;
    v.width = 65;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_SIZE);
    v.width = 64;
    v.target = v.eye; /* no direction */
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    v = s->camera; /* so far away that the projection overflows float: refused, not black */
    v.width = 64;
    v.height = 48;
    v.eye = refl_v3(1e38f, 1e38f, 1e38f);
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert(strstr(f->message, "overflow") != NULL, "%s", f->message);
    refl_frame_destroy(f);
    cr_assert_eq(refl_frame_create(0, 10, NULL, &f), REFL_ERROR_INVALID_SIZE);
    cr_assert_null(f);
    refl_scene_destroy(s);
    cr_assert_eq(refl_method_from_name("sbc"), REFL_SBC);
    cr_assert_str_eq(refl_method_name(REFL_LAYERED_EM), "layered-em");
    cr_assert_eq(refl_method_from_name("nonsense"), REFL_METHOD_DEFAULT);
}

/* Non-finite numbers are refused where the API takes them, and where the
   caller wrote them into the scene's arrays directly, by the render that
   would use them, naming the field. */
Test(refl_scene, non_finite_numbers_are_refused_everywhere) {
    static const float bad[] = {NAN, INFINITY, -INFINITY};
    refl_scene *s;
    refl_frame *f;
    refl_view v;
    refl_render_desc d;
    size_t k;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    cr_assert_eq(refl_frame_create(16, 12, NULL, &f), REFL_OK);
    memset(&d, 0, sizeof d);
    for (k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        float x = bad[k], pixels[4 * 4] = {0};
        refl_material m = refl_material_diffuse(0.5f, 0.5f, 0.5f);
        refl_light l = refl_light_point(refl_v3(0, 3, 0), 1.0f);
        refl_environment env;
        const refl_material saved_material = s->materials[0];
        const refl_light saved_light = s->lights[0];
        const float saved_ambient = s->ambient[1];
        refl_mat4 saved_transform;
        m.color[1] = x;
        cr_assert_eq(refl_scene_add_material(s, &m), REFL_ERROR_INVALID_ARGUMENT);
        m = refl_material_glass(x);
        cr_assert_eq(refl_scene_add_material(s, &m), REFL_ERROR_INVALID_ARGUMENT);
        m = refl_material_diffuse(0.5f, 0.5f, 0.5f);
        m.emissive[2] = x;
        cr_assert_eq(refl_scene_add_material(s, &m), REFL_ERROR_INVALID_ARGUMENT);
        l.position.y = x;
        cr_assert_eq(refl_scene_add_light(s, &l), REFL_ERROR_INVALID_ARGUMENT);
        l = refl_light_point(refl_v3(0, 3, 0), x);
        cr_assert_eq(refl_scene_add_light(s, &l), REFL_ERROR_INVALID_ARGUMENT);
        pixels[6] = x;
        cr_assert_eq(refl_scene_add_texture(s, 2, 2, pixels), REFL_ERROR_INVALID_ARGUMENT);
        memset(&env, 0, sizeof env);
        env.color[2] = x;
        cr_assert_eq(refl_scene_set_environment(s, &env), REFL_ERROR_INVALID_ARGUMENT);
        /* written directly: the render refuses */
        v = s->camera;
        v.width = 16; v.height = 12;
        s->materials[0].reflectance = x;
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
        cr_assert(strstr(f->message, "material") != NULL, "%s", f->message);
        s->materials[0] = saved_material;
        s->lights[0].color[0] = x;
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
        cr_assert(strstr(f->message, "light") != NULL, "%s", f->message);
        s->lights[0] = saved_light;
        s->ambient[1] = x;
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
        cr_assert(strstr(f->message, "ambient") != NULL, "%s", f->message);
        s->ambient[1] = saved_ambient;
        saved_transform = s->objects[1].transform;
        s->objects[1].transform.m[13] = x;
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
        cr_assert(strstr(f->message, "transform") != NULL, "%s", f->message);
        s->objects[1].transform = saved_transform;
        v.up.x = x;
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
        cr_assert(strstr(f->message, "view.up") != NULL, "%s", f->message);
    }
    v = s->camera;
    v.width = 16; v.height = 12;
    /* an object's mesh index written out of range: refused before the
       scene's bounds (the view's near and far planes) would read it */
    s->objects[1].mesh += s->mesh_count;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_ERROR_INVALID_ARGUMENT);
    cr_assert(strstr(f->message, "scene.objects") != NULL, "%s", f->message);
    s->objects[1].mesh -= s->mesh_count;
    cr_assert_eq(refl_render(s, &v, &d, f), REFL_OK, "the scene restored renders");
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* Functions that take pointers say what NULL does, and do it. */
Test(refl_scene, null_pointers_give_documented_results) {
    refl_vec3 o, dir;
    refl_mat4 vm, pm;
    refl_light l;
    float t = 1.0f;
    refl_view_ray(NULL, NULL, 0.5f, 0.5f, &o, &dir, &t);
    cr_assert(o.x == 0 && dir.x == 0 && t == 0.0f);
    refl_view_matrices(NULL, NULL, &vm, &pm);
    cr_assert(vm.m[0] == 1.0f && pm.m[5] == 1.0f && vm.m[1] == 0.0f);
    l = refl_light_sample(NULL, 0, 4);
    cr_assert(l.color[0] == 0.0f && l.radius == 0.0f);
}

/* Near and far from the scene bounds enclose every object: all scene
   corners project inside the depth range. */
Test(refl_scene, automatic_near_far_enclose_the_scene) {
    refl_scene *s;
    refl_mat4 vm, pm, vp;
    refl_vec3 lo, hi;
    int c;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    s->camera.width = 640;
    s->camera.height = 480;
    refl_view_matrices(&s->camera, s, &vm, &pm);
    vp = refl_mat4_mul(pm, vm);
    refl_scene_bounds(s, &lo, &hi);
    for (c = 0; c < 8; ++c) {
        refl_vec3 p = refl_v3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
        refl_vec3 q = refl_mat4_point(vm, p);
        if (q.z < 0.0f) { /* in front of the eye */
            refl_vec3 n = refl_mat4_point(vp, p);
            cr_assert(n.z >= -1.0f && n.z <= 1.0f, "corner %d at ndc z %g", c, n.z);
        }
    }
    refl_scene_destroy(s);
}

/* Binary PPM (P6), as the golden image is stored. */
static unsigned char *read_ppm(const char *path, int *w, int *h) {
    FILE *fp = fopen(path, "rb");
    unsigned char *px;
    int maxv;
    if (!fp) return NULL;
    if (fscanf(fp, "P6 %d %d %d", w, h, &maxv) != 3 || maxv != 255 || fgetc(fp) == EOF) {
        fclose(fp);
        return NULL;
    }
    px = (unsigned char *)malloc((size_t)*w * (size_t)*h * 3);
    if (px && fread(px, 3, (size_t)*w * (size_t)*h, fp) != (size_t)*w * (size_t)*h) {
        free(px);
        px = NULL;
    }
    fclose(fp);
    return px;
}

/* The DIRECT image of the default scene against its golden image: a
   regression guard for everything under it (shapes, scene, shading,
   rasteriser). Tolerance: 2/255 per channel, for compiler differences in
   float contraction; more than that is a change to look at. To renew it
   after an intended change: REFL_WRITE_GOLDEN=1, then look at the picture. */
Test(refl_scene, direct_default_matches_golden) {
    refl_scene *s;
    refl_frame *f;
    unsigned char *golden;
    int w = 0, h = 0, i, c, worst = 0, over = 0;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    f = render(s, 160, 120, 2);
    if (getenv("REFL_WRITE_GOLDEN")) {
        FILE *fp = fopen(GOLDEN, "wb");
        cr_assert_not_null(fp);
        fprintf(fp, "P6 160 120 255\n");
        for (i = 0; i < 3 * 160 * 120; ++i) fputc(tu_unorm8(f->rgba[4 * (i / 3) + i % 3]), fp);
        fclose(fp);
    }
    golden = read_ppm(GOLDEN, &w, &h);
    cr_assert_not_null(golden, "cannot read %s", GOLDEN);
    cr_assert(w == 160 && h == 120);
    for (i = 0; i < 160 * 120; ++i)
        for (c = 0; c < 3; ++c) {
            int d = abs((int)tu_unorm8(f->rgba[4 * i + c]) - (int)golden[3 * i + c]);
            if (d > worst) worst = d;
            over += d > 2;
        }
    cr_assert_eq(over, 0, "%d channels differ by more than 2/255 (worst %d)", over, worst);
    free(golden);
    refl_frame_destroy(f);
    refl_scene_destroy(s);
}

/* Environment lookups stay on their own side of an edge: a cube face does
   not blend in its opposite edge, an equirectangular map does not blend
   one pole into the other (while longitude still wraps around). */
Test(refl_scene, environment_edges_clamp_where_they_must) {
    float face[6][4 * 4 * 4], equi[8 * 4 * 4], rgb[3];
    refl_environment env;
    int f, i;
    memset(&env, 0, sizeof env);
    for (f = 0; f < 6; ++f) {
        for (i = 0; i < 16; ++i) {
            int col = i % 4;
            float v = col == 0 ? 1.0f : col == 3 ? 0.0f : 0.5f;
            face[f][4 * i] = face[f][4 * i + 1] = face[f][4 * i + 2] = v;
            face[f][4 * i + 3] = 1.0f;
        }
        env.faces[f].width = env.faces[f].height = 4;
        env.faces[f].pixels = face[f];
    }
    env.type = REFL_ENV_CUBE;
    /* +X face, s = (-z / x + 1) / 2 close to 1: the last column, value 0 */
    refl_environment_lookup(&env, refl_v3(1.0f, 0.0f, -0.999f), rgb);
    cr_assert_float_eq(rgb[0], 0.0f, 1e-6f, "cube face edge blended with its opposite edge: %g", rgb[0]);
    /* equirect 8 x 4: top row 1, bottom row 0 */
    for (i = 0; i < 32; ++i) {
        float v = i / 8 == 0 ? 1.0f : i / 8 == 3 ? 0.0f : 0.5f;
        equi[4 * i] = equi[4 * i + 1] = equi[4 * i + 2] = v;
        equi[4 * i + 3] = 1.0f;
    }
    memset(&env, 0, sizeof env);
    env.type = REFL_ENV_EQUIRECT;
    env.image.width = 8;
    env.image.height = 4;
    env.image.pixels = equi;
    refl_environment_lookup(&env, refl_v3(0.0f, -1.0f, 0.0f), rgb);
    cr_assert_float_eq(rgb[0], 0.0f, 1e-6f, "south pole blended with the north: %g", rgb[0]);
    refl_environment_lookup(&env, refl_v3(0.0f, 1.0f, 0.0f), rgb);
    cr_assert_float_eq(rgb[0], 1.0f, 1e-6f, "north pole: %g", rgb[0]);
}

/* Emission is light the surface gives off itself: on a diffuse surface with
   no light and no ambient, every method shows exactly the emitted colour;
   a negative emission is refused. */
Test(refl_scene, emission_is_what_an_unlit_surface_shows, .timeout = 120) {
    int m;
    refl_material neg = refl_material_diffuse(0.5f, 0.5f, 0.5f);
    refl_scene *s;
    cr_assert_eq(refl_scene_builtin("default", NULL, &s), REFL_OK);
    neg.emissive[0] = -0.1f;
    cr_assert_eq(refl_scene_add_material(s, &neg), REFL_ERROR_INVALID_ARGUMENT);
    refl_scene_destroy(s);
    for (m = REFL_DIRECT; m < REFL_METHOD_COUNT; ++m) {
        refl_view v;
        refl_render_desc d;
        refl_frame *f;
        int i, k, c, shown = 0;
        if (!refl_method_is_built((refl_method)m)) continue;
        s = tu_refl_builtin("default", &v, 64, 48);
        d = tu_refl_one_bounce((refl_method)m, 1);
        s->light_count = 0;
        for (c = 0; c < 3; ++c) s->ambient[c] = 0.0f;
        for (k = 0; k < s->material_count; ++k)
            if (s->materials[k].type == REFL_DIFFUSE) {
                s->materials[k].emissive[0] = 0.5f;
                s->materials[k].emissive[1] = 0.25f;
                s->materials[k].emissive[2] = 2.0f;
            }
        cr_assert_eq(refl_frame_create(v.width, v.height, NULL, &f), REFL_OK);
        cr_assert_eq(refl_render(s, &v, &d, f), REFL_OK, "%s: %s", refl_method_name((refl_method)m), f->message);
        for (i = 0; i < v.width * v.height; ++i) {
            if (f->stencil[i] || f->depth[i] >= 1.0f) continue; /* reflectors and sky */
            cr_assert(f->rgba[4 * i] == 0.5f && f->rgba[4 * i + 1] == 0.25f && f->rgba[4 * i + 2] == 2.0f,
                      "%s: pixel %d shows %g %g %g", refl_method_name((refl_method)m), i, f->rgba[4 * i],
                      f->rgba[4 * i + 1], f->rgba[4 * i + 2]);
            ++shown;
        }
        cr_assert_gt(shown, 100, "%s: %d diffuse pixels", refl_method_name((refl_method)m), shown);
        refl_frame_destroy(f);
        refl_scene_destroy(s);
    }
}
