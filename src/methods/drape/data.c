/* data.c: the drape method's inputs: the scenes' objects (Table 4 of the paper), a
 * user's object, the rest cloth and its placement, and the mesh variants' elements and
 * rescaled weights.
 *
 * Objects have the sizes of the physics scenes (scene.h), so a drape is
 * comparable with `crease drape-static`, but a finer tessellation: eq. 26
 * reads the nearest object vertex and its normal, so vertex spacing bounds
 * how well the cloth can rest on the surface (Table 4: 25,000 to 41,000
 * object vertices). The prism is midpoint-subdivided (its primitive has six
 * vertices).
 *
 * A user's object or cloth with a vertex no face uses is refused (the bounds
 * size the cloth); one far from metre-sized is used with a warning.
 *
 * Leaves out: placing a user cloth (it is used where it is), UV islands
 * outside [0,1]^2.
 */
#include "drape_internal.h"

#include "crease/diffgeo.h"
#include "crease/mesh_io.h"
#include "crease/primitives.h"
#include "crease/scene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Object sizes, m: those of scene.h's sphere, torus, prism and box. */
#define BALL_RADIUS 0.3f
#define TORUS_MAJOR 0.3f
#define TORUS_MINOR 0.1f
#define PRISM_SIDE 0.4f
#define PRISM_LENGTH 0.8f
#define TABLE_EDGE 0.4f
enum { PRISM_SUBDIVISIONS = 6 /* 16,386 vertices, about 1 cm apart */ };

/* ----------------------------------------------------------- objects -- */

/* One 4-to-1 midpoint subdivision (flat faces stay flat); UVs dropped. */
static cr_status subdivide(cr_mesh **m, cr_error *err) {
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(*m, &t, err));
    cr_mesh *o = NULL;
    cr_status st = cr_mesh_create((*m)->nv + t->ne, 4 * (*m)->nf, 0, &o, err);
    if (st == CR_OK) {
        const cr_mesh *s = *m;
        memcpy(o->pos, s->pos, (size_t)s->nv * 3 * sizeof(float));
        for (int32_t e = 0; e < t->ne; e++)
            for (int c = 0; c < 3; c++)
                o->pos[3 * (int64_t)(s->nv + e) + c] =
                    0.5f * (s->pos[3 * (int64_t)t->edge[2 * e] + c] +
                            s->pos[3 * (int64_t)t->edge[2 * e + 1] + c]);
        for (int32_t f = 0; f < s->nf; f++) {
            const int32_t *v = &s->tri[3 * (int64_t)f];
            int32_t ab = s->nv + t->face_edge[3 * f], bc = s->nv + t->face_edge[3 * f + 1],
                    ca = s->nv + t->face_edge[3 * f + 2];
            const int32_t nt[12] = {v[0], ab, ca, ab, v[1], bc, ca, bc, v[2], ab, bc, ca};
            memcpy(&o->tri[12 * (int64_t)f], nt, sizeof nt);
        }
    }
    cr_topology_destroy(t);
    if (st != CR_OK) return st;
    cr_mesh_destroy(*m);
    *m = o;
    return CR_OK;
}

/* A vertex no face uses would still size and place the cloth (bounds).
 * open_edges (may be NULL) receives the mesh's boundary edges. */
static cr_status check_referenced(const cr_mesh *m, const char *flag, const char *path,
                                  int32_t *open_edges, cr_error *err) {
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    int32_t n = t->n_isolated_vertices, first = t->first_isolated_vertex;
    if (open_edges) *open_edges = t->n_boundary_edges;
    cr_topology_destroy(t);
    if (n > 0)
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "%s %s: vertex %d (counting from 1) is used by no face (%d unreferenced "
                       "vertices); remove them",
                       flag, path, first + 1, n);
    return CR_OK;
}

/* Drape reads metres and takes objects from millimetres of detail to rooms;
 * a mesh outside this size is more likely in another unit. */
#define UNIT_WARN_MIN_M 0.01f
#define UNIT_WARN_MAX_M 20.0f

static void warn_size(const cr_mesh *m, const char *flag, const char *path) {
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    float e = fmaxf(hi[0] - lo[0], fmaxf(hi[1] - lo[1], hi[2] - lo[2]));
    if (e > UNIT_WARN_MAX_M)
        cr_log(CR_LOG_WARN,
               "%s %s: %.4g m across, read as metres; if it is in centimetres it is %.3g m, in "
               "millimetres %.3g m: scale it by 0.01 or 0.001",
               flag, path, (double)e, 0.01 * e, 0.001 * e);
    else if (e < UNIT_WARN_MIN_M)
        cr_log(CR_LOG_WARN, "%s %s: only %.3g m across, read as metres; is it in another unit?",
               flag, path, (double)e);
}

