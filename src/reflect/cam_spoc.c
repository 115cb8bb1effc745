/* cam_spoc: the single-pole occlusion camera (SPOC) of paper 004, section 4.
   The paper defers the model to [MPS05]; the one here is explicit (api.h,
   refl_spoc): a planar pinhole whose image point is pushed radially away
   from the pole by the parallax delta(z) a viewpoint moved sideways by the
   baseline sees between depth z and the bounding sphere's near depth zn,
   faded in linearly over `ramp` pixels around the pole. For a fixed depth
   the radial map r -> r' is
       r' = r (1 + D / ramp)   r <  ramp
       r' = r + D              r >= ramp          (D = max(delta, 0))
   strictly increasing and continuous, so unprojection inverts it piece by
   piece. Everything is computed in double from the stored floats so that
   project and unproject are each other's inverse to float precision. */
#include "internal.h"

/* The pinhole part: p in the camera frame (x right, y up, z forward). */
static void refl__spoc_camera_frame(const refl_spoc *cam, refl_vec3 p, double q[3]) {
    double d[3] = {(double)p.x - cam->eye.x, (double)p.y - cam->eye.y, (double)p.z - cam->eye.z};
    q[0] = d[0] * cam->right.x + d[1] * cam->right.y + d[2] * cam->right.z;
    q[1] = d[0] * cam->up.x + d[1] * cam->up.y + d[2] * cam->up.z;
    q[2] = d[0] * cam->forward.x + d[1] * cam->forward.y + d[2] * cam->forward.z;
}

/* gd of a depth z > 0 (affine in 1/z). */
static double refl__spoc_gd(const refl_spoc *cam, double z) {
    double in = 1.0 / cam->znear, inf = 1.0 / cam->zfar;
    return (in - 1.0 / z) / (in - inf);
}

/* The push at gd, in pixels, before the ramp. */
static double refl__spoc_push(const refl_spoc *cam, double gd) {
    return gd > 0.0 ? (double)cam->delta_max * gd : 0.0;
}

REFL_API refl_result refl_spoc_init(refl_spoc *cam, refl_vec3 eye, refl_vec3 center, float radius,
                                    float baseline, float strength, int size) {
    refl_vec3 fwd, up, right, world_up;
    double dist, cone, parallax, zn, zf;
    if (!cam) return REFL_ERROR_INVALID_ARGUMENT;
    if (!isfinite(eye.x) || !isfinite(eye.y) || !isfinite(eye.z) || !isfinite(center.x) ||
        !isfinite(center.y) || !isfinite(center.z) || !isfinite(radius) || !isfinite(baseline) ||
        !isfinite(strength) || !(radius > 0.0f) || baseline < 0.0f || strength < 0.0f)
        return REFL_ERROR_INVALID_ARGUMENT;
    if (size < 8 || size > 16384) return REFL_ERROR_INVALID_SIZE;
    dist = refl_v3_length(refl_v3_sub(center, eye));
    if (!(dist > 1.001 * radius)) return REFL_ERROR_INVALID_ARGUMENT;
    memset(cam, 0, sizeof *cam);
    cam->eye = eye;
    cam->center = center;
    cam->radius = radius;
    cam->baseline = baseline;
    cam->strength = strength;
    cam->size = size;
    fwd = refl_v3_normalize(refl_v3_sub(center, eye));
    world_up = fabsf(fwd.y) < 0.9f ? refl_v3(0, 1, 0) : refl_v3(1, 0, 0);
    right = refl_v3_normalize(refl_v3_cross(fwd, world_up));
    up = refl_v3_cross(right, fwd);
    cam->forward = fwd;
    cam->right = right;
    cam->up = up;
    zn = dist - radius;
    zf = dist + radius;
    cam->znear = (float)zn;
    cam->zfar = (float)zf;
    /* per unit focal length: the sphere's tangent cone radius on the image
       plane, and the push at zf; both scale with f */
    cone = radius / sqrt(dist * dist - (double)radius * radius);
    parallax = (double)strength * baseline * (1.0 / cam->znear - 1.0 / cam->zfar);
    cam->focal = (float)((0.5 * size - 1.0) / (cone + parallax));
    cam->delta_max = (float)((double)cam->focal * parallax);
    cam->ramp = (float)(0.25 * cam->focal * cone);
    cam->pole[0] = cam->pole[1] = 0.5f * (float)size;
    return REFL_OK;
}

