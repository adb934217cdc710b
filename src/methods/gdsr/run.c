/* run.c: `crease gdsr run` as one library call (cr_gdsr_run): a trained
 * model rolled out on a dataset's clip or on a freshly simulated one, its
 * files (PC2s, glb, OBJs, comparison pictures, strain over the frames), the
 * paper's metrics against the reference, upsampling and the twin (measure.c), and
 * OUT/summary.json. */
#include "crease/eval.h"
#include "crease/gdsr.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/render.h"
#include "gdsr_internal.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RUN_COOKIE 0x47525231u

cr_gdsr_run_def cr_gdsr_run_default_def(void) {
    cr_gdsr_run_def d;
    memset(&d, 0, sizeof d);
    d.garment = "tshirt";
    d.body = "normal";
    d.eps = 0.002f;
    d.relax = CR_GDSR_RELAX_DEFAULT;
    d.png_frame = -1;
    d.png_size = 512;
    d.glb_max_frames = CR_GDSR_GLB_MAX_FRAMES;
    d.fps = 30.0f;
    d.cookie = RUN_COOKIE;
    return d;
}

/* The run def's numeric fields: their ranges (checked by cr_gdsr_run) and the options of
 * `crease gdsr run` with their help (CLI_KEYS). 0 keeps its meaning where a field has one
 * (frames: the whole clip; the vertex counts: the dataset's); the rest of those ranges is
 * checked by hand. */
#define RK(...) CR_CONFIG_KEY(cr_gdsr_run_def, __VA_ARGS__)
static const cr_config_key run_keys[] = {
    RK(eps, CR_CFG_FLOAT, 0, 0.05, "--eps", "E", "collision margin, m"),
    RK(relax, CR_CFG_INT, 0, 1000, "--relax", "N",
       "smoothing steps that spread the collision pushes"),
    RK(frames, CR_CFG_INT, 0, 1000000, "--frames", "N",
       "only the clip's first N frames, at least 3 (with --simulate: frames to simulate, "
       "default 60; 0: the whole clip)"),
    RK(simulate, CR_CFG_BOOL, 0, 1, "--simulate", NULL,
       "--motion is a clip name or a motion file (.bvh, .npz, .glb) to simulate the low "
       "garment on; --dataset (optional) is then the training data whose manifest gives the "
       "vertex counts, fps and material (else 2000, 8000, 30, cotton)"),
    RK(reference, CR_CFG_BOOL, 0, 1, "--reference", NULL,
       "simulate the high resolution too: a reference and the metrics table (slow: the high "
       "simulation)"),
    RK(low_vertices, CR_CFG_INT, 0, 100000, "--low-vertices", "N",
       "with --simulate: the low garment's target vertex count, at least 500 (default 0: the "
       "dataset's, else 2000)"),
    RK(high_vertices, CR_CFG_INT, 0, 100000, "--high-vertices", "N",
       "with --simulate: the high garment's, at least 500 (default 0: the dataset's, else "
       "8000)"),
    RK(png_frame, CR_CFG_INT, -1, 1000000, "--png-frame", "F",
       "the frame of compare.png (default -1: the last)"),
    RK(png_size, CR_CFG_INT, 16, 4096, "--png-size", "N", "pixels per panel"),
    RK(glb_max_frames, CR_CFG_INT, 0, 100000, "--glb-max-frames", "N",
       "gdsr.glb animates up to N frames, else it holds the last frame alone"),
    RK(fps, CR_CFG_FLOAT, 0.01, 1000, "--fps", "F", "gdsr.glb's playback rate"),
    RK(quiet, CR_CFG_BOOL, 0, 1, "--quiet", NULL, "no progress"),
};
#undef RK
enum { NRUN_KEYS = sizeof run_keys / sizeof run_keys[0] };

const cr_config_key *cr_gdsr_run_def_keys(int *n) {
    *n = NRUN_KEYS;
    return run_keys;
}

void cr_gdsr_run_report_free(cr_gdsr_run_report *r) {
    if (!r) return;
    free(r->summary_json);
    memset(r, 0, sizeof *r);
}

/* The outputs of a roll-out r (and the baseline's rb) of clip 0 of d into
 * def->out_dir, the metrics and the summary into j. */
