/* bench_runtime.c: garments at game speed (issue 51): each method's runtime
 * stepped frame by frame, next to the reference simulators on the same
 * garment and motion, in one run.
 *
 * Cases: swingar at each named size on the default dress at 10,000 target
 * vertices on the normal mannequin; epnet (the proxy inference: E-Net twice
 * and P-Net a frame) on a t-shirt at `epnet_vertices`. Weights are untrained
 * (the cost does not depend on them). Each steps `frames` frames of the walk
 * clip one at a time (cr_*_runtime_step); with batch > 1, swingar also steps
 * `batch` characters (runtimes sharing one model) a frame each in one
 * cr_swingar_runtime_step_batch call. Then Newton and VBD at their defaults
 * (cotton, 30 fps) simulate `sim_frames` frames of the same walk on each
 * case's garment, from rest.
 *
 * gdsr: a t-shirt template instantiated at `gdsr_vertices` HIGH (the output)
 * and LOW (the input; default HIGH / 8, docs/gdsr.md's speed runs), an
 * untrained model at each named size (default, paper). Newton simulates the
 * low garment over the walk (timed: the low simulation), then the runtime
 * steps its frames with the posed body, the handling on (`gdsr run`'s),
 * timed from the third frame (the first two have no history and are only
 * upsampled). Then Newton and VBD simulate `sim_frames` frames of both
 * resolutions, and each "low simulation + gdsr" is set against the same
 * solver's high simulation.
 *
 * Printed per case: frames per second, the GEMM work of a frame (2MNK of
 * every product, cr_nn_gemm_flops: element-wise passes are not counted), the
 * GFLOP/s that makes, its share of the machine's cblas_sgemm rate measured
 * at the start of the same run (1024^3, best of 5), the time to create the
 * runtime (the garment's encoding and the arena's trial frames), the arena
 * and the process's peak resident memory so far (the runs go from small to
 * large). The CPU kernel that ran is in the first line (OpenBLAS's core and
 * the engine's SIMD level).
 *
 *   bench_runtime [frames] [sizes] [epnet_vertices] [sim_frames] [batch]
 *                 [gdsr_vertices] [gdsr_sizes]
 *   defaults: 30 frames, sizes tiny,paper (a comma list of tiny, cpu, paper;
 *   "none" skips swingar), 2000 epnet vertices (0 skips epnet), 4 simulated
 *   frames (0 skips the simulators), batch 1, gdsr at 10000/1250 vertices
 *   (0 skips gdsr), gdsr sizes default (a comma list of default, paper).
 */
#include "crease/body.h"
#include "crease/epnet.h"
#include "crease/garment.h"
#include "crease/gdsr.h"
#include "crease/motion.h"
#include "crease/nn.h"
#include "crease/scene.h"
#include "crease/swingar.h"

#include <cblas.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

enum { MAX_BATCH = 16 };

static int fail(const char *what, const cr_error *e) {
    fprintf(stderr, "bench_runtime: %s: %s\n", what, e->msg);
    return 1;
}

static double maxrss_gib(void) {
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_maxrss / (1024.0 * 1024.0); /* kB on Linux */
}

/* cblas_sgemm's rate on 1024^3 with the run's threads, GFLOP/s, best of 5. */
static double sgemm_rate(void) {
    const int n = 1024;
    float *a = malloc(sizeof(float) * n * n), *b = malloc(sizeof(float) * n * n),
          *c = malloc(sizeof(float) * n * n);
    if (!a || !b || !c) return 0;
    for (int i = 0; i < n * n; i++)
        a[i] = (float)(i % 7) * 0.1f, b[i] = (float)(i % 5) * 0.1f;
    double best = 1e30;
    for (int r = 0; r < 6; r++) { /* the first warms up */
        double t0 = cr_time_now();
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, n, n, n, 1.0f, a, n, b, n, 0.0f, c,
                    n);
        double s = cr_time_now() - t0;
        if (r > 0 && s < best) best = s;
    }
    free(a), free(b), free(c);
    return 2.0 * n * n * (double)n / best * 1e-9;
}

/* The engine's own matrix product (cr_nn_matmul, gradient off: the kernel
 * the runtimes run) on 1024^3, GFLOP/s, best of 5. */
