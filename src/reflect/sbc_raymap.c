/* sbc_raymap: SBC's ray maps (paper 003 IV-A; docs/methods/sbc.md, "1. Ray
   maps"). The reflectors' G-buffer (ENVMAP's) gives every reflector pixel
   its surface point and normal; every factor x factor pixels one reflected
   ray is taken, tail on the reflector, head twice as far as what it meets
   (or where it leaves the scene's box, grown 1%), first reflector point =
   tail. Each side of a reflector object seen (the G-buffer's id, negative
   on back faces: the inside of an open mesh) has a ray map over the whole
   frame.

   Past the first order (desc.depth > 1; section III-B's higher-order rays,
   IV's reflection histories): each sample's reflected ray is traced on
   through the mirrors and glass alone (a BVH of those; a partial reflector
   ends a history), up to desc.depth reflections (at most REFL__SB_ORDERS).
   Every history sampled (A, B, AB, BA, ABA, ...; at most
   REFL__SB_HISTORIES past the first order) is a side of its own, whose ray
   at a sample has its tail on the last reflector, its head clipped as above
   and its first reflector point the sample's. Glass seen directly also
   refracts (Fig. 20b): in at the sample's point (Snell, the material's
   ior), totally reflected inside while it must, out where it can within the
   depth: a side "refracted through" of its own, tail at the exit. */
#include "sbc_internal.h"

/* The ray map sample (u, v)'s pixel. */
static void refl__sb_sample_pixel(const refl__sb *sb, int u, int v, int *x, int *y) {
    const refl_frame *fr = sb->p->frame;
    *x = REFL__MIN(u * sb->factor + sb->factor / 2, fr->width - 1);
    *y = REFL__MIN(v * sb->factor + sb->factor / 2, fr->height - 1);
}

/* The ray from q along r (tail = first = q), its head clipped as the
   module comment says (refl__sbc_scene_ray), and what it meets first in
   *met; 0 for a ray of zero length. */
static int refl__sb_ray_dir(const refl__sb *sb, refl_vec3 q, refl_vec3 r, refl_sbc_ray *ray, refl__sbc_hit *met) {
    return refl__sbc_scene_ray(sb->bvh, sb->box_lo, sb->box_hi, sb->diagonal, q, r, ray, met);
}

/* The reflected ray of surface point q with normal n (towards the
   viewer) seen along view direction d (refl__sb_ray_dir). */
static int refl__sb_ray(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, refl_sbc_ray *ray,
                        refl__sbc_hit *met) {
    n = refl_v3_normalize(n);
    /* a normal turned past grazing (extrapolated beyond a silhouette)
       reflects as the limit does: straight on, not back */
    return refl__sb_ray_dir(sb, q, refl_v3_dot(d, n) < -1e-4f ? refl_v3_reflect(d, n) : d, ray, met);
}

static float refl__sb_surface(const refl__sb *sb, const refl_hit *h, refl_vec3 *p, refl_vec3 *ng, refl_vec3 *ns);

/* Pixel i's view direction, surface point and unit normal towards the
   viewer (as the ray map and the composite take them). */
static void refl__sb_pixel_view(const refl__sb *sb, size_t i, refl_vec3 *d, refl_vec3 *q, refl_vec3 *n) {
    const refl__pass *p = sb->p;
    int x = (int)(i % (size_t)p->frame->width), y = (int)(i / (size_t)p->frame->width);
    refl_vec3 o;
    float tmax;
    const float *gb = sb->em->gbuf + 4 * i;
    refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, d, &tmax);
    *n = refl_v3_normalize(refl_v3(gb[0], gb[1], gb[2]));
    if (refl_v3_dot(*n, *n) == 0.0f) *n = refl_v3_scale(*d, -1.0f); /* degenerate: face the eye */
    if (refl_v3_dot(*n, *d) > 0.0f) *n = refl_v3_scale(*n, -1.0f);
    *q = refl_v3(sb->em->surface[3 * i], sb->em->surface[3 * i + 1], sb->em->surface[3 * i + 2]);
}

/* Where a path seen along d at the depth buffer's point q of object
   `object` leaves it: the point of the triangle the view ray meets there,
   as RAYTRACE's path leaves it. The depth buffer's point lies up to ~1e-3
   of the room off it; in a corner, past the neighbouring wall, where the
   path then misses that wall and shows the environment. q where the view
   ray meets no triangle of the object near q. */
