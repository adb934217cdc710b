/* run.c: the step-record-report loop every run shares (`crease simulate`,
 * the dataset's sequences, bench_sim): step the simulator frame by frame,
 * log and keep each frame, sum the reports, hand each finished frame to the
 * caller, stop at a divergence. */
#include "crease/scene.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* One finished frame into the sums. */
static void add_frame(cr_scene_run_stats *s, const cr_sim_report *rep, int32_t nv) {
    s->frames++;
    s->seconds += rep->seconds;
    s->seconds_assembly += rep->seconds_assembly;
    s->seconds_factor += rep->seconds_factor;
    s->seconds_solve += rep->seconds_solve;
    s->seconds_collision += rep->seconds_collision;
    s->seconds_self_contact += rep->seconds_self_contact;
    s->self_contact_detections += rep->self_contact_detections;
    s->self_contact_pairs += rep->self_contact_pairs;
    s->newton_iterations += rep->newton_iterations;
    s->factorisations += rep->factorisations;
    s->newton_capped += rep->newton_capped;
    s->vbd_retries += rep->vbd_retries;
    s->vbd_requeries += rep->vbd_requeries;
    s->vbd_coarse_steps += rep->vbd_coarse_steps;
    s->backoffs += rep->backoffs;
    s->max_penetration_m = fmax(s->max_penetration_m, rep->max_penetration_m);
    double projected = rep->projected / ((double)nv * (rep->substeps > 0 ? rep->substeps : 1));
    s->max_projected_share = fmax(s->max_projected_share, projected);
}

cr_status cr_scene_run(cr_sim *sim, int frames, cr_scene_record *rec, cr_scene_frame_fn on_frame,
                       void *ctx, cr_scene_run_stats *stats, cr_error *err) {
    memset(stats, 0, sizeof *stats);
    const int32_t nv = cr_sim_vertex_count(sim);
    for (int f = 0; f < frames; f++) {
        cr_sim_report rep;
        cr_status st = cr_sim_step(sim, &rep, err);
        if (st != CR_OK && st != CR_ERR_DIVERGED) return st;
        if (st == CR_ERR_DIVERGED) {
            stats->diverged = 1;
            snprintf(stats->failure, sizeof stats->failure, "%s", rep.failure);
            /* the log keeps the failed frame; the solver's message stays in err */
            cr_error log_err = {0};
            cr_status logged = rec ? cr_scene_record_frame(rec, sim, &rep, &log_err) : CR_OK;
            if (logged != CR_OK) {
                if (err) *err = log_err;
                return logged;
            }
            return CR_ERR_DIVERGED;
        }
        if (rec) CR_TRY(cr_scene_record_frame(rec, sim, &rep, err));
        add_frame(stats, &rep, nv);
        if (on_frame) CR_TRY(on_frame(ctx, sim, &rep, stats, err));
    }
    return CR_OK;
}