/* A user's object; open_edges as check_referenced's. */
static cr_status read_object(const char *path, cr_mesh **out, int32_t *open_edges, cr_error *err) {
    if (!path) return CR_FAIL(err, CR_ERR_INVALID, "--object: no file given");
    CR_TRY(cr_mesh_read(path, out, err));
    cr_status st = (*out)->nf < 1 ? CR_FAIL(err, CR_ERR_TOPOLOGY,
                                            "--object %s: the mesh has no triangles", path)
                                  : check_referenced(*out, "--object", path, open_edges, err);
    if (st != CR_OK) {
        cr_mesh_destroy(*out);
        *out = NULL;
    }
    return st;
}

cr_status cr_drape_scene_object(cr_drape_scene scene, const char *path, cr_mesh **out,
                                cr_error *err) {
    *out = NULL;
    switch (scene) {
    case CR_DRAPE_BALL:
        return cr_prim_sphere_uv(BALL_RADIUS, 224, 112, out, err);
    case CR_DRAPE_TORUS:
        return cr_prim_torus(TORUS_MAJOR, TORUS_MINOR, 256, 96, out, err);
    case CR_DRAPE_TABLE:
        return cr_prim_box(TABLE_EDGE, TABLE_EDGE, TABLE_EDGE, 64, out, err);
    case CR_DRAPE_PRISM:
        CR_TRY(cr_prim_prism(PRISM_SIDE, PRISM_LENGTH, out, err));
        for (int i = 0; i < PRISM_SUBDIVISIONS; i++) {
            cr_status st = subdivide(out, err);
            if (st != CR_OK) {
                cr_mesh_destroy(*out);
                *out = NULL;
                return st;
            }
        }
        return CR_OK;
    case CR_DRAPE_OBJECT:
        return read_object(path, out, NULL, err);
    default:
        return CR_FAIL(err, CR_ERR_INVALID, "drape: scene %d out of range", (int)scene);
    }
}

/* ------------------------------------------------------------- scene -- */

static cr_status read_cloth(const char *path, cr_mesh **out, cr_error *err) {
    CR_TRY(cr_mesh_read(path, out, err));
    cr_mesh *m = *out;
    cr_status st = cr_mesh_validate(m, path, err);
    if (st == CR_OK) st = check_referenced(m, "--cloth", path, NULL, err);
    if (st == CR_OK && !cr_mesh_has_uv(m))
        st = CR_FAIL(err, CR_ERR_INVALID,
                     "--cloth %s: the cloth has no UVs (the method is defined over a UV chart)",
                     path);
    for (int32_t i = 0; st == CR_OK && i < 2 * m->nuv; i++)
        if (m->uv[i] < 0.0f || m->uv[i] > 1.0f)
            st = CR_FAIL(err, CR_ERR_INVALID, "--cloth %s: UV %d is (%g, %g), outside [0,1]^2",
                         path, i / 2, (double)m->uv[i - i % 2], (double)m->uv[i - i % 2 + 1]);
    if (st != CR_OK) {
        cr_mesh_destroy(m);
        *out = NULL;
    }
    return st;
}

/* Side of the built-in scenes' cloth, m, and the default's proportions. */
#define TABLE4_CLOTH_SIZE 1.0f
#define CLOTH_PER_EXTENT (5.0f / 3.0f)
#define DROP_PER_SIZE 0.05f

void cr_drape_cloth_placement(const cr_drape_def *def, const float lo[3], const float hi[3],
                              float *size, float *drop_height) {
    float s = def->cloth_size;
    if (s == 0.0f) {
        float extent = fmaxf(hi[0] - lo[0], hi[2] - lo[2]);
        s = def->scene != CR_DRAPE_OBJECT ? TABLE4_CLOTH_SIZE : CLOTH_PER_EXTENT * extent;
        if (!(s >= 1e-3f)) s = TABLE4_CLOTH_SIZE; /* a point or a vertical sheet: no extent */
    }
    *size = s;
    *drop_height = def->gap >= 0.0f ? def->gap : DROP_PER_SIZE * s;
}

cr_status cr_drape_scene_create(const cr_drape_def *def, drape_scene *s, cr_error *err) {
    memset(s, 0, sizeof *s);
    const int user = def->scene == CR_DRAPE_OBJECT;
    cr_status st = user ? read_object(def->object_path, &s->object, &s->open_edges, err)
                        : cr_drape_scene_object(def->scene, def->object_path, &s->object, err);
    if (st == CR_OK && user) {
        st = cr_mesh_validate(s->object, def->object_path, err);
        if (st == CR_OK) warn_size(s->object, "--object", def->object_path);
        if (st == CR_OK && s->open_edges > 0)
            cr_log(CR_LOG_WARN,
                   "--object %s is open (%d boundary edges): it has no inside, so the drape's "
                   "penetration depth is not measured",
                   def->object_path, s->open_edges);
    }
    if (st == CR_OK)
        st = cr_bvh_build(s->object->pos, s->object->nv, s->object->tri, s->object->nf, &s->bvh,
                          err);
    if (st == CR_OK && def->cloth_path) {
        st = read_cloth(def->cloth_path, &s->rest, err);
        if (st == CR_OK) warn_size(s->rest, "--cloth", def->cloth_path);
    } else if (st == CR_OK) {
        s->square = 1;
        float lo[3], hi[3];
        cr_mesh_bounds(s->object, lo, hi);
        cr_drape_cloth_placement(def, lo, hi, &s->cloth_size, &s->drop_height);
        st = cr_scene_cloth_above(s->object, def->mesh_res, s->cloth_size, s->drop_height, &s->rest,
                                  err);
    }
    if (st == CR_OK) s->metres_per_uv = cr_eval_chart_scale(s->rest);
    if (st != CR_OK) cr_drape_scene_free(s);
    return st;
}