static double engine_rate(void) {
    const int64_t n = 1024;
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = (size_t)64 << 20;
    cr_nn_ctx *ctx = NULL;
    cr_error err = {0};
    if (cr_nn_ctx_create(&cd, &ctx, &err) != CR_OK) return 0;
    cr_nn_ctx_set_grad_enabled(ctx, 0);
    double best = 1e30;
    for (int r = 0; r < 6; r++) {
        cr_nn_ctx_reset(ctx);
        cr_tensor *a = cr_nn_full(ctx, 2, (int64_t[]){n, n}, 0.1f);
        cr_tensor *b = cr_nn_full(ctx, 2, (int64_t[]){n, n}, 0.2f);
        double t0 = cr_time_now();
        cr_tensor *c = cr_nn_matmul(ctx, a, b, 0, 0);
        double s = cr_time_now() - t0;
        if (c && r > 0 && s < best) best = s;
    }
    cr_nn_ctx_destroy(ctx);
    return 2.0 * n * n * (double)n / best * 1e-9;
}

/* One case's line: fps, GEMM work, rate and share of the sgemm rate. */
static void report(const char *what, int64_t V, int frames, double seconds, uint64_t flops,
                   double create_s, double arena_gib, double peak_sgemm) {
    const double per = (double)flops / frames * 1e-9, rate = (double)flops / seconds * 1e-9;
    printf("%s V=%lld: %.2f fps (%d frames, %.3f s); GEMM %.4f GFLOP/frame, %.2f GFLOP/s = "
           "%.1f %% of the GEMM rate; create %.2f s; arena %.3f GiB; peak RSS %.2f GiB\n",
           what, (long long)V, frames / seconds, frames, seconds, per, rate,
           100.0 * rate / peak_sgemm, create_s, arena_gib, maxrss_gib());
    fflush(stdout);
}

static int bench_swingar(const char *size, const cr_garment *g, const cr_body_model *body,
                         const float *desc, const cr_motion *mo, int frames, int B,
                         double peak_sgemm) {
    cr_error err = {0};
    cr_swingar_def d = cr_swingar_default_def();
    if (cr_swingar_size_def(size, &d, &err) != CR_OK) return fail(size, &err);
    cr_swingar *m = NULL;
    cr_swingar_garment *sg = NULL; /* tiny reads z = 16: the first 16 of the 256 (timing) */
    if (cr_swingar_create(&d, 1, &m, &err) != CR_OK) return fail(size, &err);
    if (cr_swingar_garment_create(g->mesh, g->skin_joint, g->skin_weight, body, desc,
                                  d.descriptor_len, &sg, &err) != CR_OK)
        return fail("swingar garment", &err);
    const int64_t V = g->mesh->nv;
    cr_swingar_runtime *rt[MAX_BATCH] = {0};
    float *out[MAX_BATCH] = {0};
    int rc = 0;
    double t0 = cr_time_now();
    for (int b = 0; b < B && !rc; b++) {
        if (cr_swingar_runtime_create(m, sg, body->joints, 0, &rt[b], &err) != CR_OK)
            rc = fail(size, &err);
        else if (!(out[b] = malloc(sizeof(float) * 3 * (size_t)V)))
            rc = 1;
    }
    double create_s = (cr_time_now() - t0) / B;
    char what[160];
    snprintf(what, sizeof what, "swingar %s (%lld parameters)", size,
             (long long)cr_nn_params_numel(cr_swingar_params(m)));
    for (int k = 0; k < (B > 1 ? 2 : 1) && !rc; k++) {
        uint64_t f0 = cr_nn_gemm_flops();
        t0 = cr_time_now();
        for (int t = 0; t < frames && !rc; t++) {
            const float *pose = mo->poses + (size_t)t * CR_NJOINTS * 3, *tr = mo->trans + 3 * t;
            if (k == 0) {
                if (cr_swingar_runtime_step(rt[0], pose, tr, out[0], &err) != CR_OK)
                    rc = fail(size, &err);
                continue;
            }
            float poses[MAX_BATCH * CR_NJOINTS * 3], trans[MAX_BATCH * 3];
            for (int b = 0; b < B; b++) {
                memcpy(poses + b * CR_NJOINTS * 3, pose, sizeof(float) * CR_NJOINTS * 3);
                memcpy(trans + 3 * b, tr, sizeof(float) * 3);
            }
            if (cr_swingar_runtime_step_batch(rt, B, poses, trans, out, &err) != CR_OK)
                rc = fail(size, &err);
        }
        double s = cr_time_now() - t0;
        if (rc) break;
        char line[200];
        snprintf(line, sizeof line, "%s batch %d", what, k ? B : 1);
        report(line, V, frames * (k ? B : 1), s, cr_nn_gemm_flops() - f0, create_s,
               cr_swingar_runtime_arena_bytes(rt[0]) / 1073741824.0, peak_sgemm);
    }
    for (int b = 0; b < B; b++) {
        cr_swingar_runtime_destroy(rt[b]);
        free(out[b]);
    }
    cr_swingar_garment_destroy(sg);
    cr_swingar_destroy(m);
    return rc;
}

