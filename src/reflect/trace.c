/* The per-pixel tracer: Whitted ray tracing through the BVH (or a caller's
   refl_ray_caster), what RAYTRACE renders every pixel with and SBC's
   fallback renders the pixels it cannot resolve with. A primary ray per
   pixel centre, mirror reflections to desc.depth bounces, glass with
   Fresnel reflection, refraction, total internal reflection and Beer's-law
   absorption (the full ray tree, or with desc.raytrace.greedy paper 001's
   two greedy paths), optional hard or soft shadows (soft: a shadow ray per
   jittered light sample, refl__rt_diffuse), the light planar mirrors
   reflect (light_volumes), the environment on a miss. Shading is the
   shared model of shade.c, and each surface's colour is clamped to [0, 1]
   before a reflectance weighs it, exactly as the rasterised methods
   composite into their RGBA8 frame, so images differ only where
   reflection geometry differs. A pixel depends on nothing but its own
   rays, so any thread count gives the same bytes. */
#include "internal.h"

/* A branch whose weight falls below this cannot move an 8-bit pixel;
   desc.raytrace.unpruned keeps every branch of nonzero weight. */
#define REFL__RT_MIN_WEIGHT (1.0f / 1024.0f)

typedef struct refl__rt_surface {
    refl_vec3 p, ng, ns;          /* point, geometric and shading normal (unit) */
    float uv[2];
    int has_uv;
    float magnitude;              /* largest |coordinate| of the triangle */
    const refl_material *material;
    int object, triangle;
} refl__rt_surface;

static int refl__rt_bvh_intersect(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax, refl_hit *hit) {
    return refl_bvh_intersect((const refl_bvh *)user, o, d, tmin, tmax, hit);
}

static int refl__rt_bvh_occluded(void *user, refl_vec3 o, refl_vec3 d, float tmin, float tmax) {
    return refl_bvh_occluded((const refl_bvh *)user, o, d, tmin, tmax);
}

/* A secondary ray starts a hair off its surface along n: a few float ulps
   of the triangle's largest coordinate, which bounds the rounding of both
   the hit point and the ray-triangle test, so the ray cannot hit its own
   triangle's neighbours by error, yet skips no geometry an image could
   show. Its own triangle is skipped exactly (refl__rt_cast): a flat
   triangle cannot be met twice by a straight ray. */
static refl_vec3 refl__rt_offset(refl_vec3 p, refl_vec3 n, float magnitude) {
    return refl_v3_add(p, refl_v3_scale(n, 5e-7f * magnitude)); /* 4 ulps: 2^-21 */
}

/* Point, normals and texture coordinates of a hit, from the mesh. */
static int refl__rt_surface_at(const refl__rt *rt, const refl_hit *h, refl__rt_surface *s) {
    const refl__rt_object *o = &rt->objects[h->object];
    const refl_mesh *m = o->mesh;
    const uint32_t *tri = m->indices + 3 * (size_t)h->triangle;
    refl__hit_geom g;
    int k;
    refl__hit_surface(m, &o->model, &o->normal_m, h, &g);
    s->magnitude = 0.0f;
    for (k = 0; k < 3; ++k)
        s->magnitude = REFL__MAX(s->magnitude, REFL__MAX(fabsf(g.v[k].x), REFL__MAX(fabsf(g.v[k].y), fabsf(g.v[k].z))));
    s->p = g.p;
    s->ng = g.ng;
    s->ns = g.ns;
    s->has_uv = m->texcoords != NULL;
    s->uv[0] = s->uv[1] = 0.0f;
    if (s->has_uv)
        for (k = 0; k < 3; ++k) {
            s->uv[0] += g.w[k] * m->texcoords[2 * (size_t)tri[k]];
            s->uv[1] += g.w[k] * m->texcoords[2 * (size_t)tri[k] + 1];
        }
    s->material = o->material;
    s->object = h->object;
    s->triangle = h->triangle;
    return refl_v3_dot(s->ng, s->ng) > 0.0f;
}

