/* Light volumes and caustics (paper 002): light a planar mirror reflects
   onto diffuse surfaces (refl_render_desc.lighting.light_volumes).

   THE VIRTUAL LIGHTS
       A light on one side of a mirror face's plane (planar_faces.c),
       mirrored in that plane, is a virtual light behind the mirror. It
       lights a point P on the light's side exactly when the segment from
       P to it crosses the face (the face's light volume: the frustum from
       the virtual light through the face) and, with shadows, nothing
       blocks the path P -> M (M where the segment meets the face) nor
       M -> light. Its Lambert term at P is towards the virtual light,
       weighed by the face's reflectance at the incidence of that path
       (refl_material_reflectance: mirror_weight, Fresnel) and by the
       fraction of the light's samples whose paths arrive: caustic_samples
       jittered lights (refl_light_sample, each mirrored), summed as paper
       002 sums its accumulated images. Shading adds the virtual lights
       after the scene's own (refl_shade_diffuse_weighted), so RAYTRACE,
       which traces the same paths, and PLANAR compare pixel for pixel.
       Only mirror and partial faces reflect light here: the light glass
       bends (refracted caustics) is left out, as no exact virtual light
       exists for it. A face does not light its own object.

   PLANAR: THE PAPER'S TWO PASSES
       Per virtual light sample, two stencil shadow-volume masks
       (shadow.c) from the virtual light: the face alone as the occluder
       (a pixel "in its shadow" is inside the light volume: the face's
       light stencil), and, with shadows, the blockers: the objects not
       wholly behind the face's plane (they block P -> M) and the mirror
       images of those wholly in front of it (they block light -> M,
       mirrored). The paper's dot-product check decides sides per
       object's bounds; an object crossing the plane (other than the
       mirror) does not shadow the light on its way in. The face's own
       object blocks neither way. A pixel counts the samples whose volume
       holds it and whose blockers miss it; the region's diffuse objects
       are then shaded again where any virtual light arrives. */
#include "internal.h"

/* A light mirrored in the plane n . x = d. */
static refl_light refl__lv_mirror(const refl_light *l, const double n[3], double d) {
    refl_mat4 r = refl__planar_reflection(n, d);
    refl_light m = *l;
    m.position = refl_mat4_point(r, l->position);
    m.direction = refl_mat4_dir(r, l->direction);
    return m;
}

/* Which side of the face's plane the light is on (0: on it, or unusable). */
static double refl__lv_side(const refl__planar_face *f, const refl_light *l) {
    double s;
    if (l->type == REFL_LIGHT_DIRECTIONAL)
        s = -(f->n[0] * l->direction.x + f->n[1] * l->direction.y + f->n[2] * l->direction.z);
    else
        s = f->n[0] * l->position.x + f->n[1] * l->position.y + f->n[2] * l->position.z - f->d;
    return s > 0.0 ? 1.0 : s < 0.0 ? -1.0 : 0.0;
}

/* The virtual lights of every light (the first REFL__SHADOW_MAX_LIGHTS,
   which shadows can mask) in every mirror or partial face, as many as fit
   beside the scene's lights; lv->shade sums them after the scene's. */
static void refl__lv_init(refl__lv *lv, const refl_scene *s, const refl__planar_face *faces, int face_count,
                          int samples) {
    int i, f;
    memset(lv, 0, sizeof *lv);
    lv->faces = faces;
    lv->samples = REFL__MAX(samples, 1);
    if (s->light_count >= REFL__LV_MAX_LIGHTS) return;
    for (i = 0; i < s->light_count; ++i) lv->lights[i] = s->lights[i];
    for (i = 0; i < REFL__MIN(s->light_count, REFL__SHADOW_MAX_LIGHTS); ++i)
        for (f = 0; f < face_count && s->light_count + lv->count < REFL__LV_MAX_LIGHTS; ++f) {
            double side = refl__lv_side(&faces[f], &s->lights[i]);
            if (faces[f].glass || side == 0.0) continue;
            lv->v[lv->count].source = i;
            lv->v[lv->count].face = f;
            lv->v[lv->count].side = side;
            lv->lights[s->light_count + lv->count] = refl__lv_mirror(&s->lights[i], faces[f].n, faces[f].d);
            ++lv->count;
        }
    lv->shade = *s;
    lv->shade.lights = lv->lights;
    lv->shade.light_count = s->light_count + lv->count;
}

