/* raster.c: tiled z-buffer triangle rasteriser with deferred shading.
 *
 * Per frame: (1) bin: each triangle's sample-space bounding box picks the
 * tiles it may touch; (2) draw, tiles in parallel: every triangle of the tile
 * is scanned with exact integer edge functions and the top-left fill rule
 * (a sample on an edge shared by two triangles belongs to exactly one), the
 * nearest sample wins by 1/depth (interpolates linearly in screen space, no
 * near/far range needed), and the winner's id and screen-space barycentrics
 * are kept; (3) resolve: each visible sample is shaded once, with normals and
 * scalars interpolated perspective-correctly (barycentrics weighted by
 * 1/depth), and the ss x ss samples of a pixel are averaged in linear light
 * (box filter) before sRGB encoding.
 *
 * Shading: ambient + Lambert + Blinn-Phong (Blinn 1977) with a white
 * highlight; the face's screen winding decides front or back, and a back face
 * uses the flipped normal and the back tint. Wireframe: the distance of a
 * sample to the nearest triangle edge in samples is its screen-space
 * barycentric times the triangle's height over that edge; each triangle
 * darkens a band of half the line width on its side, so shared edges get the
 * full width, constant in pixels whatever the depth.
 *
 * Leaves out: clipping (render.c frames the scene so nothing reaches the near
 * plane; a vertex there is marked and its triangles skipped), back-face
 * culling (cloth is two-sided), transparency, hierarchical z.
 * References: Pineda, "A parallel algorithm for polygon rasterization",
 * SIGGRAPH 1988 (edge functions); the Direct3D 10 top-left rule; Blinn,
 * "Models of light reflection for computer synthesized pictures", 1977.
 */
#include "raster.h"
#include "base/vec3.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define FIX_ONE (1 << RASTER_SUBPIXEL_BITS)
#define FIX_HALF (1 << (RASTER_SUBPIXEL_BITS - 1))

float cr_raster_srgb_to_linear(float c) {
    return c <= 0.04045f ? c / 12.92f : powf((c + 0.055f) / 1.055f, 2.4f);
}

float cr_raster_linear_to_srgb(float c) {
    return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1.0f / 2.4f) - 0.055f;
}

void cr_raster_init_tables(raster_frame *fr) {
    for (int i = 0; i < 256; i++) {
        float rgb[3];
        cr_colormap_viridis((float)i / 255.0f, rgb);
        for (int c = 0; c < 3; c++)
            fr->cmap[i][c] = cr_raster_srgb_to_linear(rgb[c]);
    }
    for (int i = 0; i < 4096; i++)
        fr->encode[i] = (uint8_t)lrintf(255.0f * cr_raster_linear_to_srgb((float)i / 4095.0f));
}

/* Object owning global triangle `gid` (objects are few: binary search). */
static const raster_object *object_of(const raster_frame *fr, int64_t gid) {
    int lo = 0, hi = fr->nobj - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (fr->obj[mid].fbase <= gid)
            lo = mid;
        else
            hi = mid - 1;
    }
    return &fr->obj[lo];
}

static void tri_verts(const raster_frame *fr, int64_t gid, const raster_vert *v[3]) {
    const raster_object *o = object_of(fr, gid);
    const int32_t *t = &o->tri[3 * (gid - o->fbase)];
    for (int k = 0; k < 3; k++)
        v[k] = &fr->vert[o->vbase + t[k]];
}

static int64_t floor_div(int64_t a, int64_t b) {
    int64_t q = a / b;
    return (a % b != 0 && (a < 0) != (b < 0)) ? q - 1 : q;
}

/* --------------------------------------------------------------- binning -- */

/* Inclusive range of samples whose centres lie in [lo, hi] (fixed point). */
static void sample_range(int64_t lo, int64_t hi, int n, int64_t *first, int64_t *last) {
    *first = floor_div(lo - FIX_HALF + FIX_ONE - 1, FIX_ONE);
    *last = floor_div(hi - FIX_HALF, FIX_ONE);
    if (*first < 0) *first = 0;
    if (*last > n - 1) *last = n - 1;
}

typedef struct bin_ctx {
    const raster_frame *fr;
    int32_t (*box)[4]; /* (F,4) tile range x0, y0, x1, y1 inclusive; x0 > x1: no tile */
} bin_ctx;