/* Every surface's colour as the rasterised methods keep it (REFL__RADIANCE). */
static void refl__rt_radiance(float rgb[3]) {
    int c;
    for (c = 0; c < 3; ++c) rgb[c] = REFL__RADIANCE(rgb[c]);
}

/* Closest hit from o along d, skipping the triangle the ray leaves. */
static int refl__rt_cast(const refl__rt *rt, refl_vec3 o, refl_vec3 d, float tmax, const refl__rt_surface *from,
                         refl_hit *h) {
    float tmin = 0.0f;
    int tries;
    for (tries = 0; tries < 4; ++tries) {
        if (!rt->caster.intersect(rt->caster.user, o, d, tmin, tmax, h)) return 0;
        if (!from || h->object != from->object || h->triangle != from->triangle) return 1;
        tmin = h->t;
    }
    return 0;
}

/* Whether a shadow ray from o along unit d meets nothing within dist
   (from: the surface it leaves, whose triangle it skips; may be NULL). */
static int refl__rt_clear(const refl__rt *rt, refl_vec3 o, refl_vec3 d, float dist, const refl__rt_surface *from,
                          long long *rays) {
    ++*rays;
    if (rt->caster.occluded) return !rt->caster.occluded(rt->caster.user, o, d, 0.0f, dist);
    {
        refl_hit h;
        return !refl__rt_cast(rt, o, d, dist, from, &h);
    }
}

/* Whether a shadow ray from surface s towards light l (at its position or
   along its direction) reaches it. */
static int refl__rt_light_visible(const refl__rt *rt, const refl__rt_surface *s, const refl_light *l,
                                  long long *rays) {
    refl_vec3 to = l->type == REFL_LIGHT_DIRECTIONAL ? refl_v3_scale(l->direction, -1.0f)
                                                     : refl_v3_sub(l->position, s->p);
    float dist = l->type == REFL_LIGHT_DIRECTIONAL ? FLT_MAX : refl_v3_length(to);
    refl_vec3 side = refl_v3_dot(to, s->ng) >= 0.0f ? s->ng : refl_v3_scale(s->ng, -1.0f);
    return refl__rt_clear(rt, refl__rt_offset(s->p, side, s->magnitude), refl_v3_normalize(to), dist, s, rays);
}

/* Virtual light k (light_volumes, light_volume.c) at surface s with unit
   normal nn: the face's reflectance times the fraction of the light's
   samples whose path through the face arrives (with shadows: nothing on
   the way from the face to s, nor from the light to the face). */
static float refl__rt_virtual(const refl__rt *rt, const refl__rt_surface *s, refl_vec3 nn, int k, long long *rays) {
    const refl__lv *lv = &rt->lv;
    const refl_scene *scene = rt->scene;
    const refl_light *vc = &lv->lights[scene->light_count + k];
    const refl__planar_face *f = &lv->faces[lv->v[k].face];
    refl_vec3 fn = refl_v3((float)(lv->v[k].side * f->n[0]), (float)(lv->v[k].side * f->n[1]),
                           (float)(lv->v[k].side * f->n[2]));
    refl_vec3 to = vc->type == REFL_LIGHT_DIRECTIONAL ? refl_v3_scale(vc->direction, -1.0f)
                                                      : refl_v3_sub(vc->position, s->p);
    float r;
    int j, ns = refl__lv_samples(lv, scene, k), arrive = 0;
    if (refl_v3_dot(nn, refl_v3_normalize(to)) <= 0.0f) return 0.0f; /* unlit anyway: no ray needed */
    r = refl__lv_reflectance(lv, scene, k, s->object, s->p);
    if (!(r > 0.0f)) return 0.0f;
    for (j = 0; j < ns; ++j) {
        refl_light src, virt;
        refl_vec3 m, o, d, mo;
        float mag;
        if (!refl__lv_sample(lv, scene, k, j, &src, &virt) || !refl__lv_through_face(lv, scene, k, &virt, s->p, &m))
            continue;
        if (rt->p->desc.lighting.shadows) {
            /* from the surface to the face, stopping short of the mirror */
            d = refl_v3_sub(m, s->p);
            o = refl__rt_offset(s->p, refl_v3_dot(d, s->ng) >= 0.0f ? s->ng : refl_v3_scale(s->ng, -1.0f),
                                s->magnitude);
            d = refl_v3_sub(m, o);
            if (!refl__rt_clear(rt, o, refl_v3_normalize(d), refl_v3_length(d) * (1.0f - 1e-4f), s, rays)) continue;
            /* from the face, on the light's side, to the light */
            mag = REFL__MAX(REFL__MAX(fabsf(m.x), fabsf(m.y)), REFL__MAX(fabsf(m.z), 1e-3f));
            mo = refl__rt_offset(m, fn, mag);
            d = src.type == REFL_LIGHT_DIRECTIONAL ? refl_v3_scale(src.direction, -1.0f) : refl_v3_sub(src.position, mo);
            if (!refl__rt_clear(rt, mo, refl_v3_normalize(d),
                                src.type == REFL_LIGHT_DIRECTIONAL ? FLT_MAX : refl_v3_length(d), NULL, rays))
                continue;
        }
        ++arrive;
    }
    return r * (float)arrive / (float)ns;
}

