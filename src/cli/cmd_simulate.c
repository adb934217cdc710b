/* cmd_simulate.c: `crease simulate`: run the reference cloth simulator on a
 * garment against a static object or an animated body, writing the sequence
 * (PC2, glb), a per-frame JSON lines log and a picture of the last frame. The
 * scene and output code is in scene.h; this file parses and reports. */
#include "cli.h"
#include "crease/scene.h"

#include <stdlib.h>
#include <string.h>

enum { RENDER_SIZE = 800, MAX_PINS = 1 << 20 };

void help_simulate(void) {
    printf("usage: crease simulate --garment G.obj (--object O | --body-mesh B.obj --body B.pc2)\n"
           "                       --frames N -o DIR [options]\n\n"
           "Simulate a garment with the reference implicit-Euler Newton solver (docs/physics.md)\n"
           "against a collider: a static object, an object animated by a PC2, or a body (mesh +\n"
           "PC2 of the same vertex count). The garment's positions are the initial state.\n\n"
           "options:\n"
           "  --garment G          garment mesh (.obj, .ply, .glb), required\n"
           "  --object O           collider: sphere (r 0.3 m), torus (0.3/0.1), prism (side 0.4),\n"
           "                       box (0.4) or a mesh file; static unless --body animates it\n"
           "  --body-mesh B        body mesh: the collider's faces\n"
           "  --body B.pc2         collider positions per frame (frame f moves from sample f to\n"
           "                       f+1, held at the last); vertex count must match the collider\n"
           "  --frames N           frames to simulate (required, >= 1)\n"
           "  --material M         cotton (default), silk, denim or knit\n"
           "  --material-json F    override material fields from a JSON object\n"
           "  --plastic            plastic bending: rest angles follow large folds\n"
           "  --pin i,j,...        vertices held at their initial positions\n"
           "  --substeps S         implicit Euler steps per frame (default 1)\n"
           "  --max-collider-step M  more substeps in frames where the collider moves further\n"
           "                       than M metres, ceil(motion / M) (default 0: off)\n"
           "  --newton-iterations N  Newton iterations per substep at most (default 8; 4 is about\n"
           "                       twice as fast and damps bending, docs/physics.md)\n"
           "  --fps F              frames per second (default 30)\n"
           "  --garment-offset X,Y,Z  move the garment by this vector, m, before simulating\n"
           "  -o DIR               outputs: sim.pc2 and sim.glb (sample 0 is the initial state),\n"
           "                       frames.jsonl (one line per frame), last.png\n"
           "  --quiet              no progress bar\n"
           "  --json               end with a JSON summary on stdout\n\n"
           "A frame the solver cannot finish even with 8x the substeps is reported (frame and\n"
           "reason); what was simulated before it is written, and the exit code is 1.\n");
}

typedef struct {
    const char *garment, *object, *body_mesh, *body, *material, *material_json, *out;
    int frames, substeps, newton_iterations, plastic, json, quiet, has_offset;
    float fps, offset[3], max_collider_step;
    int32_t *pins;
    int32_t npins;
} sim_opts;

/* --pin "i,j,k": appended to o->pins (the option may be repeated). */
static int parse_pins(const char *cmd, const char *opt, const char *const *v, void *dst) {
    sim_opts *o = dst;
    const char *s = v[0];
    int32_t n = 1;
    for (const char *c = s; *c; c++)
        n += *c == ',';
    if (n > MAX_PINS) return cli_usage(cmd, "--pin: at most %d vertices", MAX_PINS);
    int32_t *p = realloc(o->pins, (size_t)(o->npins + n) * sizeof *p);
    if (!p) return cli_usage(cmd, "--pin: out of memory");
    o->pins = p;
    char buf[32];
    for (const char *c = s; *c;) {
        size_t len = strcspn(c, ",");
        int idx;
        if (len == 0 || len >= sizeof buf) return cli_usage(cmd, "--pin: bad list '%s'", s);
        memcpy(buf, c, len);
        buf[len] = '\0';
        if (!cli_parse_int(cmd, opt, buf, 0, 2147483647L, &idx)) return CLI_USAGE;
        o->pins[o->npins++] = idx;
        c += len + (c[len] == ',');
    }
    return CLI_OK;
}

/* --garment-offset X,Y,Z */
static int parse_vec3(const char *cmd, const char *opt, const char *const *v, void *dst) {
    float *out = dst;
    char buf[128], *save = NULL;
    snprintf(buf, sizeof buf, "%s", v[0]);
    int k = 0;
    for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save), k++)
        if (k >= 3 || !cli_parse_float(cmd, opt, tok, -1e6, 1e6, &out[k])) return CLI_USAGE;
    if (k != 3) return cli_usage(cmd, "%s expects X,Y,Z, got '%s'", opt, v[0]);
    return CLI_OK;
}