/* Samples of virtual light k: 1 for lights without a radius. */
static int refl__lv_samples(const refl__lv *lv, const refl_scene *s, int k) {
    return s->lights[lv->v[k].source].radius > 0.0f ? lv->samples : 1;
}

/* Sample j of virtual light k's source (*src) and its mirror image (*virt);
   0 when the sample is not on the light's side of the face. */
static int refl__lv_sample(const refl__lv *lv, const refl_scene *s, int k, int j, refl_light *src, refl_light *virt) {
    const refl__planar_face *f = &lv->faces[lv->v[k].face];
    *src = refl_light_sample(&s->lights[lv->v[k].source], j, refl__lv_samples(lv, s, k));
    *virt = refl__lv_mirror(src, f->n, f->d);
    return refl__lv_side(f, src) == lv->v[k].side;
}

/* The reflectance weighing virtual light k at point p of object `object`:
   the face's at the incidence of the path from the virtual light's centre;
   0 when p is not on the light's side or on the face's own object. */
static float refl__lv_reflectance(const refl__lv *lv, const refl_scene *s, int k, int object, refl_vec3 p) {
    const refl__planar_face *f = &lv->faces[lv->v[k].face];
    const refl_light *vl = &lv->lights[s->light_count + k];
    refl_vec3 d, n = refl_v3((float)f->n[0], (float)f->n[1], (float)f->n[2]);
    if (object == f->object || lv->v[k].side * (f->n[0] * p.x + f->n[1] * p.y + f->n[2] * p.z - f->d) <= 0.0)
        return 0.0f;
    d = vl->type == REFL_LIGHT_DIRECTIONAL ? vl->direction : refl_v3_sub(p, vl->position);
    return refl_material_reflectance(&s->materials[s->objects[f->object].material],
                                     fabsf(refl_v3_dot(refl_v3_normalize(d), n)));
}

/* Where the segment from p towards the virtual light virt (to infinity
   for a directional one) meets face k's plane, *m, when that point lies
   on the face's triangles (barycentrics within a hair, so a shared edge
   lets light through); 0 otherwise. RAYTRACE's light volume test. */
static int refl__lv_through_face(const refl__lv *lv, const refl_scene *s, int k, const refl_light *virt, refl_vec3 p,
                                 refl_vec3 *m) {
    const refl__planar_face *f = &lv->faces[lv->v[k].face];
    const refl_object *o = &s->objects[f->object];
    const refl_mesh *mesh = s->meshes[o->mesh];
    double to[3], pn, dn, t, q[3];
    int i, c;
    if (virt->type == REFL_LIGHT_DIRECTIONAL) {
        to[0] = -virt->direction.x; to[1] = -virt->direction.y; to[2] = -virt->direction.z;
    } else {
        to[0] = (double)virt->position.x - p.x; to[1] = (double)virt->position.y - p.y;
        to[2] = (double)virt->position.z - p.z;
    }
    pn = f->n[0] * p.x + f->n[1] * p.y + f->n[2] * p.z - f->d;
    dn = f->n[0] * to[0] + f->n[1] * to[1] + f->n[2] * to[2];
    if (dn == 0.0) return 0;
    t = -pn / dn;
    if (!(t > 0.0) || (virt->type != REFL_LIGHT_DIRECTIONAL && !(t < 1.0))) return 0;
    q[0] = p.x + t * to[0]; q[1] = p.y + t * to[1]; q[2] = p.z + t * to[2];
    for (i = 0; i + 2 < f->index_count; i += 3) {
        double v[3][3], e[3], area = 0.0, b[3];
        int inside = 1;
        for (c = 0; c < 3; ++c) {
            const float *pp = mesh->positions + 3 * (size_t)f->indices[i + c];
            refl_vec3 w = refl_mat4_point(o->transform, refl_v3(pp[0], pp[1], pp[2]));
            v[c][0] = w.x; v[c][1] = w.y; v[c][2] = w.z;
        }
        /* signed areas along the face's normal of q with each edge */
        for (c = 0; c < 3; ++c) {
            const double *a = v[(c + 1) % 3], *bb = v[(c + 2) % 3];
            double x[3], y[3];
            int j;
            for (j = 0; j < 3; ++j) { x[j] = a[j] - q[j]; y[j] = bb[j] - q[j]; }
            e[0] = x[1] * y[2] - x[2] * y[1]; e[1] = x[2] * y[0] - x[0] * y[2]; e[2] = x[0] * y[1] - x[1] * y[0];
            b[c] = e[0] * f->n[0] + e[1] * f->n[1] + e[2] * f->n[2];
            area += b[c];
        }
        if (area == 0.0) continue;
        for (c = 0; c < 3; ++c) inside &= b[c] / area >= -1e-9;
        if (inside) {
            *m = refl_v3((float)q[0], (float)q[1], (float)q[2]);
            return 1;
        }
    }
    return 0;
}