static refl_vec3 refl__sb_path_start(const refl__sb *sb, refl_vec3 q, refl_vec3 d, int object) {
    float back = 1e-3f * sb->diagonal;
    refl_hit h;
    refl_vec3 p, ng, ns;
    if (!sb->mirrors.bvh ||
        !refl_bvh_intersect(sb->mirrors.bvh, refl_v3_sub(q, refl_v3_scale(d, back)), d, 0.0f, 2.0f * back, &h) ||
        sb->mirrors.object[h.object] != object)
        return q;
    h.object = object;
    refl__sb_surface(sb, &h, &p, &ng, &ns);
    return p;
}

/* Side sd's ray map: a ray per sample showing the side (valid 1), with
   the sample's unit normal turned towards the viewer. */
static void refl__sb_ray_map(const refl__sb *sb, refl__sb_side *sd) {
    const refl__pass *p = sb->p;
    int u, v, W = p->frame->width, mw = sb->map_w;
    for (v = 0; v < sb->map_h; ++v)
        for (u = 0; u < mw; ++u) {
            size_t m = (size_t)v * (size_t)mw + (size_t)u, i;
            int x, y;
            refl_vec3 o, d, n;
            float tmax;
            const float *gb;
            refl__sb_sample_pixel(sb, u, v, &x, &y);
            i = (size_t)y * (size_t)W + (size_t)x;
            gb = sb->em->gbuf + 4 * i;
            sd->valid[m] = 0;
            if (gb[3] != sd->id) continue;
            refl__view_rays_get(&p->rays, (float)x + 0.5f, (float)y + 0.5f, &o, &d, &tmax);
            n = refl_v3_normalize(refl_v3(gb[0], gb[1], gb[2]));
            sd->normals[m] = refl_v3_dot(n, d) > 0.0f ? refl_v3_scale(n, -1.0f) : n;
            sd->valid[m] = (uint8_t)refl__sb_ray(sb, refl_v3(sb->em->surface[3 * i], sb->em->surface[3 * i + 1],
                                                             sb->em->surface[3 * i + 2]),
                                                 sd->normals[m], d, &sd->rays[m], &sd->hits[m]);
        }
}

/* A side of a higher layer: the rays of the samples whose history it is
   (sb->samples.side), at its order's reflector (or out of its glass),
   first reflector point on the pixel's own reflector. */
static void refl__sb_ray_map_higher(const refl__sb *sb, refl__sb_side *sd, int self) {
    size_t count = (size_t)sb->map_w * (size_t)sb->map_h, m;
    const int *own = sb->samples.side + (size_t)sd->layer * count;
    for (m = 0; m < count; ++m) {
        int x, y, ok = 0;
        size_t i;
        refl_vec3 d, q, n;
        sd->valid[m] = 0;
        if (own[m] != self) continue;
        refl__sb_sample_pixel(sb, (int)(m % (size_t)sb->map_w), (int)(m / (size_t)sb->map_w), &x, &y);
        i = (size_t)y * (size_t)sb->p->frame->width + (size_t)x;
        refl__sb_pixel_view(sb, i, &d, &q, &n);
        if (sd->kind) {
            refl__sb_refr rp;
            if (refl__sb_refract_path(sb, q, n, d, sb->sides[sd->parent].id, &rp) == sd->kind) {
                ok = refl__sb_ray_dir(sb, rp.tail, rp.out, &sd->rays[m], &sd->hits[m]);
                sd->normals[m] = rp.normal;
            }
        } else {
            refl__sb_path pa;
            int k = sd->order - 1;
            refl__sb_trace_path(sb, q, n, d, sb->em->gbuf[4 * i + 3], &pa);
            if (pa.count > k) {
                ok = refl__sb_ray_dir(sb, pa.q[k], k + 1 < pa.count ? pa.d[k + 1] : pa.out, &sd->rays[m],
                                      &sd->hits[m]);
                sd->normals[m] = pa.n[k];
            }
        }
        sd->rays[m].first = q;
        sd->valid[m] = (uint8_t)ok;
    }
}

