/* The one shading model every method uses: diffuse surfaces lit by ambient
   and Lambert terms (no shadows), and the environment on a miss. Methods
   differ only in where a reflected or refracted ray lands, never in how
   that point is shaded, so their images compare fairly. */
#include "internal.h"

/* Bilinear sample of an RGBA float image at (u, v), v = 0 the top row
   (glTF's convention). Each axis repeats, or is clamped to the edge when
   its bit is set in `clamp` (1: u, 2: v): cube faces must not blend in
   their opposite edge, nor an equirectangular map one pole into the other. */
enum { REFL__CLAMP_U = 1, REFL__CLAMP_V = 2 };
static void refl__image_sample(const refl_image *img, float u, float v, int clamp, float rgba[4]) {
    float x, y, fx, fy;
    int x0, y0, x1, y1, c, cu = clamp & REFL__CLAMP_U, cv = clamp & REFL__CLAMP_V;
    const float *p00, *p10, *p01, *p11;
    if (!img->pixels || img->width <= 0 || img->height <= 0) {
        rgba[0] = rgba[1] = rgba[2] = rgba[3] = 1.0f;
        return;
    }
    if (!refl__isfinite(u)) u = 0.0f;
    if (!refl__isfinite(v)) v = 0.0f;
    u = cu ? REFL__CLAMP(u, 0.0f, 1.0f) : u - floorf(u);
    v = cv ? REFL__CLAMP(v, 0.0f, 1.0f) : v - floorf(v);
    x = u * (float)img->width - 0.5f;
    y = v * (float)img->height - 0.5f;
    fx = x - floorf(x);
    fy = y - floorf(y);
    x0 = (int)floorf(x);
    y0 = (int)floorf(y);
    /* each tap into the image: wrapped around, or held at the edge */
    x1 = x0 + 1 >= img->width ? (cu ? img->width - 1 : 0) : x0 + 1;
    y1 = y0 + 1 >= img->height ? (cv ? img->height - 1 : 0) : y0 + 1;
    if (x0 < 0) x0 = cu ? 0 : img->width - 1;
    if (y0 < 0) y0 = cv ? 0 : img->height - 1;
    if (x0 >= img->width) x0 = img->width - 1;
    if (y0 >= img->height) y0 = img->height - 1;
    p00 = img->pixels + 4 * ((size_t)y0 * (size_t)img->width + (size_t)x0);
    p10 = img->pixels + 4 * ((size_t)y0 * (size_t)img->width + (size_t)x1);
    p01 = img->pixels + 4 * ((size_t)y1 * (size_t)img->width + (size_t)x0);
    p11 = img->pixels + 4 * ((size_t)y1 * (size_t)img->width + (size_t)x1);
    for (c = 0; c < 4; ++c)
        rgba[c] = (p00[c] * (1.0f - fx) + p10[c] * fx) * (1.0f - fy) + (p01[c] * (1.0f - fx) + p11[c] * fx) * fy;
}

REFL_API void refl_shade_diffuse(const refl_scene *scene, const refl_material *m, refl_vec3 p, refl_vec3 n,
                                 const float *uv, float rgb[3]) {
    refl_shade_diffuse_lit(scene, m, p, n, uv, NULL, rgb);
}

/* Ambient plus each light's Lambert term, each light counted where lit[i]
   is nonzero (lit NULL: all) and weighed by weight[i] (NULL: 1), times the
   material's colour, plus its emission. A weight of 1 adds exactly the unweighted term. */
static void refl__shade_lights(const refl_scene *scene, const refl_material *m, refl_vec3 p, refl_vec3 n,
                               const float *uv, const unsigned char *lit, const float *weight, float rgb[3]) {
    float base[4];
    int i, c;
    refl_vec3 nn = refl_v3_normalize(n);
    for (c = 0; c < 4; ++c) base[c] = m ? m->color[c] : 0.8f;
    if (m && m->texture > 0 && scene && m->texture <= scene->texture_count && uv) {
        float t[4];
        refl__image_sample(&scene->textures[m->texture - 1], uv[0], uv[1], 0, t);
        for (c = 0; c < 4; ++c) base[c] *= t[c];
    }
    for (c = 0; c < 3; ++c) rgb[c] = scene ? scene->ambient[c] : 0.1f;
    for (i = 0; scene && i < scene->light_count; ++i) {
        const refl_light *l = &scene->lights[i];
        refl_vec3 to_light = l->type == REFL_LIGHT_DIRECTIONAL ? refl_v3_scale(l->direction, -1.0f)
                                                               : refl_v3_sub(l->position, p);
        float lambert = refl_v3_dot(nn, refl_v3_normalize(to_light)), w = weight ? weight[i] : 1.0f;
        if (lambert <= 0.0f || (lit && !lit[i]) || !(w > 0.0f)) continue;
        if (w < 1.0f) lambert *= w;
        for (c = 0; c < 3; ++c) rgb[c] += lambert * l->color[c];
    }
    for (c = 0; c < 3; ++c) rgb[c] *= base[c];
    if (m)
        for (c = 0; c < 3; ++c) rgb[c] += m->emissive[c];
}

REFL_API void refl_shade_diffuse_lit(const refl_scene *scene, const refl_material *m, refl_vec3 p, refl_vec3 n,
                                     const float *uv, const unsigned char *lit, float rgb[3]) {
    refl__shade_lights(scene, m, p, n, uv, lit, NULL, rgb);
}

REFL_API void refl_shade_diffuse_weighted(const refl_scene *scene, const refl_material *m, refl_vec3 p, refl_vec3 n,
                                          const float *uv, const float *weight, float rgb[3]) {
    refl__shade_lights(scene, m, p, n, uv, NULL, weight, rgb);
}

