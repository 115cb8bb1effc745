/* SPOC: reflections of impostored diffuse objects in mirrors (paper 004,
   sections 4 and 6). Per reflector seen, every compact diffuse object gets
   an SPOC impostor (impostor.c) taken from the centre of the reflector's
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
   without shadows. Glass is handed to RAYTRACE's tracer. Rows are
   independent and step counts are summed per row, so any thread count
   gives the same bytes and stats. */
#include "internal.h"

/* What rays leaving one reflector meet: its impostors and the exact part
   of the scene. */
typedef struct refl__spoc_set {
    refl_spoc *cams;              /* per impostor */
    refl_impostor **imps;
    int *imp_object;              /* per impostor: the scene object */
    int imp_count;
    refl_bvh *exact;              /* the exactly intersected objects (NULL: none) */
    int *exact_object;            /* its object index -> scene object */
    int built;
} refl__spoc_set;

typedef struct refl__spoc_frame {
    refl__em em;
    refl__spoc_set *sets;         /* per scene object; built for reflectors */
    refl__rt_object *objects;     /* per scene object: transforms for hit surfaces */
    int object;                   /* the reflector being drawn */
    int bounces;                  /* 1, or 2: mirrors met are reflected through once more */
    float offset;                 /* reflected rays start this far off their surface */
    long long *row_steps, *row_max, *row_rays;
} refl__spoc_frame;

/* Whether object i is a mirror whose impostor stores normals: second-order
   reflections, compact mirrors only (planar ones are exact and black). */
static int refl__spoc_mirror_impostor(const refl__spoc_frame *sf, int i) {
    const refl_scene *scene = sf->em.p->scene;
    return sf->bounces > 1 && scene->materials[scene->objects[i].material].type == REFL_MIRROR &&
           !refl__object_flat(scene, i);
}

/* Whether object i gets an impostor seen from `eye`: diffuse (or a mirror
   with two bounces), not flat (its box's smallest side at least 1% of its
   largest), and the eye outside its bounding sphere. */
static int refl__spoc_impostored(const refl__spoc_frame *sf, int i, refl_vec3 eye) {
    const refl_scene *scene = sf->em.p->scene;
    refl_vec3 lo, hi, c;
    if ((refl__is_reflector(&scene->materials[scene->objects[i].material]) && !refl__spoc_mirror_impostor(sf, i)) ||
        refl__object_flat(scene, i))
        return 0;
    refl__object_world_box(scene, i, &lo, &hi);
    c = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    return refl_v3_length(refl_v3_sub(eye, c)) > 1.01f * 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
}

/* Builds reflector `object`'s impostors and exact BVH (once). */
static refl_result refl__spoc_build(refl__spoc_frame *sf, int object) {
    refl__pass *p = sf->em.p;
    refl__spoc_set *set = &sf->sets[object];
    size_t objects = (size_t)REFL__MAX(p->scene->object_count, 1);
    const refl_scene *scene = p->scene;
    const refl_allocator *al = &scene->allocator;
    const refl_spoc_options *opt = &p->desc.spoc;
    refl_vec3 lo, hi, eye;
    refl_scene sub;
    refl_object *objs;
    float baseline, strength = opt->strength < 0.0f ? 0.0f : opt->strength;
    int i, n = 0;
    refl_result r = REFL_OK;
    if (set->built) return REFL_OK;
    set->built = 1;
    set->cams = (refl_spoc *)refl__calloc(al, objects, sizeof(refl_spoc));
    set->imps = (refl_impostor **)refl__calloc(al, objects, sizeof(refl_impostor *));
    set->imp_object = (int *)refl__calloc(al, objects, sizeof(int));
    set->exact_object = (int *)refl__calloc(al, objects, sizeof(int));
    if (!set->cams || !set->imps || !set->imp_object || !set->exact_object) return REFL_ERROR_OUT_OF_MEMORY;
    refl__object_world_box(scene, object, &lo, &hi);
    eye = refl_v3_scale(refl_v3_add(lo, hi), 0.5f);
    baseline = 0.5f * refl_v3_length(refl_v3_sub(hi, lo));
    objs = (refl_object *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl_object));
    if (!objs) return REFL_ERROR_OUT_OF_MEMORY;
    for (i = 0; r == REFL_OK && i < scene->object_count; ++i) {
        if (i != object && refl__spoc_impostored(sf, i, eye)) {
            refl_vec3 olo, ohi;
            refl_impostor_camera ic;
            refl_impostor_desc d;
            refl_spoc *cam = &set->cams[set->imp_count];
            refl__object_world_box(scene, i, &olo, &ohi);
            r = refl_spoc_init(cam, eye, refl_v3_scale(refl_v3_add(olo, ohi), 0.5f),
                               0.5f * refl_v3_length(refl_v3_sub(ohi, olo)), baseline, strength, opt->size);
            if (r != REFL_OK) break;
            ic = refl_spoc_impostor_camera(cam);
            memset(&d, 0, sizeof d);
            d.max_edge_px = opt->max_edge_px;
            d.normals = refl__spoc_mirror_impostor(sf, i);
            d.layers = opt->layers;
            d.allocator = *al;
            r = refl__impostor_build(p->rc, scene, &i, 1, &ic, &d, &set->imps[set->imp_count]);
            if (r != REFL_OK) break;
            p->frame->stats.triangles += set->imps[set->imp_count]->triangles;
            p->frame->stats.model_bytes +=
                (long long)((size_t)opt->size * (size_t)opt->size * (size_t)opt->layers * (d.normals ? 8 : 5) * sizeof(float));
            ++p->frame->stats.spoc.impostors;
            set->imp_object[set->imp_count++] = i;
        } else {
            set->exact_object[n] = i;
            objs[n++] = scene->objects[i];
        }
    }
    if (r == REFL_OK && n) {
        sub = *scene;
        sub.objects = objs;
        sub.object_count = n;
        r = refl_bvh_build(&sub, al, &set->exact);
        if (r == REFL_OK) p->frame->stats.model_bytes += refl__bvh_bytes(set->exact);
    }
    refl__free(al, objs);
    return r;
}

