/* SPOC: reflections of impostored diffuse objects in mirrors (paper 004,
   sections 4 and 6). Per reflector seen (its set: refl_spoc_set_build,
   public for the GL path), every compact diffuse object gets an SPOC
   impostor (impostor.c) taken from the centre of the reflector's
   world bounding box, looking at the centre of the object's, of radius its
   half diagonal; the baseline is the reflector's half diagonal (the
   region its reflected rays start from), so the push is the parallax of a
   viewpoint moved across the reflector. Each reflector pixel's reflected
   ray (G-buffer normal, the surface point from the base pass's depth)
   meets the nearest of:
   - the impostors, marched (refl_impostor_intersect);
   - the rest of the scene, intersected exactly: flat objects (the floor,
     the paper's billboard impostor, which it calls exact), objects whose
     bounding sphere holds the reflector's centre (no SPOC can see them
     from there), and the reflectors themselves, which show as DIRECT
     draws them (one bounce: a mirror is black, a partial reflector its
     diffuse share);
   and what meets nothing shows the environment. With two bounces (depth
   2) every compact mirror other than the reflector is an impostor that
   stores normals instead (the paper's second-order reflections): a ray
   that meets one is reflected about the stored normal at its hit, one
   that meets an exact mirror (the reflector itself, a planar mirror)
   about its surface normal, and meets that mirror's own impostors and
   exact part, weighted by the mirror's reflectance; a mirror met on the
   last bounce is black. Colours are composited
   as ENVMAP's (gbuffer.c), each clamped to [0, 1] first as RAYTRACE
   does; frame->points gets the point the ray met (an impostor's: its own
   estimate on the ray). Impostor colours are the shared diffuse shading
   without shadows; each impostor has spoc.layers depth layers. Glass is
   handed to RAYTRACE's tracer, or with spoc.glass refracted in and out
   here (refl__spoc_glass). A mirror's ray whose march missed an
   impostored object the scene puts in front (as rays near the pole can),
   and so meets nothing or what lies behind it, is RAYTRACE's tracer's
   (stats.spoc.traced, refl__spoc_missed): only a ray that escapes the
   scene shows the environment. Rows are
   independent and step counts are summed per row, so any thread count
   gives the same bytes and stats. */
#include "internal.h"

typedef struct refl__spoc_frame {
    refl__em em;
    refl_spoc_set *sets;          /* per scene object; built for reflectors (cams set) */
    refl__rt_object *objects;     /* per scene object: transforms for hit surfaces */
    int object;                   /* the reflector being drawn */
    int bounces;                  /* 1, or 2: mirrors met are reflected through once more */
    float offset;                 /* reflected rays start this far off their surface */
    long long *row_steps, *row_max, *row_rays;
    /* the glass reflector being drawn (refl__spoc_glass_begin) */
    float *back;                  /* per pixel: the nearest back face's world normal and distance
                                     along the pixel's ray (0: none) */
    float *back_depth;            /* the back-face pass's depth buffer */
    refl_bvh *self;               /* the glass object alone, for the exact exit */
    const refl_bvh *scene_bvh;    /* the whole scene: does a ray SPOC met nothing with escape? */
    refl_bvh *scene_owned;
    uint8_t *handed;              /* per pixel: REFL__TRACE_ALL where RAYTRACE's tracer draws it */
    long long *row_traced;
} refl__spoc_frame;

/* Whether object i gets an impostor seen from `eye`: diffuse (or, with
   mirror_impostors, a mirror), not flat (its box's smallest side at least
   1% of its largest), and the eye outside its bounding sphere. */
static int refl__spoc_impostored(const refl_scene *scene, int i, refl_vec3 eye, int mirror_impostors) {
    int type = scene->materials[scene->objects[i].material].type;
    refl_vec3 lo, hi, c;
    if ((type != REFL_DIFFUSE && !(mirror_impostors && type == REFL_MIRROR)) || refl_object_is_flat(scene, i)) return 0;
    refl_object_world_bounds(scene, i, &lo, &hi);
    c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    return refl_v3_length(refl_v3_sub(eye, c)) > 1.01f * 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
}

/* Builds reflector `object`'s set into *set (zeroed, its allocator set)
   with rc's threads; d's fields in range, its defaults filled. */