static cr_status write_outputs(const cr_gdsr_run_def *def, const cr_gdsr_data *d,
                               const cr_gdsr_data *dt, const cr_gdsr_rollout_result *r,
                               const cr_gdsr_rollout_result *rb, cJSON *j, int *png_frame,
                               int *animated, cr_error *err) {
    const char *out = def->out_dir;
    const cr_gdsr_clip *cl = &d->clip[0];
    char path[1100], npath[1100];
    struct {
        const char *name;
        const float *x;
    } outs[] = {{"gdsr", r->gdsr},
                {"gdsr_raw", r->gdsr_raw},
                {"upsampled", r->upsampled},
                {"reference", cl->high}, /* NULL: a low-only roll-out */
                {"gdsr_nodec", rb->gdsr}};
    for (int k = 0; k < 5; k++) {
        if (!outs[k].x) continue;
        snprintf(path, sizeof path, "%s/%s.pc2", out, outs[k].name);
        CR_TRY(cr_pc2_write(path, outs[k].x, d->high->nv, cl->nframes, 0, 1, err));
    }
    snprintf(path, sizeof path, "%s/high.obj", out);
    CR_TRY(cr_obj_write(path, d->high, err));
    snprintf(path, sizeof path, "%s/gdsr.glb", out);
    CR_TRY(cr_gdsr_write_glb(d->high, r->gdsr, cl->nframes, def->fps, def->glb_max_frames, path,
                             animated, err));
    if (*png_frame < 0 || *png_frame >= cl->nframes) *png_frame = cl->nframes - 1;
    snprintf(path, sizeof path, "%s/compare.png", out);
    snprintf(npath, sizeof npath, "%s/compare_normals.png", out);
    CR_TRY(cr_gdsr_render_compare(d, 0, r, *png_frame, def->png_size, path, npath, err));
    snprintf(path, sizeof path, "%s/body.pc2", out);
    CR_TRY(cr_pc2_write(path, cl->body, d->body->nv, cl->nframes, 0, 1, err));
    snprintf(path, sizeof path, "%s/body.obj", out);
    CR_TRY(cr_obj_write(path, d->body, err));
    cr_log(CR_LOG_INFO,
           "gdsr run %s: %d frames, %d -> %d vertices, %.4f s per frame (gdsr + handling; "
           "%.4f s CPU); inside the body: %.3f %% before handling, %.3f %% after",
           def->motion, cl->nframes, d->low->nv, d->high->nv, r->seconds_per_frame,
           r->cpu_seconds_per_frame, 100 * r->inside_before, 100 * r->inside_after);
    char line[512];
    int n = snprintf(line, sizeof line,
                     "  first frame through the networks %.4f s (with the warm-up); per frame "
                     "after:",
                     r->first_frame_seconds);
    for (int k = 0; k < 4; k++)
        n += snprintf(line + n, sizeof line - (size_t)n, " %s %.4f s%s", cr_gdsr_stage_names[k],
                      r->stage_seconds[k], k < 3 ? "," : "");
    cr_log(CR_LOG_INFO, "%s", line);
    if (d->nlayers > 1)
        cr_log(CR_LOG_INFO, "  layers (Eq. 27): %lld coarse and %lld high vertices pushed out",
               (long long)r->layer_pushed, (long long)r->layer_pushed_high);
    if (cl->high) {
        cr_gdsr_measure_header_();
        cJSON *table = cJSON_AddObjectToObject(j, "metrics");
        CR_TRY(cr_gdsr_measure_row_(d, cl, r->upsampled, "upsampled", table, err));
        CR_TRY(cr_gdsr_measure_row_(d, cl, r->gdsr, "gdsr", table, err));
        CR_TRY(cr_gdsr_measure_row_(d, cl, r->gdsr_raw, "gdsr_raw", table, err));
        if (rb->gdsr) CR_TRY(cr_gdsr_measure_row_(d, cl, rb->gdsr, "gdsr_nodec", table, err));
        if (dt) CR_TRY(cr_gdsr_measure_row_(d, cl, dt->clip[0].high, "twin", table, err));
        if (d->nlayers > 1)
            CR_TRY(cr_gdsr_measure_crossings_(d, cl->high, cl->nframes,
                                              cJSON_AddObjectToObject(table, "reference"),
                                              "reference", err));
    }
    return cr_gdsr_measure_strain_(d, cl, r, out, j, err);
}