static int bench_epnet(int32_t vertices, const cr_motion *mo, int frames, double peak_sgemm,
                       cr_epnet **model) {
    cr_error err = {0};
    cr_epnet_def d = cr_epnet_default_def();
    d.garment_vertices = vertices;
    if (cr_epnet_create(&d, model, &err) != CR_OK) return fail("epnet", &err);
    cr_epnet_runtime *rt = NULL;
    double t0 = cr_time_now();
    if (cr_epnet_runtime_create(*model, NULL, NULL, &rt, &err) != CR_OK)
        return fail("epnet runtime", &err);
    double create_s = cr_time_now() - t0;
    const int64_t V = cr_epnet_runtime_vertices(rt);
    float *out = malloc(sizeof(float) * 3 * (size_t)V);
    int rc = out ? 0 : 1;
    uint64_t f0 = cr_nn_gemm_flops();
    t0 = cr_time_now();
    for (int t = 0; t < frames && !rc; t++)
        if (cr_epnet_runtime_step(rt, mo->poses + (size_t)t * CR_NJOINTS * 3, mo->trans + 3 * t,
                                  out, &err) != CR_OK)
            rc = fail("epnet step", &err);
    double s = cr_time_now() - t0;
    char what[160];
    snprintf(what, sizeof what, "epnet proxy (%lld + %lld parameters, %d hinges)",
             (long long)cr_epnet_param_count(*model, 0), (long long)cr_epnet_param_count(*model, 1),
             cr_epnet_hinge_count(*model));
    if (!rc) report(what, V, frames, s, cr_nn_gemm_flops() - f0, create_s, 0.0, peak_sgemm);
    free(out);
    cr_epnet_runtime_destroy(rt);
    return rc;
}

typedef struct sim_record {
    float *frames; /* (frames + 1, V,3): the rest, then each finished frame */
    int32_t nv;
} sim_record;

static cr_status record_frame(void *ctx, const cr_sim *sim, const cr_sim_report *rep,
                              const cr_scene_run_stats *so_far, cr_error *err) {
    (void)so_far, (void)err;
    sim_record *r = ctx;
    cr_sim_positions_f(sim, r->frames + (size_t)rep->frame * r->nv * 3);
    return CR_OK;
}

/* The reference simulator on the garment mesh `mesh` over the motion; with
 * record (may be NULL) its frames kept; *spf (may be NULL) its seconds a
 * frame. */
