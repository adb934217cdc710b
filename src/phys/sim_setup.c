/* sim_setup.c: the simulator's creation (checks, energies, assembly pattern,
 * Cholesky analysis, collider BVH), accessors, state hash and state files.
 *
 * State file (little-endian, all fields native on x86-64 and arm64):
 *   offset  0  8 bytes   magic "CRSIMST1"
 *           8  u32 V, u32 H
 *          16  i64 frame
 *          24  f64 penetration left by the last substep, m (bounds the next
 *              collider query, so it is part of the integrator's state)
 *          32  u64 FNV-1a 64 of the payload
 *          40  payload: positions (V,3) f64 m, velocities (V,3) f64 m/s,
 *              rest angles (H) f64 rad
 * A simulator with the VBD solver writes magic "CRSIMST2" and appends the
 * last substep's acceleration (V,3) f64 m/s^2 (its next initial guess) to
 * the payload; either loads into either solver (an ST1 file gives
 * acceleration 0).
 * Doubles are stored bit for bit, which safetensors through the project's
 * float32 writer could not do; resuming from the file is therefore exactly
 * the run that never stopped.
 *
 * Left out: saving the def or the collider sequence (the caller rebuilds the
 * simulator from its inputs, then loads the state).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "phys/sim_internal.h"
#include "phys/vbd_internal.h"

static const char STATE_MAGIC[8] = {'C', 'R', 'S', 'I', 'M', 'S', 'T', '1'};
static const char STATE_MAGIC2[8] = {'C', 'R', 'S', 'I', 'M', 'S', 'T', '2'};
enum { STATE_HEADER = 40 };

void cr_sim_destroy(cr_sim *s) {
    if (!s) return;
    cr_cholesky_destroy(s->chol);
    cr_vbd_destroy(s->vbd);
    cr_vbd_coarse_destroy(s->vbd_coarse);
    cr_assembly_destroy(s->assembly);
    cr_friction_destroy(s->friction);
    cr_collision_destroy(s->collision);
    cr_self_contact_destroy(s->self);
    free(s->self_prev);
    cr_inertia_destroy(s->inertia);
    cr_gravity_destroy(s->gravity);
    cr_bending_destroy(s->bending);
    cr_membrane_destroy(s->membrane);
    cr_topology_destroy(s->topo);
    cr_bvh_destroy(s->bvh);
    free(s->pinned);
    free(s->pin_index);
    free(s->x), free(s->v), free(s->x_frame), free(s->v_frame), free(s->rest_frame);
    free(s->a_prev), free(s->a_frame);
    free(s->x_start), free(s->x_pred), free(s->grad), free(s->dx), free(s->xt), free(s->disp);
    free(s->theta), free(s->xf), free(s->dist), free(s->normal), free(s->smooth);
    free(s->qx), free(s->qlow), free(s->qsel), free(s->qdist), free(s->qnormal);
    free(s->collider_rest), free(s->cpos), free(s->cpos_prev);
    free(s);
}

#define CHECK_DEF(cond, ...)                                                                       \
    do {                                                                                           \
        if (!(cond)) return CR_FAIL(err, CR_ERR_INVALID, "simulator: " __VA_ARGS__);               \
    } while (0)

static cr_status check_def(const cr_sim_def *d, cr_error *err) {
    CHECK_DEF(isfinite(d->dt) && d->dt > 0.0, "dt must be a positive time, got %g s", d->dt);
    CHECK_DEF(d->substeps >= 1 && d->substeps <= 4096, "substeps must be 1..4096, got %d",
              d->substeps);
    CHECK_DEF(d->max_collider_step >= 0.0 && d->max_collider_step <= 1e3,
              "max_collider_step must be 0..1000 m, got %g", d->max_collider_step);
    CHECK_DEF(d->max_backoff >= 0 && d->max_backoff <= 12, "max_backoff must be 0..12, got %d",
              d->max_backoff);
    CHECK_DEF(d->newton_max_iterations >= 1 && d->static_max_iterations >= 1,
              "Newton iteration limits must be >= 1, got %d and %d", d->newton_max_iterations,
              d->static_max_iterations);
    CHECK_DEF(isfinite(d->newton_rtol) && d->newton_rtol >= 0.0 && d->newton_rtol < 1.0,
              "newton_rtol must be in [0, 1), got %g", d->newton_rtol);
    CHECK_DEF(isfinite(d->newton_tol) && d->newton_tol > 0.0 && isfinite(d->static_tol) &&
                  d->static_tol > 0.0,
              "tolerances must be positive, got newton_tol %g m/s, static_tol %g m", d->newton_tol,
              d->static_tol);
    CHECK_DEF(isfinite(d->static_max_step) && d->static_max_step > 0.0,
              "static_max_step must be positive, got %g m", d->static_max_step);
    CHECK_DEF(d->line_search_max >= 0 && d->line_search_max <= 60,
              "line_search_max must be 0..60, got %d", d->line_search_max);
    CHECK_DEF(d->armijo > 0.0 && d->armijo < 0.5, "armijo must be in (0, 0.5), got %g", d->armijo);
    CHECK_DEF(isfinite(d->gravity[0]) && isfinite(d->gravity[1]) && isfinite(d->gravity[2]),
              "gravity must be finite");
    CHECK_DEF(!d->membrane_rest_from_uv || (isfinite(d->uv_scale) && d->uv_scale > 0.0f),
              "uv_scale must be positive, got %g", (double)d->uv_scale);
    CHECK_DEF(isfinite(d->damping) && d->damping >= 0.0, "damping must be >= 0, got %g 1/s",
              d->damping);
    CHECK_DEF(isfinite(d->friction_eps) && d->friction_eps > 0.0,
              "friction_eps must be positive, got %g m", d->friction_eps);
    CHECK_DEF(isfinite(d->max_speed) && d->max_speed > 0.0 && isfinite(d->max_penetration) &&
                  d->max_penetration > 0.0,
              "max_speed and max_penetration must be positive, got %g m/s and %g m", d->max_speed,
              d->max_penetration);
    CHECK_DEF(d->plastic_rule == CR_PLASTIC_LINEAR || d->plastic_rule == CR_PLASTIC_SMOOTH,
              "unknown plastic rule %d", (int)d->plastic_rule);
    CHECK_DEF(d->npinned >= 0 && (d->npinned == 0 || d->pinned), "pinned: %d vertices, list %s",
              d->npinned, d->pinned ? "set" : "NULL");
    CHECK_DEF(!d->pin_frames || (d->npinned > 0 && d->pin_nframes >= 1),
              "pin_frames needs pinned vertices and pin_nframes >= 1 (got %d and %d)", d->npinned,
              d->pin_nframes);
    if (d->pin_frames)
        for (int64_t k = 0; k < 3 * (int64_t)d->npinned * d->pin_nframes; k++)
            CHECK_DEF(isfinite(d->pin_frames[k]),
                      "pin_frames: frame %lld has a non-finite coordinate",
                      (long long)(k / (3 * (int64_t)d->npinned)));
    CHECK_DEF(!d->collider_frames || (d->collider && d->collider_nframes >= 1),
              "collider_frames needs a collider mesh and collider_nframes >= 1 (got %d)",
              d->collider_nframes);
    CHECK_DEF(d->solver == CR_SIM_SOLVER_NEWTON || d->solver == CR_SIM_SOLVER_VBD,
              "unknown solver %d", (int)d->solver);
    CHECK_DEF(d->vbd_hessian_every >= 1, "vbd_hessian_every must be >= 1, got %d",
              d->vbd_hessian_every);
    CHECK_DEF(d->vbd_iterations >= 1, "vbd_iterations must be >= 1, got %d", d->vbd_iterations);
    CHECK_DEF(isfinite(d->vbd_tol) && d->vbd_tol >= 0.0,
              "vbd_tol must be >= 0 m/s (0: newton_tol's), got %g", d->vbd_tol);
    CHECK_DEF(isfinite(d->vbd_chebyshev) && d->vbd_chebyshev >= 0.0 && d->vbd_chebyshev < 1.0,
              "vbd_chebyshev must be in [0, 1), got %g", d->vbd_chebyshev);
    CHECK_DEF(!d->self_contact ||
                  (isfinite(d->self_contact_thickness) && d->self_contact_thickness > 0.0 &&
                   d->self_contact_thickness < 1.0),
              "self_contact_thickness must be in (0, 1) m, got %g", d->self_contact_thickness);
    CHECK_DEF(isfinite(d->vbd_collision_scale) && d->vbd_collision_scale >= 1.0,
              "vbd_collision_scale must be >= 1, got %g", d->vbd_collision_scale);
    CHECK_DEF(isfinite(d->vbd_requery_move) && d->vbd_requery_move >= 0.0,
              "vbd_requery_move must be >= 0, got %g", d->vbd_requery_move);
    CHECK_DEF(d->vbd_coarse_every >= 0, "vbd_coarse_every must be >= 0 (0: off), got %d",
              d->vbd_coarse_every);
    CHECK_DEF(d->vbd_coarse_refresh >= 1, "vbd_coarse_refresh must be >= 1, got %d",
              d->vbd_coarse_refresh);
    CHECK_DEF(d->vbd_coarse_rings >= 1 && d->vbd_coarse_rings <= 8,
              "vbd_coarse_rings must be in 1..8, got %d", d->vbd_coarse_rings);
    CHECK_DEF(isfinite(d->vbd_damping) && d->vbd_damping >= 0.0,
              "vbd_damping must be >= 0, got %g s", d->vbd_damping);
    return CR_OK;
}

static cr_status setup_collider(cr_sim *s, cr_error *err) {
    const cr_sim_def *d = &s->def;
    const cr_mesh *c = d->collider;
    CR_TRY(cr_mesh_validate(c, "collider", err));
    s->ncv = c->nv;
    size_t n3 = 3 * (size_t)c->nv;
    if (d->collider_frames)
        for (size_t k = 0; k < n3 * (size_t)d->collider_nframes; k++)
            if (!isfinite(d->collider_frames[k]))
                return CR_FAIL(err, CR_ERR_NAN,
                               "simulator: collider frame %zu has a non-finite coordinate", k / n3);
    s->collider_rest = cr_malloc(n3 * sizeof(float), err);
    s->cpos = cr_malloc(n3 * sizeof(float), err);
    s->cpos_prev = cr_malloc(n3 * sizeof(float), err);
    if (!s->collider_rest || !s->cpos || !s->cpos_prev) return err ? err->status : CR_ERR_MEMORY;
    memcpy(s->collider_rest, d->collider_frames ? d->collider_frames : c->pos, n3 * sizeof(float));
    CR_TRY(cr_bvh_build(s->collider_rest, c->nv, c->tri, c->nf, &s->bvh, err));
    CR_TRY(cr_collision_create(s->nv, &d->material, &s->collision, err));
    CR_TRY(cr_collision_set_edges(s->collision, s->topo->edge, s->topo->ne, err));
    if (d->material.friction > 0.0)
        CR_TRY(cr_friction_create(s->nv, &d->material, d->friction_eps, &s->friction, err));
    return CR_OK;
}

static cr_status allocate_buffers(cr_sim *s, cr_error *err) {
    size_t n3 = 3 * (size_t)s->nv, nh = (size_t)(s->nh > 0 ? s->nh : 1);
    double **vec3[] = {
        &s->x,    &s->v,  &s->x_frame, &s->v_frame, &s->x_start, &s->x_pred,
        &s->grad, &s->dx, &s->xt,      &s->disp,    &s->a_prev,  &s->a_frame,
    };
    for (size_t k = 0; k < sizeof vec3 / sizeof vec3[0]; k++)
        if (!(*vec3[k] = cr_calloc(n3, sizeof(double), err)))
            return err ? err->status : CR_ERR_MEMORY;
    s->rest_frame = cr_calloc(nh, sizeof(double), err);
    s->theta = cr_calloc(nh, sizeof(double), err);
    s->xf = cr_calloc(n3, sizeof(float), err);
    s->dist = cr_calloc((size_t)s->nv, sizeof(float), err);
    s->normal = cr_calloc(n3, sizeof(float), err);
    s->smooth = cr_calloc(n3, sizeof(float), err);
    s->pinned = cr_calloc((size_t)s->nv, 1, err);
    if (!s->rest_frame || !s->theta || !s->xf || !s->dist || !s->normal || !s->smooth || !s->pinned)
        return err ? err->status : CR_ERR_MEMORY;
    s->qx = cr_calloc(n3, sizeof(double), err);
    s->qlow = cr_calloc((size_t)s->nv, sizeof(double), err);
    s->qsel = cr_calloc((size_t)s->nv, sizeof(int32_t), err);
    s->qdist = cr_calloc((size_t)s->nv, sizeof(float), err);
    s->qnormal = cr_calloc(n3, sizeof(float), err);
    if (!s->qx || !s->qlow || !s->qsel || !s->qdist || !s->qnormal)
        return err ? err->status : CR_ERR_MEMORY;
    return CR_OK;
}

static void add_term(cr_sim *s, cr_energy_term t) {
    CR_ASSERT(s->nterms < CR_SIM_MAX_TERMS);
    s->terms[s->nterms++] = t;
}

static cr_status setup(cr_sim *s, const cr_mesh *garment, cr_error *err) {
    const cr_sim_def *d = &s->def;
    const cr_material *mat = &d->material;
    CR_TRY(cr_topology_build(garment, &s->topo, err));
    CR_TRY(cr_topology_require_manifold(s->topo, "garment", err));
    CR_TRY(
        cr_membrane_create(garment, d->membrane_rest_from_uv, d->uv_scale, mat, &s->membrane, err));
    CR_TRY(cr_bending_create(garment, s->topo, mat, d->bending_rest_from_mesh, &s->bending, err));
    cr_bending_set_hessian(s->bending, d->bending_hessian);
    CR_TRY(cr_gravity_create(garment, mat, d->gravity, &s->gravity, err));
    s->mass = cr_gravity_masses(s->gravity);
    CR_TRY(cr_inertia_create(s->mass, s->nv, &s->inertia, err));
    s->nh = cr_bending_count(s->bending);
    s->rest = cr_bending_rest_angles(s->bending);
    CR_TRY(allocate_buffers(s, err));
    for (int32_t i = 0; i < d->npinned; i++) {
        if (d->pinned[i] < 0 || d->pinned[i] >= s->nv)
            return CR_FAIL(err, CR_ERR_RANGE, "simulator: pinned[%d] = %d is not a vertex (V = %d)",
                           i, d->pinned[i], s->nv);
        s->pinned[d->pinned[i]] = 1;
    }
    if (d->pin_frames) {
        s->pin_index = cr_malloc((size_t)d->npinned * sizeof(int32_t), err);
        if (!s->pin_index) return err ? err->status : CR_ERR_MEMORY;
        memcpy(s->pin_index, d->pinned, (size_t)d->npinned * sizeof(int32_t));
        s->npin = d->npinned;
    }
    for (int64_t k = 0; k < 3 * (int64_t)s->nv; k++)
        s->x[k] = garment->pos[k];
    if (d->collider) CR_TRY(setup_collider(s, err));

    cr_energy_term t;
    s->t_inertia = s->nterms;
    cr_inertia_term(s->inertia, &t), add_term(s, t);
    s->drag = (sim_drag){0.0, s->mass, s->x_start};
    s->t_drag = s->nterms;
    cr_sim_drag_term(&s->drag, s->nv, &t), add_term(s, t);
    cr_gravity_term(s->gravity, &t), add_term(s, t);
    cr_membrane_term(s->membrane, &t), add_term(s, t);
    cr_bending_term(s->bending, &t), add_term(s, t);
    if (s->collision) cr_collision_term(s->collision, &t), add_term(s, t);
    s->t_friction = s->friction ? s->nterms : -1;
    if (s->friction) cr_friction_term(s->friction, &t), add_term(s, t);
    s->t_self = -1;
    if (d->self_contact) {
        /* No pairs until the first substep finds them (sim.c). */
        CR_TRY(cr_self_contact_create(garment, s->topo, d->self_contact_thickness,
                                      mat->collision_stiffness, &s->self, err));
        s->t_self = s->nterms;
        cr_self_contact_term(s->self, &t), add_term(s, t);
    }
    CR_TRY(cr_assembly_create(s->terms, s->nterms, s->nv, &s->assembly, err));
    s->assembly_builds++;
    /* VBD's simulator analyses the Cholesky pattern only when a static solve
     * first needs it (sim.c). */
    if (d->solver == CR_SIM_SOLVER_VBD) {
        CR_TRY(cr_vbd_create(s, &s->vbd, err));
        if (d->vbd_coarse_every > 0)
            CR_TRY(cr_vbd_coarse_create(s, d->vbd_coarse_rings, &s->vbd_coarse, err));
    } else {
        CR_TRY(cr_cholesky_create(cr_assembly_hessian(s->assembly), s->pinned, &s->chol, err));
    }

    if (s->bvh) {
        /* Unbounded once, so a garment that starts inside the collider is seen. */
        for (int64_t k = 0; k < 3 * (int64_t)s->nv; k++)
            s->xf[k] = (float)s->x[k];
        cr_bvh_signed_distance_batch(s->bvh, s->xf, s->nv, INFINITY, s->dist, s->normal, NULL);
        for (int32_t i = 0; i < s->nv; i++)
            if (-(double)s->dist[i] > s->pen_start) s->pen_start = -(double)s->dist[i];
        if (s->pen_start > mat->collision_thickness)
            cr_log(CR_LOG_WARN, "simulator: the garment starts %.3g m inside the collider",
                   s->pen_start);
    }
    return CR_OK;
}