static void add_summary(const cr_gdsr_run_def *def, const cr_gdsr_data *d,
                        const cr_gdsr_rollout_result *r, const cr_gdsr_sim_result *sr,
                        const char *simdir, int png_frame, int animated, cJSON *j) {
    const cr_gdsr_clip *cl = &d->clip[0];
    cJSON_AddStringToObject(j, "command", "gdsr run");
    cJSON_AddStringToObject(j, "motion", def->motion);
    cJSON_AddNumberToObject(j, "frames", cl->nframes);
    cJSON_AddNumberToObject(j, "low_vertices", d->low->nv);
    cJSON_AddNumberToObject(j, "high_vertices", d->high->nv);
    cJSON_AddNumberToObject(j, "seconds_per_frame", r->seconds_per_frame);
    cJSON_AddNumberToObject(j, "cpu_seconds_per_frame", r->cpu_seconds_per_frame);
    cJSON_AddNumberToObject(j, "first_frame_seconds", r->first_frame_seconds);
    cJSON *stages = cJSON_AddObjectToObject(j, "stage_seconds_per_frame");
    for (int k = 0; k < 4; k++)
        cJSON_AddNumberToObject(stages, cr_gdsr_stage_names[k], r->stage_seconds[k]);
    cJSON_AddNumberToObject(j, "inside_before", r->inside_before);
    cJSON_AddNumberToObject(j, "inside_after", r->inside_after);
    cJSON_AddNumberToObject(j, "layer_pushed", (double)r->layer_pushed);
    cJSON_AddNumberToObject(j, "layer_pushed_high", (double)r->layer_pushed_high);
    cJSON_AddBoolToObject(j, "glb_animated", animated);
    cJSON_AddNumberToObject(j, "png_frame", png_frame);
    if (def->simulate) {
        cJSON *o = cJSON_AddObjectToObject(j, "simulated");
        cJSON_AddStringToObject(o, "dir", simdir);
        cJSON_AddStringToObject(o, "garment", sr->garment);
        cJSON_AddBoolToObject(o, "reference", def->reference);
        cJSON_AddNumberToObject(o, "seconds", sr->seconds);
        cJSON_AddNumberToObject(o, "max_inside_share", sr->max_inside_share);
    }
}

/* The clip: a dataset's (and the twin dataset's), or a fresh simulation. */
static cr_status load_clip(cr_gdsr_run_def *def, cr_gdsr_data *d, cr_gdsr_data *dt,
                           cr_gdsr_sim_result *sr, char *simdir, size_t simcap, cr_error *err) {
    if (def->simulate) {
        snprintf(simdir, simcap, "%s/sim", def->out_dir);
        cr_gdsr_sim_def sd = cr_gdsr_sim_default_def();
        sd.out_dir = simdir, sd.garment = def->garment, sd.body = def->body;
        sd.motion = def->motion, sd.like = def->dataset;
        sd.low_vertices = def->low_vertices, sd.high_vertices = def->high_vertices;
        if (def->frames > 0) sd.frames = def->frames;
        sd.reference = def->reference, sd.quiet = def->quiet;
        sd.motion_import = def->motion_import, sd.motion_prepare = def->motion_prepare;
        CR_TRY(cr_gdsr_simulate(&sd, d, sr, err));
        cr_log(CR_LOG_INFO,
               "gdsr run: simulated %s on %s (%s), %d frames, %d low vertices%s, %.1f s (%s)",
               sr->garment, def->body, sr->motion, d->clip[0].nframes - 1, sr->low_vertices,
               def->reference ? " and the high reference" : "", sr->seconds, simdir);
        def->motion = sr->motion;
        def->frames = 0;
        return CR_OK;
    }
    const char *motion = def->motion;
    CR_TRY(cr_gdsr_data_load(def->dataset, def->garment, def->body, &motion, 1, d, err));
    if (!def->twin) return CR_OK;
    cr_status st = cr_gdsr_data_load(def->twin, def->garment, def->body, &motion, 1, dt, err);
    if (st == CR_OK && (dt->high->nv != d->high->nv || dt->clip[0].nframes < d->clip[0].nframes))
        st = CR_FAIL(err, CR_ERR_SHAPE,
                     "gdsr run: %s's high %s clip has %d vertices and %d frames, %s's %d and %d",
                     def->twin, motion, dt->high->nv, dt->clip[0].nframes, def->dataset,
                     d->high->nv, d->clip[0].nframes);
    if (st != CR_OK) { /* a failed load freed what it had */
        if (dt->high) cr_gdsr_data_free(dt);
        cr_gdsr_data_free(d);
    }
    return st;
}