static int parse(int argc, char **argv, sim_opts *o) {
    int npos = 0;
    const cli_opt opts[] = {
        CLI_STR("--garment", &o->garment),
        CLI_STR("--object", &o->object),
        CLI_STR("--body-mesh", &o->body_mesh),
        CLI_STR("--body", &o->body),
        CLI_STR("--material", &o->material),
        CLI_STR("--material-json", &o->material_json),
        CLI_OUTPUT(&o->out),
        CLI_INT("--frames", &o->frames, 1, 100000000),
        CLI_INT("--substeps", &o->substeps, 1, 4096),
        CLI_FLOAT("--max-collider-step", &o->max_collider_step, 0, 1000),
        CLI_INT("--newton-iterations", &o->newton_iterations, 1, 1000),
        CLI_FLOAT("--fps", &o->fps, 0.01, 100000),
        CLI_CUSTOM("--pin", parse_pins, o, 1),
        {.name = "--garment-offset",
         .kind = CLI_OPT_CUSTOM,
         .fn = parse_vec3,
         .dst = o->offset,
         .seen = &o->has_offset},
        CLI_FLAG("--plastic", &o->plastic),
        CLI_FLAG("--quiet", &o->quiet),
        CLI_FLAG("--json", &o->json),
        CLI_END,
    };
    int rc = cli_parse("simulate", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!o->garment) return cli_usage("simulate", "missing --garment G.obj");
    if (!o->out) return cli_usage("simulate", "missing -o DIR");
    if (o->frames < 1) return cli_usage("simulate", "missing --frames N");
    if (o->object && o->body_mesh)
        return cli_usage("simulate", "give --object or --body-mesh, not both");
    if (o->body && !o->object && !o->body_mesh)
        return cli_usage("simulate", "--body needs --body-mesh (or --object) for its faces");
    if (o->body_mesh && !o->body)
        return cli_usage("simulate", "--body-mesh needs --body B.pc2 (its animation)");
    return CLI_OK;
}

/* Everything a run holds, released together. */
typedef struct {
    cr_mesh *garment, *collider;
    cr_pc2 anim;
    cr_sim *sim;
    cr_scene_record *rec;
} sim_run;

static void run_free(sim_run *r, sim_opts *o) {
    cr_scene_record_destroy(r->rec);
    cr_sim_destroy(r->sim);
    cr_pc2_free(&r->anim);
    cr_mesh_destroy(r->collider);
    cr_mesh_destroy(r->garment);
    free(o->pins);
}

static cr_status setup(const sim_opts *o, sim_run *r, cr_sim_def *def, cr_error *err) {
    if (o->material_json) CR_TRY(cr_material_load_json(o->material_json, &def->material, err));
    CR_TRY(cr_mesh_read(o->garment, &r->garment, err));
    if (o->has_offset) cr_mesh_transform(r->garment, 1.0f, o->offset);
    const char *cname = o->object ? o->object : o->body_mesh;
    if (cname) {
        CR_TRY(o->object ? cr_scene_object_create(o->object, &r->collider, err)
                         : cr_mesh_read(o->body_mesh, &r->collider, err));
        def->collider = r->collider;
    }
    if (o->body) {
        CR_TRY(cr_scene_animation_read(o->body, r->collider, cname, &r->anim, err));
        def->collider_frames = r->anim.frames;
        def->collider_nframes = r->anim.nframes;
        if (r->anim.nframes < o->frames + 1)
            cr_log(CR_LOG_WARN, "%s: %d samples for %d frames; the collider holds its last pose",
                   o->body, r->anim.nframes, o->frames);
    }
    def->dt = 1.0 / o->fps;
    if (o->substeps > 0) def->substeps = o->substeps;
    def->max_collider_step = o->max_collider_step;
    if (o->newton_iterations > 0) def->newton_max_iterations = o->newton_iterations;
    def->plasticity = o->plastic;
    def->pinned = o->pins;
    def->npinned = o->npins;
    CR_TRY(cr_sim_create(def, r->garment, &r->sim, err));
    CR_TRY(cr_mkdir_p(o->out, err));
    char path[1200];
    snprintf(path, sizeof path, "%s/frames.jsonl", o->out);
    return cr_scene_record_create(path, r->sim, r->garment, o->frames + 1, &r->rec, err);
}

