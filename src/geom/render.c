/* render.c: scenes to pictures: options, checks, camera framing, images, turntables.
 *
 * A render goes: check the def and the objects (finite positions and
 * scalars, indices in range), compute area-weighted vertex normals once,
 * bound the scene, place the camera on a sphere around the bounding-box
 * centre at the distance where the bounding sphere just fits the field of
 * view (plus the margin), project every vertex, then let raster.c bin, scan,
 * shade and filter. A turntable keeps the normals and the bounds and only
 * moves the camera.
 *
 * Framing keeps the eye outside the bounding sphere, so every vertex lies in
 * front of the camera and inside the image: the rasteriser never needs to
 * clip. Image layout helpers (create, free, grid) live here too.
 *
 * Leaves out: orthographic cameras, user-placed cameras, text labels.
 */
#include "raster.h"

#include "base/vec3.h"
#include "crease/diffgeo.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RENDER_COOKIE 0x52454e44u /* "REND" */
#define DEG2RAD 0.017453292519943295
/* Global triangle ids are stored as 2 * id + back-face bit in an int32. */
#define MAX_TRIANGLES (1 << 30)

/* ----------------------------------------------------------------- image -- */

cr_status cr_image_create(int width, int height, cr_image *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    if (width < 1 || width > CR_IMAGE_MAX_SIDE || height < 1 || height > CR_IMAGE_MAX_SIDE)
        return CR_FAIL(err, CR_ERR_INVALID, "image: size %dx%d outside 1..%d", width, height,
                       CR_IMAGE_MAX_SIDE);
    out->rgb = cr_calloc((size_t)width * (size_t)height, 3, err);
    if (!out->rgb) return err ? err->status : CR_ERR_MEMORY;
    out->width = width, out->height = height;
    return CR_OK;
}

void cr_image_free(cr_image *img) {
    if (!img) return;
    free(img->rgb);
    memset(img, 0, sizeof *img);
}

static int in_unit(const float c[3]) {
    return c[0] >= 0.0f && c[0] <= 1.0f && c[1] >= 0.0f && c[1] <= 1.0f && c[2] >= 0.0f &&
           c[2] <= 1.0f;
}

cr_status cr_image_grid(const cr_image *imgs, int n, int cols, int gap_px, const float fill[3],
                        cr_image *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    if (n < 1 || !imgs) return CR_FAIL(err, CR_ERR_INVALID, "image grid: no images (n = %d)", n);
    if (gap_px < 0 || gap_px > CR_IMAGE_MAX_SIDE)
        return CR_FAIL(err, CR_ERR_INVALID, "image grid: gap %d px outside 0..%d", gap_px,
                       CR_IMAGE_MAX_SIDE);
    if (!in_unit(fill))
        return CR_FAIL(err, CR_ERR_INVALID, "image grid: fill colour outside [0,1]");
    int cw = 0, ch = 0;
    for (int i = 0; i < n; i++) {
        if (!imgs[i].rgb || imgs[i].width < 1 || imgs[i].height < 1)
            return CR_FAIL(err, CR_ERR_INVALID, "image grid: image %d is empty", i);
        if (imgs[i].width > cw) cw = imgs[i].width;
        if (imgs[i].height > ch) ch = imgs[i].height;
    }
    if (cols <= 0 || cols > n) cols = n;
    int rows = (n + cols - 1) / cols;
    int64_t w = (int64_t)cols * cw + (int64_t)(cols - 1) * gap_px;
    int64_t h = (int64_t)rows * ch + (int64_t)(rows - 1) * gap_px;
    if (w > CR_IMAGE_MAX_SIDE || h > CR_IMAGE_MAX_SIDE)
        return CR_FAIL(err, CR_ERR_INVALID, "image grid: result %lldx%lld exceeds %d", (long long)w,
                       (long long)h, CR_IMAGE_MAX_SIDE);
    CR_TRY(cr_image_create((int)w, (int)h, out, err));
    uint8_t fb[3];
    for (int c = 0; c < 3; c++)
        fb[c] = (uint8_t)lrintf(255.0f * fill[c]);
    for (size_t p = 0; p < (size_t)w * (size_t)h; p++)
        memcpy(out->rgb + 3 * p, fb, 3);
    for (int i = 0; i < n; i++) {
        const cr_image *im = &imgs[i];
        int x0 = (i % cols) * (cw + gap_px) + (cw - im->width) / 2;
        int y0 = (i / cols) * (ch + gap_px) + (ch - im->height) / 2;
        for (int y = 0; y < im->height; y++)
            memcpy(out->rgb + ((size_t)(y0 + y) * (size_t)w + (size_t)x0) * 3,
                   im->rgb + (size_t)y * im->width * 3, (size_t)im->width * 3);
    }
    return CR_OK;
}