static refl_result refl__spoc_set_build(rast_context *rc, const refl_scene *scene, int object,
                                        const refl_spoc_set_desc *d, refl_spoc_set *set) {
    size_t objects = (size_t)REFL__MAX(scene->object_count, 1);
    const refl_allocator *al = &set->allocator;
    refl_vec3 lo, hi, eye;
    refl_scene sub;
    refl_object *objs;
    float baseline, strength = d->strength < 0.0f ? 0.0f : d->strength;
    int i, n = 0;
    refl_result r = REFL_OK;
    set->cams = (refl_spoc *)refl__calloc(al, objects, sizeof(refl_spoc));
    set->imps = (refl_impostor **)refl__calloc(al, objects, sizeof(refl_impostor *));
    set->imp_object = (int *)refl__calloc(al, objects, sizeof(int));
    set->exact_object = (int *)refl__calloc(al, objects, sizeof(int));
    if (!set->cams || !set->imps || !set->imp_object || !set->exact_object) return REFL_ERROR_OUT_OF_MEMORY;
    refl_object_world_bounds(scene, object, &lo, &hi);
    eye = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    baseline = 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
    objs = (refl_object *)refl__calloc(al, objects, sizeof(refl_object));
    if (!objs) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; r == REFL_OK && i < scene->object_count; ++i) {
        int type = scene->materials[scene->objects[i].material].type;
        if (i != object && refl__spoc_impostored(scene, i, eye, d->mirror_impostors)) {
            refl_vec3 olo, ohi;
            refl_impostor_camera ic;
            refl_impostor_desc id;
            refl_spoc *cam = &set->cams[set->imp_count];
            refl_object_world_bounds(scene, i, &olo, &ohi);
            r = refl_spoc_init(cam, eye, refl_v3_scale(refl_v3_add(olo, ohi), 0.5f),
                               0.5f * refl_v3_length(refl_v3_sub(ohi, olo)), baseline, strength, d->size);
            if (r != REFL_OK) break;
            ic = refl_spoc_impostor_camera(cam);
            memset(&id, 0, sizeof id);
            id.max_edge_px = d->max_edge_px;
            id.normals = type == REFL_MIRROR;
            id.layers = d->layers;
            id.allocator = *al;
            r = refl__impostor_build(rc, scene, &i, 1, &ic, &id, &set->imps[set->imp_count]);
            if (r != REFL_OK) break;
            set->imp_object[set->imp_count++] = i;
        } else if (i != object || type != REFL_GLASS) {
            /* a glass reflector's rays leave it for good (refl__spoc_glass) */
            set->exact_object[n] = i;
            objs[n++] = scene->objects[i];
        }
    }
    set->exact_count = n;
    if (r == REFL_OK && n) {
        sub = *scene;
        sub.objects = objs;
        sub.object_count = n;
        r = refl_bvh_build(&sub, al, &set->exact);
    }
    refl__free(al, objs);
    return r;
}

static void refl__spoc_set_release(refl_spoc_set *set) {
    refl_allocator al = set->allocator;
    int i;
    for (i = 0; i < set->imp_count; ++i) refl_impostor_destroy(set->imps[i]);
    refl_bvh_destroy(set->exact);
    refl__free(&al, set->cams);
    refl__free(&al, set->imps);
    refl__free(&al, set->imp_object);
    refl__free(&al, set->exact_object);
    memset(set, 0, sizeof *set);
    set->allocator = al;
}

REFL_API refl_result refl_spoc_set_build(const refl_scene *scene, int reflector, const refl_spoc_set_desc *desc,
                                         refl_spoc_set **out) {
    refl_spoc_set_desc d;
    refl_spoc_set *set;
    rast_context *rc = NULL;
    const refl_allocator *al;
    refl_result r;
    if (!out) return REFL_ERROR_INVALID_ARGUMENT;
    *out = NULL;
    if (!scene || reflector < 0 || reflector >= scene->object_count) return REFL_ERROR_INVALID_ARGUMENT;
    if (desc) d = *desc;
    else memset(&d, 0, sizeof d);
    if (d.size == 0) d.size = 512;
    if (d.strength == 0.0f) d.strength = 1.0f;
    if (d.layers == 0) d.layers = 3;
    if (d.max_edge_px == 0.0f) d.max_edge_px = 4.0f;
    if (d.size < 8 || d.size > 4096 || !refl__isfinite(d.strength) || d.strength > 64.0f || d.layers < 1 ||
        d.layers > REFL_IMPOSTOR_MAX_LAYERS || !(d.max_edge_px >= 0.5f && d.max_edge_px <= 64.0f) || d.threads < 0)
        return REFL_ERROR_INVALID_ARGUMENT;
    al = d.allocator.alloc || d.allocator.free ? &d.allocator : &scene->allocator;
    if (!(set = (refl_spoc_set *)refl__calloc(al, 1, sizeof *set))) return REFL_ERROR_OUT_OF_MEMORY;
    set->allocator = *al;
    r = refl__context_create(scene, d.threads, &rc);
    if (r == REFL_OK) r = refl__spoc_set_build(rc, scene, reflector, &d, set);
    if (rc) rast_context_destroy(rc);
    if (r != REFL_OK) {
        refl_spoc_set_destroy(set);
        return r;
    }
    *out = set;
    return REFL_OK;
}

REFL_API void refl_spoc_set_destroy(refl_spoc_set *set) {
    refl_allocator al;
    if (!set) return;
    refl__spoc_set_release(set);
    al = set->allocator;
    refl__free(&al, set);
}

/* Builds reflector `object`'s set (once) with the frame's options, its
   impostors and memory counted in the frame's stats. */
