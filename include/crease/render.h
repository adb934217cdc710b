/* crease/render.h: pictures of meshes, from a software rasteriser, as PNG.
 *
 *   cr_render_def def = cr_render_default_def();
 *   def.yaw_deg = 45.0f;
 *   cr_render_object obj = {.mesh = garment, .color = {0.8f, 0.3f, 0.2f}};
 *   cr_status st = cr_render_to_png(&def, &obj, 1, "drape.png", &err);
 *
 * What it draws: several meshes in one scene, framed automatically (the
 * bounding sphere of all objects fits the view with a margin), Y up, seen by a
 * perspective camera orbiting the scene centre by yaw and pitch. Surfaces are
 * smooth-shaded from vertex normals computed on the fly (area-weighted) with
 * ambient + Lambert + a soft Blinn-Phong highlight, both sides lit: a back
 * face is shaded with its normal flipped and its colour multiplied by
 * `back_tint`, so the inside of cloth reads as inside. Optional: a wireframe
 * overlay of constant width in pixels, and a colour map (viridis) of a
 * per-vertex scalar instead of the flat object colour. Edges are anti-aliased
 * by supersampling and a box filter; filtering and shading happen in linear
 * light, colours in and pixels out are sRGB.
 *
 * What it leaves out: textures, shadows, transparency, line primitives, text.
 *
 * Cost: binning plus one z-buffered pass per screen tile, tiles in parallel
 * (cr_parallel_for); about O(V + F + W*H*supersample^2). No back-face culling
 * (cloth is two-sided). Triangles reaching behind the camera's near plane are
 * dropped, which never happens with the automatic framing (the eye sits
 * outside the bounding sphere).
 *
 * Thread safety: calls share no state; the same scene may be rendered from
 * several threads at once.
 */
#ifndef CREASE_RENDER_H
#define CREASE_RENDER_H

#include "crease/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ----------------------------------------------------------------- image -- */

/* An 8-bit sRGB image, (H, W, 3) row-major, row 0 at the top. Owns `rgb`. */
typedef struct cr_image {
    int width, height; /* pixels */
    uint8_t *rgb;      /* (H, W, 3) */
} cr_image;

/* A zero-filled (black) image; width and height in 1..CR_IMAGE_MAX_SIDE. */
enum { CR_IMAGE_MAX_SIDE = 32768 };
cr_status cr_image_create(int width, int height, cr_image *out, cr_error *err);
/* Frees the pixels and zeroes the struct; NULL and already-freed images are fine. */
void cr_image_free(cr_image *img);

/* Write 8-bit RGB PNG (sRGB chunk set) through a temporary file renamed into place. */
cr_status cr_image_write_png(const cr_image *img, const char *path, cr_error *err);

/* Lay out `n` images in rows of `cols` (cols <= 0: one row), each in a cell
 * the size of the largest image, centred, with `gap_px` pixels between
 * cells. Gaps and unused cell area get `fill` (sRGB in [0,1]). `out` is new. */
cr_status cr_image_grid(const cr_image *imgs, int n, int cols, int gap_px, const float fill[3],
                        cr_image *out, cr_error *err);

/* ------------------------------------------------------------- colour map -- */

/* Viridis (van der Walt & Smith, matplotlib 2015): perceptually uniform, dark
 * blue to yellow, luminance rising monotonically. t is clamped to [0,1] (NaN
 * gives the low end); rgb is sRGB in [0,1]. Interpolates every fifth of
 * matplotlib's 256 entries linearly, within 0.0025 of the full table. */
void cr_colormap_viridis(float t, float rgb[3]);

/* ----------------------------------------------------------------- scene -- */

typedef struct cr_render_object {
    const cr_mesh *mesh; /* borrowed; positions must be finite */
    float color[3];      /* sRGB in [0,1], used when scalar is NULL */
    const float *scalar; /* (V) per-vertex value shown through the colour map, or NULL */
    int wireframe;       /* non-zero: draw this object's edges even when def.wireframe is 0 */
} cr_render_object;