cr_status cr_sim_create(const cr_sim_def *def, const cr_mesh *garment, cr_sim **out,
                        cr_error *err) {
    *out = NULL;
    CR_ASSERT(def && def->cookie == CR_SIM_DEF_COOKIE); /* made by cr_sim_default_def */
    CR_TRY(check_def(def, err));
    CR_TRY(cr_material_validate(&def->material, err));
    CR_TRY(cr_mesh_validate(garment, "garment", err));
    cr_sim *s = cr_calloc(1, sizeof(cr_sim), err);
    if (!s) return err ? err->status : CR_ERR_MEMORY;
    s->def = *def;
    s->def.pinned = def->pinned, s->def.npinned = def->npinned, s->def.collider = def->collider;
    s->nv = garment->nv;
    s->rep = &s->scratch_report;
    cr_status st = setup(s, garment, err);
    s->def.pinned = NULL, s->def.npinned = 0, s->def.collider = NULL; /* borrowed only here */
    if (st != CR_OK) {
        cr_sim_destroy(s);
        return st;
    }
    *out = s;
    return CR_OK;
}

/* ----------------------------------------------------------- accessors -- */

int32_t cr_sim_vertex_count(const cr_sim *s) {
    return s->nv;
}
int32_t cr_sim_hinge_count(const cr_sim *s) {
    return s->nh;
}
int64_t cr_sim_frame(const cr_sim *s) {
    return s->frame;
}
const double *cr_sim_positions(const cr_sim *s) {
    return s->x;
}
const double *cr_sim_velocities(const cr_sim *s) {
    return s->v;
}
const double *cr_sim_rest_angles(const cr_sim *s) {
    return s->rest;
}
const double *cr_sim_masses(const cr_sim *s) {
    return s->mass;
}

