/* Paper 001's shading model (Hakura and Snyder, section 3): instead of the
   binary ray tree glass spawns, two greedy ray paths. An eye ray meeting a
   lens object (mirror or glass) starts a path by reflection and, at glass,
   one by refraction; at every later interface a path follows only the child
   of the larger Fresnel coefficient until it leaves the lens system. Each
   path carries the product of the coefficients taken (F) and the glass's
   transparency attenuation (G), and ends in an exit ray whose radiance the
   caller looks up (ray tracing, or the layered environment maps):
   pixel = T F_T G_T + R F_R G_R. Pure geometry: a path depends on nothing
   but its ray, so callers on any thread count get the same answers. */
#include "internal.h"

/* The closest hit of caster along o + t d skipping triangle (skip_object,
   skip_triangle), the one the ray leaves: 1 and *hit, or 0 for none. */
static int refl__gp_closest(const refl_ray_caster *caster, refl_vec3 o, refl_vec3 d, int skip_object,
                            int skip_triangle, refl_hit *hit) {
    float tmin = 0.0f;
    int tries;
    for (tries = 0; tries < 4; ++tries) {
        if (!caster->intersect(caster->user, o, d, tmin, FLT_MAX, hit)) return 0;
        if (hit->object != skip_object || hit->triangle != skip_triangle) return 1;
        tmin = hit->t;
    }
    return 0;
}

static int refl__caster_blocked(const refl_ray_caster *c, refl_vec3 o, refl_vec3 d, float tmax) {
    refl_hit hit;
    return c->occluded ? c->occluded(c->user, o, d, 0.0f, tmax) : c->intersect(c->user, o, d, 0.0f, tmax, &hit);
}

/* The next lens surface along o + t d skipping triangle (skip_object,
   skip_triangle), the one the ray leaves: 1 and *h, or 0 where the ray
   leaves the lens system (it meets nothing, or another surface first).
   With the split casters (c->lenses, c->others) the closest lens surface
   is found among the lens triangles alone and the rest of the scene only
   asked whether it has anything before it (any hit); a ray that meets no
   lens costs no test of the rest at all (what it meets there is the
   maps' to answer). Either way the answer is the scene's closest hit's
   (the split BVHs hold the scene's triangles as the same floats). */
static int refl__gp_cast(const refl_scene *scene, const refl__gp_casters *c, refl_vec3 o, refl_vec3 d,
                         int skip_object, int skip_triangle, refl__gp_hit *h, long long *rays) {
    refl_hit hit;
    if (rays) ++*rays;
    if (c->lenses && c->others) {
        if (!refl__gp_closest(c->lenses, o, d, skip_object, skip_triangle, &hit)) return 0;
        if (c->own >= 0 && hit.object != c->own) return 0; /* leaves own: the rest is its environment */
        if (refl__caster_blocked(c->others, o, d, hit.t)) return 0;
    } else if (!refl__gp_closest(c->scene, o, d, skip_object, skip_triangle, &hit)) {
        return 0;
    }
    if (c->own >= 0 && hit.object != c->own) return 0;
    return refl__gp_hit_of(scene, &hit, h);
}

static int refl__gp_hit_of(const refl_scene *scene, const refl_hit *hit_in, refl__gp_hit *h) {
    refl_hit hit = *hit_in;
    const refl_object *obj;
    refl_mat4 nm;
    refl__hit_geom g;
    int k;
    if (hit.object < 0 || hit.object >= scene->object_count) return 0;
    obj = &scene->objects[hit.object];
    if (!refl__is_reflector(&scene->materials[obj->material])) return 0;
    nm = refl__normal_matrix(obj->transform);
    refl__hit_surface(scene->meshes[obj->mesh], &obj->transform, &nm, &hit, &g);
    if (!(refl_v3_dot(g.ng, g.ng) > 0.0f)) return 0;
    h->p = g.p;
    h->ng = g.ng;
    h->ns = g.ns;
    h->magnitude = 0.0f;
    for (k = 0; k < 3; ++k)
        h->magnitude = REFL__MAX(h->magnitude, REFL__MAX(fabsf(g.v[k].x), REFL__MAX(fabsf(g.v[k].y), fabsf(g.v[k].z))));
    h->material = &scene->materials[obj->material];
    h->object = hit.object;
    h->triangle = hit.triangle;
    h->t = hit.t;
    return 1;
}

