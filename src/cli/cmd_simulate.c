/* cmd_simulate.c: `crease simulate`: run the reference cloth simulator on a
 * garment against a static object or an animated body, writing the sequence
 * (PC2, glb), a per-frame JSON lines log and a picture of the last frame:
 * parse, one library call (cr_scene_simulate, crease/scene.h), report. */
#include "cli.h"
#include "crease/body.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/phys_sim.h"
#include "crease/scene.h"

#include <stdlib.h>
#include <string.h>

enum { RENDER_SIZE = 800, MAX_PINS = 1 << 20 };

void help_simulate(void) {
    printf(
        "usage: crease simulate --garment G.obj (--object O | --body-mesh B.obj --body B.pc2 |\n"
        "                       --motion CLIP|FILE | --body-mesh CHAR.glb [--motion F.bvh])\n"
        "                       --frames N -o DIR [options]\n\n"
        "Simulate a garment with the reference implicit-Euler Newton solver (docs/physics.md)\n"
        "against a collider: a static object, an object animated by a PC2, or a body (mesh +\n"
        "PC2 of the same vertex count). The garment's positions are the initial state.\n\n"
        "options:\n"
        "  --garment G          garment mesh (.obj, .ply, .glb), required\n"
        "  --object O           collider: sphere (r 0.3 m), torus (0.3/0.1), prism (side 0.4),\n"
        "                       box (0.4) or a mesh file; static unless --body animates it\n"
        "  --body-mesh B        body mesh: the collider's faces; a .glb character (skinned,\n"
        "                       any skeleton) or sequence moves by its own animation, or a\n"
        "                       rigged .glb by --motion F.bvh (or another rigged\n"
        "                       OTHER.glb[:MAP]'s own animation) retargeted onto its skeleton\n"
        "                       (joints matched by name: SMPL, Mixamo, CMU, DAZ, Unreal,\n"
        "                       Rigify; eased in from its rest pose over --ease-in S, default\n"
        "                       1; --scale, --start-frame and --end-frame (the BVH's frames)\n"
        "                       as below; written with the garment as DIR/scene.glb;\n"
        "                       docs/body.md)\n"
        "  --joint-map F        with --body-mesh CHAR.glb --motion F.bvh: lines\n"
        "                       'character_joint = bvh_joint' (# comments) that override the\n"
        "                       name matching; 'joint =' leaves a joint unmapped; or a JSON\n"
        "                       object {\"character_joint\": \"bvh_joint\", ...}\n"
        "  --body B.pc2         collider positions per frame (frame f moves from sample f to\n"
        "                       f+1, held at the last); vertex count must match the collider\n"
        "  --motion CLIP|FILE   collider: the mannequin (or --body B: a preset, an SMPL-family\n"
        "                       FILE.npz[:betas] or a rigged CHAR.glb[:MAP], docs/body.md)\n"
        "                       posed by a clip (crease motion --list), a .bvh or .npz\n"
        "                       motion or a rigged CHAR.glb[:MAP]'s own animation,\n"
        "                       resampled to --fps, starting at the rest pose (where\n"
        "                       garments are fitted) and easing in, written as DIR/body.obj\n"
        "                       and DIR/body.pc2, and with the garment as DIR/scene.glb (a\n"
        "                       skinned character); with --scale, --start-frame, --end-frame,\n"
        "                       --ease-in S (default 1) and --ground as in pose-body\n"
        "  --frames N           frames to simulate (required, >= 1)\n"
        "  --material M         cotton (default), silk, denim or knit\n"
        "  --material-json F    override material fields from a JSON object\n"
        "  --plastic            plastic bending: rest angles follow large folds (rest_angles.npy)\n"
        "  --solver S           newton (default: Newton + CHOLMOD, the converged reference)\n"
        "                       or vbd (vertex block descent, no "
        "factorisation)\n" CLI_SELF_CONTACT_HELP
        "  --pin i,j,...        vertices held at their initial positions\n"
        "  --substeps S         implicit Euler steps per frame (default 1)\n"
        "  --max-collider-step M  more substeps in frames where the collider moves further\n"
        "                       than M metres, ceil(motion / M) (default 0: off)\n"
        "  --newton-iterations N  Newton iterations per substep at most (default 8; 4 is about\n"
        "                       twice as fast and damps bending, docs/physics.md)\n"
        "  --vbd-iterations N   VBD sweeps per substep at most (default 30; fewer are faster\n"
        "                       and further from the converged step, docs/physics.md)\n"
        "  --vbd-tolerance T    a VBD substep stops when a sweep moves no vertex further than\n"
        "                       T / fps / substeps (m/s; default 1e-3, Newton's; 1e-5 with\n"
        "                       --vbd-coarse 2 --vbd-iterations 100 is near converged Newton)\n"
        "  --vbd-coarse N       VBD's coarse-level correction every N sweeps: a Newton step on\n"
        "                       patches of vertices that removes the stretch the sweeps leave\n"
        "                       after an impact (0: off; default: the simulator's)\n"
        "  --vbd-coarse-rings R  a patch is a vertex and its neighbours within R rings, 1..8\n"
        "  --vbd-coarse-refresh K  the coarse matrix again every K corrections (and at each\n"
        "                       substep's first); between, the last one with a new gradient\n"
        "  --fps F              frames per second (default 30)\n"
        "  --garment-offset X,Y,Z  move the garment by this vector, m, before "
        "simulating\n" CLI_TWIN_HELP
        "  -o DIR               outputs: sim.pc2 and sim.glb (sample 0 is the initial state),\n"
        "                       frames.jsonl (one line per frame), last.png\n"
        "  --quiet              no progress bar\n"
        "  --json               end with a JSON summary on stdout\n\n"
        "A frame the solver cannot finish even with 8x the substeps is reported (frame and\n"
        "reason); what was simulated before it is written, and the exit code is 1.\n");
}