/* ------------------------------------------------------------------- def -- */

cr_render_def cr_render_default_def(void) {
    cr_render_def d = {0};
    d.width = 1024, d.height = 1024;
    d.supersample = 2;
    d.background[0] = d.background[1] = d.background[2] = 1.0f;
    d.yaw_deg = 30.0f, d.pitch_deg = 20.0f;
    d.fov_deg = 35.0f;
    d.margin = 0.05f;
    /* Key light from the upper left, in front: the usual studio placement. */
    d.light_dir[0] = -0.4f, d.light_dir[1] = 0.6f, d.light_dir[2] = 0.7f;
    d.ambient = 0.25f, d.diffuse = 0.75f;
    d.specular = 0.25f, d.shininess = 32.0f;
    d.back_tint[0] = 0.70f, d.back_tint[1] = 0.78f, d.back_tint[2] = 0.92f;
    d.wireframe = 0;
    d.wire_color[0] = d.wire_color[1] = d.wire_color[2] = 0.08f;
    d.wire_width_px = 1.0f;
    d.colormap_auto = 1;
    d.colormap_min = 0.0f, d.colormap_max = 1.0f;
    d.cookie = RENDER_COOKIE;
    return d;
}

/* x in [lo, hi]; NaN fails. */
static int within(float x, float lo, float hi) {
    return x >= lo && x <= hi;
}

static cr_status check_def(const cr_render_def *d, cr_error *err) {
    CR_ASSERT(d && d->cookie == RENDER_COOKIE);
    if (d->width < 1 || d->width > CR_IMAGE_MAX_SIDE || d->height < 1 ||
        d->height > CR_IMAGE_MAX_SIDE)
        return CR_FAIL(err, CR_ERR_INVALID, "render def: size %dx%d outside 1..%d", d->width,
                       d->height, CR_IMAGE_MAX_SIDE);
    if (d->supersample < 1 || d->supersample > 8)
        return CR_FAIL(err, CR_ERR_INVALID, "render def: supersample %d outside 1..8",
                       d->supersample);
    if (!in_unit(d->background))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: background outside [0,1]");
    if (!isfinite(d->yaw_deg))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: yaw_deg is not finite");
    if (!(d->pitch_deg > -90.0f && d->pitch_deg < 90.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: pitch_deg %g outside (-90, 90)",
                       (double)d->pitch_deg);
    if (!(d->fov_deg > 0.0f && d->fov_deg < 170.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: fov_deg %g outside (0, 170)",
                       (double)d->fov_deg);
    if (!within(d->margin, 0.0f, 1e6f))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: margin %g must be finite and >= 0",
                       (double)d->margin);
    float l2 = d->light_dir[0] * d->light_dir[0] + d->light_dir[1] * d->light_dir[1] +
               d->light_dir[2] * d->light_dir[2];
    if (!(l2 > 0.0f) || !isfinite(l2))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: light_dir must be finite and non-zero");
    if (!within(d->ambient, 0.0f, 1e6f) || !within(d->diffuse, 0.0f, 1e6f) ||
        !within(d->specular, 0.0f, 1e6f))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "render def: ambient, diffuse and specular must be finite and >= 0");
    if (!within(d->shininess, 1.0f, 1e6f))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: shininess %g must be >= 1",
                       (double)d->shininess);
    if (!in_unit(d->back_tint))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: back_tint outside [0,1]");
    if (!in_unit(d->wire_color))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: wire_color outside [0,1]");
    if (!(d->wire_width_px > 0.0f && d->wire_width_px <= 1e4f))
        return CR_FAIL(err, CR_ERR_INVALID, "render def: wire_width_px %g must be in (0, 1e4]",
                       (double)d->wire_width_px);
    if (!d->colormap_auto && !(isfinite(d->colormap_min) && isfinite(d->colormap_max) &&
                               d->colormap_min < d->colormap_max))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "render def: fixed colour map range [%g, %g] needs finite min < max",
                       (double)d->colormap_min, (double)d->colormap_max);
    return CR_OK;
}

/* ----------------------------------------------------------------- scene -- */

/* What every frame of one scene shares. */
typedef struct scene {
    int nobj;
    const cr_render_object *src; /* (nobj) the caller's objects */
    raster_object *obj;          /* (nobj) */
    float *normal; /* (V,3) area-weighted unit vertex normals, all objects, world space */
    int64_t nv, nf;
    float center[3], radius; /* bounding sphere of the bounding box, m */
    float smin, smax;        /* scalar range over all objects; smin > smax when none */
} scene;