/* Side i's ray map and pieces (a job: sides map in parallel). */
static void refl__sb_map_side(void *arg, int job) {
    refl__sb *sb = (refl__sb *)arg;
    const refl_allocator *al = &sb->p->scene->allocator;
    int i = sb->map_first + job;
    refl__sb_side *sd = &sb->sides[i];
    size_t n = (size_t)sb->map_w * (size_t)sb->map_h;
    sd->normals = (refl_vec3 *)refl__calloc(al, n, sizeof(refl_vec3));
    sd->rays = (refl_sbc_ray *)refl__calloc(al, n, sizeof(refl_sbc_ray));
    sd->hits = (refl__sbc_hit *)refl__calloc(al, n, sizeof(refl__sbc_hit));
    sd->valid = (uint8_t *)refl__calloc(al, n, 1);
    sd->comp = (int *)refl__calloc(al, n, sizeof(int));
    sd->group = (int *)refl__calloc(al, n, sizeof(int));
    sd->crossing = (uint8_t *)refl__calloc(al, n, 1);
    if (sd->normals && sd->rays && sd->hits && sd->valid && sd->comp && sd->group && sd->crossing) {
        if (sd->layer) refl__sb_ray_map_higher(sb, sd, i);
        else refl__sb_ray_map(sb, sd);
        refl__sb_pieces(sb, sd);
    }
}