static void bin_boxes(void *ctx, int64_t begin, int64_t end) {
    bin_ctx *bc = ctx;
    const raster_frame *fr = bc->fr;
    int64_t tile_samples = (int64_t)RASTER_TILE_PX * fr->ss;
    for (int64_t g = begin; g < end; g++) {
        int32_t *box = bc->box[g];
        box[0] = box[1] = 1, box[2] = box[3] = 0;
        const raster_vert *v[3];
        tri_verts(fr, g, v);
        if (v[0]->iz <= 0.0f || v[1]->iz <= 0.0f || v[2]->iz <= 0.0f) continue;
        int64_t area2 = (int64_t)(v[1]->x - v[0]->x) * (v[2]->y - v[0]->y) -
                        (int64_t)(v[1]->y - v[0]->y) * (v[2]->x - v[0]->x);
        if (area2 == 0) continue;
        int64_t x_lo = v[0]->x, x_hi = v[0]->x, y_lo = v[0]->y, y_hi = v[0]->y;
        for (int k = 1; k < 3; k++) {
            if (v[k]->x < x_lo) x_lo = v[k]->x;
            if (v[k]->x > x_hi) x_hi = v[k]->x;
            if (v[k]->y < y_lo) y_lo = v[k]->y;
            if (v[k]->y > y_hi) y_hi = v[k]->y;
        }
        int64_t sx0, sx1, sy0, sy1;
        sample_range(x_lo, x_hi, fr->sw, &sx0, &sx1);
        sample_range(y_lo, y_hi, fr->sh, &sy0, &sy1);
        if (sx0 > sx1 || sy0 > sy1) continue;
        box[0] = (int32_t)(sx0 / tile_samples), box[2] = (int32_t)(sx1 / tile_samples);
        box[1] = (int32_t)(sy0 / tile_samples), box[3] = (int32_t)(sy1 / tile_samples);
    }
}

cr_status cr_raster_bin(raster_frame *fr, cr_error *err) {
    int64_t ntiles = (int64_t)fr->tiles_x * fr->tiles_y;
    fr->bin_start = NULL, fr->bin_tri = NULL;
    bin_ctx bc = {fr, NULL};
    bc.box = cr_malloc((size_t)(fr->nf > 0 ? fr->nf : 1) * sizeof *bc.box, err);
    fr->bin_start = cr_calloc((size_t)ntiles + 1, sizeof *fr->bin_start, err);
    if (!bc.box || !fr->bin_start) goto fail;
    cr_parallel_for(fr->nf, 4096, bin_boxes, &bc);

    /* Count, prefix-sum, fill: serial and in triangle order, so each tile
     * lists its triangles in ascending id and equal depths resolve the same
     * way on any thread count. */
    int64_t *count = fr->bin_start + 1;
    for (int64_t g = 0; g < fr->nf; g++) {
        const int32_t *b = bc.box[g];
        for (int32_t ty = b[1]; ty <= b[3]; ty++)
            for (int32_t tx = b[0]; tx <= b[2]; tx++)
                count[(int64_t)ty * fr->tiles_x + tx]++;
    }
    for (int64_t t = 0; t < ntiles; t++)
        fr->bin_start[t + 1] += fr->bin_start[t];
    fr->bin_tri = cr_malloc(
        (size_t)(fr->bin_start[ntiles] > 0 ? fr->bin_start[ntiles] : 1) * sizeof *fr->bin_tri, err);
    if (!fr->bin_tri) goto fail;
    /* bin_start[t] serves as tile t's cursor, then shifts back into place. */
    for (int64_t g = 0; g < fr->nf; g++) {
        const int32_t *b = bc.box[g];
        for (int32_t ty = b[1]; ty <= b[3]; ty++)
            for (int32_t tx = b[0]; tx <= b[2]; tx++)
                fr->bin_tri[fr->bin_start[(int64_t)ty * fr->tiles_x + tx]++] = (int32_t)g;
    }
    for (int64_t t = ntiles; t > 0; t--)
        fr->bin_start[t] = fr->bin_start[t - 1];
    fr->bin_start[0] = 0;
    free(bc.box);
    return CR_OK;
fail:
    free(bc.box);
    cr_raster_free_bins(fr);
    return err ? err->status : CR_ERR_MEMORY;
}

void cr_raster_free_bins(raster_frame *fr) {
    free(fr->bin_start);
    free(fr->bin_tri);
    fr->bin_start = NULL, fr->bin_tri = NULL;
}

/* ------------------------------------------------------------- scanning -- */

/* One tile's sample buffers, T x T with T = RASTER_TILE_PX * ss (row stride T). */
typedef struct tile_buf {
    int x0, y0, w, h; /* sample-space rectangle of this tile */
    int stride;
    float *iz;   /* 1/depth of the nearest sample so far; 0 = empty */
    int32_t *id; /* 2 * triangle id + (1 if back face), -1 = background */
    float *b1;   /* screen-space barycentric of the triangle's vertex 1 */
    float *b2;   /* ... of vertex 2 */
} tile_buf;

