/* dataset_run.c: the dataset's sequences (plan, resume, parallel simulation,
 * failures) and its manifest. See crease/dataset.h for the layout.
 *
 * A sequence's share of vertices inside the body is counted twice: on every
 * stored frame, by a signed-distance query of the garment against the posed
 * body of its own (what the dataset holds), and per substep before the
 * simulator projects vertices out (the report's `projected`: what the
 * solver let through, the projection's share of the work).
 *
 * Crossing (intersecting) triangle pairs of the garment with itself are
 * counted exactly on every stored frame (cr_bvh_self_intersections over a
 * BVH of the garment refitted to the frame), and on the garment as built
 * (dataset.c): a seam whose panels touch at rest counts there, so the two
 * are told apart.
 */
#include "dataset_internal.h"

#include "crease/base_mpi.h"
#include "crease/bvh.h"
#include "crease/scene.h"
#include "crease/topology.h"

#include <cjson/cJSON.h>
#include <glob.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

/* -------------------------------------------------------------- plan -- */

static void seq_dir(const dataset *ds, const dataset_seq *q, char *out, size_t size) {
    snprintf(out, size, "%s/sequences/%s", ds->def.out_dir, q->id);
}

/* 1 when sequences/<id>/result.json says done; its figures go into q. */
static int already_done(const dataset *ds, dataset_seq *q) {
    char path[CR_DATASET_PATH];
    seq_dir(ds, q, path, sizeof path);
    strncat(path, "/result.json", sizeof path - strlen(path) - 1);
    char *text = NULL;
    size_t len = 0;
    if (cr_file_read_all(path, &text, &len, NULL) != CR_OK) return 0;
    cJSON *j = cJSON_Parse(text);
    free(text);
    const cJSON *status = cJSON_GetObjectItemCaseSensitive(j, "status");
    int done = cJSON_IsString(status) && !strcmp(status->valuestring, "done");
    if (done) {
        const cJSON *share = cJSON_GetObjectItemCaseSensitive(j, "max_inside_share");
        const cJSON *pen = cJSON_GetObjectItemCaseSensitive(j, "max_penetration_m");
        const cJSON *frames = cJSON_GetObjectItemCaseSensitive(j, "frames");
        const cJSON *solver = cJSON_GetObjectItemCaseSensitive(j, "max_inside_share_solver");
        const cJSON *cross = cJSON_GetObjectItemCaseSensitive(j, "max_crossings");
        const cJSON *secs = cJSON_GetObjectItemCaseSensitive(j, "seconds");
        q->max_inside_share = cJSON_IsNumber(share) ? share->valuedouble : 0.0;
        q->max_inside_share_solver = cJSON_IsNumber(solver) ? solver->valuedouble : 0.0;
        q->max_penetration_m = cJSON_IsNumber(pen) ? pen->valuedouble : 0.0;
        q->frames_done = cJSON_IsNumber(frames) ? frames->valueint : 0;
        /* -1: a result.json from before crossings were counted */
        q->max_crossings = cJSON_IsNumber(cross) ? (int64_t)cross->valuedouble : -1;
        q->seconds = cJSON_IsNumber(secs) ? secs->valuedouble : 0.0;
    }
    cJSON_Delete(j);
    return done;
}

cr_status cr_dataset_plan(dataset *ds, cr_error *err) {
    const cr_dataset_def *d = &ds->def;
    int nsim = 0;
    for (int r = 0; r < d->nres; r++)
        nsim += !(d->mesh_only_res >> r & 1u);
    ds->nseq = d->ngarments * d->nmotions * d->nbodies * nsim;
    ds->seq = cr_calloc((size_t)(ds->nseq > 0 ? ds->nseq : 1), sizeof(dataset_seq), err);
    if (!ds->seq) return err ? err->status : CR_ERR_MEMORY;
    int k = 0;
    for (int b = 0; b < d->nbodies; b++)
        for (int g = 0; g < d->ngarments; g++)
            for (int r = 0; r < d->nres; r++)
                for (int m = 0; m < d->nmotions && !(d->mesh_only_res >> r & 1u); m++, k++) {
                    dataset_seq *q = &ds->seq[k];
                    q->b = b, q->g = g, q->r = r, q->m = m;
                    snprintf(q->id, sizeof q->id, "%s_%s_%s_%s", ds->variant[g].label, d->res[r],
                             ds->body_label[b], ds->motion_name[m]);
                    q->state = already_done(ds, q) ? SEQ_SKIPPED : SEQ_PENDING;
                }
    return CR_OK;
}