REFL_API int refl_spoc_project(const refl_spoc *cam, refl_vec3 p, float out[3]) {
    double q[3], rx, ry, r, gd, push, scale;
    if (!cam || !out) return 0;
    refl__spoc_camera_frame(cam, p, q);
    if (!(q[2] > 0.0)) return 0;
    rx = cam->focal * q[0] / q[2];
    ry = -cam->focal * q[1] / q[2];
    r = sqrt(rx * rx + ry * ry);
    gd = refl__spoc_gd(cam, q[2]);
    push = refl__spoc_push(cam, gd);
    /* r' / r: 1 + push / ramp inside the ramp, 1 + push / r outside */
    scale = r < cam->ramp ? 1.0 + push / cam->ramp : 1.0 + push / r;
    out[0] = (float)(cam->pole[0] + rx * scale);
    out[1] = (float)(cam->pole[1] + ry * scale);
    out[2] = (float)gd;
    return 1;
}

REFL_API int refl_spoc_unproject(const refl_spoc *cam, const float uvd[3], refl_vec3 *out) {
    double in, inf, inv_z, z, push, rx, ry, r2, r, x, y;
    if (!cam || !uvd || !out) return 0;
    in = 1.0 / cam->znear;
    inf = 1.0 / cam->zfar;
    inv_z = in - (double)uvd[2] * (in - inf);
    if (!(inv_z > 0.0)) return 0;
    z = 1.0 / inv_z;
    push = refl__spoc_push(cam, uvd[2]);
    rx = (double)uvd[0] - cam->pole[0];
    ry = (double)uvd[1] - cam->pole[1];
    r2 = sqrt(rx * rx + ry * ry);
    /* invert r' = r (1 + push / ramp) below ramp + push, r' = r + push above */
    if (r2 < cam->ramp + push) r = r2 / (1.0 + push / cam->ramp);
    else r = r2 - push;
    if (r2 > 0.0) {
        rx *= r / r2;
        ry *= r / r2;
    }
    x = rx * z / cam->focal;
    y = -ry * z / cam->focal;
    out->x = (float)(cam->eye.x + x * cam->right.x + y * cam->up.x + z * cam->forward.x);
    out->y = (float)(cam->eye.y + x * cam->right.y + y * cam->up.y + z * cam->forward.y);
    out->z = (float)(cam->eye.z + x * cam->right.z + y * cam->up.z + z * cam->forward.z);
    return 1;
}

REFL_API void refl_spoc_bounds(const refl_spoc *cam, float rect[4]) {
    double dist, cone, extent;
    if (!cam || !rect) return;
    dist = 0.5 * ((double)cam->znear + cam->zfar);
    cone = cam->radius / sqrt(dist * dist - (double)cam->radius * cam->radius);
    extent = cam->focal * cone + cam->delta_max;
    rect[0] = (float)(cam->pole[0] - extent);
    rect[1] = (float)(cam->pole[1] - extent);
    rect[2] = (float)(cam->pole[0] + extent);
    rect[3] = (float)(cam->pole[1] + extent);
}

REFL_API long long refl_spoc_count_folds(const refl_spoc *cam, const refl_mesh *mesh, const refl_mat4 *transform,
                                         long long *facing) {
    long long folds = 0, front = 0;
    int t, k;
    if (facing) *facing = 0;
    if (!cam || !mesh) return 0;
    for (t = 0; t < mesh->triangle_count; ++t) {
        refl_vec3 p[3];
        float img[3][3];
        double pin[3][2], q[3], area_pin, area_spoc;
        int ok = 1;
        for (k = 0; k < 3; ++k) {
            const float *v = mesh->positions + 3 * (size_t)mesh->indices[3 * t + k];
            p[k] = refl_v3(v[0], v[1], v[2]);
            if (transform) p[k] = refl_mat4_point(*transform, p[k]);
            refl__spoc_camera_frame(cam, p[k], q);
            if (!(q[2] > 0.0) || !refl_spoc_project(cam, p[k], img[k])) { ok = 0; break; }
            pin[k][0] = q[0] / q[2];
            pin[k][1] = -q[1] / q[2];
        }
        if (!ok) continue;
        /* image rows grow downwards: an eye-facing (counter-clockwise seen
           from outside) triangle has negative signed area in (u, v) */
        area_pin = (pin[1][0] - pin[0][0]) * (pin[2][1] - pin[0][1]) -
                   (pin[2][0] - pin[0][0]) * (pin[1][1] - pin[0][1]);
        if (!(area_pin < 0.0)) continue;
        ++front;
        area_spoc = ((double)img[1][0] - img[0][0]) * ((double)img[2][1] - img[0][1]) -
                    ((double)img[2][0] - img[0][0]) * ((double)img[1][1] - img[0][1]);
        if (area_spoc > 0.0) ++folds;
    }
    if (facing) *facing = front;
    return folds;
}