/* Edge u -> v as E(p) = a (p.x - u.x) + b (p.y - u.y); positive inside a
 * triangle of positive area2. Top-left edges (a > 0, or a == 0 and b > 0:
 * the interior lies right of or below the edge) own samples lying exactly on
 * them; others need E > 0, folded into `bias`. */
typedef struct edge {
    int64_t a, b, ux, uy, bias;
} edge;

static edge make_edge(const raster_vert *u, const raster_vert *v) {
    edge e = {(int64_t)u->y - v->y, (int64_t)v->x - u->x, u->x, u->y, 0};
    e.bias = (e.a > 0 || (e.a == 0 && e.b > 0)) ? 0 : -1;
    return e;
}

static void scan_triangle(const raster_frame *fr, int64_t gid, tile_buf *tb) {
    const raster_vert *v[3];
    tri_verts(fr, gid, v);
    int64_t area2 = (int64_t)(v[1]->x - v[0]->x) * (v[2]->y - v[0]->y) -
                    (int64_t)(v[1]->y - v[0]->y) * (v[2]->x - v[0]->x);
    /* Counter-clockwise in the world is clockwise on a y-down screen, so a
     * front face has negative area2 here; swapping two corners gives every
     * triangle positive area for the scan. */
    int back = area2 > 0;
    const raster_vert *p[3] = {v[0], back ? v[1] : v[2], back ? v[2] : v[1]};
    if (!back) area2 = -area2;
    edge e[3] = {make_edge(p[1], p[2]), make_edge(p[2], p[0]), make_edge(p[0], p[1])};

    int64_t x_lo = p[0]->x, x_hi = p[0]->x, y_lo = p[0]->y, y_hi = p[0]->y;
    for (int k = 1; k < 3; k++) {
        if (p[k]->x < x_lo) x_lo = p[k]->x;
        if (p[k]->x > x_hi) x_hi = p[k]->x;
        if (p[k]->y < y_lo) y_lo = p[k]->y;
        if (p[k]->y > y_hi) y_hi = p[k]->y;
    }
    int64_t sx0, sx1, sy0, sy1;
    sample_range(x_lo, x_hi, fr->sw, &sx0, &sx1);
    sample_range(y_lo, y_hi, fr->sh, &sy0, &sy1);
    if (sx0 < tb->x0) sx0 = tb->x0;
    if (sy0 < tb->y0) sy0 = tb->y0;
    if (sx1 > tb->x0 + tb->w - 1) sx1 = tb->x0 + tb->w - 1;
    if (sy1 > tb->y0 + tb->h - 1) sy1 = tb->y0 + tb->h - 1;
    if (sx0 > sx1 || sy0 > sy1) return;

    float inv_area = 1.0f / (float)area2;
    float iz0 = p[0]->iz, iz1 = p[1]->iz, iz2 = p[2]->iz;
    int32_t code = (int32_t)(2 * gid + back);
    int64_t px0 = sx0 * FIX_ONE + FIX_HALF;
    for (int64_t sy = sy0; sy <= sy1; sy++) {
        int64_t py = sy * FIX_ONE + FIX_HALF;
        int64_t w[3];
        for (int k = 0; k < 3; k++)
            w[k] = e[k].a * (px0 - e[k].ux) + e[k].b * (py - e[k].uy);
        size_t row = (size_t)(sy - tb->y0) * tb->stride - tb->x0;
        for (int64_t sx = sx0; sx <= sx1; sx++) {
            if (((w[0] + e[0].bias) | (w[1] + e[1].bias) | (w[2] + e[2].bias)) >= 0) {
                float l0 = (float)w[0] * inv_area, l1 = (float)w[1] * inv_area;
                float l2 = (float)w[2] * inv_area;
                float iz = l0 * iz0 + l1 * iz1 + l2 * iz2;
                size_t s = row + (size_t)sx;
                if (iz > tb->iz[s]) {
                    tb->iz[s] = iz;
                    tb->id[s] = code;
                    /* Back to the triangle's own corner order (p swapped 1 and 2 for fronts). */
                    tb->b1[s] = back ? l1 : l2;
                    tb->b2[s] = back ? l2 : l1;
                }
            }
            for (int k = 0; k < 3; k++)
                w[k] += e[k].a * FIX_ONE;
        }
    }
}

/* -------------------------------------------------------------- shading -- */