static refl_result refl__spoc_build(refl__spoc_frame *sf, int object) {
    refl__pass *p = sf->em.p;
    refl_spoc_set *set = &sf->sets[object];
    const refl_spoc_options *opt = &p->desc.spoc;
    refl_spoc_set_desc d;
    refl_result r;
    int k;
    if (set->cams) return REFL_OK; /* built */
    memset(&d, 0, sizeof d);
    d.size = opt->size;
    d.strength = opt->strength;
    d.layers = opt->layers;
    d.max_edge_px = opt->max_edge_px;
    d.mirror_impostors = sf->bounces > 1;
    set->allocator = p->scene->allocator;
    r = refl__spoc_set_build(p->rc, p->scene, object, &d, set);
    for (k = 0; k < set->imp_count; ++k) {
        p->frame->stats.triangles += set->imps[k]->triangles;
        p->frame->stats.model_bytes += (long long)((size_t)opt->size * (size_t)opt->size * (size_t)opt->layers *
                                                   (set->imps[k]->normal ? 8 : 5) * sizeof(float));
        ++p->frame->stats.spoc.impostors;
    }
    if (set->exact) p->frame->stats.model_bytes += refl__bvh_bytes(set->exact);
    return r;
}

/* What the ray o + t d leaving reflector `from` meets first: its colour
   (clamped to [0, 1]) and point; 0 for nothing. A mirror met (an impostor:
   its stored normal; an exact one, the reflector itself included: its
   surface's) shows what the ray reflected there meets, leaving that mirror
   (bounce `bounce` of sf->bounces), times its reflectance; on the last
   bounce it is black. */
static int refl__spoc_trace(const refl__spoc_frame *sf, int from, int bounce, refl_vec3 o, refl_vec3 d, float exact_tmin,
                            float rgb[3], refl_vec3 *shown, long long *steps, long long *max_steps) {
    const refl__pass *p = sf->em.p;
    const refl_spoc_set *set = &sf->sets[from];
    float best = FLT_MAX;
    int i, c, found = 0, mirror = -1;
    float footprint = 0.0f;       /* the mirror impostor met: 2 texels, in world units */
    refl_vec3 normal = refl_v3(0.0f, 0.0f, 0.0f);
    refl_hit h;
    for (i = 0; i < set->imp_count; ++i) {
        refl_impostor_hit ih;
        int n = 0;
        if (refl_impostor_intersect(set->imps[i], o, d, 0.0f, best, p->desc.spoc.step_scale, &ih, &n) && ih.t < best) {
            best = ih.t;
            for (c = 0; c < 3; ++c) rgb[c] = REFL__CLAMP(ih.color[c], 0.0f, 1.0f);
            *shown = ih.point;
            mirror = set->imps[i]->normal ? set->imp_object[i] : -1;
            normal = ih.normal;
            footprint = 4.0f * set->cams[i].radius / (float)set->cams[i].size;
            found = 1;
        }
        *steps += n;
        if (n > *max_steps) *max_steps = n;
    }
    if (set->exact && refl_bvh_intersect(set->exact, o, d, exact_tmin, best, &h)) {
        int object = set->exact_object[h.object];
        refl__exact_hit_shade(p->scene, &sf->objects[object], &h, rgb, shown, &normal);
        mirror = sf->objects[object].material->type == REFL_MIRROR ? object : -1;
        footprint = 0.0f;
        found = 1;
    }
    if (mirror >= 0) {
        const refl_material *m = sf->objects[mirror].material;
        float sub[3] = {0.0f, 0.0f, 0.0f}, w = 0.0f;
        refl_vec3 n = refl_v3_normalize(normal), at = *shown, met;
        if (bounce < sf->bounces && refl_v3_dot(n, n) > 0.0f) {
            refl_vec3 r;
            if (refl_v3_dot(d, n) > 0.0f) n = refl_v3_scale(n, -1.0f);
            w = refl_material_reflectance(m, REFL__CLAMP(-refl_v3_dot(refl_v3_normalize(d), n), 0.0f, 1.0f));
            r = refl_v3_reflect(d, n);
            /* an impostor's hit is its estimate, off the mirror's own surface by
               up to its footprint: the exact mirror is not met again that near */
            if (refl__spoc_trace(sf, mirror, bounce + 1, refl_v3_add(at, refl_v3_scale(n, sf->offset)), r, footprint, sub,
                                 &met, steps, max_steps)) {
                w *= refl_material_fade(m, refl_v3_length(refl_v3_sub(met, at)));
            } else {
                refl_environment_lookup(&p->scene->environment, r, sub);
                for (c = 0; c < 3; ++c) sub[c] = REFL__RADIANCE(sub[c]);
            }
        }
        for (c = 0; c < 3; ++c) rgb[c] = REFL__CLAMP(w * sub[c], 0.0f, 1.0f);
    }
    return found;
}

/* ---- glass (spoc.glass ESTIMATE or EXACT_EXIT) ----------------------------------
   Paper 004 refracts through glass with Wyman's image-space approximation
   [Wym05]: a first pass stores the depth and normals of the refractor's
   back faces, the second refracts each front pixel's ray in, estimates
   where it leaves from them, refracts it out there and intersects the
   emerging ray with the impostors. */

/* The back-face pass's fragment: the object's faces turned away from the
   eye (by the interpolated normal, whatever the winding), as the world
   normal and the distance along the pixel's ray. */