typedef struct {
    const char *garment, *object, *body_mesh, *body, *motion, *material, *material_json, *out;
    const char *joint_map;
    const char *solver, *self_contact;
    float self_contact_thickness;
    cli_motion_file mf; /* --motion's options */
    cli_twin twin;
    int frames, substeps, newton_iterations, vbd_iterations, plastic, json, quiet, has_offset;
    int vbd_coarse_every, vbd_coarse_rings, vbd_coarse_refresh;
    float fps, offset[3], max_collider_step, vbd_tol;
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

static int parse(int argc, char **argv, sim_opts *o) {
    int npos = 0;
    const cli_opt opts[] = {
        CLI_STR("--garment", &o->garment),
        CLI_STR("--object", &o->object),
        CLI_STR("--body-mesh", &o->body_mesh),
        CLI_STR("--body", &o->body),
        CLI_STR("--motion", &o->motion),
        CLI_STR("--joint-map", &o->joint_map),
        CLI_MOTION_FILE_OPTS(&o->mf),
        CLI_STR("--material", &o->material),
        CLI_STR("--material-json", &o->material_json),
        CLI_OUTPUT(&o->out),
        CLI_INT("--frames", &o->frames, 1, 100000000),
        CLI_INT("--substeps", &o->substeps, 1, 4096),
        CLI_FLOAT("--max-collider-step", &o->max_collider_step, 0, 1000),
        CLI_INT("--newton-iterations", &o->newton_iterations, 1, 1000),
        CLI_INT("--vbd-iterations", &o->vbd_iterations, 1, 100000),
        CLI_FLOAT("--vbd-tolerance", &o->vbd_tol, 1e-9, 1),
        CLI_INT("--vbd-coarse", &o->vbd_coarse_every, 0, 100000),
        CLI_INT("--vbd-coarse-rings", &o->vbd_coarse_rings, 1, 8),
        CLI_INT("--vbd-coarse-refresh", &o->vbd_coarse_refresh, 1, 100000),
        CLI_FLOAT("--fps", &o->fps, 0.01, 100000),
        CLI_CUSTOM("--pin", parse_pins, o, 1),
        {.name = "--garment-offset",
         .kind = CLI_OPT_CUSTOM,
         .fn = cli_parse_vec3,
         .dst = o->offset,
         .seen = &o->has_offset},
        CLI_CHOICE("--solver", &o->solver, cli_solvers),
        CLI_SELF_CONTACT_OPTS(&o->self_contact, &o->self_contact_thickness),
        CLI_FLAG("--plastic", &o->plastic),
        CLI_TWIN_OPTS(&o->twin),
        CLI_FLAG("--quiet", &o->quiet),
        CLI_FLAG("--json", &o->json),
        CLI_END,
    };
    int rc = cli_parse("simulate", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!o->garment) return cli_usage("simulate", "missing --garment G.obj");
    if (!o->out) return cli_usage("simulate", "missing -o DIR");
    if (o->frames < 1) return cli_usage("simulate", "missing --frames N");
    char ext[16] = "", mext[16] = "";
    if (o->body_mesh) cr_path_ext(o->body_mesh, ext, sizeof ext);
    if (o->motion) cr_path_ext(o->motion, mext, sizeof mext);
    if (o->motion && o->body_mesh &&
        (strcmp(ext, "glb") != 0 || (strcmp(mext, "bvh") != 0 && !strstr(o->motion, ".glb")) ||
         o->body || o->object))
        return cli_usage("simulate", "--motion with --body-mesh: a .bvh or another character's "
                                     ".glb driving a rigged .glb character (no --body, --object)");
    if (o->motion && !o->body_mesh && (o->object || (o->body && strstr(o->body, ".pc2"))))
        return cli_usage("simulate", "--motion poses a body model (--body a preset, FILE.npz or "
                                     "CHAR.glb): no --object, no --body B.pc2");
    if (o->joint_map && !(o->motion && o->body_mesh))
        return cli_usage("simulate", "--joint-map needs --body-mesh CHAR.glb --motion F.bvh");
    if (o->object && o->body_mesh)
        return cli_usage("simulate", "give --object or --body-mesh, not both");
    if (o->body && !o->object && !o->body_mesh && !o->motion)
        return cli_usage("simulate", "--body needs --body-mesh (or --object) for its faces");
    if (o->body_mesh && !o->body && strcmp(ext, "glb") != 0)
        return cli_usage("simulate", "--body-mesh needs --body B.pc2 (its animation), or a .glb");
    return CLI_OK;
}

int cmd_simulate(int argc, char **argv) {
    sim_opts o = {.material = "cotton",
                  .fps = 30.0f,
                  .mf = cli_motion_file_default(1.0f),
                  .vbd_coarse_every = -1};
    int rc = parse(argc, argv, &o);
    cr_error err = {0};
    cr_material material;
    if (rc == CLI_OK && cr_material_preset(o.material, &material, &err) != CR_OK)
        rc = cli_usage("simulate", "%s", err.msg);
    if (rc != CLI_OK) {
        free(o.pins);
        return rc;
    }
    cr_scene_sim_def def = cr_scene_sim_default_def();
    def.garment = o.garment, def.garment_offset = o.has_offset ? o.offset : NULL;
    def.object = o.object, def.body_mesh = o.body_mesh;
    def.body = o.motion && !o.body_mesh ? NULL : o.body;
    def.material = o.material, def.material_json = o.material_json;
    def.frames = o.frames, def.fps = o.fps, def.substeps = o.substeps;
    def.newton_iterations = o.newton_iterations, def.vbd_iterations = o.vbd_iterations;
    def.vbd_coarse_every = o.vbd_coarse_every, def.vbd_coarse_rings = o.vbd_coarse_rings;
    def.vbd_coarse_refresh = o.vbd_coarse_refresh, def.vbd_tol = o.vbd_tol;
    def.max_collider_step = o.max_collider_step;
    def.plastic = o.plastic, def.pins = o.pins, def.npins = o.npins;
    def.solver = cr_sim_solver_parse(o.solver ? o.solver : "newton");
    def.self_contact = cli_self_contact(o.self_contact);
    def.self_thickness = o.self_contact_thickness;
    def.out_dir = o.out, def.render_size = RENDER_SIZE, def.quiet = o.quiet;
    cli_twin_get(&o.twin, &def.twin);
    if (o.motion && o.body_mesh) { /* a BVH driving the user's character */
        def.body_motion = o.motion, def.joint_map = o.joint_map;
        def.body_bvh_scale = o.mf.scale, def.body_ease_in_s = o.mf.ease_in;
        def.body_start_frame = o.mf.start_set ? o.mf.start_frame : -1;
        def.body_end_frame = o.mf.end_frame;
    } else if (o.motion) { /* a body model (the mannequin by default) posed by it */
        def.pose_motion = o.motion, def.pose_body = o.body;
        def.pose_def = cli_motion_resolve_def(&o.mf, NULL);
    }
    cr_scene_sim_result r;
    cr_status st = cr_scene_simulate(&def, &r, &err);
    free(o.pins);
    if (st != CR_OK) return cli_fail(&err);

    const cr_scene_run_stats *run = &r.run;
    int done = run->frames;
    double per_frame = done ? run->seconds / done : 0.0;
    if (run->diverged)
        fprintf(stderr,
                "crease simulate: diverged at frame %d: %s; writing the %d frames before it\n",
                done + 1, run->failure, done);
    if (!o.quiet)
        fprintf(stderr, "simulate: %d frames of %d vertices, %.3f s per frame, deepest %.3g mm\n",
                done, r.vertices, per_frame, 1e3 * run->max_penetration_m);
    const char *collider = r.body_mesh[0]  ? r.body_mesh
                           : def.body_mesh ? def.body_mesh
                                           : def.object;
    const char *anim = r.body_pc2[0] ? r.body_pc2 : def.body;
    if (!o.quiet && collider && anim)
        fprintf(stderr, "view: crease view %s+%s@%s -o %s/view\n", r.glb, anim, collider, o.out);
    else if (!o.quiet)
        fprintf(stderr, "view: crease view %s%s%s -o %s/view\n", r.glb, collider ? "+" : "",
                collider ? collider : "", o.out);
    if (o.json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "simulate");
        cJSON_AddNumberToObject(j, "frames", done);
        cJSON_AddNumberToObject(j, "frames_requested", o.frames);
        cJSON_AddBoolToObject(j, "diverged", run->diverged);
        if (run->diverged) {
            cJSON_AddNumberToObject(j, "diverged_frame", done + 1);
            cJSON_AddStringToObject(j, "failure", run->failure);
        }
        cJSON_AddNumberToObject(j, "vertices", r.vertices);
        cJSON_AddStringToObject(j, "material", r.material);
        cli_twin_json(j, &def.twin);
        cJSON_AddNumberToObject(j, "max_penetration_m", run->max_penetration_m);
        cJSON_AddNumberToObject(j, "seconds_per_frame", per_frame);
        cJSON_AddNumberToObject(j, "seconds_assembly", run->seconds_assembly);
        cJSON_AddNumberToObject(j, "seconds_factor", run->seconds_factor);
        cJSON_AddNumberToObject(j, "seconds_solve", run->seconds_solve);
        cJSON_AddNumberToObject(j, "seconds_collision", run->seconds_collision);
        cJSON_AddNumberToObject(j, "newton_iterations", (double)run->newton_iterations);
        cJSON_AddNumberToObject(j, "backoffs", (double)run->backoffs);
        if (run->vbd_coarse_steps > 0)
            cJSON_AddNumberToObject(j, "vbd_coarse_steps", (double)run->vbd_coarse_steps);
        cJSON_AddNumberToObject(j, "threads", cr_thread_count());
        cJSON *out = cJSON_AddObjectToObject(j, "outputs");
        cJSON_AddStringToObject(out, "pc2", r.pc2);
        cJSON_AddStringToObject(out, "glb", r.glb);
        cJSON_AddStringToObject(out, "log", r.log);
        if (r.rest_angles[0]) cJSON_AddStringToObject(out, "rest_angles", r.rest_angles);
        if (r.scene[0]) cJSON_AddStringToObject(out, "scene", r.scene);
        cJSON_AddStringToObject(out, "png", r.png);
        cli_json_print(j);
    }
    return run->diverged ? CLI_BAD_INPUT : CLI_OK;
}