/* ---------------------------------------------------------- pinning -- */

/* The waistband of a skirt or trousers: the boundary loop highest on the
 * body (largest mean y). Returns its vertex count (0 for other types). */
static int32_t waist_loop(const cr_garment *g, int32_t **out, cr_error *err) {
    *out = NULL;
    if (g->type != CR_GARMENT_SKIRT && g->type != CR_GARMENT_TROUSERS) return 0;
    cr_topology *t = NULL;
    if (cr_topology_build(g->mesh, &t, err) != CR_OK) return -1;
    int best = -1;
    double best_y = -INFINITY;
    for (int32_t l = 0; l < t->nloop; l++) {
        double y = 0.0;
        for (int32_t k = t->loop_off[l]; k < t->loop_off[l + 1]; k++)
            y += g->mesh->pos[3 * t->loop_vert[k] + 1];
        y /= t->loop_off[l + 1] - t->loop_off[l];
        if (y > best_y) best_y = y, best = l;
    }
    int32_t n = best < 0 ? 0 : t->loop_off[best + 1] - t->loop_off[best];
    if (n > 0) {
        *out = cr_malloc((size_t)n * sizeof(int32_t), err);
        if (*out)
            memcpy(*out, t->loop_vert + t->loop_off[best], (size_t)n * sizeof(int32_t));
        else
            n = -1;
    }
    cr_topology_destroy(t);
    return n;
}

/* (T, n, 3) positions of garment vertices pins[] carried by the body through
 * the garment's own skinning weights, frame by frame. */
static float *pin_trajectory(const cr_garment *g, const cr_body_model *body, const cr_motion *mo,
                             const int32_t *pins, int32_t n, cr_error *err) {
    float *out = cr_malloc(sizeof(float) * 3 * (size_t)n * (size_t)mo->nframes, err);
    if (!out) return NULL;
    float xf[CR_NJOINTS * 12];
    for (int32_t f = 0; f < mo->nframes; f++) {
        cr_body_skin_transforms(body->joints, mo->poses + (size_t)f * CR_NJOINTS * 3,
                                mo->trans + 3 * (size_t)f, xf);
        for (int32_t i = 0; i < n; i++) {
            const float *x = g->mesh->pos + 3 * pins[i];
            double p[3] = {0, 0, 0};
            for (int s = 0; s < 4; s++) {
                float w = g->skin_weight[4 * pins[i] + s];
                const float *a = xf + 12 * g->skin_joint[4 * pins[i] + s];
                for (int k = 0; k < 3; k++)
                    p[k] += w * (a[4 * k] * x[0] + a[4 * k + 1] * x[1] + a[4 * k + 2] * x[2] +
                                 a[4 * k + 3]);
            }
            for (int k = 0; k < 3; k++)
                out[3 * ((size_t)n * f + i) + k] = (float)p[k];
        }
    }
    return out;
}

/* --------------------------------------------------------- sequences -- */

/* Print j (freed here) to path atomically. */
static cr_status write_json(const char *path, cJSON *j, cr_error *err) {
    char *text = cJSON_Print(j);
    cJSON_Delete(j);
    if (!text) return CR_FAIL(err, CR_ERR_MEMORY, "dataset: out of memory writing %s", path);
    cr_atomic_file f;
    cr_status st = cr_atomic_open(&f, path, err);
    if (st == CR_OK) {
        fputs(text, f.fp);
        fputc('\n', f.fp);
        st = cr_atomic_commit(&f, err);
    }
    free(text);
    return st;
}