void cr_drape_scene_free(drape_scene *s) {
    cr_bvh_destroy(s->bvh);
    cr_mesh_destroy(s->object);
    cr_mesh_destroy(s->rest);
    memset(s, 0, sizeof *s);
}

/* ------------------------------------------------------- mesh losses -- */

/* A smooth surface under isotropic stretch eps gives per structure 9 eps^2
 * strain, and per vertex of a grid of spacing d (three edges a vertex)
 * 3 eps^2. For bending, a chordal triangle's normal is the surface normal
 * at its circumcentre (exactly so for a sphere): the structure's face pairs
 * have circumcentres s/sqrt(3) apart (s the 3-D side), so a sphere of
 * curvature kappa gives kappa^2 s^2 per structure and a cylinder
 * kappa^2 s^2 / 2; the grid's right triangles share their circumcentre across
 * the diagonal and lie d apart across the other two edges, so per vertex a
 * sphere gives 2 kappa^2 d^2 and a cylinder along either axis kappa^2 d^2.
 * With gravity per vertex equal to gravity per structure, the mesh weights
 *     w_strain' = 3 w_strain,   w_bend' = w_bend s^2 / (2 d^2)
 * make both discretisations estimate the same energy per area (up to one
 * common factor, which Adam does not see). d^2 is the area per vertex. */
cr_status cr_drape_mesh_losses_create(const cr_drape_def *def, const drape_scene *s,
                                      drape_mesh_losses *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    const cr_mesh *m = s->rest;
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    out->ne = t->ne, out->nh = t->nh;
    out->edges = cr_malloc((size_t)t->ne * 2 * sizeof(int32_t) + 1, err);
    out->rest = cr_malloc((size_t)t->ne * sizeof(float) + 1, err);
    out->hinges = cr_malloc((size_t)t->nh * 4 * sizeof(int32_t) + 1, err);
    cr_status st = out->edges && out->rest && out->hinges ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) {
        memcpy(out->edges, t->edge, (size_t)t->ne * 2 * sizeof(int32_t));
        memcpy(out->hinges, t->hinge, (size_t)t->nh * 4 * sizeof(int32_t));
        for (int32_t e = 0; e < t->ne && st == CR_OK; e++) {
            const float *a = &m->pos[3 * (int64_t)t->edge[2 * e]],
                        *b = &m->pos[3 * (int64_t)t->edge[2 * e + 1]];
            double d2 = 0.0;
            for (int c = 0; c < 3; c++)
                d2 += ((double)a[c] - b[c]) * ((double)a[c] - b[c]);
            out->rest[e] = (float)sqrt(d2);
            if (!(out->rest[e] > 0.0f))
                st = CR_FAIL(err, CR_ERR_TOPOLOGY, "drape: cloth edge %d has zero length", e);
        }
    }
    if (st == CR_OK) {
        float *area = cr_malloc((size_t)m->nf * sizeof(float) + 1, err);
        if (!area) st = CR_ERR_MEMORY;
        double total = 0.0;
        if (st == CR_OK) {
            cr_mesh_face_normals(m, NULL, area);
            for (int32_t f = 0; f < m->nf; f++)
                total += area[f];
        }
        free(area);
        double d2 = total / m->nv, side = (double)def->side * s->metres_per_uv;
        out->w = def->w;
        out->w.strain = 3.0f * def->w.strain;
        out->w.bend = (float)(0.5 * def->w.bend * side * side / d2);
    }
    if (st == CR_OK) st = cr_drape_strain_create(out->ne, &out->strain, err);
    if (st == CR_OK)
        st = cr_drape_strain_set(out->strain, out->edges, out->rest, out->ne, m->nv, err);
    if (st == CR_OK) st = cr_drape_bend_create(out->nh, &out->bend, err);
    if (st == CR_OK) st = cr_drape_bend_set(out->bend, out->hinges, out->nh, m->nv, err);
    cr_topology_destroy(t);
    if (st != CR_OK) cr_drape_mesh_losses_free(out);
    return st;
}

void cr_drape_mesh_losses_free(drape_mesh_losses *ml) {
    free(ml->edges), free(ml->rest), free(ml->hinges);
    cr_drape_strain_destroy(ml->strain);
    cr_drape_bend_destroy(ml->bend);
    memset(ml, 0, sizeof *ml);
}