/* ---- PLANAR: masks and shading ------------------------------------------------------ */

typedef struct refl__lv_shade {
    refl__draw_ctx dc;            /* first: the base pass's vertex program reads it */
    int object;
    const refl__lv *lv;
    const refl_scene *scene;
    const uint8_t *lit;           /* hard shadows: the scene lights' bits; NULL: see counts */
    const uint16_t *counts;       /* soft shadows: per light the samples that arrive; both NULL: all lit */
    const int *samples;           /* per scene light (soft) */
    const uint16_t *vcounts;      /* per virtual light, the samples that arrive */
    int width, height;
} refl__lv_shade;

/* The shared model with the scene's lights as shadows left them and the
   virtual lights that reach the pixel; keeps the pixel when none does. */
static int refl__lv_fragment(void *user, const rast_fragment_in *in, float rgba[4]) {
    const refl__lv_shade *d = (const refl__lv_shade *)user;
    const refl__lv *lv = d->lv;
    const refl_scene *s = d->scene;
    const float *v = in->varyings;
    refl_vec3 p = refl_v3(v[0], v[1], v[2]);
    float weight[REFL__LV_MAX_LIGHTS], rgb[3];
    size_t i, npx = (size_t)d->width * (size_t)d->height;
    int k, any = 0;
    if (in->x < 0 || in->y < 0 || in->x >= d->width || in->y >= d->height) return 0;
    i = (size_t)in->y * (size_t)d->width + (size_t)in->x;
    for (k = 0; k < s->light_count; ++k) {
        weight[k] = 1.0f;
        if (k >= REFL__SHADOW_MAX_LIGHTS) continue;
        if (d->counts) {
            int c = d->counts[(size_t)k * npx + i];
            if (c < d->samples[k]) weight[k] = (float)c / (float)d->samples[k];
        } else if (d->lit && !((d->lit[i] >> k) & 1)) {
            weight[k] = 0.0f;
        }
    }
    for (k = 0; k < lv->count; ++k) {
        int c = d->vcounts[(size_t)k * npx + i], ns = refl__lv_samples(lv, s, k);
        float r = c ? refl__lv_reflectance(lv, s, k, d->object, p) : 0.0f;
        weight[s->light_count + k] = c < ns ? r * (float)c / (float)ns : r;
        any |= weight[s->light_count + k] > 0.0f;
    }
    if (!any) return 0; /* what the scene's own lights gave it */
    refl_shade_diffuse_weighted(&lv->shade, d->dc.material, p, refl_v3(v[3], v[4], v[5]), v + 6, weight, rgb);
    refl__surface_rgba(d->dc.material, rgb, rgba);
    return 1;
}

/* Counts into plane, for the job's pixels, the samples of virtual light k
   that reach them: per sample, the face's light volume from the virtual
   light and (shadows) its blockers, as masks from shadow.c into scratch
   (two planes of the job's size). */
