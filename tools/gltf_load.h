/* gltf_load.h - glTF 2.0 (.gltf and .glb) into a refl_scene, through
   tinygltf. A C API; the implementation (gltf_load.cpp) is C++17 and links
   with -ltinygltf -lstdc++. Part of reflect.h + rast.h's tools/, never of
   the headers.

       refl_gltf_options opt = {0};
       opt.normalize_size = 2.0f;              // 0: keep the file's units
       refl_scene *scene;
       char err[512];
       if (refl_gltf_load("Duck.glb", &opt, &scene, err, sizeof err) != REFL_OK) {
           fprintf(stderr, "%s\n", err);       // "Duck.glb: ..."
           exit(1);
       }
       if (err[0]) fprintf(stderr, "%s", err); // warnings, one per line
       ...
       refl_scene_destroy(scene);

   WHAT LOADS
     - The default scene (glTF "scene", else scenes[0]; a file without scenes:
       every root node), its whole node hierarchy with matrix or TRS
       transforms. Each primitive becomes one refl_mesh, shared by every
       primitive that reads the same accessors (glTF puts the material in
       the primitive, so a shape instanced with several materials repeats
       its accessors in several meshes: MetalRoughSpheres has 98 spheres,
       one refl_mesh); each instance is one refl_object (named after the
       node) with the node's world transform. Skins, morph targets and
       animations are ignored (the rest pose). A node reached twice (a cycle
       or two parents, both invalid glTF) is visited once, with a warning.
     - Primitives: TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (the last two
       turned into lists); indexed (u8/u16/u32) or not. POSITION (float vec3,
       required), NORMAL (float vec3; computed when absent, or when any is
       not finite or zero), TEXCOORD_n (float or normalised u8/u16 vec2; n is
       the material's baseColorTexture.texCoord, else 0), COLOR_0 (vec3/vec4,
       float or normalised u8/u16, linear). POINTS and LINE* primitives are
       skipped with a warning; a file left with no triangles at all is an
       error (REFL_ERROR_UNSUPPORTED when it had only such primitives,
       REFL_ERROR_BAD_MESH when it had no primitives).
     - Materials, one refl_material per glTF material in file order (plus a
       default white diffuse one for primitives without a material), first
       rule that applies:
         metallicFactor >= 0.99 and roughnessFactor <= 0.05 -> REFL_MIRROR,
             color = baseColorFactor, reflectance = its luminance (Rec. 709;
             1 when zero). (A metal is opaque, so a transmissive metal is a
             mirror too.)
         KHR_materials_transmission with transmissionFactor > 0 ->
             REFL_GLASS, ior = KHR_materials_ior.ior (1.5), tint =
             baseColorFactor.rgb, and KHR_materials_volume's absorption
             (thicknessFactor > 0, finite attenuationDistance) per channel
             as far as one attenuation and a tint can hold it: with
             sigma_c = -ln(attenuationColor_c) / attenuationDistance,
             attenuation = min_c sigma_c (per unit of world length) and
             tint_c *= exp(-(sigma_c - min sigma) * thicknessFactor), so
             light through the nominal thickness comes out exactly
             attenuationColor^(thickness / distance) per channel, and
             through other lengths with that hue. thicknessFactor 0 (thin
             walled, the extension's default) absorbs nothing.
         mirror_weight = (1 - roughness)^2 * (0.04 (1 - metallic) + metallic)
             at least 0.05 -> REFL_PARTIAL: the sharp share of glTF's
             specular lobe at its normal-incidence reflectance (0.04 for a
             dielectric, so plastics stay diffuse: glTF shows their 4%
             mostly at grazing angles), the rest diffuse; reflectance = (0.04 (1 -
             metallic) + metallic * lum(baseColor)) / that F0, so a metal
             reflects its colour's luminance; no Fresnel rise, color and
             texture as for diffuse. A rough surface's reflection is blurred
             beyond what a mirror shows, hence the square.
         otherwise REFL_DIFFUSE with color = baseColorFactor and
             baseColorTexture: the image decoded by tinygltf's decoder (8 or
             16 bits, any channel count), sRGB -> linear (alpha kept
             linear), added with refl_scene_add_texture and set as texture
             = index + 1. Images are shared between materials. Only images
             a base colour texture uses are decoded; one that fails to
             decode is a warning (no texture), not an error.
             Images other than PNG and JPEG are ignored with a warning.
         Emission: emissiveFactor times KHR_materials_emissive_strength
             becomes refl_material.emissive on diffuse and partial
             materials (a warning on mirrors and glass); none where the
             material has an emissiveTexture, which the factor scales.
         Texture transforms, sampler wrap modes, alpha modes, every other map
         and material extension, skins, morph targets and animations are
         not drawn: one warning line per feature the file uses, with its
         count ("not drawn: normalTexture (3 uses)").
     - Camera: the opt.camera-th node (depth first, in scene order) with a
       perspective camera, the first by default, sets scene->camera (eye =
       node origin, target = eye + its -Z axis, up = its +Y axis, fovy from
       yfov; znear/zfar and the size left 0) and has_camera = 1.
     - Lights: KHR_lights_punctual point and spot (as point) lights at their
       node's position, directional lights along the node's -Z axis; color
       = color * intensity. A file without lights adds none.
     - normalize_size > 0: refl_scene_normalize(scene, normalize_size), and
       glass attenuation rescaled to the new units.

   ERRORS
     Never a crash or an abort: missing or unreadable files, truncated or
     corrupted .glb (the GLB header and chunks are checked before tinygltf
     sees them), JSON errors, every byte range read (accessors against
     their bufferView and buffer: offset, stride, count, component type,
     normalised flag; an image's bufferView against its buffer, before a
     byte of it is read), and every double that would not survive as a
     float give a REFL_ERROR_* code and one line in err that starts with
     the path, e.g.
         "teapot.glb: primitive 3 of mesh 'x': index 40123 out of range (2082 vertices)".
     Limits, each refused with a message that names it: the JSON text is
     scanned before tinygltf parses it, at most 512 levels of nested arrays
     and objects (tinygltf's parser recurses per level) and 2^24 values
     (INVALID_SIZE); every world coordinate (vertices after their node's
     transform, light and camera positions) within +-1e18, so that float
     squares of coordinates stay finite; transforms, light colours times
     intensity, ior and attenuation within float's range (BAD_MESH).
     Codes: INVALID_ARGUMENT (NULL arguments), UNKNOWN_NAME (file missing),
     BAD_MESH (malformed file or data: parse errors, bounds, indices,
     non-finite positions, node cycles, no triangles), UNSUPPORTED (sparse
     accessors, non-triangle primitives only, a file that needs an unknown
     extension), INVALID_SIZE (counts too large, a texture over
     opt.max_texture_pixels, a file over 2 GiB or not a regular file),
     OUT_OF_MEMORY. On error *out_scene is NULL and nothing leaks.
     On success err holds the warnings, one per line ("" when none).
     err may be NULL (then nothing is written). */