typedef struct refl__spoc_back_draw {
    refl__draw_ctx dc;
    const refl__view_rays *rays;
} refl__spoc_back_draw;

static int refl__spoc_back_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__spoc_back_draw *b = (const refl__spoc_back_draw *)user;
    refl_vec3 o, d, wp = refl_v3(in->varyings[0], in->varyings[1], in->varyings[2]);
    refl_vec3 n = refl_v3_normalize(refl_v3(in->varyings[3], in->varyings[4], in->varyings[5]));
    float tmax;
    refl__view_rays_get(b->rays, (float)in->x + 0.5f, (float)in->y + 0.5f, &o, &d, &tmax);
    if (!(refl_v3_dot(n, d) > 0.0f)) return 0;
    rgba[0] = n.x;
    rgba[1] = n.y;
    rgba[2] = n.z;
    rgba[3] = REFL__MAX(refl_v3_dot(refl_v3_sub(wp, o), d), 1e-6f);
    return 1;
}

/* Before glass reflector `object`'s rows: the object alone in a BVH (the
   exact exit; the estimate's d_N), and for the estimate its back faces
   (the first pass). */
static refl_result refl__spoc_glass_begin(refl__spoc_frame *sf, int object) {
    refl__pass *p = sf->em.p;
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_frame *fr = p->frame;
    size_t npx = (size_t)fr->width * (size_t)fr->height;
    refl_result r = REFL_OK;
    refl_scene sub = *scene;
    sub.objects = &scene->objects[object];
    sub.object_count = 1;
    r = refl_bvh_build(&sub, al, &sf->self);
    if (r == REFL_OK) fr->stats.model_bytes += refl__bvh_bytes(sf->self);
    if (r == REFL_OK && p->desc.spoc.glass == REFL_SPOC_GLASS_ESTIMATE) {
        refl__spoc_back_draw b;
        rast_targets t;
        rast_state st;
        rast_clear_desc cl;
        rast_result rr;
        if (!sf->back) sf->back = (float *)refl__calloc(al, npx, 4 * sizeof(float));
        if (!sf->back_depth) sf->back_depth = (float *)refl__calloc(al, npx, sizeof(float));
        if (!sf->back || !sf->back_depth) return REFL_ERROR_OUT_OF_MEMORY;
        refl__draw_ctx_init(&b.dc, scene, object, p->vp);
        b.rays = &p->rays;
        t = refl__float_targets(sf->back, sf->back_depth, NULL, fr->width, fr->height);
        memset(&st, 0, sizeof st);
        memset(&cl, 0, sizeof cl);
        cl.flags = RAST_CLEAR_COLOR | RAST_CLEAR_DEPTH;
        cl.depth = 1.0f;
        if ((rr = rast_set_targets(p->rc, &t)) == RAST_OK && (rr = rast_set_state(p->rc, &st)) == RAST_OK &&
            (rr = rast_clear(p->rc, &cl)) == RAST_OK) {
            st.depth_test = 1;
            st.depth_func = RAST_LESS;
            st.vertex_fn = refl__base_vertex;
            st.fragment_fn = refl__spoc_back_fragment;
            st.vertex_user = st.fragment_user = &b;
            if ((rr = rast_set_state(p->rc, &st)) == RAST_OK &&
                (rr = refl__draw_mesh(p->rc, b.dc.mesh, NULL, 0, REFL__BASE_VARYINGS)) == RAST_OK)
                rr = rast_finish(p->rc);
        }
        memset(&t, 0, sizeof t);
        rast_set_targets(p->rc, &t);
        r = refl__result_from_rast(rr);
        fr->stats.model_bytes += (long long)(npx * 5 * sizeof(float));
    }
    return r;
}

static void refl__spoc_glass_end(refl__spoc_frame *sf) {
    refl_bvh_destroy(sf->self);
    sf->self = NULL;
}

/* The pixel (u, v) the view sees point q at; 0 behind the eye. */
static int refl__spoc_pixel_of(const refl__view_rays *r, refl_vec3 q, float *u, float *v) {
    refl_vec3 e = refl_v3_sub(q, r->eye);
    float z = refl_v3_dot(e, r->forward);
    if (!(z > 0.0f)) return 0;
    *u = 0.5f * (1.0f + refl_v3_dot(e, r->right) / (z * refl_v3_dot(r->right, r->right))) * (float)r->width;
    *v = 0.5f * (1.0f - refl_v3_dot(e, r->up) / (z * refl_v3_dot(r->up, r->up))) * (float)r->height;
    return 1;
}

/* The back face stored at pixel (u, v): a point on it and its normal; 0
   where none is. */
static int refl__spoc_back_at(const refl__spoc_frame *sf, float u, float v, refl_vec3 *point, refl_vec3 *normal) {
    const refl__view_rays *r = &sf->em.p->rays;
    const float *b;
    refl_vec3 o, d;
    float fu = floorf(u), fv = floorf(v), tmax;
    if (!(fu >= 0.0f && fv >= 0.0f && fu < (float)r->width && fv < (float)r->height)) return 0;
    b = sf->back + 4 * ((size_t)fv * (size_t)r->width + (size_t)fu);
    if (!(b[3] > 0.0f)) return 0;
    refl__view_rays_get(r, fu + 0.5f, fv + 0.5f, &o, &d, &tmax);
    *point = refl_v3_add(o, refl_v3_scale(d, b[3]));
    *normal = refl_v3(b[0], b[1], b[2]);
    return 1;
}