int cmd_simulate(int argc, char **argv) {
    sim_opts o = {.material = "cotton", .fps = 30.0f};
    int rc = parse(argc, argv, &o);
    if (rc != CLI_OK) {
        free(o.pins);
        return rc;
    }
    cr_error err = {0};
    cr_sim_def def = cr_sim_default_def();
    if (cr_material_preset(o.material, &def.material, &err) != CR_OK) {
        free(o.pins);
        return cli_usage("simulate", "%s", err.msg);
    }
    sim_run r = {0};
    if (setup(&o, &r, &def, &err) != CR_OK) {
        run_free(&r, &o);
        return cli_fail(&err);
    }

    cr_progress bar;
    cr_progress_begin(&bar, "simulate", o.frames, o.quiet);
    cr_sim_report rep = {0};
    double max_pen = 0.0, seconds = 0.0, split[4] = {0};
    long long newton = 0;
    int done = 0, backoffs = 0;
    cr_status st = CR_OK;
    cr_error sim_err = {0};
    while (done < o.frames) {
        cr_status step = cr_sim_step(r.sim, &rep, &sim_err);
        if (step != CR_OK && step != CR_ERR_DIVERGED) {
            st = step;
            err = sim_err;
            break;
        }
        st = cr_scene_record_frame(r.rec, r.sim, &rep, &err);
        if (step == CR_ERR_DIVERGED || st != CR_OK) break;
        done++;
        if (rep.max_penetration_m > max_pen) max_pen = rep.max_penetration_m;
        seconds += rep.seconds;
        split[0] += rep.seconds_assembly, split[1] += rep.seconds_factor;
        split[2] += rep.seconds_solve, split[3] += rep.seconds_collision;
        newton += rep.newton_iterations;
        backoffs += rep.backoffs;
        cr_progress_update(&bar, done, "%d Newton its, %.2f mm deepest", rep.newton_iterations,
                           1e3 * rep.max_penetration_m);
    }
    cr_progress_end(&bar);
    int diverged = rep.diverged;
    if (diverged)
        fprintf(stderr,
                "crease simulate: diverged at frame %d: %s; writing the %d frames before it\n",
                done + 1, rep.failure, done);

    char pc2[1200], glb[1200], png[1200], log[1200];
    snprintf(pc2, sizeof pc2, "%s/sim.pc2", o.out);
    snprintf(glb, sizeof glb, "%s/sim.glb", o.out);
    snprintf(png, sizeof png, "%s/last.png", o.out);
    snprintf(log, sizeof log, "%s/frames.jsonl", o.out);
    if (st == CR_OK) st = cr_scene_record_write(r.rec, pc2, glb, o.fps, &err);
    if (st == CR_OK) {
        const float *cpos = NULL;
        if (r.anim.frames) {
            int32_t k = done < r.anim.nframes - 1 ? done : r.anim.nframes - 1;
            cpos = r.anim.frames + (size_t)k * (size_t)r.anim.nv * 3;
        }
        st = cr_scene_render(png, r.garment, cr_scene_record_last(r.rec), r.collider, cpos,
                             RENDER_SIZE, &err);
    }
    if (st == CR_OK && !o.quiet)
        fprintf(stderr, "simulate: %d frames of %d vertices, %.3f s per frame, deepest %.3g mm\n",
                done, r.garment->nv, done ? seconds / done : 0.0, 1e3 * max_pen);
    if (st == CR_OK && !o.quiet)
        fprintf(stderr, "view: crease view %s+%s%s%s -o %s/view\n", glb, o.body ? o.body : "",
                o.body ? "@" : "", o.object ? o.object : o.body_mesh, o.out);
    if (st == CR_OK && o.json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "simulate");
        cJSON_AddNumberToObject(j, "frames", done);
        cJSON_AddNumberToObject(j, "frames_requested", o.frames);
        cJSON_AddBoolToObject(j, "diverged", diverged);
        if (diverged) {
            cJSON_AddNumberToObject(j, "diverged_frame", done + 1);
            cJSON_AddStringToObject(j, "failure", rep.failure);
        }
        cJSON_AddNumberToObject(j, "vertices", r.garment->nv);
        cJSON_AddStringToObject(j, "material", def.material.name);
        cJSON_AddNumberToObject(j, "max_penetration_m", max_pen);
        cJSON_AddNumberToObject(j, "seconds_per_frame", done ? seconds / done : 0.0);
        cJSON_AddNumberToObject(j, "seconds_assembly", split[0]);
        cJSON_AddNumberToObject(j, "seconds_factor", split[1]);
        cJSON_AddNumberToObject(j, "seconds_solve", split[2]);
        cJSON_AddNumberToObject(j, "seconds_collision", split[3]);
        cJSON_AddNumberToObject(j, "newton_iterations", (double)newton);
        cJSON_AddNumberToObject(j, "backoffs", backoffs);
        cJSON_AddNumberToObject(j, "threads", cr_thread_count());
        cJSON *out = cJSON_AddObjectToObject(j, "outputs");
        cJSON_AddStringToObject(out, "pc2", pc2);
        cJSON_AddStringToObject(out, "glb", glb);
        cJSON_AddStringToObject(out, "log", log);
        cJSON_AddStringToObject(out, "png", png);
        cli_json_print(j);
    }
    run_free(&r, &o);
    if (st != CR_OK) return cli_fail(&err);
    return diverged ? CLI_BAD_INPUT : CLI_OK;
}