static void scene_free(scene *sc) {
    free(sc->obj);
    free(sc->normal);
    memset(sc, 0, sizeof *sc);
}

static cr_status scene_prepare(const cr_render_object *objs, int nobj, scene *sc, cr_error *err) {
    memset(sc, 0, sizeof *sc);
    if (nobj < 0) return CR_FAIL(err, CR_ERR_INVALID, "render: nobj %d is negative", nobj);
    if (nobj > 0 && !objs)
        return CR_FAIL(err, CR_ERR_INVALID, "render: objs is NULL with nobj %d", nobj);
    sc->smin = INFINITY, sc->smax = -INFINITY;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < nobj; i++) {
        const cr_render_object *o = &objs[i];
        if (!o->mesh) return CR_FAIL(err, CR_ERR_INVALID, "render object %d: mesh is NULL", i);
        char name[48];
        snprintf(name, sizeof name, "render object %d", i);
        CR_TRY(cr_mesh_validate(o->mesh, name, err));
        if (!in_unit(o->color))
            return CR_FAIL(err, CR_ERR_INVALID, "render object %d: colour outside [0,1]", i);
        for (int32_t v = 0; o->scalar && v < o->mesh->nv; v++) {
            float s = o->scalar[v];
            if (!isfinite(s))
                return CR_FAIL(err, CR_ERR_NAN,
                               "render object %d: scalar at vertex %d is not finite", i, v);
            if (s < sc->smin) sc->smin = s;
            if (s > sc->smax) sc->smax = s;
        }
        float a[3], b[3];
        cr_mesh_bounds(o->mesh, a, b);
        for (int k = 0; k < 3 && o->mesh->nv > 0; k++) {
            if (a[k] < lo[k]) lo[k] = a[k];
            if (b[k] > hi[k]) hi[k] = b[k];
        }
        sc->nv += o->mesh->nv;
        sc->nf += o->mesh->nf;
    }
    if (sc->nf >= MAX_TRIANGLES)
        return CR_FAIL(err, CR_ERR_RANGE, "render: %lld triangles, at most %d", (long long)sc->nf,
                       MAX_TRIANGLES - 1);
    double r2 = 0.0;
    for (int k = 0; k < 3; k++) {
        sc->center[k] = sc->nv > 0 ? 0.5f * (lo[k] + hi[k]) : 0.0f;
        double half = sc->nv > 0 ? 0.5 * ((double)hi[k] - lo[k]) : 0.0;
        r2 += half * half;
    }
    /* A scene of one point (or none) still needs a camera distance. */
    sc->radius = r2 > 0.0 ? (float)sqrt(r2) : 1.0f;

    sc->nobj = nobj, sc->src = objs;
    sc->obj = cr_calloc((size_t)(nobj > 0 ? nobj : 1), sizeof *sc->obj, err);
    sc->normal = cr_malloc((size_t)(sc->nv > 0 ? sc->nv : 1) * 3 * sizeof(float), err);
    if (!sc->obj || !sc->normal) {
        scene_free(sc);
        return err ? err->status : CR_ERR_MEMORY;
    }
    int64_t vbase = 0, fbase = 0;
    for (int i = 0; i < nobj; i++) {
        const cr_mesh *m = objs[i].mesh;
        raster_object *ro = &sc->obj[i];
        ro->tri = m->tri, ro->nf = m->nf;
        ro->vbase = vbase, ro->fbase = fbase;
        ro->scalar = objs[i].scalar;
        ro->wire = objs[i].wireframe != 0;
        for (int c = 0; c < 3; c++)
            ro->color[c] = cr_raster_srgb_to_linear(objs[i].color[c]);
        cr_mesh_vertex_normals(m, CR_NORMAL_AREA, sc->normal + 3 * vbase);
        vbase += m->nv, fbase += m->nf;
    }
    return CR_OK;
}

/* ---------------------------------------------------------------- camera -- */

typedef struct project_ctx {
    const float *pos;    /* (V,3) one object's positions, m */
    const float *normal; /* (V,3) its unit normals */
    raster_vert *out;    /* (V) */
    float eye[3], right[3], up[3], fwd[3];
    float focal, cx, cy; /* samples */
    float near;          /* m */
} project_ctx;