/* The shared diffuse model at a surface, with shadow rays when asked: one
   per light, or with soft shadows (paper 002's jittered lights) one per
   sample of each light with a radius (refl_light_sample), its Lambert term
   (towards its centre) weighed by the fraction that arrive, what the
   rasterised methods count with one shadow mask per sample. */
static void refl__rt_diffuse(const refl__rt *rt, const refl__rt_surface *s, refl_vec3 n, long long *rays,
                             float rgb[3]) {
    enum { MAX_LIGHTS = 64 };
    float weight[MAX_LIGHTS];
    const refl_scene *scene = rt->scene;
    int i, k, samples = REFL__MAX(rt->p->desc.lighting.soft_shadow_samples, 1);
    refl_vec3 nn = refl_v3_normalize(n);
    /* lights beyond MAX_LIGHTS (absurd scenes) go unshadowed */
    if ((!rt->p->desc.lighting.shadows && rt->lv.count == 0) || scene->light_count > MAX_LIGHTS) {
        refl_shade_diffuse(scene, s->material, s->p, n, s->has_uv ? s->uv : NULL, rgb);
        return;
    }
    for (i = 0; i < scene->light_count; ++i) {
        const refl_light *l = &scene->lights[i];
        refl_vec3 to = l->type == REFL_LIGHT_DIRECTIONAL ? refl_v3_scale(l->direction, -1.0f)
                                                         : refl_v3_sub(l->position, s->p);
        int ns = l->radius > 0.0f ? samples : 1, visible = 0;
        weight[i] = 1.0f;
        if (!rt->p->desc.lighting.shadows) continue;
        if (refl_v3_dot(nn, refl_v3_normalize(to)) <= 0.0f) continue; /* unlit anyway: no ray needed */
        for (k = 0; k < ns; ++k) {
            refl_light ls = ns > 1 ? refl_light_sample(l, k, ns) : *l;
            visible += refl__rt_light_visible(rt, s, &ls, rays);
        }
        weight[i] = (float)visible / (float)ns;
    }
    if (rt->lv.count == 0) {
        refl_shade_diffuse_weighted(scene, s->material, s->p, n, s->has_uv ? s->uv : NULL, weight, rgb);
        return;
    }
    /* then the light the mirrors reflect, as PLANAR's light volumes add it */
    for (k = 0; k < rt->lv.count; ++k) weight[scene->light_count + k] = refl__rt_virtual(rt, s, nn, k, rays);
    refl_shade_diffuse_weighted(&rt->lv.shade, s->material, s->p, n, s->has_uv ? s->uv : NULL, weight, rgb);
}

/* The medium a ray travels through: air, or the inside of a glass object
   (absorbing per unit length). */