static void refl__spoc_release(refl__spoc_frame *sf, int object) {
    const refl_allocator *al = &sf->em.p->scene->allocator;
    refl__spoc_set *set = &sf->sets[object];
    int i;
    for (i = 0; i < set->imp_count; ++i) refl_impostor_destroy(set->imps[i]);
    refl_bvh_destroy(set->exact);
    refl__free(al, set->cams);
    refl__free(al, set->imps);
    refl__free(al, set->imp_object);
    refl__free(al, set->exact_object);
    memset(set, 0, sizeof *set);
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
    const refl__spoc_set *set = &sf->sets[from];
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

/* One frame row: every pixel of the current reflector. */
static void refl__spoc_row(void *arg, int y) {
    refl__spoc_frame *sf = (refl__spoc_frame *)arg;
    const refl__pass *p = sf->em.p;
    const refl_frame *fr = p->frame;
    float id = (float)(sf->object + 1);
    long long steps = 0, max_steps = 0, rays = 0;
    int x;
    for (x = 0; x < fr->width; ++x) {
        size_t i = (size_t)y * (size_t)fr->width + (size_t)x;
        const float *g = sf->em.gbuf + 4 * i;
        float rgb[3], tmax;
        refl_vec3 o, d, n, s, shown = refl_v3(NAN, NAN, NAN);
        if (fabsf(g[3]) != id) continue;
        refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
        n = refl_v3_normalize(refl_v3(g[0], g[1], g[2]));
        if (refl_v3_dot(n, n) == 0.0f) n = refl_v3_scale(d, -1.0f);
        if (refl_v3_dot(d, n) > 0.0f) n = refl_v3_scale(n, -1.0f);
        s = refl_v3(sf->em.surface[3 * i], sf->em.surface[3 * i + 1], sf->em.surface[3 * i + 2]);
        s = refl_v3_add(s, refl_v3_scale(n, sf->offset));
        ++rays;
        if (refl__spoc_trace(sf, sf->object, 1, s, refl_v3_reflect(d, n), 0.0f, rgb, &shown, &steps, &max_steps))
            refl__em_composite(p, g, x, y, rgb, shown);
        else
            refl__em_composite(p, g, x, y, NULL, shown);
    }
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
    return NULL;
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
        sf.sets = (refl__spoc_set *)refl__calloc(al, objects, sizeof(refl__spoc_set));
        sf.objects = (refl__rt_object *)refl__calloc(al, objects, sizeof(refl__rt_object));
        sf.row_steps = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        sf.row_max = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        sf.row_rays = (long long *)refl__calloc(al, (size_t)fr->height, sizeof(long long));
        if (!sf.em.surface || !sf.sets || !sf.objects || !sf.row_steps ||
            !sf.row_max || !sf.row_rays)
            r = REFL_ERROR_OUT_OF_MEMORY;
    }
    if (r == REFL_OK && any) {
        for (i = 0; i < scene->object_count; ++i) {
            const refl_object *o = &scene->objects[i];
            sf.objects[i].mesh = scene->meshes[o->mesh];
            sf.objects[i].material = &scene->materials[o->material];
            sf.objects[i].model = o->transform;
            sf.objects[i].normal_m = refl__normal_matrix(o->transform);
        }
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
        t0 = refl__now_ms();
        fr->stats.ms_build += t0 - t1;
        if (r == REFL_OK) {
            sf.object = i;
            rast_run_jobs(p->rc, fr->height, refl__spoc_row, &sf);
        }
        if (sf.bounces == 1) refl__spoc_release(&sf, i);
        t1 = refl__now_ms();
        fr->stats.ms_reflect += t1 - t0;
    }
    if (r == REFL_OK && any)
        for (y = 0; y < fr->height; ++y) {
            fr->stats.spoc.steps += sf.row_steps[y];
            fr->stats.rays += sf.row_rays[y];
            if (sf.row_max[y] > fr->stats.spoc.max_steps) fr->stats.spoc.max_steps = sf.row_max[y];
        }
    /* leave the frame bound, as the method found it (the impostors bound their own buffers) */
    if (r == REFL_OK) {
        rast_targets t = refl__frame_targets(fr);
        r = refl__result_from_rast(rast_set_targets(p->rc, &t));
    }
    for (i = 0; sf.sets && i < scene->object_count; ++i) refl__spoc_release(&sf, i);
    refl__free(al, sf.sets);
    refl__free(al, sf.em.gbuf);
    refl__free(al, sf.em.draws);
    refl__free(al, sf.em.surface);
    refl__free(al, seen);
    refl__free(al, sf.objects);
    refl__free(al, sf.row_steps);
    refl__free(al, sf.row_max);
    refl__free(al, sf.row_rays);
    return r;
}