/* Sides [first, end)'s ray maps and pieces, a job each. */
static refl_result refl__sb_map_sides(refl__sb *sb, int first, int end) {
    double bytes = (double)end * (double)sb->map_w * (double)sb->map_h * (double)REFL__SB_SAMPLE_BYTES;
    int i;
    /* refused before the maps are allocated, with what they would take */
    if (bytes > (double)sb->memory_limit) {
        refl__frame_say(sb->p->frame, "sbc.memory_mb: %d ray maps of %dx%d samples need %.0f MiB, more than %.0f", end,
                        sb->map_w, sb->map_h, bytes / 1048576.0, (double)sb->memory_limit / 1048576.0);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    sb->map_first = first;
    rast_run_jobs(sb->p->rc, end - first, refl__sb_map_side, sb);
    for (i = first; i < end; ++i)
        if (!sb->sides[i].rays || !sb->sides[i].hits || !sb->sides[i].valid || !sb->sides[i].normals ||
            !sb->sides[i].comp || !sb->sides[i].group || !sb->sides[i].crossing)
            return REFL_ERROR_OUT_OF_MEMORY;
    return REFL_OK;
}

/* ---- higher orders: paths through the mirrors and glass alone ---- */

/* Reflectors a history goes on through: mirrors and glass. A partial
   reflector ends it (its diffuse share is drawn where it is met). */
static int refl__sb_goes_on(const refl_material *m) { return m->type == REFL_MIRROR || m->type == REFL_GLASS; }

/* What a path from o along unit d meets first among the mirrors and glass
   (h->object: the scene's index), within the scene's box. The path starts
   on object `self` (-1: none): the search skips 1e-4 of the box's
   diagonal past o, where only another object counts, searched from
   `near` (o, or where the path leaves a depth buffer's point o:
   refl__sb_path_start) on, past 1e-6 of the diagonal (its own surface
   there is the point it leaves, met again by rounding; a neighbouring
   mirror there is the other wall of a corner). */
static int refl__sb_mirror_hit(const refl__sb *sb, refl_vec3 o, refl_vec3 near, refl_vec3 d, int self, refl_hit *h) {
    float reach = refl__sbc_box_exit(sb->box_lo, sb->box_hi, o, d), skip = 1e-4f * sb->diagonal;
    float near_skip = skip + refl_v3_length(refl_v3_sub(near, o));
    if (!sb->mirrors.bvh) return 0;
    if (self >= 0 && refl_bvh_intersect(sb->mirrors.bvh, near, d, 1e-6f * sb->diagonal, REFL__MIN(near_skip, reach), h) &&
        sb->mirrors.object[h->object] != self) {
        h->object = sb->mirrors.object[h->object];
        return 1;
    }
    if (!refl_bvh_intersect(sb->mirrors.bvh, o, d, skip, reach, h)) return 0;
    h->object = sb->mirrors.object[h->object];
    return 1;
}

/* A hit's point (barycentric, as RAYTRACE reads it), geometric and
   shading normals (unit, as the mesh winds and interpolates them); the
   triangle's longest edge. */
static float refl__sb_surface(const refl__sb *sb, const refl_hit *h, refl_vec3 *p, refl_vec3 *ng, refl_vec3 *ns) {
    const refl_object *o = &sb->p->scene->objects[h->object];
    refl__hit_geom g;
    refl__hit_surface(sb->p->scene->meshes[o->mesh], &o->transform, &sb->mirrors.normal_m[h->object], h, &g);
    *p = g.p;
    *ng = g.ng;
    *ns = g.ns;
    return REFL__MAX(refl_v3_length(refl_v3_sub(g.v[1], g.v[0])),
                     REFL__MAX(refl_v3_length(refl_v3_sub(g.v[2], g.v[1])), refl_v3_length(refl_v3_sub(g.v[0], g.v[2]))));
}

/* The material of G-buffer side id `id` (object + 1, negated on the back). */
static const refl_material *refl__sb_material(const refl__sb *sb, float id) {
    const refl_scene *scene = sb->p->scene;
    return &scene->materials[scene->objects[(int)fabsf(id) - 1].material];
}

/* The history of reflector point q (side id, unit normal n towards the
   viewer) seen along d, through sb->orders reflections at most: the first
   reflects as refl__sb_ray does, later ones as RAYTRACE reflects. */
static void refl__sb_trace_path(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, float id,
                                refl__sb_path *pa) {
    const refl_scene *scene = sb->p->scene;
    int object = (int)fabsf(id) - 1, k;
    refl_vec3 r;
    n = refl_v3_normalize(n);
    r = refl_v3_dot(d, n) < -1e-4f ? refl_v3_reflect(d, n) : d;
    pa->count = 1;
    pa->id[0] = id;
    pa->q[0] = q;
    pa->n[0] = n;
    pa->d[0] = d;
    pa->weight[0] = refl_material_reflectance(&scene->materials[scene->objects[object].material],
                                              REFL__CLAMP(-refl_v3_dot(d, n), 0.0f, 1.0f));
    for (k = 1; k < sb->orders; ++k) {
        refl_hit h;
        refl_vec3 p, ng, ns, rd;
        float edge;
        int front;
        if (!refl__sb_mirror_hit(sb, pa->q[k - 1], k > 1 ? pa->q[k - 1] : refl__sb_path_start(sb, q, d, object), r,
                                 (int)fabsf(pa->id[k - 1]) - 1, &h))
            break;
        edge = refl__sb_surface(sb, &h, &p, &ng, &ns);
        front = refl_v3_dot(r, ng) < 0.0f;
        if (!front) {
            ng = refl_v3_scale(ng, -1.0f);
            ns = refl_v3_scale(ns, -1.0f);
        }
        if (refl_v3_dot(r, ns) > 0.0f) ns = ng;
        /* into its own reflector's other side, or its own facets within an
           edge: a shading normal sent it (nearly) along the surface or below
           its facet (RAYTRACE then reflects about the facet, which the
           G-buffer does not hold), not a reflection seen */
        if (h.object + 1 == (int)fabsf(pa->id[k - 1]) && (front != (pa->id[k - 1] > 0.0f) || h.t < edge)) break;
        pa->id[k] = front ? (float)(h.object + 1) : -(float)(h.object + 1);
        pa->q[k] = p;
        pa->n[k] = ns;
        pa->d[k] = r;
        /* RAYTRACE fades a bounce by its reflected ray's length (paper 003 V-D) */
        pa->weight[k] = pa->weight[k - 1] * refl_material_fade(refl__sb_material(sb, pa->id[k - 1]), h.t) *
                        refl_material_reflectance(&scene->materials[scene->objects[h.object].material],
                                                  REFL__CLAMP(-refl_v3_dot(r, ns), 0.0f, 1.0f));
        pa->count = k + 1;
        rd = refl_v3_reflect(r, ns);
        if (refl_v3_dot(rd, ng) <= 0.0f) rd = refl_v3_reflect(r, ng);
        r = rd;
    }
    pa->out = r;
}

/* The path refracted through glass (paper 003's Fig. 20b): in at q (unit
   normal n towards the viewer, seen along d), reflected totally inside
   while it must, out where it refracts, within sb->budget interfaces and
   meeting only its own glass. tail: the exit point; out: the direction
   beyond; normal: the exit's, facing out; weight: what RAYTRACE's
   refracted branch keeps past the entry's (1 - F) and tint: (1 - F) at
   the exit times the absorption inside. Its partial reflections inside
   are left out. 1: such a path; 2: it meets another object inside (the
   floor under a glass sunk into it; the whole scene's BVH tells): tail
   where the last segment starts, out along it, weight the absorption up
   to the object; 0: still inside when the budget runs out (RAYTRACE's
   black); -1: it leaves without meeting its glass again (a silhouette
   pixel whose point lies just off the glass). */
static int refl__sb_refract_path(const refl__sb *sb, refl_vec3 q, refl_vec3 n, refl_vec3 d, float id,
                                 refl__sb_refr *rp) {
    const refl_scene *scene = sb->p->scene;
    int object = (int)fabsf(id) - 1, b;
    const refl_material *m;
    float ior, len = 0.0f, f;
    refl_vec3 t, pos = q;
    if (object < 0 || object >= scene->object_count || sb->budget < 2 || !sb->mirrors.bvh) return 0;
    m = &scene->materials[scene->objects[object].material];
    if (m->type != REFL_GLASS) return 0;
    ior = m->ior > 0.0f ? m->ior : 1.5f;
    f = refl_fresnel_dielectric(REFL__CLAMP(-refl_v3_dot(d, n), 0.0f, 1.0f), 1.0f, ior);
    if (!(f < 1.0f) || !refl_v3_refract(d, n, 1.0f / ior, &t)) return 0;
    for (b = 1; b < sb->budget; ++b) {
        refl_hit h, in;
        refl_vec3 p, ng, ns, t2, rd;
        int entering;
        if (!refl__sb_mirror_hit(sb, pos, pos, t, -1, &h) || h.object != object) return -1;
        /* a surface inside the glass (SBC-paper searches no scene: none) */
        if (refl_bvh_intersect(sb->bvh, pos, t, 1e-4f * sb->diagonal, h.t, &in) && in.object != object) {
            rp->tail = pos;
            rp->out = t;
            rp->normal = b > 1 ? rp->normal : refl_v3_scale(n, -1.0f);
            rp->weight = expf(-REFL__MAX(m->attenuation, 0.0f) * (len + in.t));
            return 2;
        }
        refl__sb_surface(sb, &h, &p, &ng, &ns);
        /* as RAYTRACE: a face turned towards the ray is entered (an inner
           wall of a glass whose parts overlap), else left; the normals
           turned against the ray */
        entering = refl_v3_dot(t, ng) < 0.0f;
        if (!entering) {
            ng = refl_v3_scale(ng, -1.0f);
            ns = refl_v3_scale(ns, -1.0f);
        }
        if (refl_v3_dot(t, ns) > 0.0f) ns = ng;
        len += h.t;
        pos = p;
        f = refl_fresnel_dielectric(REFL__CLAMP(-refl_v3_dot(t, ns), 0.0f, 1.0f), entering ? 1.0f : ior,
                                    entering ? ior : 1.0f);
        if (f < 1.0f && refl_v3_refract(t, ns, entering ? 1.0f / ior : ior, &t2)) {
            rp->tail = p;
            rp->out = t2;
            rp->normal = refl_v3_scale(ns, -1.0f);
            rp->weight = (1.0f - f) * expf(-REFL__MAX(m->attenuation, 0.0f) * len);
            return 1;
        }
        /* totally reflected inside: a reflection on the way */
        rp->normal = ns;
        rd = refl_v3_reflect(t, ns);
        if (refl_v3_dot(rd, ng) <= 0.0f) rd = refl_v3_reflect(t, ng);
        t = rd;
    }
    return 0;
}

/* Sample rows [v, v + 1)'s histories: the side ids of their paths into
   sb->samples.id, and whether their glass refracts them out. */
static void refl__sb_sample_row(void *arg, int v) {
    refl__sb *sb = (refl__sb *)arg;
    size_t count = (size_t)sb->map_w * (size_t)sb->map_h;
    int u, k;
    for (u = 0; u < sb->map_w; ++u) {
        size_t m = (size_t)v * (size_t)sb->map_w + (size_t)u, i;
        int x, y;
        refl_vec3 d, q, n;
        refl__sb_path pa;
        refl__sb_refr rp;
        for (k = 0; k < sb->budget; ++k) sb->samples.id[(size_t)k * count + m] = 0.0f;
        sb->samples.refr[m] = 0;
        if (sb->samples.side[m] < 0) continue;
        refl__sb_sample_pixel(sb, u, v, &x, &y);
        i = (size_t)y * (size_t)sb->p->frame->width + (size_t)x;
        refl__sb_pixel_view(sb, i, &d, &q, &n);
        refl__sb_trace_path(sb, q, n, d, sb->em->gbuf[4 * i + 3], &pa);
        for (k = 0; k < pa.count; ++k) sb->samples.id[(size_t)k * count + m] = pa.id[k];
        k = refl__sb_refract_path(sb, q, n, d, pa.id[0], &rp);
        sb->samples.refr[m] = (uint8_t)(k > 0 ? k : 0);
    }
}

/* The side of history `parent` followed by side id `id` (kind 0) or
   refracted through parent's glass (kind 1); -1: none sampled. */
static int refl__sb_find_side(const refl__sb *sb, int parent, float id, int kind) {
    int i;
    /* a child comes after its parent and the first order's sides */
    for (i = REFL__MAX(parent + 1, sb->sides1); i < sb->side_count; ++i)
        if (sb->sides[i].parent == parent && sb->sides[i].kind == kind && (kind || sb->sides[i].id == id)) return i;
    return -1;
}

/* The scene's mirrors and glass in a BVH of their own (none: mi->bvh
   stays NULL), and every object's normal matrix. */
static refl_result refl__sb_mirrors_build(refl__sb_mirrors *mi, const refl_scene *scene) {
    const refl_allocator *al = &scene->allocator;
    refl_scene sub;
    refl_object *objs = (refl_object *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl_object));
    refl_result r = REFL_OK;
    int i, n = 0;
    mi->object = (int *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(int));
    mi->normal_m = (refl_mat4 *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(refl_mat4));
    if (!objs || !mi->object || !mi->normal_m) {
        refl__free(al, objs);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count; ++i) {
        refl_mat4 xf = scene->objects[i].transform;
        mi->normal_m[i] = refl__normal_matrix(xf);
        if (!refl__sb_goes_on(&scene->materials[scene->objects[i].material])) continue;
        mi->object[n] = i;
        objs[n++] = scene->objects[i];
    }
    sub = *scene;
    sub.objects = objs;
    sub.object_count = n;
    if (n) r = refl_bvh_build(&sub, al, &mi->bvh);
    refl__free(al, objs);
    return r;
}