static cr_status write_result(const dataset *ds, const dataset_seq *q, cr_error *err) {
    char path[CR_DATASET_PATH];
    seq_dir(ds, q, path, sizeof path);
    strncat(path, "/result.json", sizeof path - strlen(path) - 1);
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "status", q->state == SEQ_FAILED ? "failed" : "done");
    cJSON_AddNumberToObject(j, "frames", q->frames_done);
    cJSON_AddNumberToObject(j, "seconds", q->seconds);
    cJSON_AddNumberToObject(j, "max_inside_share", q->max_inside_share);
    cJSON_AddNumberToObject(j, "max_inside_share_solver", q->max_inside_share_solver);
    cJSON_AddNumberToObject(j, "max_penetration_m", q->max_penetration_m);
    cJSON_AddNumberToObject(j, "max_crossings", (double)q->max_crossings);
    cJSON_AddNumberToObject(j, "rest_crossings", (double)ds->rest_crossings[q->b][q->g][q->r]);
    if (q->state == SEQ_FAILED) cJSON_AddStringToObject(j, "failure", q->failure);
    return write_json(path, j, err);
}

/* Share of the simulator's vertices inside the body posed at `frame`
 * (held at the motion's last frame); the BVH is refitted to that pose.
 * xf (V,3) and dist (V) are scratch. */
static double inside_share(cr_bvh *bvh, const float *posed, int32_t nframes, int32_t frame,
                           const cr_sim *sim, float *xf, float *dist, cr_error *err) {
    int32_t nb = cr_bvh_vertex_count(bvh), nv = cr_sim_vertex_count(sim);
    int64_t f = frame < nframes ? frame : nframes - 1;
    if (cr_bvh_refit(bvh, posed + f * 3 * (int64_t)nb, err) != CR_OK) return NAN;
    const double *x = cr_sim_positions(sim);
    for (int64_t k = 0; k < 3 * (int64_t)nv; k++)
        xf[k] = (float)x[k];
    /* Beyond 5 cm a point counts as outside; no garment vertex is that deep. */
    cr_bvh_signed_distance_batch(bvh, xf, nv, 0.05f, dist, NULL, NULL);
    int32_t inside = 0;
    for (int32_t i = 0; i < nv; i++)
        inside += dist[i] < 0.0f;
    return (double)inside / nv;
}

int64_t cr_dataset_crossings(cr_bvh **bvh, const cr_mesh *m, const float *pos, cr_error *err) {
    cr_status st =
        *bvh ? cr_bvh_refit(*bvh, pos, err) : cr_bvh_build(pos, m->nv, m->tri, m->nf, bvh, err);
    if (st != CR_OK) return -1;
    int64_t n = cr_bvh_self_intersections(*bvh);
    if (n < 0) CR_FAIL(err, CR_ERR_MEMORY, "dataset: out of memory counting crossing triangles");
    return n;
}

/* Per stored frame: the share of vertices inside the body and the garment's
 * crossing triangle pairs, the largest of each so far. */
typedef struct inside_ctx {
    cr_bvh *bvh;
    const float *posed;
    int32_t nframes;
    float *xf, *dist;
    double max_share;
    const cr_mesh *garment;
    cr_bvh *cloth; /* over the garment, refitted to each frame */
    int64_t max_crossings;
} inside_ctx;

