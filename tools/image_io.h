/* image_io.h - images in and out through OpenImageIO, and image comparison.
   A C API; the implementation (image_io.cpp) is C++17 and links with
   `pkg-config --libs OpenImageIO` -lstdc++. Part of reflect.h + rast.h's
   tools/, never of the headers.

   CONVENTIONS
     Pixels are interleaved, rows top first, tightly packed. Floats are
     linear; 8-bit pixels are display-encoded (sRGB). Every error returns a
     REFL_ERROR_* code and writes one line starting with the file's path to
     err (err may be NULL; err_size counts the terminating zero):
       REFL_ERROR_INVALID_ARGUMENT  NULL or inconsistent arguments
       REFL_ERROR_INVALID_SIZE      zero, negative or absurd sizes (more than
                                    2^27 pixels), sizes that do not match
       REFL_ERROR_UNKNOWN_NAME      the file is missing or cannot be opened,
                                    or no format for the extension
       REFL_ERROR_BAD_MESH          the file is corrupt or truncated (the
                                    code refl_result has for bad input data)
       REFL_ERROR_OUT_OF_MEMORY
     Pixel buffers handed out are allocated with the given allocator (NULL:
     malloc) and freed with refl_image_free / refl_env_free / the same
     allocator. On error nothing is allocated and outputs are zeroed. */
#ifndef REFL_IMAGE_IO_H
#define REFL_IMAGE_IO_H

#include <stddef.h>
#include <stdint.h>

#include "../reflect.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Writes a width x height image with `channels` (1 grey, 2 grey + alpha,
   3 RGB, 4 RGBA) interleaved channels from exactly one of rgba8 or rgbaf.
   The format follows the extension (anything OpenImageIO writes):
     .exr, .hdr, .pfm   float pixels (EXR: 32-bit float, so float data
                        round-trips exactly); 8-bit input is decoded sRGB ->
                        linear first. HDR (RGBE) stores RGB only: grey is
                        expanded and alpha dropped.
     anything else      8-bit pixels (.png, .ppm, .jpg, .tif ...); float
                        input is encoded linear -> sRGB, clamped to [0, 1]
                        and rounded.
   Alpha is never converted and is stored unassociated (not premultiplied). */
refl_result refl_image_write(const char *path, int width, int height, int channels, const uint8_t *rgba8,
                             const float *rgbaf, char *err, size_t err_size);

/* Reads the first subimage of any file OpenImageIO reads (HDR, EXR, PNG,
   JPEG, PPM, TIFF ...) into linear RGBA floats: integer files whose colour
   space is not "Linear" (PNG, JPEG ...) are decoded sRGB -> linear; float
   files are taken as linear. Alpha stays as stored (unassociated); grey is
   copied to R, G, B; a missing alpha is 1. Non-finite values become 0.
   PNG files are checked whole first (all chunks present, CRCs right). */
refl_result refl_image_read(const char *path, refl_image *out, const refl_allocator *a, char *err,
                            size_t err_size);

/* Reads an image as stored, as RGBA8 (no colour conversion: floats are
   clamped to [0, 1] and scaled by 255), e.g. for comparing rendered PNGs. */
refl_result refl_image_read_rgba8(const char *path, int *width, int *height, uint8_t **rgba8,
                                  const refl_allocator *a, char *err, size_t err_size);

/* Frees out->pixels (allocated with `a`) and zeroes the image. */
void refl_image_free(refl_image *image, const refl_allocator *a);

/* An environment map into *out (then refl_scene_set_environment copies it):
     - a path: one equirectangular image (width = 2 x height; longitude
       across, +Y at the top row) -> REFL_ENV_EQUIRECT;
     - a pattern with "%s": six square faces of one size, "%s" replaced by
       px, nx, py, ny, pz, nz (+X -X +Y -Y +Z -Z, GL's cube-map order, GL's
       face orientation) -> REFL_ENV_CUBE, e.g. "sky_%s.hdr".
   Images are read with refl_image_read (so any format, linear RGBA). */
refl_result refl_env_load(const char *path_or_pattern, refl_environment *out, const refl_allocator *a,
                          char *err, size_t err_size);
/* Frees the images of an environment from refl_env_load and zeroes it. */
void refl_env_free(refl_environment *env, const refl_allocator *a);

typedef struct refl_image_diff {
    double rmse;             /* root mean square difference over R, G, B, values in [0, 1] */
    double psnr;             /* 20 log10(1 / rmse) in dB; INFINITY when identical */
    double max_error;        /* largest R, G or B difference, in [0, 1] */
    double fraction_over;    /* fraction of pixels with some R, G or B difference > threshold */
    long long pixels_over;
} refl_image_diff;

/* Compares two width x height RGBA8 images (alpha ignored). threshold is in
   [0, 1] units of a channel (e.g. 4.0 / 255). Computed directly, so the
   numbers are the same on every machine. */
refl_result refl_image_compare(const uint8_t *a, const uint8_t *b, int width, int height, double threshold,
                               refl_image_diff *out);
/* The same for two image files read with refl_image_read_rgba8; their sizes
   must match (else REFL_ERROR_INVALID_SIZE). */
refl_result refl_image_compare_files(const char *path_a, const char *path_b, double threshold,
                                     refl_image_diff *out, char *err, size_t err_size);

#ifdef __cplusplus
}
#endif
#endif /* REFL_IMAGE_IO_H */