static void refl__sb_mirrors_free(refl__sb_mirrors *mi, const refl_allocator *al) {
    refl_bvh_destroy(mi->bvh);
    refl__free(al, mi->object);
    refl__free(al, mi->normal_m);
    memset(mi, 0, sizeof *mi);
}

static void refl__sb_samples_free(refl__sb_samples *s, const refl_allocator *al) {
    refl__free(al, s->id);
    refl__free(al, s->refr);
    refl__free(al, s->side);
    memset(s, 0, sizeof *s);
}

/* The higher layers' sides (the paper's reflection groups AB, ABA, ...
   and refractions through glass): every sample's history traced through
   the mirrors and glass alone, one side per history sampled (at most
   REFL__SB_HISTORIES; in sample order, so the same for any thread
   count), then their ray maps and pieces, a layer at a time (a piece lies
   within its parent's). */
static refl_result refl__sb_histories(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    size_t count = (size_t)sb->map_w * (size_t)sb->map_h, m;
    refl_result r;
    int i, n, k, first, longest = 1, refr = 0, cap = sb->side_count + REFL__SB_HISTORIES;
    if ((r = refl__sb_mirrors_build(&sb->mirrors, sb->p->scene)) != REFL_OK || !sb->mirrors.bvh) return r;
    sb->samples.id = (float *)refl__calloc(al, (size_t)sb->budget * count, sizeof(float));
    sb->samples.refr = (uint8_t *)refl__calloc(al, count, 1);
    sb->samples.side = (int *)refl__calloc(al, (size_t)(sb->budget + 1) * count, sizeof(int));
    if (!sb->samples.id || !sb->samples.refr || !sb->samples.side) return REFL_ERROR_OUT_OF_MEMORY;
    /* every sample's first side, then its history */
    for (m = 0; m < (size_t)(sb->budget + 1) * count; ++m) sb->samples.side[m] = -1;
    for (i = 0; i < sb->side_count; ++i)
        for (m = 0; m < count; ++m)
            if (sb->sides[i].valid[m]) sb->samples.side[m] = i;
    sb->orders = sb->budget;
    rast_run_jobs(sb->p->rc, sb->map_h, refl__sb_sample_row, sb);
    for (k = 1; k < sb->budget; ++k)
        for (m = 0; m < count; ++m) {
            int parent = sb->samples.side[(size_t)(k - 1) * count + m], s;
            float id = sb->samples.id[(size_t)k * count + m];
            if (parent < 0 || id == 0.0f) continue;
            if ((s = refl__sb_find_side(sb, parent, id, 0)) < 0 && sb->side_count < cap) {
                refl__sb_side *sd = &sb->sides[s = sb->side_count++];
                sd->object = (int)fabsf(id) - 1;
                sd->id = id;
                sd->order = k + 1;
                sd->layer = k;
                sd->parent = parent;
            }
            sb->samples.side[(size_t)k * count + m] = s;
            if (s >= 0) longest = k + 1;
        }
    /* the refractions' layer follows the longest history's */
    sb->orders = longest;
    for (m = 0; m < count; ++m) {
        int parent = sb->samples.side[m], s;
        if (!sb->samples.refr[m] || parent < 0) continue;
        if ((s = refl__sb_find_side(sb, parent, 0.0f, sb->samples.refr[m])) < 0 && sb->side_count < cap) {
            refl__sb_side *sd = &sb->sides[s = sb->side_count++];
            sd->object = sb->sides[parent].object;
            sd->id = sb->sides[parent].id;
            sd->order = 1;
            sd->layer = longest;
            sd->parent = parent;
            sd->kind = sb->samples.refr[m];
        }
        sb->samples.side[(size_t)longest * count + m] = s;
        refr |= s >= 0;
    }
    sb->layers = longest + refr;
    for (k = 1; k < sb->layers; ++k) {
        for (first = 0; first < sb->side_count && sb->sides[first].layer != k; ++first) {}
        for (n = first; n < sb->side_count && sb->sides[n].layer == k; ++n) {}
        if ((r = refl__sb_map_sides(sb, first, n)) != REFL_OK) return r;
    }
    return REFL_OK;
}