/* Distance in samples from the point with screen barycentrics l to the
 * nearest edge of triangle v: l_k times the height over the edge opposite k. */
static float edge_distance(const raster_vert *const v[3], const float l[3]) {
    float x[3], y[3];
    for (int k = 0; k < 3; k++) {
        x[k] = (float)v[k]->x * (1.0f / FIX_ONE);
        y[k] = (float)v[k]->y * (1.0f / FIX_ONE);
    }
    float area2 = fabsf((x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]));
    float d = INFINITY;
    for (int k = 0; k < 3; k++) {
        int i = (k + 1) % 3, j = (k + 2) % 3;
        float len = hypotf(x[j] - x[i], y[j] - y[i]);
        float dk = fabsf(l[k]) * area2 / len;
        if (dk < d) d = dk;
    }
    return d;
}

/* Linear RGB of the visible surface at sample (sx, sy) of the tile. */
static void shade_sample(const raster_frame *fr, const tile_buf *tb, size_t s, int sx, int sy,
                         float out[3]) {
    int32_t code = tb->id[s];
    int64_t gid = code >> 1;
    int back = code & 1;
    const raster_object *o = object_of(fr, gid);
    const int32_t *t = &o->tri[3 * (gid - o->fbase)];
    const raster_vert *v[3];
    for (int k = 0; k < 3; k++)
        v[k] = &fr->vert[o->vbase + t[k]];

    float l[3] = {1.0f - tb->b1[s] - tb->b2[s], tb->b1[s], tb->b2[s]};
    /* Perspective-correct weights: attributes are affine in 1/depth-weighted
     * screen barycentrics. */
    float pw[3], wsum = 0.0f;
    for (int k = 0; k < 3; k++)
        wsum += pw[k] = l[k] * v[k]->iz;
    for (int k = 0; k < 3; k++)
        pw[k] /= wsum;

    float n[3] = {0.0f, 0.0f, 0.0f};
    for (int k = 0; k < 3; k++)
        for (int c = 0; c < 3; c++)
            n[c] += pw[k] * v[k]->n[c];
    if (dot3f(n, n) < 1e-12f) {
        /* Normals cancelled (folded or degenerate neighbourhood): face the camera. */
        n[0] = n[1] = 0.0f, n[2] = -1.0f;
    } else {
        normalize3f(n);
        if (back) n[0] = -n[0], n[1] = -n[1], n[2] = -n[2];
    }

    float base[3];
    if (o->scalar) {
        float value = 0.0f;
        for (int k = 0; k < 3; k++)
            value += pw[k] * o->scalar[t[k]];
        float u = (value - fr->cmap_lo) * fr->cmap_scale * 255.0f;
        if (!(u > 0.0f)) u = 0.0f;
        if (u > 255.0f) u = 255.0f;
        int i = (int)u;
        if (i > 254) i = 254;
        float f = u - (float)i;
        for (int c = 0; c < 3; c++)
            base[c] = fr->cmap[i][c] + f * (fr->cmap[i + 1][c] - fr->cmap[i][c]);
    } else {
        memcpy(base, o->color, sizeof base);
    }
    if (back)
        for (int c = 0; c < 3; c++)
            base[c] *= fr->back_tint[c];

    float ndl = dot3f(n, fr->light);
    float lit = fr->ambient + fr->diffuse * (ndl > 0.0f ? ndl : 0.0f);
    float spec = 0.0f;
    if (ndl > 0.0f && fr->specular > 0.0f) {
        /* Towards the eye from the surface: minus the sample's view ray. */
        float view[3] = {-((float)sx + 0.5f - fr->cx), ((float)sy + 0.5f - fr->cy), -fr->focal};
        normalize3f(view);
        float h[3] = {view[0] + fr->light[0], view[1] + fr->light[1], view[2] + fr->light[2]};
        normalize3f(h);
        float ndh = dot3f(n, h);
        if (ndh > fr->spec_cut) spec = fr->specular * powf(ndh, fr->shininess);
    }
    /* Clamp per sample, so a blown-out highlight cannot bleed into the
     * neighbouring samples of its pixel through the box filter. */
    for (int c = 0; c < 3; c++) {
        float x = base[c] * lit + spec;
        out[c] = x < 1.0f ? x : 1.0f;
    }

    if (o->wire) {
        float a = fr->wire_half + 0.5f - edge_distance(v, l);
        if (a > 0.0f) {
            if (a > 1.0f) a = 1.0f;
            for (int c = 0; c < 3; c++)
                out[c] += a * (fr->wire_color[c] - out[c]);
        }
    }
}