static cr_status count_inside(void *vctx, const cr_sim *sim, const cr_sim_report *rep,
                              const cr_scene_run_stats *so_far, cr_error *err) {
    (void)rep;
    inside_ctx *c = vctx;
    double share =
        inside_share(c->bvh, c->posed, c->nframes, so_far->frames, sim, c->xf, c->dist, err);
    if (isnan(share)) return err ? err->status : CR_ERR_MEMORY;
    c->max_share = fmax(c->max_share, share);
    /* inside_share left the frame's positions in xf */
    int64_t n = cr_dataset_crossings(&c->cloth, c->garment, c->xf, err);
    if (n < 0) return err ? err->status : CR_ERR_MEMORY;
    if (n > c->max_crossings) c->max_crossings = n;
    return CR_OK;
}

static cr_status simulate(const dataset *ds, dataset_seq *q, cr_error *err) {
    const cr_dataset_def *d = &ds->def;
    const cr_garment *g = ds->garment[q->b][q->g][q->r];
    const cr_body_model *body = ds->body[q->b];
    const cr_motion *mo = ds->motion[q->m];
    char dir[CR_DATASET_PATH], path[CR_DATASET_PATH + 32];
    seq_dir(ds, q, dir, sizeof dir);
    CR_TRY(cr_mkdir_p(dir, err));
    /* A run killed while writing one of this sequence's files left its
     * temporary (cr_atomic_open's <name>.tmp.<pid>): the rerun removes it. */
    snprintf(path, sizeof path, "%s/*.tmp.*", dir);
    glob_t stale;
    if (glob(path, 0, NULL, &stale) == 0)
        for (size_t i = 0; i < stale.gl_pathc; i++)
            remove(stale.gl_pathv[i]);
    globfree(&stale);
    cr_sim_def sd = cr_sim_default_def();
    CR_TRY(cr_material_preset(d->material, &sd.material, err));
    CR_TRY(cr_scene_twin_material(&d->twin, &sd.material, err));
    sd.dt = 1.0 / d->fps;
    sd.plasticity = d->plastic;
    sd.solver = (cr_sim_solver)d->solver;
    if (d->self_contact >= 0)
        sd.self_contact = d->self_contact;
    else if (ds->outfit[q->g].nparts)
        sd.self_contact = 1; /* an outfit's layers collide (dataset_outfit.c) */
    /* Newton finds the contact pairs once per substep, and a pair that closes
     * by more than the query radius (8 mm) within one is missed: a vest's
     * armhole fell 2 cm in one frame and passed through the t-shirt at one
     * substep (and the high one at two). */
    if (ds->outfit[q->g].nparts && sd.substeps < CR_DATASET_OUTFIT_SUBSTEPS)
        sd.substeps = CR_DATASET_OUTFIT_SUBSTEPS;
    if (d->self_thickness > 0.0f) sd.self_contact_thickness = d->self_thickness;
    sd.collider = body->rest;
    sd.collider_frames = ds->posed[q->b][q->m];
    sd.collider_nframes = mo->nframes;
    sd.max_collider_step = d->max_collider_step;
    int32_t *pins = NULL;
    int32_t npins = waist_loop(g, &pins, err);
    if (npins < 0) return err ? err->status : CR_ERR_MEMORY;
    float *pin_frames = NULL;
    cr_sim *sim = NULL;
    cr_scene_record *rec = NULL;
    cr_status st = CR_OK;
    if (npins > 0) {
        pin_frames = pin_trajectory(g, body, mo, pins, npins, err);
        if (!pin_frames) st = err ? err->status : CR_ERR_MEMORY;
        sd.pinned = pins, sd.npinned = npins;
        sd.pin_frames = pin_frames, sd.pin_nframes = mo->nframes;
    }
    cr_mesh *start = NULL; /* a twin's moved start */
    if (st == CR_OK && cr_scene_twin_is_set(&d->twin)) {
        st = cr_mesh_clone(g->mesh, &start, err);
        if (st == CR_OK) cr_mesh_transform(start, 1.0f, d->twin.offset);
    }
    if (st == CR_OK) st = cr_sim_create(&sd, start ? start : g->mesh, &sim, err);
    cr_mesh_destroy(start);
    cr_bvh *bvh = NULL;
    const int32_t nv = g->mesh->nv;
    float *xf = cr_malloc(sizeof(float) * 3 * (size_t)nv, err);
    float *dist = cr_malloc(sizeof(float) * (size_t)nv, err);
    if (st == CR_OK && (!xf || !dist)) st = err ? err->status : CR_ERR_MEMORY;
    if (st == CR_OK)
        st = cr_bvh_build(sd.collider_frames, body->rest->nv, body->rest->tri, body->rest->nf, &bvh,
                          err);
    snprintf(path, sizeof path, "%s/frames.jsonl", dir);
    if (st == CR_OK) st = cr_scene_record_create(path, sim, g->mesh, d->frames + 1, &rec, err);
    if (st == CR_OK) {
        inside_ctx ic = {bvh, sd.collider_frames, mo->nframes, xf, dist, 0.0, g->mesh, NULL, 0};
        cr_scene_run_stats run = {0};
        st = cr_scene_run(sim, d->frames, rec, count_inside, &ic, &run, err);
        cr_bvh_destroy(ic.cloth);
        q->max_inside_share = ic.max_share;
        q->max_crossings = ic.max_crossings;
        q->max_inside_share_solver = run.max_projected_share;
        q->max_penetration_m = run.max_penetration_m;
        q->frames_done = run.frames;
    }
    snprintf(path, sizeof path, "%s/garment.pc2", dir);
    if (st == CR_OK) st = cr_scene_record_write(rec, path, NULL, d->fps, err);
    cr_scene_record_destroy(rec);
    cr_sim_destroy(sim);
    cr_bvh_destroy(bvh);
    free(xf), free(dist);
    free(pins), free(pin_frames);
    return st;
}