void cr_sim_positions_f(const cr_sim *s, float *out) {
    for (int64_t k = 0; k < 3 * (int64_t)s->nv; k++)
        out[k] = (float)s->x[k];
}

/* ---------------------------------------------------------------- state -- */

static uint64_t fnv1a(uint64_t h, const void *data, size_t n) {
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}
#define FNV_OFFSET 14695981039346656037ull

static uint64_t payload_hash(const cr_sim *s) {
    size_t n3 = 3 * (size_t)s->nv * sizeof(double);
    uint64_t h = fnv1a(FNV_OFFSET, s->x, n3);
    h = fnv1a(h, s->v, n3);
    return fnv1a(h, s->rest, (size_t)s->nh * sizeof(double));
}

static int state_v2(const cr_sim *s) {
    return s->def.solver == CR_SIM_SOLVER_VBD;
}

uint64_t cr_sim_state_hash(const cr_sim *s) {
    uint64_t h = payload_hash(s);
    return fnv1a(h, &s->frame, sizeof s->frame);
}

cr_status cr_sim_state_save(const cr_sim *s, const char *path, cr_error *err) {
    unsigned char head[STATE_HEADER];
    uint32_t counts[2] = {(uint32_t)s->nv, (uint32_t)s->nh};
    uint64_t hash = payload_hash(s);
    if (state_v2(s)) hash = fnv1a(hash, s->a_prev, 3 * (size_t)s->nv * sizeof(double));
    memcpy(head, state_v2(s) ? STATE_MAGIC2 : STATE_MAGIC, 8);
    memcpy(head + 8, counts, 8);
    memcpy(head + 16, &s->frame, 8);
    memcpy(head + 24, &s->pen_start, 8);
    memcpy(head + 32, &hash, 8);
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    size_t n3 = 3 * (size_t)s->nv;
    int ok = fwrite(head, 1, STATE_HEADER, f.fp) == STATE_HEADER &&
             fwrite(s->x, sizeof(double), n3, f.fp) == n3 &&
             fwrite(s->v, sizeof(double), n3, f.fp) == n3 &&
             fwrite(s->rest, sizeof(double), (size_t)s->nh, f.fp) == (size_t)s->nh &&
             (!state_v2(s) || fwrite(s->a_prev, sizeof(double), n3, f.fp) == n3);
    if (!ok) {
        cr_atomic_abort(&f);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
    }
    return cr_atomic_commit(&f, err);
}