enum { REFL__SPOC_EXIT_STEPS = 2 };

/* Where the ray p1 + t dir (dir unit, refracted in at pixel (x, y) whose
   view direction d meets the surface at normal n) leaves the glass,
   estimated from the back faces: first Wyman's distance
   d~ = (theta_t / theta_i) d_V + (1 - theta_t / theta_i) d_N,
   d_V the distance from p1 to the back face along the pixel's ray, d_N
   the distance through the object along -n (Wyman precomputes it per
   vertex and interpolates it; here it is cast per pixel), theta_i and
   theta_t the angles of incidence and refraction; then
   REFL__SPOC_EXIT_STEPS times the ray met with the tangent plane of the
   back face stored where the estimate projects (Wyman's point alone lies
   off the stored back faces, and the normal read there is another
   point's). The normal is the back face's where the point projects (else
   at the pixel's own back face). *exit and its outward normal; 0 where
   the pixel sees no back face. */
static int refl__spoc_exit_estimate(const refl__spoc_frame *sf, int x, int y, refl_vec3 p1, refl_vec3 n,
                                    refl_vec3 d, refl_vec3 dir, float ior, refl_vec3 *exit, refl_vec3 *normal) {
    refl_vec3 b, bn;
    refl_hit h;
    float u, v, d_v, d_n, ti, tt, ratio, dist;
    int k;
    if (!refl__spoc_back_at(sf, (float)x + 0.5f, (float)y + 0.5f, &b, normal)) return 0;
    d_v = REFL__MAX(refl_v3_dot(refl_v3_sub(b, p1), d), 0.0f);
    d_n = refl_bvh_intersect(sf->self, refl_v3_sub(p1, refl_v3_scale(n, sf->offset)), refl_v3_scale(n, -1.0f), 0.0f,
                             FLT_MAX, &h) ? h.t : d_v;
    ti = acosf(REFL__CLAMP(-refl_v3_dot(d, n), -1.0f, 1.0f));
    tt = acosf(REFL__CLAMP(-refl_v3_dot(dir, n), -1.0f, 1.0f));
    ratio = ti > 1e-4f ? REFL__CLAMP(tt / ti, 0.0f, 1.0f) : 1.0f / ior;
    dist = ratio * d_v + (1.0f - ratio) * d_n;
    for (k = 0; k < REFL__SPOC_EXIT_STEPS; ++k) {
        float den, t;
        if (!refl__spoc_pixel_of(&sf->em.p->rays, refl_v3_add(p1, refl_v3_scale(dir, dist)), &u, &v) ||
            !refl__spoc_back_at(sf, u, v, &b, &bn))
            break;
        den = refl_v3_dot(dir, bn);
        t = den > 1e-3f ? refl_v3_dot(refl_v3_sub(b, p1), bn) / den : -1.0f;
        if (!(t > 0.0f)) break;
        dist = t;
    }
    *exit = refl_v3_add(p1, refl_v3_scale(dir, dist));
    if (refl__spoc_pixel_of(&sf->em.p->rays, *exit, &u, &v) && refl__spoc_back_at(sf, u, v, &b, &bn)) *normal = bn;
    *normal = refl_v3_normalize(*normal);
    return 1;
}

/* The same, exactly: the glass object's own surface met (its shading
   normal, the geometric one where that faces the ray, as RAYTRACE). */
static int refl__spoc_exit_exact(const refl__spoc_frame *sf, int object, refl_vec3 p1, refl_vec3 dir,
                                 refl_vec3 *exit, refl_vec3 *normal) {
    const refl__rt_object *ro = &sf->objects[object];
    refl_hit h;
    refl__hit_geom g;
    if (!refl_bvh_intersect(sf->self, p1, dir, 0.0f, FLT_MAX, &h)) return 0;
    refl__hit_surface(ro->mesh, &ro->model, &ro->normal_m, &h, &g);
    if (refl_v3_dot(g.ng, dir) < 0.0f) g.ng = refl_v3_scale(g.ng, -1.0f);
    if (refl_v3_dot(g.ns, g.ng) < 0.0f) g.ns = refl_v3_scale(g.ns, -1.0f);
    *exit = g.p;
    *normal = refl_v3_dot(dir, g.ns) > 0.0f ? refl_v3_normalize(g.ns) : g.ng;
    return 1;
}

/* What the ray o + t d meets leaving glass `object` (bounce `bounce`),
   else the environment: its colour and point (NaN: none). With `self`,
   the glass object met again first is black (RAYTRACE's, with no bounce
   left to go through it); without, the ray ignores it. */
