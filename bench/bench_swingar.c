/* bench_swingar.c: SwinGar's inference speed on a 10k-vertex garment
 * (issue 20: frames per second at batch 1 and batched over 10 sequences,
 * next to the reference simulator on the same garment, in one run).
 *
 * The garment is the default dress on the normal mannequin at 10,000 target
 * vertices; the sequences are procedural clips (cr_motion_clip_names, the
 * first `batch`, cycled with a faster tempo when there are fewer). Each
 * model size (untrained weights: the cost does not depend on them) predicts
 * batch x frames frames of one sequence (batch 1) and then `frames` frames
 * of each of `batch` sequences in one call (cr_swingar_predict_batch: the
 * garment encoded once), one frame per step (chunk 1, the least memory). Then the reference
 * simulator, Newton and VBD at their defaults (30 fps), simulates `sim_frames` frames of the first
 * sequence on the same garment, from rest. Printed: fps of each, the
 * garment's encoding (once per garment), the arena's high-water mark (the
 * activations one step keeps) and the process's peak resident memory so far
 * (getrusage; the runs go from small to large, so it tracks the latest).
 * The descriptor (once per garment, not per frame) is timed apart.
 *
 *   bench_swingar [frames] [batch] [sizes] [sim_frames] [arena_mb]
 *   defaults: 2 frames, batch 10, sizes tiny,cpu, 2 simulated frames, arena
 *   16384 MiB (reserved, touched only as used); sizes: a comma list of
 *   tiny, cpu, paper; sim_frames 0 skips the simulator.
 */
#include "crease/body.h"
#include "crease/garment.h"
#include "crease/motion.h"
#include "crease/nn.h"
#include "crease/scene.h"
#include "crease/swingar.h"

#include <cblas.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

enum { MAX_BATCH = 64 };

static int fail(const char *what, const cr_error *e) {
    fprintf(stderr, "bench_swingar: %s: %s\n", what, e->msg);
    return 1;
}

static double maxrss_gib(void) {
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_maxrss / (1024.0 * 1024.0); /* kB on Linux */
}

/* batch 1, then batch B, of one size; returns nonzero on a setup error. */
static int bench_size(const char *size, const cr_swingar_garment *g, const cr_swingar_motion *mos,
                      int B, int frames, size_t arena) {
    cr_error err = {0};
    cr_swingar_def d = cr_swingar_default_def();
    if (cr_swingar_size_def(size, &d, &err) != CR_OK) return fail(size, &err);
    cr_swingar *m = NULL;
    if (cr_swingar_create(&d, 1, &m, &err) != CR_OK) return fail(size, &err);
    const int64_t V = g->rest->nv, np = cr_nn_params_numel(cr_swingar_params(m));
    /* the same number of frames both ways: batch 1 runs B x frames frames of
     * the first sequence, batch B the first `frames` of each */
    float *out[MAX_BATCH];
    for (int b = 0; b < B; b++)
        if (!(out[b] = malloc(sizeof(float) * 3 * (size_t)V * (size_t)(b ? frames : B * frames))))
            return 1;
    cr_swingar_motion seq[MAX_BATCH];
    for (int b = 0; b < B; b++)
        seq[b] = mos[b], seq[b].nframes = frames;
    int ns[2] = {1, B};
    for (int k = 0; k < 2; k++) {
        cr_swingar_predict_stats ps = {0};
        double t0 = cr_time_now();
        cr_status st = k == 0 ? cr_swingar_predict_batch(m, g, mos, 1, arena, out, &ps, &err)
                              : cr_swingar_predict_batch(m, g, seq, B, arena, out, &ps, &err);
        double s = cr_time_now() - t0;
        if (st != CR_OK) {
            printf("swingar %s batch %d: failed: %s (peak RSS %.2f GiB)\n", size, ns[k], err.msg,
                   maxrss_gib());
            fflush(stdout);
            continue;
        }
        double per = s - ps.encode_seconds; /* the frames, without the garment's encoding */
        const int each = k == 0 ? B * frames : frames, total = B * frames;
        printf("swingar %s (%lld parameters) V=%lld batch %d: %.3f fps (%d frames each, %.2f s; "
               "garment encoding %.2f s once, %.3f fps with it); arena peak %.2f GiB, peak RSS "
               "%.2f GiB\n",
               size, (long long)np, (long long)V, ns[k], total / per, each, per, ps.encode_seconds,
               total / s, ps.arena_peak_bytes / 1073741824.0, maxrss_gib());
        fflush(stdout);
    }
    for (int b = 0; b < B; b++)
        free(out[b]);
    cr_swingar_destroy(m);
    return 0;
}