typedef struct run_ctx {
    dataset *ds;
    int32_t *todo;
    cr_progress *bar;
    int64_t finished;
} run_ctx;

static void run_range(void *vctx, int64_t begin, int64_t end) {
    run_ctx *c = vctx;
    for (int64_t i = begin; i < end; i++) {
        dataset_seq *q = &c->ds->seq[c->todo[i]];
        cr_error err = {0};
        double t0 = cr_time_now();
        cr_status st = simulate(c->ds, q, &err);
        q->seconds = cr_time_now() - t0;
        q->state = st == CR_OK ? SEQ_DONE : SEQ_FAILED;
        if (st != CR_OK)
            snprintf(q->failure, sizeof q->failure, "%.199s",
                     err.msg[0] ? err.msg : cr_status_str(st));
        cr_error werr = {0};
        if (write_result(c->ds, q, &werr) != CR_OK && q->state == SEQ_DONE) {
            q->state = SEQ_FAILED;
            snprintf(q->failure, sizeof q->failure, "%.199s", werr.msg);
        }
#ifdef _OPENMP
#pragma omp critical
#endif
        {
            c->finished++;
            if (q->state == SEQ_FAILED)
                cr_log(CR_LOG_WARN, "dataset: %s failed: %s", q->id, q->failure);
            cr_progress_update(c->bar, c->finished, "%s %s", q->id,
                               q->state == SEQ_DONE ? "done" : "FAILED");
        }
    }
}

/* Under MPI the pending sequences are dealt in plan order, the k-th to rank
 * k mod N (every rank has made the same plan: the caller holds a barrier
 * between planning and running); afterwards rank 0 collects every
 * sequence's state from the rank that ran it. A sequence's bytes do not
 * depend on the rank or thread that simulates it. */