REFL_API refl_light refl_light_sample(const refl_light *light, int index, int count) {
    refl_light l;
    float phi, cp, sp;
    memset(&l, 0, sizeof l);
    if (!light) return l;
    l = *light;
    if (count <= 1 || !(light->radius > 0.0f)) return l;
    phi = (float)((double)index * 2.39996322972865332);
    cp = (float)cos((double)phi);
    sp = (float)sin((double)phi);
    if (light->type == REFL_LIGHT_DIRECTIONAL) {
        refl_vec3 d = refl_v3_normalize(light->direction), u, v;
        float r = sqrtf(((float)index + 0.5f) / (float)count) * tanf(REFL__MIN(light->radius, 1.5f));
        if (refl_v3_dot(d, d) == 0.0f) return l;
        u = refl_v3_normalize(refl_v3_cross(d, fabsf(d.x) < 0.9f ? refl_v3(1, 0, 0) : refl_v3(0, 1, 0)));
        v = refl_v3_cross(d, u);
        l.direction = refl_v3_normalize(refl_v3_add(d, refl_v3_add(refl_v3_scale(u, r * cp), refl_v3_scale(v, r * sp))));
    } else {
        float z = 1.0f - (2.0f * (float)index + 1.0f) / (float)count, rr = sqrtf(REFL__MAX(0.0f, 1.0f - z * z));
        l.position = refl_v3_add(light->position, refl_v3_scale(refl_v3(rr * cp, rr * sp, z), light->radius));
    }
    return l;
}

REFL_API void refl_environment_lookup(const refl_environment *env, refl_vec3 dir, float rgb[3]) {
    float k = env && env->intensity > 0.0f ? env->intensity : 1.0f, t[4];
    int c;
    refl_vec3 d = refl_v3_normalize(dir);
    if (!env || env->type == REFL_ENV_COLOR || (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f)) {
        for (c = 0; c < 3; ++c) rgb[c] = env ? env->color[c] * k : 0.0f;
        return;
    }
    if (env->type == REFL_ENV_EQUIRECT) {
        /* longitude across (-z at the centre column), +y at the top row */
        float u = 0.5f + atan2f(d.x, -d.z) * (float)(0.5 / REFL__PI);
        float v = acosf(REFL__CLAMP(d.y, -1.0f, 1.0f)) * (float)(1.0 / REFL__PI);
        refl__image_sample(&env->image, u, v, REFL__CLAMP_V, t); /* longitude wraps */
    } else {
        float dv[3], s, tt;
        int face;
        dv[0] = d.x; dv[1] = d.y; dv[2] = d.z;
        face = rast_cube_face(dv, &s, &tt);
        refl__image_sample(&env->faces[face], s, tt, REFL__CLAMP_U | REFL__CLAMP_V, t);
    }
    for (c = 0; c < 3; ++c) rgb[c] = t[c] * k;
}

REFL_API float refl_fresnel_dielectric(float cos_i, float n1, float n2) {
    float sin_t, cos_t, rs, rp;
    cos_i = REFL__CLAMP(cos_i, 0.0f, 1.0f);
    if (!(n1 > 0.0f) || !(n2 > 0.0f)) return 1.0f;
    sin_t = n1 / n2 * sqrtf(REFL__MAX(0.0f, 1.0f - cos_i * cos_i));
    if (sin_t >= 1.0f) return 1.0f;
    cos_t = sqrtf(1.0f - sin_t * sin_t);
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    rp = (n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i);
    return 0.5f * (rs * rs + rp * rp);
}

/* A weight clamped to [0, 1]; NaN counts as 0 (a material edited by hand
   must not turn a frame NaN). */
static float refl__unit(float v) { return v > 0.0f ? (v < 1.0f ? v : 1.0f) : 0.0f; }

REFL_API float refl_material_reflectance(const refl_material *m, float cos_i) {
    float r, c5;
    if (!m || m->type == REFL_DIFFUSE) return 0.0f;
    if (m->type == REFL_GLASS) return refl_fresnel_dielectric(cos_i, 1.0f, m->ior > 0.0f ? m->ior : 1.5f);
    r = m->reflectance > 0.0f ? REFL__MIN(m->reflectance, 1.0f) : 1.0f;
    if (m->fresnel) {
        c5 = 1.0f - REFL__CLAMP(cos_i, 0.0f, 1.0f);
        c5 = c5 * c5 * c5 * c5 * c5;
        r = r + (1.0f - r) * c5;
    }
    if (m->fresnel_max > 0.0f) { /* paper 003 V-D: weights in cos^2, scaled to [min, max] */
        float c2 = REFL__CLAMP(cos_i, 0.0f, 1.0f) * REFL__CLAMP(cos_i, 0.0f, 1.0f);
        float lo = refl__unit(m->fresnel_min), hi = refl__unit(m->fresnel_max);
        r *= hi - (hi - lo) * c2;
    }
    if (m->type == REFL_PARTIAL) r *= REFL__CLAMP(m->mirror_weight, 0.0f, 1.0f);
    return r;
}

REFL_API float refl_material_fade(const refl_material *m, float distance) {
    float lo, hi, f;
    if (!m || (m->type != REFL_MIRROR && m->type != REFL_PARTIAL) || !(m->fade_distance > 0.0f)) return 1.0f;
    lo = refl__unit(m->fade_min);
    hi = refl__unit(m->fade_max);
    /* NaN (no point) fades as the environment does: wholly */
    f = distance >= 0.0f ? REFL__MIN(distance / m->fade_distance, 1.0f) : 1.0f;
    return hi - (hi - lo) * f * f;
}