static int bench_sim(const cr_garment *g, const cr_body_model *body, const cr_motion *mo,
                     cr_sim_solver solver, int frames) {
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
    if (cr_sim_create(&sd, g->mesh, &sim, &err) != CR_OK) return fail("sim", &err);
    cr_scene_run_stats rs;
    cr_status st = cr_scene_run(sim, frames, NULL, NULL, NULL, &rs, &err);
    if (st != CR_OK) printf("sim %s: stopped: %s\n", cr_sim_solver_name(solver), err.msg);
    printf("sim %s V=%d: %.3f fps (%.2f s/frame over %d frames, %.1f Newton iterations a frame, "
           "%s); peak RSS %.2f GiB\n",
           cr_sim_solver_name(solver), g->mesh->nv, rs.frames / rs.seconds,
           rs.seconds / (rs.frames ? rs.frames : 1), rs.frames,
           rs.newton_iterations / (rs.frames ? rs.frames : 1.0),
           rs.diverged ? "DIVERGED" : "no divergence", maxrss_gib());
    fflush(stdout);
    cr_sim_destroy(sim);
    free(posed);
    return st != CR_OK;
}

int main(int argc, char **argv) {
    int frames = argc > 1 ? atoi(argv[1]) : 2, B = argc > 2 ? atoi(argv[2]) : 10;
    char sizes[64];
    snprintf(sizes, sizeof sizes, "%s", argc > 3 ? argv[3] : "tiny,cpu");
    int sim_frames = argc > 4 ? atoi(argv[4]) : 2, arena_mb = argc > 5 ? atoi(argv[5]) : 16384;
    if (frames < 1 || frames > 1000 || B < 1 || B > MAX_BATCH || sim_frames < 0 || arena_mb < 16 ||
        argc > 6) {
        fprintf(stderr,
                "usage: bench_swingar [frames 1..1000] [batch 1..%d] [tiny,cpu,paper] "
                "[sim_frames] [arena_mb]\n",
                MAX_BATCH);
        return 2;
    }
    printf("threads %d, OpenBLAS %s, core type %s\n", cr_thread_count(), openblas_get_config(),
           openblas_get_corename());
    cr_error err = {0};
    cr_mannequin_def md = cr_mannequin_default_def();
    cr_body_model *body = NULL;
    if (cr_mannequin_create(&md, &body, &err) != CR_OK) return fail("mannequin", &err);
    cr_garment_def gd = cr_garment_default_def(CR_GARMENT_DRESS);
    gd.target_vertices = 10000;
    cr_garment *g = NULL;
    double t0 = cr_time_now();
    if (cr_garment_create(&gd, body, &g, &err) != CR_OK) return fail("garment", &err);
    printf("dress V=%d F=%d built in %.1f s\n", g->mesh->nv, g->mesh->nf, cr_time_now() - t0);
    /* the sequences: the clips in turn, a faster tempo on each new round */
    int nclips = 0;
    const char *const *names = cr_motion_clip_names(&nclips);
    cr_motion *mo[MAX_BATCH];
    cr_swingar_motion sm[MAX_BATCH];
    int T = B * frames > sim_frames ? B * frames : sim_frames;
    for (int b = 0; b < B; b++) {
        cr_motion_clip_def cd = cr_motion_clip_default_def();
        cd.name = names[b % nclips];
        cd.nframes = T;
        cd.speed = 1.0f + 0.25f * (float)(b / nclips);
        if (cr_motion_clip_make(&cd, &mo[b], &err) != CR_OK) return fail(cd.name, &err);
        sm[b] = (cr_swingar_motion){T, body->joints, mo[b]->poses, mo[b]->trans};
    }
    printf("sequences: %d clips of %d frames, the first %s\n", B, T, names[0]);
    /* the descriptor, z = 256, geodesic: once per garment */
    float desc[256];
    t0 = cr_time_now();
    if (cr_swingar_compute_descriptor(g->mesh, 256, 0, desc, &err) != CR_OK)
        return fail("descriptor", &err);
    printf("descriptor z=256: %.2f s (once per garment)\n", cr_time_now() - t0);
    fflush(stdout);
    int rc = 0;
    for (char *s = strtok(sizes, ","); s; s = strtok(NULL, ",")) {
        cr_swingar_def d = cr_swingar_default_def();
        if (cr_swingar_size_def(s, &d, &err) != CR_OK) return fail(s, &err);
        cr_swingar_garment *sg = NULL; /* tiny reads z = 16: the first 16 of the 256 (timing) */
        if (cr_swingar_garment_create(g->mesh, g->skin_joint, g->skin_weight, body, desc,
                                      d.descriptor_len, &sg, &err) != CR_OK)
            return fail("swingar garment", &err);
        rc |= bench_size(s, sg, sm, B, frames, (size_t)arena_mb << 20);
        cr_swingar_garment_destroy(sg);
    }
    if (sim_frames > 0) {
        rc |= bench_sim(g, body, mo[0], CR_SIM_SOLVER_NEWTON, sim_frames);
        rc |= bench_sim(g, body, mo[0], CR_SIM_SOLVER_VBD, sim_frames);
    }
    for (int b = 0; b < B; b++)
        cr_motion_destroy(mo[b]);
    cr_garment_destroy(g);
    cr_body_model_destroy(body);
    return rc;
}