typedef struct refl__rt_medium {
    float attenuation;
    int inside;
    /* translucency (desc.lighting.translucency): entered through glass at fog_p
       (plane normal fog_n), what the ray shows first beyond the glass is
       fogged towards fog_rgb by exp(-fog h), h its distance from that
       plane, as PLANAR fogs the image behind a glass face; 0: clear */
    float fog;
    refl_vec3 fog_p, fog_n;
    const float *fog_rgb;
    /* desc.raytrace.greedy, past the eye ray's first interface: glass
       spawns only its child of the larger Fresnel coefficient (paper 001) */
    int greedy;
} refl__rt_medium;

static void refl__rt_trace(const refl__rt *rt, refl_vec3 o, refl_vec3 d, const refl__rt_surface *from,
                           int depth, float weight, refl__rt_medium medium, long long *rays, float rgb[3],
                           refl_vec3 *first_point, float *hit_t);

/* A new ray leaving surface s in direction d, on the side d points to;
   *hit_t (may be NULL) the distance to what it meets, INFINITY for none. */
static void refl__rt_spawn(const refl__rt *rt, const refl__rt_surface *s, refl_vec3 d, int depth, float weight,
                           refl__rt_medium medium, long long *rays, float rgb[3], refl_vec3 *first_point,
                           float *hit_t) {
    refl_vec3 side = refl_v3_dot(d, s->ng) >= 0.0f ? s->ng : refl_v3_scale(s->ng, -1.0f);
    refl__rt_trace(rt, refl__rt_offset(s->p, side, s->magnitude), d, s, depth, weight, medium, rays, rgb,
                   first_point, hit_t);
}

/* The mirror direction of unit d at s: about the shading normal turned to
   face d; near a silhouette, where that sends the ray into the surface
   itself, about the true surface instead. */
static refl_vec3 refl__rt_mirror(const refl__rt_surface *s, refl_vec3 d) {
    int entering = refl_v3_dot(d, s->ng) < 0.0f;
    refl_vec3 n = entering ? s->ns : refl_v3_scale(s->ns, -1.0f), ng = entering ? s->ng : refl_v3_scale(s->ng, -1.0f);
    refl_vec3 rd;
    if (refl_v3_dot(d, n) > 0.0f) n = ng;
    rd = refl_v3_reflect(d, n);
    return refl_v3_dot(rd, ng) <= 0.0f ? refl_v3_reflect(d, ng) : rd;
}

/* Colour of surface s seen along unit d with `depth` bounces left,
   clamped to [0, 1]. first_point (may be NULL) receives the first point
   outside glass that the reflected or refracted light comes from, along
   the stronger branch at each interface. */