static refl_result refl__lv_count(const refl__shadow_job *job, const refl__lv *lv, int k, int shadows,
                                  uint8_t *scratch, uint16_t *plane) {
    const refl_scene *scene = job->scene;
    const uint8_t *region = job->region;
    const uint8_t region_value = job->region_value;
    const refl_allocator *al = &scene->allocator;
    const refl__planar_face *f = &lv->faces[lv->v[k].face];
    refl_mat4 mirror = refl__planar_reflection(f->n, f->d);
    refl_mesh face_mesh;
    refl_mesh **meshes;
    refl_object *objs, face_obj;
    refl_scene sc;
    refl__shadow_job virtual_job = *job;
    refl_light src, virt;
    refl_result r = REFL_OK;
    size_t i, npx = (size_t)job->width * (size_t)job->height;
    uint8_t *in_volume = scratch, *unblocked = scratch + npx;
    int ob, nb = 0, j, ns = refl__lv_samples(lv, scene, k);
    meshes = (refl_mesh **)refl__alloc(al, (size_t)(scene->mesh_count + 1) * sizeof(*meshes));
    objs = (refl_object *)refl__alloc(al, 2 * (size_t)REFL__MAX(scene->object_count, 1) * sizeof(*objs));
    if (!meshes || !objs) {
        refl__free(al, meshes);
        refl__free(al, objs);
        return REFL_ERROR_OUT_OF_MEMORY;
    }
    /* the face alone, as a mesh of its triangles */
    for (ob = 0; ob < scene->mesh_count; ++ob) meshes[ob] = scene->meshes[ob];
    face_obj = scene->objects[f->object];
    face_mesh = *scene->meshes[face_obj.mesh];
    face_mesh.indices = f->indices;
    face_mesh.triangle_count = f->index_count / 3;
    meshes[scene->mesh_count] = &face_mesh;
    face_obj.mesh = scene->mesh_count;
    /* the blockers: the objects not wholly behind the plane, and the mirror
       images of those wholly in front of it */
    for (ob = 0; ob < scene->object_count && shadows; ++ob) {
        refl_vec3 lo, hi;
        double dmin = DBL_MAX, dmax = -DBL_MAX;
        int c;
        if (ob == f->object) continue;
        refl_mesh_bounds(scene->meshes[scene->objects[ob].mesh], &lo, &hi);
        for (c = 0; c < 8; ++c) {
            refl_vec3 q = refl_mat4_point(scene->objects[ob].transform,
                                          refl_v3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z));
            double s = lv->v[k].side * (f->n[0] * q.x + f->n[1] * q.y + f->n[2] * q.z - f->d);
            dmin = REFL__MIN(dmin, s);
            dmax = REFL__MAX(dmax, s);
        }
        if (dmax > 0.0) objs[nb++] = scene->objects[ob];
        if (dmin > 0.0) {
            objs[nb] = scene->objects[ob];
            objs[nb++].transform = refl_mat4_mul(mirror, scene->objects[ob].transform);
        }
    }
    for (i = 0; i < npx; ++i)
        if (!region || region[i] == region_value) plane[i] = 0;
    sc = *scene;
    sc.meshes = meshes;
    sc.mesh_count = scene->mesh_count + 1;
    sc.lights = &virt;
    sc.light_count = 1;
    virtual_job.scene = &sc;
    for (j = 0; j < ns && r == REFL_OK; ++j) {
        if (!refl__lv_sample(lv, scene, k, j, &src, &virt)) continue;
        sc.objects = &face_obj;
        sc.object_count = 1;
        r = refl__shadow_mask(&virtual_job, in_volume);
        if (r == REFL_OK && shadows && nb > 0) {
            sc.objects = objs;
            sc.object_count = nb;
            r = refl__shadow_mask(&virtual_job, unblocked);
        }
        if (r != REFL_OK) break;
        for (i = 0; i < npx; ++i)
            if ((!region || region[i] == region_value) && job->depth[i] < 1.0f && !(in_volume[i] & 1) &&
                (!shadows || nb == 0 || (unblocked[i] & 1)))
                ++plane[i];
    }
    refl__free(al, meshes);
    refl__free(al, objs);
    return r;
}