static void refl__spoc_glass_ray(const refl__spoc_frame *sf, int object, int bounce, refl_vec3 o, refl_vec3 d, int self,
                                 float rgb[3], refl_vec3 *shown, long long *steps, long long *max_steps) {
    refl_hit h;
    int c, met;
    *shown = refl_v3(NAN, NAN, NAN);
    met = refl__spoc_trace(sf, object, bounce, o, d, 0.0f, rgb, shown, steps, max_steps);
    if (self && refl_bvh_intersect(sf->self, o, d, 0.0f, met ? refl_v3_dot(refl_v3_sub(*shown, o), d) : FLT_MAX, &h)) {
        rgb[0] = rgb[1] = rgb[2] = 0.0f;
        *shown = refl_v3_add(o, refl_v3_scale(d, h.t));
    } else if (!met) {
        refl_environment_lookup(&sf->em.p->scene->environment, d, rgb);
        for (c = 0; c < 3; ++c) rgb[c] = REFL__CLAMP(REFL__RADIANCE(rgb[c]), 0.0f, 1.0f);
        *shown = refl_v3(NAN, NAN, NAN);
    }
}

/* Glass pixel (x, y) as RAYTRACE's two interfaces show it: the Fresnel
   share F of the reflection, and 1 - F, tinted and absorbed along the
   inside, of the ray refracted in at the pixel's surface point p1 (normal
   n facing the eye, view direction d) and out where it leaves
   (estimated or exact), times the exit's own 1 - F (internally reflected
   light is black: two bounces). One bounce: the refracted share is black.
   The point is that of the branch with the larger coefficient at each
   interface, as RAYTRACE's. */
static void refl__spoc_glass(const refl__spoc_frame *sf, int x, int y, refl_vec3 p1, refl_vec3 n, refl_vec3 d,
                             float rgb[3], refl_vec3 *shown, long long *steps, long long *max_steps) {
    const refl__pass *p = sf->em.p;
    const refl_material *m = sf->objects[sf->object].material;
    float ior = m->ior > 0.0f ? m->ior : 1.5f, sub[3], f = 1.0f, cos_i = REFL__CLAMP(-refl_v3_dot(d, n), 0.0f, 1.0f);
    refl_vec3 t1, t2, exit, out_n, met;
    int c, tinted = m->tint[0] + m->tint[1] + m->tint[2] > 0.0f;
    int refracts = refl_v3_refract(d, n, 1.0f / ior, &t1);
    if (refracts) f = refl_fresnel_dielectric(cos_i, 1.0f, ior);
    if (!(f < 1.0f)) refracts = 0, f = 1.0f;
    refl__spoc_glass_ray(sf, sf->object, 1, refl_v3_add(p1, refl_v3_scale(n, sf->offset)), refl_v3_reflect(d, n), 1,
                         sub, &met, steps, max_steps);
    for (c = 0; c < 3; ++c) rgb[c] = f * sub[c];
    *shown = refracts && f < 0.5f ? refl_v3(NAN, NAN, NAN) : met;
    if (!refracts || sf->bounces < 2) return;
    t1 = refl_v3_normalize(t1);
    {
        refl_vec3 inside = refl_v3_sub(p1, refl_v3_scale(n, sf->offset));
        int found = p->desc.spoc.glass == REFL_SPOC_GLASS_EXACT_EXIT
                        ? refl__spoc_exit_exact(sf, sf->object, inside, t1, &exit, &out_n)
                        : refl__spoc_exit_estimate(sf, x, y, p1, n, d, t1, ior, &exit, &out_n);
        float k = 1.0f - f, f2 = 0.0f, cos2;
        if (!found) {
            /* leaves through no face (an open mesh): the environment, unabsorbed */
            refl_environment_lookup(&p->scene->environment, t1, sub);
            for (c = 0; c < 3; ++c) rgb[c] += k * (tinted ? m->tint[c] : 1.0f) * REFL__RADIANCE(sub[c]);
            return;
        }
        if (m->attenuation > 0.0f) k *= expf(-m->attenuation * refl_v3_length(refl_v3_sub(exit, p1)));
        /* out: from inside, about the normal turned against the ray */
        cos2 = REFL__CLAMP(refl_v3_dot(t1, out_n), 0.0f, 1.0f);
        if (!refl_v3_refract(t1, refl_v3_scale(out_n, -1.0f), ior, &t2) ||
            !((f2 = refl_fresnel_dielectric(cos2, ior, 1.0f)) < 1.0f)) {
            /* totally reflected inside: black with two bounces */
            if (f < 0.5f) *shown = refl_v3(NAN, NAN, NAN);
            return;
        }
        /* the estimated exit may lie inside the surface: the glass is not met again */
        refl__spoc_glass_ray(sf, sf->object, 2, refl_v3_add(exit, refl_v3_scale(out_n, sf->offset)),
                             refl_v3_normalize(t2), p->desc.spoc.glass == REFL_SPOC_GLASS_EXACT_EXIT, sub, &met, steps,
                             max_steps);
        k *= 1.0f - f2;
        for (c = 0; c < 3; ++c) rgb[c] += k * (tinted ? m->tint[c] : 1.0f) * sub[c];
        if (f < 0.5f) *shown = f2 < 0.5f ? met : refl_v3(NAN, NAN, NAN);
    }
}