static int bench_sim(const cr_mesh *mesh, const cr_body_model *body, const cr_motion *mo,
                     cr_sim_solver solver, int frames, float *record, double *spf) {
    cr_error err = {0};
    float *posed = NULL;
    if (cr_body_pose_motion(body, mo, &posed, &err) != CR_OK) return fail("pose", &err);
    cr_sim_def sd = cr_sim_default_def();
    if (cr_material_preset("cotton", &sd.material, &err) != CR_OK) return fail("material", &err);
    sd.dt = 1.0 / 30.0;
    sd.solver = solver;
    sd.collider = body->rest;
    sd.collider_frames = posed;
    sd.collider_nframes = mo->nframes;
    cr_sim *sim = NULL;
    if (cr_sim_create(&sd, mesh, &sim, &err) != CR_OK) return fail("sim", &err);
    sim_record rec = {record, mesh->nv};
    if (record) memcpy(record, mesh->pos, sizeof(float) * 3 * (size_t)mesh->nv);
    cr_scene_run_stats rs;
    cr_status st = cr_scene_run(sim, frames, NULL, record ? record_frame : NULL, &rec, &rs, &err);
    if (st != CR_OK) printf("sim %s: stopped: %s\n", cr_sim_solver_name(solver), err.msg);
    printf("sim %s V=%d: %.3f fps (%.2f s/frame over %d frames, %.1f Newton iterations a frame, "
           "%s); peak RSS %.2f GiB\n",
           cr_sim_solver_name(solver), mesh->nv, rs.frames / rs.seconds,
           rs.seconds / (rs.frames ? rs.frames : 1), rs.frames,
           rs.newton_iterations / (rs.frames ? rs.frames : 1.0),
           rs.diverged ? "DIVERGED" : "no divergence", maxrss_gib());
    fflush(stdout);
    if (spf) *spf = rs.seconds / (rs.frames ? rs.frames : 1);
    cr_sim_destroy(sim);
    free(posed);
    return st != CR_OK;
}

/* One gdsr size stepped over the low simulation's frames (lowsim, (T,Vl,3))
 * with the posed body; *spf its seconds a frame. */
static int bench_gdsr_size(const char *size, const cr_gdsr_data *d, const float *lowsim,
                           const float *posed, int frames, double peak_sgemm, double *spf) {
    cr_error err = {0};
    cr_gdsr_model_def md;
    if (strcmp(size, "default") == 0)
        md = cr_gdsr_model_default_def();
    else if (strcmp(size, "paper") == 0)
        md = cr_gdsr_model_paper_def();
    else
        return fprintf(stderr, "bench_runtime: gdsr size %s (default, paper)\n", size), 1;
    cr_gdsr_model *m = NULL;
    if (cr_gdsr_model_create(&md, &m, &err) != CR_OK) return fail("gdsr model", &err);
    cr_gdsr_runtime *rt = NULL;
    double t0 = cr_time_now();
    if (cr_gdsr_runtime_create(m, d, NULL, &rt, &err) != CR_OK) {
        cr_gdsr_model_destroy(m);
        return fail("gdsr runtime", &err);
    }
    const double create_s = cr_time_now() - t0;
    const int64_t Vl = d->low->nv, Vh = d->high->nv, Vb = d->body->nv;
    float *out = malloc(sizeof(float) * 3 * (size_t)Vh);
    int rc = out ? 0 : 1;
    uint64_t f0 = 0;
    double stage[4] = {0, 0, 0, 0};
    for (int t = 0; t < frames + 2 && !rc; t++) {
        if (t == 2) f0 = cr_nn_gemm_flops(), t0 = cr_time_now(); /* the first two: no networks */
        if (cr_gdsr_runtime_step(rt, lowsim + (size_t)t * Vl * 3, posed + (size_t)t * Vb * 3, out,
                                 &err) != CR_OK)
            rc = fail("gdsr step", &err);
        cr_gdsr_runtime_stats st = cr_gdsr_runtime_last_stats(rt);
        for (int k = 0; k < 4; k++)
            stage[k] += st.seconds[k];
    }
    const double s = cr_time_now() - t0;
    char what[160];
    snprintf(what, sizeof what, "gdsr %s (%lld parameters, from %lld low vertices)", size,
             (long long)cr_nn_params_numel(cr_gdsr_model_params(m)), (long long)Vl);
    if (!rc)
        report(what, Vh, frames, s, cr_nn_gemm_flops() - f0, create_s,
               cr_gdsr_runtime_arena_bytes(rt) / 1073741824.0, peak_sgemm);
    if (!rc) {
        printf("  its stages, ms a frame:");
        for (int k = 0; k < 4; k++)
            printf(" %s %.2f%s", cr_gdsr_stage_names[k], 1e3 * stage[k] / frames, k < 3 ? "," : "");
        printf(" (without the handling: %.2f fps)\n", frames / (s - stage[3]));
    }
    *spf = s / frames;
    free(out);
    cr_gdsr_runtime_destroy(rt);
    cr_gdsr_model_destroy(m);
    return rc;
}