static refl_result refl__lv_pass(const refl__shadow_job *job, const refl__lv *lv, const refl_render_desc *desc,
                                 int skip) {
    rast_context *rc = job->rc;
    const refl_scene *scene = job->scene;
    const refl_allocator *al = &scene->allocator;
    size_t npx = (size_t)job->width * (size_t)job->height;
    uint8_t *lit = NULL, *scratch = NULL;
    uint16_t *counts = NULL, *vcounts = NULL;
    refl__lv_shade *dc = NULL;
    int soft = refl__soft_shadows(desc, scene), ns[REFL__SHADOW_MAX_LIGHTS], i, k, queued = 0;
    rast_result rr = RAST_OK;
    refl_result r = REFL_OK;
    if (lv->count == 0) return REFL_OK;
    lit = (uint8_t *)refl__alloc(al, npx);
    scratch = (uint8_t *)refl__alloc(al, 2 * npx);
    vcounts = (uint16_t *)refl__calloc(al, npx * (size_t)lv->count, sizeof(uint16_t));
    if (soft) counts = (uint16_t *)refl__calloc(al, npx * REFL__SHADOW_MAX_LIGHTS, sizeof(uint16_t));
    dc = (refl__lv_shade *)refl__calloc(al, (size_t)REFL__MAX(scene->object_count, 1), sizeof(*dc));
    if (!lit || !scratch || !vcounts || (soft && !counts) || !dc) { r = REFL_ERROR_OUT_OF_MEMORY; goto done; }
    /* the scene's own lights, as the shadow pass saw them */
    for (i = 0; i < REFL__SHADOW_MAX_LIGHTS; ++i)
        ns[i] = i < scene->light_count && scene->lights[i].radius > 0.0f ? REFL__MAX(desc->lighting.soft_shadow_samples, 1) : 1;
    if (soft)
        r = refl__shadow_mask_soft(job, desc->lighting.soft_shadow_samples, counts, lit);
    else if (desc->lighting.shadows)
        r = refl__shadow_mask(job, lit);
    for (k = 0; k < lv->count && r == REFL_OK; ++k)
        r = refl__lv_count(job, lv, k, desc->lighting.shadows, scratch, vcounts + (size_t)k * npx);
    if (r != REFL_OK) goto done;
    for (i = 0; i < scene->object_count && rr == RAST_OK; ++i) {
        const refl_material *mat = &scene->materials[scene->objects[i].material];
        rast_state s;
        if (i == skip || (mat->type != REFL_DIFFUSE && mat->type != REFL_PARTIAL)) continue;
        refl__draw_ctx_init(&dc[i].dc, scene, i, job->vp);
        dc[i].object = i;
        dc[i].lv = lv;
        dc[i].scene = scene;
        dc[i].lit = desc->lighting.shadows && !soft ? lit : NULL;
        dc[i].counts = soft ? counts : NULL;
        dc[i].samples = ns;
        dc[i].vcounts = vcounts;
        dc[i].width = job->width;
        dc[i].height = job->height;
        memset(&s, 0, sizeof s);
        s.depth_test = 1;
        s.depth_func = RAST_EQUAL;
        s.depth_write_disabled = 1;
        if (job->region) { /* the bound stencil is the region */
            s.stencil_test = 1;
            s.stencil_front.func = RAST_EQUAL;
            s.stencil_front.ref = job->region_value;
            s.stencil_back = s.stencil_front;
        }
        s.vertex_fn = refl__base_vertex;
        s.vertex_user = &dc[i].dc;
        s.fragment_fn = refl__lv_fragment;
        s.fragment_user = &dc[i];
        queued = 1;
        if ((rr = rast_set_state(rc, &s)) == RAST_OK) rr = refl__draw_mesh(rc, dc[i].dc.mesh, NULL, 0, REFL__BASE_VARYINGS);
        if (job->st) job->st->triangles += dc[i].dc.mesh->triangle_count;
    }
    /* nothing queued may outlive the arrays it reads */
    if (queued) {
        rast_result rf = rast_finish(rc);
        if (rr == RAST_OK) rr = rf;
    }
    r = refl__result_from_rast(rr);
done:
    refl__free(al, lit);
    refl__free(al, scratch);
    refl__free(al, vcounts);
    refl__free(al, counts);
    refl__free(al, dc);
    return r;
}