/* Whether the ray o + t d leaving the current reflector, which SPOC
   answered with `shown` (NaN: nothing), missed an impostored object the
   scene puts in front: the ray meets the scene where SPOC met nothing, or
   meets an impostored object more than two of its texels nearer than
   what SPOC shows. */
static int refl__spoc_missed(const refl__spoc_frame *sf, refl_vec3 o, refl_vec3 d, refl_vec3 shown) {
    const refl_spoc_set *set = &sf->sets[sf->object];
    refl_hit h;
    int i;
    if (!refl_bvh_intersect(sf->scene_bvh, o, d, 0.0f, 1e30f, &h)) return 0;
    if (!refl__isfinite(shown.x)) return 1;
    for (i = 0; i < set->imp_count; ++i)
        if (set->imp_object[i] == h.object)
            return h.t * refl_v3_length(d) < refl_v3_length(refl_v3_sub(shown, o)) -
                                                  4.0f * set->cams[i].radius / (float)set->cams[i].size;
    return 0;
}

/* One frame row: every pixel of the current reflector. */
static void refl__spoc_row(void *arg, int y) {
    refl__spoc_frame *sf = (refl__spoc_frame *)arg;
    const refl__pass *p = sf->em.p;
    const refl_frame *fr = p->frame;
    float id = (float)(sf->object + 1);
    long long steps = 0, max_steps = 0, rays = 0, traced = 0;
    int x, k, met;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
        const float *g = sf->em.gbuf + 4 * i;
        float rgb[3], tmax;
        refl_vec3 o, d, n, s, r, shown = refl_v3(NAN, NAN, NAN);
        if (fabsf(g[3]) != id) continue;
        refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
        n = refl_v3_normalize(refl_v3(g[0], g[1], g[2]));
        if (refl_v3_dot(n, n) == 0.0f) n = refl_v3_scale(d, -1.0f);
        if (refl_v3_dot(d, n) > 0.0f) n = refl_v3_scale(n, -1.0f);
        s = refl_v3(sf->em.surface[3 * i], sf->em.surface[3 * i + 1], sf->em.surface[3 * i + 2]);
        ++rays;
        if (sf->objects[sf->object].material->type == REFL_GLASS) {
            refl__spoc_glass(sf, x, y, s, n, d, rgb, &shown, &steps, &max_steps);
            for (k = 0; k < 3; ++k) rgb[k] = REFL__RADIANCE(rgb[k]);
            refl__em_put(p->frame, i, rgb, shown);
            continue;
        }
        s = refl_v3_add(s, refl_v3_scale(n, sf->offset));
        r = refl_v3_reflect(d, n);
        met = refl__spoc_trace(sf, sf->object, 1, s, r, 0.0f, rgb, &shown, &steps, &max_steps);
        if (refl__spoc_missed(sf, s, r, met ? shown : refl_v3(NAN, NAN, NAN))) {
            (p->trace ? p->trace : sf->handed)[i] = REFL__TRACE_ALL;
            traced++;
        } else {
            refl__em_composite(p, g, x, y, met ? rgb : NULL, shown);
        }
    }
    sf->row_traced[y] += traced;
    sf->row_steps[y] += steps;
    sf->row_rays[y] += rays;
    if (max_steps > sf->row_max[y]) sf->row_max[y] = max_steps;
}

static const char *refl__options_spoc(refl_render_desc *d) {
    refl_spoc_options *o = &d->spoc;
    if (o->size < 0 || o->size > 4096) return "spoc.size: 0 (512) or 8 to 4096";
    if (o->size == 0) o->size = 512;
    if (o->size < 8) return "spoc.size: 0 (512) or 8 to 4096";
    if (!refl__isfinite(o->strength) || o->strength > 64.0f) return "spoc.strength: finite, at most 64";
    if (o->strength == 0.0f) o->strength = 1.0f;
    if (!refl__isfinite(o->step_scale) || o->step_scale < 0.0f || o->step_scale > 16.0f)
        return "spoc.step_scale: 0 (1) to 16";
    if (o->step_scale == 0.0f) o->step_scale = 1.0f;
    if (!refl__isfinite(o->max_edge_px) || o->max_edge_px < 0.0f || (o->max_edge_px > 0.0f && o->max_edge_px < 0.5f) ||
        o->max_edge_px > 64.0f)
        return "spoc.max_edge_px: 0 (4) or 0.5 to 64";
    if (o->max_edge_px == 0.0f) o->max_edge_px = 4.0f;
    if (o->layers < 0 || o->layers > REFL_IMPOSTOR_MAX_LAYERS) return "spoc.layers: 0 (3) or 1 to 4";
    if (o->layers == 0) o->layers = 3;
    if (o->glass < REFL_SPOC_GLASS_TRACED || o->glass > REFL_SPOC_GLASS_EXACT_EXIT)
        return "spoc.glass: REFL_SPOC_GLASS_TRACED, _ESTIMATE or _EXACT_EXIT";
    return NULL;
}