static void refl__rt_shade(const refl__rt *rt, const refl__rt_surface *s, refl_vec3 d, int depth, float weight,
                           refl__rt_medium medium, long long *rays, float rgb[3], refl_vec3 *first_point) {
    const refl_material *m = s->material;
    float cos_i, r, sub[3], min_weight;
    int c, entering;
    refl_vec3 n = s->ns, ng = s->ng;
    if (m->type == REFL_DIFFUSE) {
        refl__rt_diffuse(rt, s, n, rays, rgb);
        refl__rt_radiance(rgb);
        return;
    }
    entering = refl_v3_dot(d, ng) < 0.0f;
    if (!entering) {
        n = refl_v3_scale(n, -1.0f);
        ng = refl_v3_scale(ng, -1.0f);
    }
    if (refl_v3_dot(d, n) > 0.0f) n = ng; /* shading normal faces away: trust the geometry */
    cos_i = -refl_v3_dot(d, n);
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    if (m->type == REFL_PARTIAL) {
        /* the diffuse share, as the base pass draws it */
        float k = 1.0f - REFL__CLAMP(m->mirror_weight, 0.0f, 1.0f);
        refl__rt_diffuse(rt, s, s->ns, rays, rgb);
        refl__rt_radiance(rgb);
        for (c = 0; c < 3; ++c) rgb[c] *= k;
    }
    if (depth <= 0) return; /* what DIRECT shows: the diffuse share, or black */
    min_weight = rt->p->desc.raytrace.unpruned ? FLT_MIN : REFL__RT_MIN_WEIGHT;
    if (m->type != REFL_GLASS) {
        refl_vec3 rd = refl__rt_mirror(s, d);
        float t = INFINITY;
        medium.greedy = rt->p->desc.raytrace.greedy; /* glass met past a mirror goes greedy */
        r = refl_material_reflectance(m, cos_i);
        if (r * weight >= min_weight || first_point) {
            refl__rt_spawn(rt, s, rd, depth - 1, weight * r, medium, rays, sub, first_point, &t);
            r *= refl_material_fade(m, t); /* paper 003 V-D: by the reflected ray's length */
            for (c = 0; c < 3; ++c) rgb[c] += r * sub[c];
        }
    } else {
        float ior = m->ior > 0.0f ? m->ior : 1.5f;
        float n1 = entering ? 1.0f : ior, n2 = entering ? ior : 1.0f;
        float f = refl_fresnel_dielectric(cos_i, n1, n2), tint[3];
        refl_vec3 t;
        int refracts = f < 1.0f && refl_v3_refract(d, n, n1 / n2, &t);
        int point_on_refraction = refracts && f < 0.5f;
        /* greedy: the one child of the larger coefficient (a tie reflects),
           as refl_greedy_paths takes it; the first interface spawns both */
        int greedy_reflect = !medium.greedy || !refracts || f >= 1.0f - f;
        int greedy_refract = !medium.greedy || (refracts && f < 1.0f - f);
        /* inside translucent glass the fog scatters what reflects within
           (PLANAR's slab has no inner reflections either) */
        int scattered = !entering && medium.fog > 0.0f && refracts;
        refl__rt_medium through;
        if (!refracts) f = 1.0f; /* total internal reflection */
        for (c = 0; c < 3; ++c) tint[c] = m->tint[0] + m->tint[1] + m->tint[2] > 0.0f ? m->tint[c] : 1.0f;
        medium.greedy = rt->p->desc.raytrace.greedy; /* both children of this interface go greedy */
        if (!scattered && greedy_reflect &&
            (f * weight >= min_weight || (first_point && !point_on_refraction))) {
            refl__rt_spawn(rt, s, refl_v3_reflect(d, n), depth - 1, weight * f, medium, rays, sub,
                           point_on_refraction ? NULL : first_point, NULL);
            for (c = 0; c < 3; ++c) rgb[c] += f * sub[c];
        }
        if (refracts && greedy_refract &&
            ((1.0f - f) * weight >= min_weight || (first_point && point_on_refraction))) {
            /* entering: tinted once, then absorbed along the inside */
            through = medium;
            through.attenuation = entering ? REFL__MAX(m->attenuation, 0.0f) : 0.0f;
            through.inside = entering;
            if (entering) { /* translucency: fogged from this face on (refl__rt_trace) */
                through.fog = rt->p->desc.lighting.translucency;
                through.fog_p = s->p;
                through.fog_n = s->ng;
                through.fog_rgb = m->color;
            }
            refl__rt_spawn(rt, s, t, depth - 1, weight * (1.0f - f), through, rays, sub,
                           point_on_refraction ? first_point : NULL, NULL);
            for (c = 0; c < 3; ++c) rgb[c] += (1.0f - f) * (entering ? tint[c] : 1.0f) * sub[c];
        }
    }
    refl__rt_radiance(rgb);
}