static void project_range(void *ctx, int64_t begin, int64_t end) {
    const project_ctx *pc = ctx;
    for (int64_t i = begin; i < end; i++) {
        const float *p = pc->pos + 3 * i, *n = pc->normal + 3 * i;
        float d[3] = {p[0] - pc->eye[0], p[1] - pc->eye[1], p[2] - pc->eye[2]};
        raster_vert *rv = &pc->out[i];
        rv->n[0] = dot3f(n, pc->right), rv->n[1] = dot3f(n, pc->up), rv->n[2] = dot3f(n, pc->fwd);
        float z = dot3f(d, pc->fwd);
        rv->x = rv->y = 0, rv->iz = 0.0f;
        if (!(z > pc->near)) continue;
        float sx = pc->cx + pc->focal * dot3f(d, pc->right) / z;
        float sy = pc->cy - pc->focal * dot3f(d, pc->up) / z;
        if (!(fabsf(sx) < RASTER_GUARD_SAMPLES) || !(fabsf(sy) < RASTER_GUARD_SAMPLES)) continue;
        rv->x = (int32_t)lrintf(sx * (float)(1 << RASTER_SUBPIXEL_BITS));
        rv->y = (int32_t)lrintf(sy * (float)(1 << RASTER_SUBPIXEL_BITS));
        rv->iz = 1.0f / z;
    }
}

static cr_status render_frame(const cr_render_def *def, const scene *sc, float yaw_deg,
                              cr_image *out, cr_error *err) {
    CR_TRY(cr_image_create(def->width, def->height, out, err));
    raster_frame fr;
    memset(&fr, 0, sizeof fr);
    fr.width = def->width, fr.height = def->height, fr.ss = def->supersample;
    fr.sw = fr.width * fr.ss, fr.sh = fr.height * fr.ss;
    fr.tiles_x = (fr.width + RASTER_TILE_PX - 1) / RASTER_TILE_PX;
    fr.tiles_y = (fr.height + RASTER_TILE_PX - 1) / RASTER_TILE_PX;
    fr.nobj = sc->nobj, fr.nf = sc->nf;

    /* Camera on a sphere around the centre, far enough that the bounding
     * sphere (grown by the margin) is tangent to the view cone of half-angle
     * fov/2 across the narrower image side. */
    double yaw = yaw_deg * DEG2RAD, pitch = def->pitch_deg * DEG2RAD;
    double half_fov = 0.5 * def->fov_deg * DEG2RAD;
    double reach = (double)sc->radius * (1.0 + def->margin);
    double dist = reach / sin(half_fov);
    float dir[3] = {(float)(sin(yaw) * cos(pitch)), (float)sin(pitch),
                    (float)(cos(yaw) * cos(pitch))};
    project_ctx pc;
    memset(&pc, 0, sizeof pc);
    for (int k = 0; k < 3; k++) {
        pc.eye[k] = sc->center[k] + (float)dist * dir[k];
        pc.fwd[k] = -dir[k];
    }
    const float world_up[3] = {0.0f, 1.0f, 0.0f};
    cross3f(pc.fwd, world_up, pc.right);
    normalize3f(pc.right);
    cross3f(pc.right, pc.fwd, pc.up);
    fr.focal = (float)(0.5 * (fr.sw < fr.sh ? fr.sw : fr.sh) / tan(half_fov));
    fr.cx = 0.5f * (float)fr.sw, fr.cy = 0.5f * (float)fr.sh;
    pc.focal = fr.focal, pc.cx = fr.cx, pc.cy = fr.cy;
    pc.near = (float)(1e-6 * dist);

    for (int c = 0; c < 3; c++) {
        fr.background[c] = cr_raster_srgb_to_linear(def->background[c]);
        fr.back_tint[c] = def->back_tint[c];
        fr.wire_color[c] = cr_raster_srgb_to_linear(def->wire_color[c]);
    }
    /* The user's light is (right, up, towards the viewer); ours looks forward. */
    fr.light[0] = def->light_dir[0], fr.light[1] = def->light_dir[1];
    fr.light[2] = -def->light_dir[2];
    normalize3f(fr.light);
    fr.ambient = def->ambient, fr.diffuse = def->diffuse;
    fr.specular = def->specular, fr.shininess = def->shininess;
    fr.spec_cut = expf(logf(1e-3f) / def->shininess);
    fr.wire_half = 0.5f * def->wire_width_px * (float)fr.ss;
    if (!def->colormap_auto) {
        fr.cmap_lo = def->colormap_min;
        fr.cmap_scale = 1.0f / (def->colormap_max - def->colormap_min);
    } else if (sc->smax > sc->smin) {
        fr.cmap_lo = sc->smin, fr.cmap_scale = 1.0f / (sc->smax - sc->smin);
    } else {
        /* One value everywhere: show the middle of the map. */
        fr.cmap_lo = sc->smin - 0.5f, fr.cmap_scale = 1.0f;
    }
    cr_raster_init_tables(&fr);

    /* A per-frame copy of the objects: the def may switch every wireframe on. */
    raster_object *obj = cr_malloc((size_t)(sc->nobj > 0 ? sc->nobj : 1) * sizeof *obj, err);
    raster_vert *vert = cr_malloc((size_t)(sc->nv > 0 ? sc->nv : 1) * sizeof *vert, err);
    cr_status st = (obj && vert) ? CR_OK : (err ? err->status : CR_ERR_MEMORY);
    if (st == CR_OK) {
        fr.obj = obj, fr.vert = vert;
        for (int i = 0; i < sc->nobj; i++) {
            obj[i] = sc->obj[i];
            obj[i].wire = obj[i].wire || def->wireframe;
            pc.pos = sc->src[i].mesh->pos;
            pc.normal = sc->normal + 3 * sc->obj[i].vbase;
            pc.out = vert + sc->obj[i].vbase;
            cr_parallel_for(sc->src[i].mesh->nv, 4096, project_range, &pc);
        }
        st = cr_raster_bin(&fr, err);
    }
    if (st == CR_OK) st = cr_raster_draw(&fr, out, err);
    cr_raster_free_bins(&fr);
    free(obj);
    free(vert);
    if (st != CR_OK) cr_image_free(out);
    return st;
}