void cr_dataset_run_sequences(dataset *ds) {
    int32_t *todo = malloc(sizeof(int32_t) * (size_t)(ds->nseq > 0 ? ds->nseq : 1));
    if (!todo) {
        for (int i = 0; i < ds->nseq; i++)
            if (ds->seq[i].state == SEQ_PENDING) {
                ds->seq[i].state = SEQ_FAILED;
                snprintf(ds->seq[i].failure, sizeof ds->seq[i].failure, "out of memory");
            }
        return;
    }
    const int rank = cr_mpi_rank(), size = cr_mpi_size();
    int32_t n = 0, npending = 0;
    for (int i = 0; i < ds->nseq; i++)
        if (ds->seq[i].state == SEQ_PENDING && npending++ % size == rank) todo[n++] = i;
    /* Only rank 0 draws; under MPI its bar counts its own share, and says so. */
    char label[64];
    if (size > 1)
        snprintf(label, sizeof label, "sequences (rank 0's share, %d ranks)", size);
    else
        snprintf(label, sizeof label, "sequences");
    cr_progress bar;
    cr_progress_begin(&bar, label, n, ds->def.quiet || rank != 0);
    run_ctx c = {ds, todo, &bar, 0};
    cr_parallel_for(n, 1, run_range, &c);
    cr_progress_end(&bar);
    free(todo);
    if (size <= 1) return;
    /* Every rank's copy of the plan to rank 0, which keeps each sequence's
     * entry from the rank that ran it. */
    size_t bytes = sizeof(dataset_seq) * (size_t)ds->nseq;
    dataset_seq *all = rank == 0 ? malloc(bytes * (size_t)size) : NULL;
    cr_error err = {0};
    if ((rank == 0 && !all) || cr_mpi_gather(ds->seq, bytes, all, 0, &err) != CR_OK) {
        cr_log(CR_LOG_WARN, "dataset: collecting the ranks' results failed: %s",
               err.msg[0] ? err.msg : "out of memory");
        free(all);
        return;
    }
    if (rank == 0) {
        int k = 0;
        for (int i = 0; i < ds->nseq; i++) {
            if (ds->seq[i].state == SEQ_SKIPPED) continue;
            int owner = k++ % size;
            if (owner != 0) ds->seq[i] = all[(size_t)owner * (size_t)ds->nseq + (size_t)i];
        }
    }
    free(all);
}

/* ---------------------------------------------------------- manifest -- */

static cJSON *string_array(const char *const *items, int n) {
    cJSON *a = cJSON_CreateArray();
    for (int i = 0; i < n; i++)
        cJSON_AddItemToArray(a, cJSON_CreateString(items[i]));
    return a;
}