static void refl__rt_trace(const refl__rt *rt, refl_vec3 o, refl_vec3 d, const refl__rt_surface *from,
                           int depth, float weight, refl__rt_medium medium, long long *rays, float rgb[3],
                           refl_vec3 *first_point, float *hit_t) {
    refl_hit h;
    refl__rt_surface s;
    int c;
    float fog = 1.0f;             /* the share the fog leaves */
    ++*rays;
    if (hit_t) *hit_t = INFINITY;
    if (!refl__rt_cast(rt, o, d, FLT_MAX, from, &h) || h.object < 0 ||
        h.object >= rt->scene->object_count || !refl__rt_surface_at(rt, &h, &s)) {
        refl_environment_lookup(&rt->scene->environment, d, rgb);
        refl__rt_radiance(rgb);
        if (first_point && rt->p->desc.debug.points_last) *first_point = refl_v3(NAN, NAN, NAN); /* ends here */
        if (medium.fog > 0.0f) /* infinitely far: wholly fogged */
            for (c = 0; c < 3; ++c) rgb[c] = REFL__CLAMP(medium.fog_rgb[c], 0.0f, 1.0f);
        return;
    }
    if (hit_t) *hit_t = h.t;
    /* inside glass, the light's source lies further on */
    if (first_point && !medium.inside) {
        *first_point = s.p;
        if (!rt->p->desc.debug.points_last) first_point = NULL; /* else followed to the path's end */
    }
    if (medium.fog > 0.0f && s.material->type != REFL_GLASS) {
        fog = expf(-medium.fog * fabsf(refl_v3_dot(refl_v3_sub(s.p, medium.fog_p), medium.fog_n)));
        medium.fog = 0.0f; /* once */
    }
    refl__rt_shade(rt, &s, d, depth, weight, medium, rays, rgb, first_point);
    if (fog < 1.0f)
        for (c = 0; c < 3; ++c) rgb[c] = fog * rgb[c] + (1.0f - fog) * REFL__CLAMP(medium.fog_rgb[c], 0.0f, 1.0f);
    if (medium.attenuation > 0.0f) {
        float k = expf(-medium.attenuation * h.t);
        for (c = 0; c < 3; ++c) rgb[c] *= k;
    }
}

/* Pixel (x, y) as RAYTRACE renders it: a primary ray from the near plane
   to the far plane (what the rasteriser clips to); colour, the point its
   reflector shows (NaN: none, or no reflector), window depth and stencil
   as the base pass writes them; *rays counts the rays cast. SBC's
   fallback traces pixels with it too (desc.sbc.trace_fallback). */
static void refl__rt_pixel(const refl__rt *rt, int x, int y, long long *rays, float rgb[3], refl_vec3 *shown,
                           float *depth, uint8_t *stencil) {
    refl_vec3 a, d;
    float len;
    refl_hit h;
    refl__rt_surface s;
    refl__rt_medium air;
    memset(&air, 0, sizeof air);
    *shown = refl_v3(NAN, NAN, NAN);
    *depth = 1.0f;
    *stencil = 0;
    refl__view_rays_get(&rt->p->rays, (float)x + 0.5f, (float)y + 0.5f, &a, &d, &len);
    ++*rays;
    if (rt->caster.intersect(rt->caster.user, a, d, 0.0f, len, &h) && h.object >= 0 &&
        h.object < rt->scene->object_count && refl__rt_surface_at(rt, &h, &s)) {
        /* GL's window depth of the eye distance along the axis */
        const refl__view_rays *vr = &rt->p->rays;
        float ze = refl_v3_dot(refl_v3_sub(s.p, vr->eye), vr->forward), zn = vr->znear, zf = vr->zfar;
        float ndc = (zf + zn) / (zf - zn) - 2.0f * zf * zn / ((zf - zn) * ze);
        int reflector = refl__is_reflector(s.material);
        *depth = REFL__CLAMP(0.5f * ndc + 0.5f, 0.0f, 1.0f);
        refl__rt_shade(rt, &s, d, rt->p->desc.depth, 1.0f, air, rays, rgb, reflector ? shown : NULL);
        if (reflector) *stencil = (uint8_t)(h.object + 1 < 255 ? h.object + 1 : 255);
    } else {
        refl_environment_lookup(&rt->scene->environment, d, rgb);
    }
}