static void draw_tile(const raster_frame *fr, int64_t tile, tile_buf *tb, cr_image *out) {
    int T = RASTER_TILE_PX * fr->ss;
    int tx = (int)(tile % fr->tiles_x), ty = (int)(tile / fr->tiles_x);
    tb->x0 = tx * T, tb->y0 = ty * T;
    tb->w = fr->sw - tb->x0 < T ? fr->sw - tb->x0 : T;
    tb->h = fr->sh - tb->y0 < T ? fr->sh - tb->y0 : T;
    for (int y = 0; y < tb->h; y++)
        for (int x = 0; x < tb->w; x++) {
            tb->iz[(size_t)y * T + x] = 0.0f;
            tb->id[(size_t)y * T + x] = -1;
        }
    for (int64_t i = fr->bin_start[tile]; i < fr->bin_start[tile + 1]; i++)
        scan_triangle(fr, fr->bin_tri[i], tb);

    /* Resolve: box filter over each pixel's ss x ss samples, in linear light. */
    float inv_n = 1.0f / (float)(fr->ss * fr->ss);
    for (int py = tb->y0 / fr->ss; py < (tb->y0 + tb->h) / fr->ss; py++)
        for (int px = tb->x0 / fr->ss; px < (tb->x0 + tb->w) / fr->ss; px++) {
            float sum[3] = {0.0f, 0.0f, 0.0f};
            for (int j = 0; j < fr->ss; j++)
                for (int i = 0; i < fr->ss; i++) {
                    int sx = px * fr->ss + i, sy = py * fr->ss + j;
                    size_t s = (size_t)(sy - tb->y0) * T + (size_t)(sx - tb->x0);
                    float c[3];
                    if (tb->id[s] < 0)
                        memcpy(c, fr->background, sizeof c);
                    else
                        shade_sample(fr, tb, s, sx, sy, c);
                    sum[0] += c[0], sum[1] += c[1], sum[2] += c[2];
                }
            uint8_t *dst = out->rgb + ((size_t)py * out->width + px) * 3;
            for (int c = 0; c < 3; c++) {
                float x = sum[c] * inv_n;
                x = x < 0.0f ? 0.0f : x > 1.0f ? 1.0f : x;
                dst[c] = fr->encode[(int)(x * 4095.0f + 0.5f)];
            }
        }
}

typedef struct draw_ctx {
    const raster_frame *fr;
    cr_image *out;
    int64_t ntiles, stride; /* tile order: i -> (i * stride) % ntiles */
    atomic_int failed;
} draw_ctx;

static void draw_range(void *ctx, int64_t begin, int64_t end) {
    draw_ctx *dc = ctx;
    int T = RASTER_TILE_PX * dc->fr->ss;
    size_t n = (size_t)T * T;
    /* One block per chunk of tiles (a few per thread per frame). */
    unsigned char *mem = malloc(n * (sizeof(float) * 3 + sizeof(int32_t)));
    if (!mem) {
        atomic_store(&dc->failed, 1);
        return;
    }
    tile_buf tb = {0};
    tb.stride = T;
    tb.iz = (float *)mem;
    tb.b1 = tb.iz + n;
    tb.b2 = tb.b1 + n;
    tb.id = (int32_t *)(tb.b2 + n);
    for (int64_t i = begin; i < end; i++)
        draw_tile(dc->fr, (i * dc->stride) % dc->ntiles, &tb, dc->out);
    free(mem);
}

static int64_t gcd64(int64_t a, int64_t b) {
    while (b) {
        int64_t t = a % b;
        a = b, b = t;
    }
    return a;
}

cr_status cr_raster_draw(const raster_frame *fr, cr_image *out, cr_error *err) {
    draw_ctx dc = {.fr = fr, .out = out};
    dc.ntiles = (int64_t)fr->tiles_x * fr->tiles_y;
    /* The parallel-for hands out contiguous index ranges; walking tiles with a
     * golden-ratio stride spreads the busy centre of the image over all of
     * them, which balances threads. */
    dc.stride = (int64_t)(0.618034 * (double)dc.ntiles) | 1;
    while (gcd64(dc.stride, dc.ntiles) != 1)
        dc.stride += 2;
    atomic_init(&dc.failed, 0);
    cr_parallel_for(dc.ntiles, 1, draw_range, &dc);
    if (atomic_load(&dc.failed))
        return CR_FAIL(err, CR_ERR_MEMORY, "render: out of memory for tile buffers (%d samples)",
                       RASTER_TILE_PX * fr->ss * RASTER_TILE_PX * fr->ss);
    return CR_OK;
}