static void add_path(cJSON *o, const char *key, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void add_path(cJSON *o, const char *key, const char *fmt, ...) {
    char buf[CR_DATASET_PATH];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    cJSON_AddStringToObject(o, key, buf);
}

static cJSON *manifest(const dataset *ds) {
    const cr_dataset_def *d = &ds->def;
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "format", "crease-dataset");
    cJSON_AddNumberToObject(j, "version", 1);
    cJSON *def = cJSON_AddObjectToObject(j, "def");
    cJSON_AddItemToObject(def, "garments", string_array(d->garments, d->ngarments));
    cJSON_AddItemToObject(def, "motions", string_array(d->motions, d->nmotions));
    cJSON_AddItemToObject(def, "bodies", string_array(d->bodies, d->nbodies));
    cJSON_AddItemToObject(def, "res", string_array(d->res, d->nres));
    cJSON_AddNumberToObject(def, "low_vertices", d->low_vertices);
    cJSON_AddNumberToObject(def, "high_vertices", d->high_vertices);
    cJSON_AddNumberToObject(def, "frames", d->frames);
    cJSON_AddNumberToObject(def, "fps", d->fps);
    cJSON_AddStringToObject(def, "material", d->material);
    cJSON_AddBoolToObject(def, "plastic", d->plastic);
    cJSON_AddNumberToObject(def, "seed", (double)d->seed);
    if (d->mesh_only_res) cJSON_AddNumberToObject(def, "mesh_only_res", d->mesh_only_res);
    if (cr_scene_twin_is_set(&d->twin)) {
        cJSON *tw = cJSON_AddObjectToObject(def, "twin");
        cJSON *off = cJSON_AddArrayToObject(tw, "offset_m");
        char num[32]; /* the float as typed: 1e-4, not 9.99999974737875e-05 */
        for (int k = 0; k < 3; k++) {
            snprintf(num, sizeof num, "%.7g", (double)d->twin.offset[k]);
            cJSON_AddItemToArray(off, cJSON_CreateNumber(strtod(num, NULL)));
        }
        cJSON_AddNumberToObject(tw, "friction_delta", d->twin.friction_delta);
    }
    cJSON *bodies = cJSON_AddArrayToObject(j, "bodies");
    for (int b = 0; b < d->nbodies; b++) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", ds->body_label[b]);
        cJSON_AddStringToObject(o, "spec", d->bodies[b]);
        add_path(o, "rest", "bodies/%s/rest.obj", ds->body_label[b]);
        add_path(o, "skin", "bodies/%s/skin.npz", ds->body_label[b]);
        cJSON *mo = cJSON_AddObjectToObject(o, "motions");
        for (int m = 0; m < d->nmotions; m++)
            add_path(mo, ds->motion_name[m], "bodies/%s/%s.pc2", ds->body_label[b],
                     ds->motion_name[m]);
        cJSON_AddItemToArray(bodies, o);
    }
    cJSON *motions = cJSON_AddArrayToObject(j, "motions");
    for (int m = 0; m < d->nmotions; m++) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", ds->motion_name[m]);
        cJSON_AddStringToObject(o, "source", d->motions[m]);
        add_path(o, "path", "motions/%s.npz", ds->motion_name[m]);
        cJSON_AddNumberToObject(o, "frames", ds->motion[m]->nframes);
        cJSON_AddNumberToObject(o, "fps", ds->motion[m]->fps);
        const cr_motion_prepare_report *rep = &ds->motion_rep[m];
        cJSON_AddNumberToObject(o, "source_fps", rep->source_fps);
        cJSON_AddNumberToObject(o, "source_frames", rep->source_frames);
        cJSON_AddNumberToObject(o, "first_frame", rep->first_frame);
        cJSON_AddNumberToObject(o, "last_frame", rep->last_frame);
        cJSON_AddBoolToObject(o, "calibration_dropped", rep->calibration_dropped);
        cJSON_AddNumberToObject(o, "ease_in_frames", rep->ease_frames);
        cJSON_AddItemToArray(motions, o);
    }
    cJSON *garments = cJSON_AddArrayToObject(j, "garments");
    for (int b = 0; b < d->nbodies; b++)
        for (int g = 0; g < d->ngarments; g++)
            for (int r = 0; r < d->nres; r++) {
                const cr_garment *gm = ds->garment[b][g][r];
                const cr_garment_variant *v = &ds->built[b][g];
                const char *label = ds->variant[g].label;
                cJSON *o = cJSON_CreateObject();
                cJSON_AddStringToObject(o, "type", cr_garment_type_name(ds->garment_type[g]));
                cJSON_AddStringToObject(o, "variant", d->garments[g]);
                cJSON_AddStringToObject(o, "label", label);
                const char *bl = ds->body_label[b];
                cJSON_AddStringToObject(o, "body", bl);
                cJSON_AddStringToObject(o, "res", d->res[r]);
                add_path(o, "mesh", "garments/%s/%s_%s.obj", bl, label, d->res[r]);
                add_path(o, "skin", "garments/%s/%s_%s_skin.npz", bl, label, d->res[r]);
                if (d->nres == 2)
                    add_path(o, "high_from_low", "garments/%s/%s_high_from_low.npz", bl, label);
                if (ds->user_garment[g]) { /* a file: what regenerates it is the file */
                    cJSON_AddNumberToObject(o, "vertices", gm ? gm->mesh->nv : 0);
                    cJSON_AddNumberToObject(o, "faces", gm ? gm->mesh->nf : 0);
                    cJSON_AddNumberToObject(o, "uv_scale_m", gm ? gm->uv_scale_m : 0);
                    cJSON_AddNumberToObject(o, "rest_crossings",
                                            (double)ds->rest_crossings[b][g][r]);
                    cJSON_AddItemToArray(garments, o);
                    continue;
                }
                /* What regenerates it: the parameters and their exact spec. */
                cJSON *p = cJSON_AddObjectToObject(o, "params");
                for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
                    cJSON_AddNumberToObject(p, cr_garment_param_at(i)->key,
                                            cr_garment_param_get(&v->def, i));
                char spec[256];
                cr_garment_def_spec(&v->def, spec, sizeof spec);
                cJSON_AddStringToObject(o, "spec", spec);
                if (v->random) {
                    cJSON_AddNumberToObject(o, "seed", (double)v->seed);
                    cJSON_AddNumberToObject(o, "attempts", v->attempts);
                    if (v->rejected[0]) cJSON_AddStringToObject(o, "rejected", v->rejected);
                }
                const dataset_outfit *of = &ds->outfit[g];
                if (of->nparts) { /* its layers, innermost first, as the parts were built */
                    cJSON *ls = cJSON_AddArrayToObject(o, "layers");
                    for (int k = 0; k < of->nparts; k++) {
                        cJSON *lo = cJSON_CreateObject();
                        cJSON_AddStringToObject(lo, "label", of->part[k].label);
                        cr_garment_def_spec(&of->built[b][k].def, spec, sizeof spec);
                        cJSON_AddStringToObject(lo, "spec", spec);
                        cJSON_AddNumberToObject(lo, "moved_out_m", of->offset_m[b][r][k]);
                        cJSON_AddItemToArray(ls, lo);
                    }
                }
                cJSON_AddNumberToObject(o, "vertices", gm ? gm->mesh->nv : 0);
                cJSON_AddNumberToObject(o, "faces", gm ? gm->mesh->nf : 0);
                cJSON_AddNumberToObject(o, "uv_scale_m", gm ? gm->uv_scale_m : 0);
                cJSON_AddNumberToObject(o, "rest_crossings", (double)ds->rest_crossings[b][g][r]);
                cJSON_AddItemToArray(garments, o);
            }
    cJSON *seqs = cJSON_AddArrayToObject(j, "sequences");
    static const char *const state_name[] = {"pending", "done", "done", "failed"};
    for (int i = 0; i < ds->nseq; i++) {
        const dataset_seq *q = &ds->seq[i];
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "id", q->id);
        cJSON_AddStringToObject(o, "garment", ds->variant[q->g].label);
        cJSON_AddStringToObject(o, "res", d->res[q->r]);
        cJSON_AddStringToObject(o, "body", ds->body_label[q->b]);
        cJSON_AddStringToObject(o, "motion", ds->motion_name[q->m]);
        cJSON_AddStringToObject(o, "status", state_name[q->state]);
        add_path(o, "garment_pc2", "sequences/%s/garment.pc2", q->id);
        add_path(o, "body_pc2", "bodies/%s/%s.pc2", ds->body_label[q->b], ds->motion_name[q->m]);
        add_path(o, "log", "sequences/%s/frames.jsonl", q->id);
        cJSON_AddNumberToObject(o, "frames", q->frames_done);
        cJSON_AddNumberToObject(o, "max_inside_share", q->max_inside_share);
        cJSON_AddNumberToObject(o, "max_inside_share_solver", q->max_inside_share_solver);
        cJSON_AddNumberToObject(o, "max_crossings", (double)q->max_crossings);
        if (q->state == SEQ_FAILED) cJSON_AddStringToObject(o, "failure", q->failure);
        cJSON_AddItemToArray(seqs, o);
    }
    return j;
}

cr_status cr_dataset_write_manifest(const dataset *ds, cr_error *err) {
    char path[CR_DATASET_PATH];
    snprintf(path, sizeof path, "%s/manifest.json", ds->def.out_dir);
    return write_json(path, manifest(ds), err);
}