/* gdsr at hv output vertices from lv: the low Newton
 * simulation over frames + 2 frames, each size stepped over it, then both
 * resolutions simulated by both solvers, and the ratios. */
static int bench_gdsr(int32_t hv, int32_t lv, const char *sizes_in, const cr_body_model *body,
                      const cr_motion *mo, int frames, int sim_frames, double peak_sgemm) {
    cr_error err = {0};
    cr_garment_def gd = cr_garment_default_def(CR_GARMENT_TSHIRT);
    gd.target_vertices = lv;
    cr_garment_template *tp = NULL;
    cr_garment *low = NULL, *high = NULL;
    if (cr_garment_template_create(&gd, body, &tp, &err) != CR_OK ||
        cr_garment_template_instantiate(tp, lv, body, &low, &err) != CR_OK ||
        cr_garment_template_instantiate(tp, hv, body, &high, &err) != CR_OK)
        return fail("gdsr garment", &err);
    cr_garment_template_destroy(tp);
    cr_gdsr_data d;
    if (cr_gdsr_data_from_arrays(low->mesh, high->mesh, body->rest, 1, low->mesh->pos,
                                 high->mesh->pos, body->rest->pos, &d, &err) != CR_OK)
        return fail("gdsr data", &err);
    printf("t-shirt pair V=%d / %d\n", low->mesh->nv, high->mesh->nv);
    const int T = frames + 2; /* the runtime's two frames without networks, then `frames` */
    float *lowsim = malloc(sizeof(float) * 3 * (size_t)(T + 1) * low->mesh->nv), *posed = NULL;
    if (!lowsim) return 1;
    if (cr_body_pose_motion(body, mo, &posed, &err) != CR_OK) return fail("pose", &err);
    double low_newton = 0, low_vbd = 0, high_newton = 0, high_vbd = 0;
    int rc = bench_sim(low->mesh, body, mo, CR_SIM_SOLVER_NEWTON, T, lowsim, &low_newton);
    char sizes[64];
    snprintf(sizes, sizeof sizes, "%s", sizes_in);
    double gdsr_spf[4] = {0};
    const char *names[4] = {NULL};
    int n = 0;
    for (char *s = strtok(sizes, ","); s && n < 4 && !rc; s = strtok(NULL, ","), n++) {
        names[n] = s;
        rc |= bench_gdsr_size(s, &d, lowsim, posed, frames, peak_sgemm, &gdsr_spf[n]);
    }
    if (sim_frames > 0 && !rc) {
        rc |= bench_sim(low->mesh, body, mo, CR_SIM_SOLVER_VBD, sim_frames, NULL, &low_vbd);
        rc |= bench_sim(high->mesh, body, mo, CR_SIM_SOLVER_NEWTON, sim_frames, NULL, &high_newton);
        rc |= bench_sim(high->mesh, body, mo, CR_SIM_SOLVER_VBD, sim_frames, NULL, &high_vbd);
        for (int k = 0; k < n && !rc; k++)
            printf("low simulation + gdsr %s V=%d: Newton %.3f fps (%.2f x Newton at V=%d), VBD "
                   "%.3f fps (%.2f x VBD at V=%d)\n",
                   names[k], high->mesh->nv, 1.0 / (low_newton + gdsr_spf[k]),
                   high_newton / (low_newton + gdsr_spf[k]), high->mesh->nv,
                   1.0 / (low_vbd + gdsr_spf[k]), high_vbd / (low_vbd + gdsr_spf[k]),
                   high->mesh->nv);
    }
    free(lowsim);
    free(posed);
    cr_gdsr_data_free(&d);
    cr_garment_destroy(low);
    cr_garment_destroy(high);
    return rc;
}