/* Whether pixel (x, y)'s exact path, after the modelled[object] mirror
   reflections its reflector's method models, meets a reflector again
   (refl__trace_beyond). Glass met on the way is the method's own. */
static int refl__rt_goes_beyond(const refl__rt *rt, int x, int y, const int *modelled, long long *rays) {
    refl_vec3 o, d;
    float len;
    refl_hit h;
    refl__rt_surface s;
    int k, j;
    refl__view_rays_get(&rt->p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &len);
    ++*rays;
    if (!rt->caster.intersect(rt->caster.user, o, d, 0.0f, len, &h) || h.object < 0 ||
        h.object >= rt->scene->object_count || !refl__rt_surface_at(rt, &h, &s))
        return 0;
    k = modelled[s.object];
    if (k <= 0 || k >= rt->p->desc.depth) return 0;
    for (j = 0; j < k; ++j) {
        refl_vec3 rd, side;
        refl__rt_surface from = s;
        if (s.material->type == REFL_DIFFUSE || s.material->type == REFL_GLASS) return 0;
        rd = refl__rt_mirror(&s, d);
        side = refl_v3_dot(rd, s.ng) >= 0.0f ? s.ng : refl_v3_scale(s.ng, -1.0f);
        ++*rays;
        if (!refl__rt_cast(rt, refl__rt_offset(s.p, side, s.magnitude), rd, FLT_MAX, &from, &h) || h.object < 0 ||
            h.object >= rt->scene->object_count || !refl__rt_surface_at(rt, &h, &s))
            return 0;
        d = rd;
    }
    return refl__is_reflector(s.material);
}

/* What tracing a frame of pass p needs besides the tiles: the objects'
   transforms and materials, the caster (p's, else `bvh` when the caller
   has built one of the scene, else a BVH built here), and with light
   volumes the planar mirror faces and their virtual lights. refl__rt_end
   frees it. */
static refl__rt_object *refl__rt_objects_new(const refl_scene *scene) {
    refl__rt_object *objects = (refl__rt_object *)refl__calloc(
        &scene->allocator, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl__rt_object));
    int i;
    for (i = 0; objects && i < scene->object_count; ++i) {
        const refl_object *o = &scene->objects[i];
        objects[i].mesh = scene->meshes[o->mesh];
        objects[i].material = &scene->materials[o->material];
        objects[i].model = o->transform;
        objects[i].normal_m = refl__normal_matrix(o->transform);
    }
    return objects;
}

static refl_result refl__rt_begin(refl__rt *rt, const refl__pass *p, refl_bvh *bvh) {
    const refl_scene *scene = p->scene;
    refl_result r = REFL_OK;
    memset(rt, 0, sizeof *rt);
    rt->p = p;
    rt->scene = scene;
    rt->caster = p->desc.raytrace.caster;
    rt->objects = refl__rt_objects_new(scene);
    if (!rt->objects) return REFL_ERROR_OUT_OF_MEMORY;
    if (!rt->caster.intersect) {
        if (!bvh && (r = refl_bvh_build(scene, &scene->allocator, &rt->bvh)) != REFL_OK) return r;
        rt->caster.intersect = refl__rt_bvh_intersect;
        rt->caster.occluded = refl__rt_bvh_occluded;
        rt->caster.user = bvh ? bvh : rt->bvh;
    }
    if (p->desc.lighting.light_volumes) {
        if ((r = refl__planar_find_faces(scene, NULL, &rt->faces, &rt->face_count)) != REFL_OK) return r;
        refl__lv_init(&rt->lv, scene, rt->faces, rt->face_count, p->desc.lighting.caustic_samples);
    }
    return REFL_OK;
}

static void refl__rt_end(refl__rt *rt) {
    if (!rt->scene) return;
    refl_bvh_destroy(rt->bvh);
    if (rt->faces) refl__planar_free_faces(rt->scene, rt->faces, rt->face_count);
    refl__free(&rt->scene->allocator, rt->objects);
    rt->scene = NULL;
}