/* ---- the sides seen ---- */

/* The sides seen (reflector objects and sides with a pixel; a front drawn
   from a morphing grid has none), their ray maps and pieces; past the
   first order, the histories' sides too. */
static refl_result refl__sb_ray_maps(refl__sb *sb) {
    const refl_scene *scene = sb->p->scene;
    const refl_allocator *al = &scene->allocator;
    const refl_frame *fr = sb->p->frame;
    size_t npx = (size_t)fr->width * (size_t)fr->height, k;
    uint8_t *sides = (uint8_t *)refl__calloc(al, (size_t)scene->object_count, 1);
    refl_result r;
    int i, side;
    if (!sides) return REFL_ERROR_OUT_OF_MEMORY;
    for (k = 0; k < npx; ++k) {
        float id = sb->em->gbuf[4 * k + 3];
        int o = (int)fabsf(id) - 1;
        if (o >= 0 && o < scene->object_count) sides[o] |= (uint8_t)(id > 0.0f ? 1 : 2);
    }
    sb->sides = (refl__sb_side *)refl__calloc(al, 2 * (size_t)scene->object_count + REFL__SB_HISTORIES,
                                              sizeof(refl__sb_side));
    if (!sb->sides) {
        refl__free(al, sides);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < scene->object_count; ++i)
        for (side = 0; side < 2; ++side)
            if ((sides[i] & (1 << side)) && !(side == 0 && refl__sb_morph_for(sb->p, i))) {
                refl__sb_side *sd = &sb->sides[sb->side_count++];
                sd->object = i;
                sd->id = side ? -(float)(i + 1) : (float)(i + 1);
                sd->order = 1;
                sd->parent = -1;
            }
    refl__free(al, sides);
    sb->sides1 = sb->side_count;
    if ((r = refl__sb_map_sides(sb, 0, sb->side_count)) != REFL_OK) return r;
    if (sb->budget > 1) {
        r = refl__sb_histories(sb);
        refl__sb_samples_free(&sb->samples, al); /* read by the histories alone */
    }
    return r;
}

static void refl__sb_ray_maps_free(refl__sb *sb) {
    const refl_allocator *al = &sb->p->scene->allocator;
    int i;
    for (i = 0; sb->sides && i < sb->side_count; ++i) {
        refl__free(al, sb->sides[i].rays);
        refl__free(al, sb->sides[i].valid);
        refl__free(al, sb->sides[i].hits);
        refl__free(al, sb->sides[i].normals);
        refl__free(al, sb->sides[i].comp);
        refl__free(al, sb->sides[i].group);
        refl__free(al, sb->sides[i].crossing);
    }
    refl__free(al, sb->sides);
    refl__sb_mirrors_free(&sb->mirrors, al);
    refl__sb_samples_free(&sb->samples, al);
}
