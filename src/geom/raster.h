/* raster.h (private): the tiled z-buffer rasteriser behind cr_render_scene.
 *
 * render.c places the camera and projects every vertex into a raster_vert;
 * raster.c bins triangles to screen tiles, then draws each tile on its own
 * (its own z-buffer, so tiles run in parallel without locks), shades the
 * visible sample of each pixel's supersamples and box-filters them into the
 * output image.
 *
 * Coordinates: "sample space" is the supersampled image, x right, y down,
 * sample (i, j) centred at (i + 0.5, j + 0.5); positions there are fixed
 * point with RASTER_SUBPIXEL_BITS fraction bits so edge functions are exact
 * integers and shared edges are watertight. "Camera space" is (right, up,
 * forward), forward pointing into the scene.
 */
#ifndef CREASE_GEOM_RASTER_H
#define CREASE_GEOM_RASTER_H

#include "crease/render.h"

enum {
    RASTER_SUBPIXEL_BITS = 8, /* 1/256 of a sample: finer than any visible error */
    RASTER_TILE_PX = 32       /* tile side in output pixels; a tile's buffers stay in L2 */
};

/* Largest |sample coordinate| a vertex may have: keeps fixed-point edge
 * function products (two coordinates of 2^(21+8)) inside int64. */
#define RASTER_GUARD_SAMPLES 2097152.0f /* 2^21 */

/* One projected vertex. */
typedef struct raster_vert {
    int32_t x, y; /* sample-space position, fixed point */
    float iz;     /* 1 / depth along forward, 1/m; 0 marks a vertex the rasteriser must skip */
    float n[3];   /* unit vertex normal, camera space */
} raster_vert;

/* One object as the rasteriser sees it. Triangles of all objects share one
 * numbering: object o owns global ids [fbase, fbase + nf). */
typedef struct raster_object {
    const int32_t *tri; /* (nf,3) indices into this object's vertices */
    int32_t nf;
    int64_t vbase;       /* first vertex of this object in raster_frame.vert */
    int64_t fbase;       /* first global triangle id */
    const float *scalar; /* (V) colour-map values, or NULL */
    float color[3];      /* linear RGB */
    int wire;            /* draw edges */
} raster_object;

typedef struct raster_frame {
    int width, height;    /* output pixels */
    int ss;               /* samples per pixel along each axis */
    int sw, sh;           /* sample-space size: width * ss, height * ss */
    int tiles_x, tiles_y; /* tiles of RASTER_TILE_PX output pixels */

    int nobj;
    const raster_object *obj; /* (nobj) */
    int64_t nf;               /* triangles over all objects */
    const raster_vert *vert;  /* (all objects' vertices) */

    /* Projection: sample (sx, sy) looks along (sx - cx, -(sy - cy), focal) in camera space. */
    float focal, cx, cy; /* samples */

    /* Shading, all colours linear RGB. */
    float background[3];
    float light[3]; /* unit, camera space, towards the light */
    float ambient, diffuse, specular, shininess;
    float spec_cut; /* n.h below this gives a highlight under 1e-3: skip powf */
    float back_tint[3];
    float wire_color[3];
    float wire_half;           /* half the line width, samples */
    float cmap_lo, cmap_scale; /* colour-map coordinate t = (s - cmap_lo) * cmap_scale */
    float cmap[256][3];        /* viridis, linear RGB */
    uint8_t encode[4096];      /* linear [0,1] -> sRGB byte, index round(c * 4095) */

    /* Filled by cr_raster_bin: triangles of tile t are bin_tri[bin_start[t] .. bin_start[t+1]). */
    int64_t *bin_start; /* (tiles + 1) */
    int32_t *bin_tri;   /* global triangle ids, ascending within a tile */
} raster_frame;

/* sRGB transfer functions (IEC 61966-2-1), per channel in [0,1]. */
float cr_raster_srgb_to_linear(float c);
float cr_raster_linear_to_srgb(float c);

/* Fill the colour-map and encoding tables of `fr`. */
void cr_raster_init_tables(raster_frame *fr);

/* Bin every triangle to the tiles its bounding box covers. */
cr_status cr_raster_bin(raster_frame *fr, cr_error *err);

/* Draw all tiles into `out` (already width x height). */
cr_status cr_raster_draw(const raster_frame *fr, cr_image *out, cr_error *err);

void cr_raster_free_bins(raster_frame *fr);

#endif