/* ------------------------------------------------------------------ API -- */

cr_status cr_render_scene(const cr_render_def *def, const cr_render_object *objs, int nobj,
                          cr_image *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    CR_TRY(check_def(def, err));
    scene sc;
    CR_TRY(scene_prepare(objs, nobj, &sc, err));
    cr_status st = render_frame(def, &sc, def->yaw_deg, out, err);
    scene_free(&sc);
    return st;
}

cr_status cr_render_to_png(const cr_render_def *def, const cr_render_object *objs, int nobj,
                           const char *path, cr_error *err) {
    cr_image img;
    CR_TRY(cr_render_scene(def, objs, nobj, &img, err));
    cr_status st = cr_image_write_png(&img, path, err);
    cr_image_free(&img);
    return st;
}

/* The pattern must take exactly one int: one %d (flag 0, width allowed), any
 * number of %%, nothing else, so snprintf cannot read a missing argument. */
static cr_status check_pattern(const char *pattern, cr_error *err) {
    if (!pattern) return CR_FAIL(err, CR_ERR_INVALID, "turntable: path pattern is NULL");
    int ints = 0;
    for (const char *p = pattern; *p; p++) {
        if (*p != '%') continue;
        p++;
        if (*p == '%') continue;
        while (*p == '0')
            p++;
        while (*p >= '0' && *p <= '9')
            p++;
        if (*p != 'd')
            return CR_FAIL(err, CR_ERR_INVALID,
                           "turntable: path pattern \"%s\": only %%d (e.g. %%03d) and %%%% allowed",
                           pattern);
        ints++;
    }
    if (ints != 1)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "turntable: path pattern \"%s\" needs exactly one %%d, has %d", pattern,
                       ints);
    return CR_OK;
}

cr_status cr_render_turntable(const cr_render_def *def, const cr_render_object *objs, int nobj,
                              int nframes, const char *path_pattern, cr_error *err) {
    CR_TRY(check_def(def, err));
    if (nframes < 1 || nframes > 100000)
        return CR_FAIL(err, CR_ERR_INVALID, "turntable: %d frames outside 1..100000", nframes);
    CR_TRY(check_pattern(path_pattern, err));
    scene sc;
    CR_TRY(scene_prepare(objs, nobj, &sc, err));
    cr_status st = CR_OK;
    for (int k = 0; k < nframes && st == CR_OK; k++) {
        char path[1024];
        int len = snprintf(path, sizeof path, path_pattern, k);
        if (len < 0 || (size_t)len >= sizeof path) {
            st = CR_FAIL(err, CR_ERR_INVALID, "turntable: path for frame %d is too long", k);
            break;
        }
        cr_image img;
        float yaw = def->yaw_deg + 360.0f * (float)k / (float)nframes;
        st = render_frame(def, &sc, yaw, &img, err);
        if (st == CR_OK) st = cr_image_write_png(&img, path, err);
        cr_image_free(&img);
    }
    scene_free(&sc);
    return st;
}