/* The two children of an interface for a ray along unit d: the reflected
   and (glass, below the critical angle) refracted directions, the
   reflected share f, and whether the ray enters the material. */
typedef struct refl__gp_children {
    refl_vec3 reflect, refract;
    float f;                     /* reflected share; the refracted carries 1 - f */
    int refracts, entering;
} refl__gp_children;

static void refl__gp_interface(const refl__gp_hit *h, refl_vec3 d, refl__gp_children *c) {
    const refl_material *m = h->material;
    refl_vec3 n = h->ns, ng = h->ng;
    float cos_i;
    c->entering = refl_v3_dot(d, ng) < 0.0f;
    if (!c->entering) {
        n = refl_v3_scale(n, -1.0f);
        ng = refl_v3_scale(ng, -1.0f);
    }
    if (refl_v3_dot(d, n) > 0.0f) n = ng; /* shading normal faces away: trust the geometry (as trace.c) */
    cos_i = -refl_v3_dot(d, n);
    c->reflect = refl_v3_reflect(d, n);
    c->refracts = 0;
    c->refract = d;
    if (m->type != REFL_GLASS) {
        if (refl_v3_dot(c->reflect, ng) <= 0.0f) c->reflect = refl_v3_reflect(d, ng);
        c->f = refl_material_reflectance(m, cos_i);
        return;
    }
    {
        float ior = m->ior > 0.0f ? m->ior : 1.5f;
        float n1 = c->entering ? 1.0f : ior, n2 = c->entering ? ior : 1.0f;
        c->f = refl_fresnel_dielectric(cos_i, n1, n2);
        c->refracts = c->f < 1.0f && refl_v3_refract(d, n, n1 / n2, &c->refract);
        if (!c->refracts) c->f = 1.0f; /* total internal reflection */
    }
}

/* A path taking child `reflect` (0: refraction) of the interface at h:
   its F and G, and the ray it continues by. */
static void refl__gp_take(refl_greedy_path *path, const refl__gp_hit *h, const refl__gp_children *c, int reflect,
                          refl_vec3 *o, refl_vec3 *d) {
    const refl_material *m = h->material;
    refl_vec3 side;
    int k;
    if (path->length < 32 && reflect) path->reflected |= 1u << path->length;
    ++path->length;
    path->fresnel *= reflect ? c->f : 1.0f - c->f;
    if (!reflect && c->entering) /* entering glass: tinted once (as trace.c) */
        for (k = 0; k < 3; ++k)
            path->attenuation[k] *= m->tint[0] + m->tint[1] + m->tint[2] > 0.0f ? m->tint[k] : 1.0f;
    *d = reflect ? c->reflect : c->refract;
    path->exit_origin = h->p;
    path->exit_direction = *d;
    side = refl_v3_dot(*d, h->ng) >= 0.0f ? h->ng : refl_v3_scale(h->ng, -1.0f);
    *o = refl__rt_offset(h->p, side, h->magnitude);
}

/* Follows a path from the ray (o, d) that left interface `from` until it
   leaves the lens system, or meets an interface past max_interfaces. */
static void refl__gp_follow(const refl_scene *scene, const refl__gp_casters *c, refl_greedy_path *path,
                            refl_vec3 o, refl_vec3 d, refl__gp_hit from, int max_interfaces, long long *rays) {
    refl__gp_hit h;
    refl__gp_children ch;
    int k;
    for (;;) {
        if (!refl__gp_cast(scene, c, o, d, from.object, from.triangle, &h, rays)) {
            path->exited = 1;
            return;
        }
        if (path->length >= max_interfaces) return; /* one interface too many: it ends inside */
        refl__gp_interface(&h, d, &ch);
        if (!ch.entering && h.material->type == REFL_GLASS) { /* the segment just travelled was inside */
            float a = REFL__MAX(h.material->attenuation, 0.0f), len = h.t * refl_v3_length(d);
            path->inside_length += len;
            if (a > 0.0f)
                for (k = 0; k < 3; ++k) path->attenuation[k] *= expf(-a * len);
        }
        /* the larger coefficient; a tie reflects */
        refl__gp_take(path, &h, &ch, !ch.refracts || ch.f >= 1.0f - ch.f, &o, &d);
        from = h;
    }
}