typedef struct cr_render_def {
    int width, height;   /* output size, pixels, 1..CR_IMAGE_MAX_SIDE */
    int supersample;     /* samples per pixel along each axis, 1..8; box-filtered down */
    float background[3]; /* sRGB in [0,1] */

    /* Camera: orbits the centre of the scene's bounding box. yaw = 0, pitch = 0
     * looks along -Z from the +Z side (x right, y up on screen); positive yaw
     * turns the camera counter-clockwise seen from above, positive pitch
     * raises it. */
    float yaw_deg;   /* any finite value */
    float pitch_deg; /* (-90, 90) */
    float fov_deg;   /* field of view across the narrower image side, (0, 170) */
    float margin;    /* >= 0: extra room around the bounding sphere, as a fraction of its radius */

    /* Lighting, in camera space: x right, y up, z towards the viewer, so the
     * light turns with the camera and every turntable frame is lit alike. */
    float light_dir[3]; /* direction towards the light; need not be unit, must not be zero */
    float ambient;      /* >= 0 */
    float diffuse;      /* >= 0, Lambert strength */
    float specular;     /* >= 0, Blinn-Phong strength (white highlight) */
    float shininess;    /* >= 1, Blinn-Phong exponent */
    float back_tint[3]; /* in [0,1], multiplies the colour of back faces */

    int wireframe;       /* non-zero: draw the edges of every object */
    float wire_color[3]; /* sRGB in [0,1] */
    float wire_width_px; /* > 0, line width in output pixels */

    /* Colour map range for the objects' scalars: automatic (min and max over
     * every object's scalars, one range for the whole scene so objects
     * compare; one value everywhere shows the middle colour) or fixed
     * [colormap_min, colormap_max]; values outside the range clamp. Shading
     * still applies to colour-mapped surfaces, so shape stays readable. */
    int colormap_auto;
    float colormap_min, colormap_max; /* used when colormap_auto == 0; min < max */

    uint32_t cookie; /* set by cr_render_default_def; a hand-zeroed def is a bug */
} cr_render_def;

/* 1024x1024, supersample 2, white background, yaw 30, pitch 20, fov 35,
 * margin 0.05, light from the upper left front, ambient 0.25, diffuse 0.75,
 * specular 0.25, shininess 32, bluish-darker back faces, wireframe off
 * (dark grey, 1 px), automatic colour map range. */
cr_render_def cr_render_default_def(void);

/* Render `nobj` objects into `out` (new image; zeroed on failure). Refuses a
 * bad def (CR_ERR_INVALID naming the field), a NULL mesh (CR_ERR_INVALID),
 * out-of-range indices (CR_ERR_RANGE) and non-finite positions or scalars
 * (CR_ERR_NAN), each naming the object index. nobj == 0 gives the background. */
cr_status cr_render_scene(const cr_render_def *def, const cr_render_object *objs, int nobj,
                          cr_image *out, cr_error *err);

/* cr_render_scene then cr_image_write_png. */
cr_status cr_render_to_png(const cr_render_def *def, const cr_render_object *objs, int nobj,
                           const char *path, cr_error *err);

/* `nframes` (1..100000) PNGs with the camera yaw going round 360 degrees from
 * def->yaw_deg in equal steps (frame k at yaw + 360 k / nframes), framed
 * alike. `path_pattern` holds exactly one integer conversion, %d with
 * optional zero flag and width ("out/turn_%03d.png"), and otherwise only
 * %% escapes; it gets the frame index. Directories must exist. Normals are
 * computed once for all frames. */
cr_status cr_render_turntable(const cr_render_def *def, const cr_render_object *objs, int nobj,
                              int nframes, const char *path_pattern, cr_error *err);

#ifdef __cplusplus
}
#endif
#endif