cr_status cr_gdsr_run(const cr_gdsr_run_def *def_in, cr_gdsr_run_report *out, cr_error *err) {
    if (!def_in || def_in->cookie != RUN_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID, "gdsr run: def not made by cr_gdsr_run_default_def");
    cr_gdsr_run_def def = *def_in;
    if (out) memset(out, 0, sizeof *out);
    if (!def.motion || !def.model || !def.out_dir || (!def.dataset && !def.simulate))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr run: needs a motion, a model, an output folder and a dataset or "
                       "simulate");
    if (def.twin && def.simulate)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr run: a twin measures a dataset's clip, not a "
                       "simulated one");
    CR_TRY(cr_config_check(run_keys, NRUN_KEYS, &def, "gdsr run", err));
    if ((def.frames > 0 && def.frames < 3) || (def.low_vertices > 0 && def.low_vertices < 500) ||
        (def.high_vertices > 0 && def.high_vertices < 500))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr run: frames %d (0 or at least 3), vertex counts %d, %d (0 or at "
                       "least 500)",
                       def.frames, def.low_vertices, def.high_vertices);
    if (!def.simulate && (def.reference || def.low_vertices || def.high_vertices))
        return CR_FAIL(err, CR_ERR_INVALID,
                       "gdsr run: reference, low_vertices and high_vertices need simulate");
    cr_gdsr_data d, dt = {0};
    cr_gdsr_sim_result sr = {0};
    char simdir[1100] = "";
    CR_TRY(load_clip(&def, &d, &dt, &sr, simdir, sizeof simdir, err));
    if (def.frames > 0 && def.frames < d.clip[0].nframes) d.clip[0].nframes = def.frames;
    cr_gdsr_model *m = NULL, *mb = NULL;
    cr_gdsr_rollout_result r = {0}, rb = {0};
    cJSON *j = cJSON_CreateObject();
    int png_frame = def.png_frame, animated = 0;
    cr_status st = j ? cr_mkdir_p(def.out_dir, err) : CR_FAIL(err, CR_ERR_MEMORY, "gdsr run");
    if (st == CR_OK) st = cr_gdsr_model_load(def.model, &m, err);
    if (st == CR_OK) st = cr_gdsr_rollout(m, &d, 0, def.eps, def.relax, def.surface, &r, err);
    if (st == CR_OK && def.baseline) {
        st = cr_gdsr_model_load(def.baseline, &mb, err);
        if (st == CR_OK) st = cr_gdsr_rollout(mb, &d, 0, def.eps, def.relax, def.surface, &rb, err);
    }
    if (st == CR_OK)
        st = write_outputs(&def, &d, def.twin ? &dt : NULL, &r, &rb, j, &png_frame, &animated, err);
    if (st == CR_OK) {
        add_summary(&def, &d, &r, &sr, simdir, png_frame, animated, j);
        char *s = cJSON_Print(j), path[1100];
        snprintf(path, sizeof path, "%s/summary.json", def.out_dir);
        cr_atomic_file f;
        st = s ? cr_atomic_open(&f, path, err)
               : CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory", path);
        if (st == CR_OK) {
            fputs(s, f.fp);
            st = cr_atomic_commit(&f, err);
        }
        if (st == CR_OK && out) {
            out->frames = d.clip[0].nframes;
            out->low_vertices = d.low->nv, out->high_vertices = d.high->nv;
            out->seconds_per_frame = r.seconds_per_frame;
            out->inside_before = r.inside_before, out->inside_after = r.inside_after;
            out->summary_json = s;
            s = NULL;
        }
        free(s);
    }
    cJSON_Delete(j);
    cr_gdsr_rollout_free(&r);
    cr_gdsr_rollout_free(&rb);
    cr_gdsr_model_destroy(m);
    cr_gdsr_model_destroy(mb);
    cr_gdsr_data_free(&d);
    if (def.twin) cr_gdsr_data_free(&dt);
    return st;
}