#ifndef REFL_GLTF_LOAD_H
#define REFL_GLTF_LOAD_H

#include <stddef.h>

#include "../reflect.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct refl_gltf_options {
    float normalize_size;    /* 0: keep the file's units; > 0: scene diagonal */
    refl_allocator allocator; /* for the scene, its meshes and textures; zero: malloc */
    int camera;              /* which perspective camera node (depth first, in scene order)
                                sets scene->camera: 0 the first; negative: none; one
                                past the last: INVALID_ARGUMENT */
    int *camera_count;       /* optional out: how many perspective camera nodes there are */
    long long max_texture_pixels; /* a larger base colour image is refused (INVALID_SIZE)
                                     before it is decoded; 0: 2^24 (4096 x 4096) */
} refl_gltf_options;

/* opt may be NULL (all defaults). */
refl_result refl_gltf_load(const char *path, const refl_gltf_options *opt, refl_scene **out_scene,
                           char *err, size_t err_size);
/* The same from a file's bytes in memory (.glb or .gltf, told apart by the
   GLB magic). `name` stands for the path: messages start with it, and a
   .gltf's external files are looked up next to it. */
refl_result refl_gltf_load_memory(const void *data, size_t size, const char *name,
                                  const refl_gltf_options *opt, refl_scene **out_scene, char *err,
                                  size_t err_size);

#ifdef __cplusplus
}
#endif
#endif /* REFL_GLTF_LOAD_H */