/* Glass is SPOC's with spoc.glass ESTIMATE or EXACT_EXIT, else RAYTRACE's. */
static refl_result refl__spoc_handles(const refl__pass *p, int object, int *can) {
    *can = p->scene->materials[p->scene->objects[object].material].type != REFL_GLASS ||
           p->desc.spoc.glass != REFL_SPOC_GLASS_TRACED;
    return REFL_OK;
}

static refl_result refl__method_spoc(refl__pass *p) {
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    refl_frame *fr = p->frame;
    refl__spoc_frame sf;
    unsigned char *seen = NULL;
    size_t objects = (size_t)REFL__MAX(scene->object_count, 1);
    double t0 = refl__now_ms(), t1;
    refl_vec3 lo, hi;
    refl_result r;
    int i, y, any = 0;
    memset(&sf, 0, sizeof sf);
    sf.em.p = p;
    r = refl__em_gbuffer_new(&sf.em, &seen, &any);
    if (r == REFL_OK && any) {
        size_t npx = (size_t)fr->width * (size_t)fr->height;
        sf.em.surface = (float *)refl__calloc(al, npx, 3 * sizeof(float));
        sf.sets = (refl_spoc_set *)refl__calloc(al, objects, sizeof(refl_spoc_set));
        sf.objects = refl__rt_objects_new(scene);
        sf.row_steps = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        sf.row_max = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        sf.row_rays = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        sf.row_traced = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        sf.handed = (uint8_t *)refl__calloc(al, npx, 1);
        if (!sf.em.surface || !sf.sets || !sf.objects || !sf.row_steps ||
            !sf.row_max || !sf.row_rays || !sf.row_traced || !sf.handed)
            r = REFL_ERROR_OUT_OF_MEMORY;
    }
    if (r == REFL_OK && any) {
        refl_bvh *bvh = NULL;
        r = refl__models_bvh(p, &bvh, &sf.scene_owned);
        sf.scene_bvh = bvh;
    }
    if (r == REFL_OK && any) {
        refl_scene_bounds(scene, &lo, &hi);
        sf.offset = 1e-4f * refl_v3_length(refl_v3_sub(hi, lo));
        sf.bounces = REFL__MIN(p->desc.depth, 2);
        rast_run_jobs(p->rc, fr->height, refl__em_surface_row, &sf.em);
    }
    t1 = refl__now_ms();
    fr->stats.ms_reflect += t1 - t0;
    /* with two bounces, rays leave every mirror: their sets are kept for
       the whole frame */
    for (i = 0; r == REFL_OK && any && sf.bounces > 1 && i < scene->object_count; ++i)
        if (scene->materials[scene->objects[i].material].type == REFL_MIRROR) r = refl__spoc_build(&sf, i);
    for (i = 0; r == REFL_OK && any && i < scene->object_count; ++i) {
        if (!seen[i] || !refl__pass_draws(p, i)) continue;
        r = refl__spoc_build(&sf, i);
        if (r == REFL_OK && scene->materials[scene->objects[i].material].type == REFL_GLASS)
            r = refl__spoc_glass_begin(&sf, i);
        t0 = refl__now_ms();
        fr->stats.ms_build += t0 - t1;
        if (r == REFL_OK) {
            sf.object = i;
            rast_run_jobs(p->rc, fr->height, refl__spoc_row, &sf);
        }
        refl__spoc_glass_end(&sf);
        if (sf.bounces == 1) refl__spoc_set_release(&sf.sets[i]);
        t1 = refl__now_ms();
        fr->stats.ms_reflect += t1 - t0;
    }
    if (r == REFL_OK && any)
        for (y = 0; y < fr->height; ++y) {
            fr->stats.spoc.steps += sf.row_steps[y];
            fr->stats.rays += sf.row_rays[y];
            fr->stats.spoc.traced += sf.row_traced[y];
            if (sf.row_max[y] > fr->stats.spoc.max_steps) fr->stats.spoc.max_steps = sf.row_max[y];
        }
    /* past one bounce, refl__trace_beyond traces what was marked in p->trace */
    if (r == REFL_OK && any && !p->trace && fr->stats.spoc.traced) r = refl__trace_marked(p, sf.handed);
    /* leave the frame bound, as the method found it (the impostors bound their own buffers) */
    if (r == REFL_OK) {
        rast_targets t = refl__frame_targets(fr);
        r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    }
    for (i = 0; sf.sets && i < scene->object_count; ++i) refl__spoc_set_release(&sf.sets[i]);
    refl__free(al, sf.sets);
    refl__free(al, sf.em.gbuf);
    refl__free(al, sf.em.draws);
    refl__free(al, sf.em.surface);
    refl__free(al, seen);
    refl__free(al, sf.objects);
    refl__free(al, sf.row_steps);
    refl__free(al, sf.row_max);
    refl__free(al, sf.row_rays);
    refl__free(al, sf.row_traced);
    refl__free(al, sf.handed);
    refl_bvh_destroy(sf.scene_owned);
    refl__free(al, sf.back);
    refl__free(al, sf.back_depth);
    return r;
}