static void refl__gp_start(refl_greedy_path *path, refl_vec3 o, refl_vec3 d) {
    memset(path, 0, sizeof *path);
    path->fresnel = 1.0f;
    path->attenuation[0] = path->attenuation[1] = path->attenuation[2] = 1.0f;
    path->exit_origin = o;
    path->exit_direction = d;
}

/* The two paths of a ray along unit `dir` meeting lens surface h first. */
static void refl__greedy_paths_from(const refl_scene *scene, const refl__gp_casters *casters, refl_vec3 dir,
                                    const refl__gp_hit *h, int max_interfaces, refl_greedy_paths_result *out,
                                    long long *rays) {
    refl__gp_children c;
    refl_vec3 o, d;
    max_interfaces = max_interfaces <= 0 || max_interfaces > REFL_GREEDY_MAX_INTERFACES ? REFL_GREEDY_MAX_INTERFACES
                                                                                         : max_interfaces;
    out->object = h->object;
    out->first_point = h->p;
    refl__gp_interface(h, dir, &c);
    out->terms = h->material->type == REFL_GLASS ? 2 : 1;
    out->reflect.fresnel = 1.0f;
    refl__gp_take(&out->reflect, h, &c, 1, &o, &d);
    refl__gp_follow(scene, casters, &out->reflect, o, d, *h, max_interfaces, rays);
    if (out->terms == 2 && c.refracts) {
        out->refract.fresnel = 1.0f;
        refl__gp_take(&out->refract, h, &c, 0, &o, &d);
        refl__gp_follow(scene, casters, &out->refract, o, d, *h, max_interfaces, rays);
    }
}

/* No terms yet: both paths empty, the exit rays the eye ray itself. */
static void refl__greedy_paths_none(refl_vec3 origin, refl_vec3 dir, refl_greedy_paths_result *out) {
    memset(out, 0, sizeof *out);
    out->object = -1;
    out->first_point = refl_v3(NAN, NAN, NAN);
    refl__gp_start(&out->reflect, origin, dir);
    refl__gp_start(&out->refract, origin, dir);
    out->reflect.fresnel = out->refract.fresnel = 0.0f;
}

static void refl__greedy_paths_cast(const refl_scene *scene, const refl__gp_casters *casters, refl_vec3 origin,
                                    refl_vec3 dir, int max_interfaces, refl_greedy_paths_result *out,
                                    long long *rays) {
    refl__gp_casters first = *casters;
    refl__gp_hit h;
    refl__greedy_paths_none(origin, dir, out);
    first.own = -1; /* the eye ray meets any lens first */
    if (!refl__gp_cast(scene, &first, origin, dir, -1, -1, &h, rays)) return;
    refl__greedy_paths_from(scene, casters, dir, &h, max_interfaces, out, rays);
}

static void refl__greedy_path_on(const refl_scene *scene, const refl_ray_caster *caster, refl_vec3 dir,
                                 const refl_hit *hit, int max_interfaces, refl_greedy_path *path, long long *rays) {
    refl__gp_casters c;
    refl__gp_hit h;
    refl__gp_children ch;
    refl_vec3 o, d;
    refl__gp_start(path, refl_v3(0.0f, 0.0f, 0.0f), dir);
    c.scene = caster;
    c.lenses = c.others = NULL;
    c.own = -1;
    if (max_interfaces <= 0 || !refl__gp_hit_of(scene, hit, &h)) return;
    max_interfaces = REFL__MIN(max_interfaces, REFL_GREEDY_MAX_INTERFACES);
    refl__gp_interface(&h, dir, &ch);
    refl__gp_take(path, &h, &ch, !ch.refracts || ch.f >= 1.0f - ch.f, &o, &d);
    refl__gp_follow(scene, &c, path, o, d, h, max_interfaces, rays);
}

REFL_API void refl_greedy_paths(const refl_scene *scene, const refl_ray_caster *caster, refl_vec3 origin,
                                refl_vec3 dir, int max_interfaces, refl_greedy_paths_result *out,
                                long long *rays) {
    refl__gp_casters c;
    if (!out) return;
    refl__greedy_paths_none(origin, dir, out);
    if (!scene || !caster || !caster->intersect || !refl__v3_finite(origin) || !refl__v3_finite(dir)) return;
    c.scene = caster;
    c.lenses = c.others = NULL;
    c.own = -1;
    refl__greedy_paths_cast(scene, &c, origin, dir, max_interfaces, out, rays);
}