cr_status cr_sim_state_load(cr_sim *s, const char *path, cr_error *err) {
    char *buf = NULL;
    size_t len = 0;
    CR_TRY(cr_file_read_all(path, &buf, &len, err));
    cr_status st = CR_OK;
    uint32_t counts[2];
    int64_t frame;
    double pen;
    uint64_t hash;
    size_t n3 = 3 * (size_t)s->nv;
    int v2 = len >= STATE_HEADER && memcmp(buf, STATE_MAGIC2, 8) == 0;
    if (len < STATE_HEADER || (!v2 && memcmp(buf, STATE_MAGIC, 8) != 0)) {
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: not a crease simulator state (bad magic or size)",
                     path);
        goto done;
    }
    memcpy(counts, buf + 8, 8);
    memcpy(&frame, buf + 16, 8);
    memcpy(&pen, buf + 24, 8);
    memcpy(&hash, buf + 32, 8);
    if (counts[0] != (uint32_t)s->nv || counts[1] != (uint32_t)s->nh) {
        st = CR_FAIL(err, CR_ERR_SHAPE,
                     "%s: state of %u vertices and %u hinges, simulator has %d and %d", path,
                     counts[0], counts[1], s->nv, s->nh);
        goto done;
    }
    size_t nd = 2 * n3 + (size_t)s->nh + (v2 ? n3 : 0); /* payload doubles */
    size_t want = STATE_HEADER + nd * sizeof(double);
    if (len != want || frame < 0 || !(pen >= 0.0 && pen < INFINITY)) {
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: %zu bytes, expected %zu (frame %lld, penetration %g)",
                     path, len, want, (long long)frame, pen);
        goto done;
    }
    const char *p = buf + STATE_HEADER;
    uint64_t h = fnv1a(FNV_OFFSET, p, nd * sizeof(double));
    if (h != hash) {
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: checksum mismatch (damaged file)", path);
        goto done;
    }
    /* Refuse non-finite numbers before touching the state. */
    for (size_t k = 0; k < nd; k++) {
        double v;
        memcpy(&v, p + k * sizeof(double), sizeof v);
        if (!isfinite(v)) {
            st = CR_FAIL(err, CR_ERR_NAN, "%s: non-finite value at payload entry %zu", path, k);
            goto done;
        }
    }
    memcpy(s->x, p, n3 * sizeof(double));
    memcpy(s->v, p + n3 * sizeof(double), n3 * sizeof(double));
    memcpy(s->rest, p + 2 * n3 * sizeof(double), (size_t)s->nh * sizeof(double));
    if (v2)
        memcpy(s->a_prev, p + (2 * n3 + (size_t)s->nh) * sizeof(double), n3 * sizeof(double));
    else
        memset(s->a_prev, 0, n3 * sizeof(double));
    s->frame = frame;
    s->pen_start = pen;
done:
    free(buf);
    return st;
}