int main(int argc, char **argv) {
    cr_parallel_choose_wait_policy(argv); /* as the tool: no spinning against a busy core */
    int frames = argc > 1 ? atoi(argv[1]) : 30;
    char sizes[64];
    snprintf(sizes, sizeof sizes, "%s", argc > 2 ? argv[2] : "tiny,paper");
    int ev = argc > 3 ? atoi(argv[3]) : 2000, sim_frames = argc > 4 ? atoi(argv[4]) : 4;
    int B = argc > 5 ? atoi(argv[5]) : 1;
    int gv = 10000, glv = 1250; /* HIGH[/LOW]: docs/gdsr.md's ratio of 8 by default */
    if (argc > 6 && sscanf(argv[6], "%d/%d", &gv, &glv) == 1) glv = gv / 8;
    const char *gsizes = argc > 7 ? argv[7] : "default";
    if (frames < 1 || frames > 10000 || ev < 0 || sim_frames < 0 || B < 1 || B > MAX_BATCH ||
        (gv != 0 && (gv < 2000 || gv > 100000 || glv < 500 || glv > gv)) || argc > 8) {
        fprintf(stderr,
                "usage: bench_runtime [frames 1..10000] [tiny,cpu,paper|none] [epnet_vertices] "
                "[sim_frames] [batch 1..%d] [gdsr_vertices 0|HIGH[/LOW]] [default,paper]\n",
                MAX_BATCH);
        return 2;
    }
    double blas = sgemm_rate(), own = engine_rate(), peak = blas > own ? blas : own;
    printf("threads %d, OpenBLAS %s, core type %s, engine kernels %s; 1024^3 products: "
           "cblas_sgemm %.1f GFLOP/s, the engine's (cr_nn_matmul) %.1f; shares below are of the "
           "faster\n",
           cr_thread_count(), openblas_get_config(), openblas_get_corename(), cr_nn_kernel_level(),
           blas, own);
    cr_error err = {0};
    cr_mannequin_def md = cr_mannequin_default_def();
    cr_body_model *body = NULL;
    if (cr_mannequin_create(&md, &body, &err) != CR_OK) return fail("mannequin", &err);
    cr_motion_clip_def cd = cr_motion_clip_default_def();
    cd.name = "walk";
    cd.nframes = (frames > sim_frames ? frames : sim_frames) + 3; /* gdsr's two, and its rest */
    cr_motion *mo = NULL;
    if (cr_motion_clip_make(&cd, &mo, &err) != CR_OK) return fail("walk", &err);
    int rc = 0;
    if (strcmp(sizes, "none") != 0) {
        cr_garment_def gd = cr_garment_default_def(CR_GARMENT_DRESS);
        gd.target_vertices = 10000;
        cr_garment *g = NULL;
        if (cr_garment_create(&gd, body, &g, &err) != CR_OK) return fail("garment", &err);
        float desc[256]; /* z = 256, geodesic: once per garment, not per frame */
        double t0 = cr_time_now();
        if (cr_swingar_compute_descriptor(g->mesh, 256, 0, desc, &err) != CR_OK)
            return fail("descriptor", &err);
        printf("dress V=%d F=%d; its descriptor (z = 256) %.2f s, once per garment\n", g->mesh->nv,
               g->mesh->nf, cr_time_now() - t0);
        for (char *s = strtok(sizes, ","); s; s = strtok(NULL, ","))
            rc |= bench_swingar(s, g, body, desc, mo, frames, B, peak);
        if (sim_frames > 0) {
            rc |= bench_sim(g->mesh, body, mo, CR_SIM_SOLVER_NEWTON, sim_frames, NULL, NULL);
            rc |= bench_sim(g->mesh, body, mo, CR_SIM_SOLVER_VBD, sim_frames, NULL, NULL);
        }
        cr_garment_destroy(g);
    }
    if (ev > 0) {
        cr_epnet *m = NULL;
        rc |= bench_epnet(ev, mo, frames, peak, &m);
        if (m && sim_frames > 0) {
            rc |= bench_sim(cr_epnet_garment(m), body, mo, CR_SIM_SOLVER_NEWTON, sim_frames, NULL,
                            NULL);
            rc |=
                bench_sim(cr_epnet_garment(m), body, mo, CR_SIM_SOLVER_VBD, sim_frames, NULL, NULL);
        }
        cr_epnet_destroy(m);
    }
    if (gv > 0) rc |= bench_gdsr(gv, glv, gsizes, body, mo, frames, sim_frames, peak);
    cr_motion_destroy(mo);
    cr_body_model_destroy(body);
    return rc;
}
