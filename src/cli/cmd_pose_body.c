/* cmd_pose_body.c: `crease pose-body`: skin the procedural mannequin through
 * a procedural clip or a motion file and write the posed sequence as a PC2
 * point cache (with the rest mesh beside it as OBJ) or a skinned, animated .glb. */
#include "cli.h"
#include "crease/body.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"

#include <stdlib.h>
#include <string.h>

void help_pose_body(void) {
    printf("usage: crease pose-body (--clip NAME | --motion FILE) [options] -o OUT.pc2|OUT.glb\n\n"
           "Pose the procedural mannequin with every frame of a motion (linear blend skinning)\n"
           "and write it: OUT.pc2 is a point cache of the vertex positions, written with the\n"
           "rest mesh as OUT.obj beside it (the cache holds no faces); OUT.glb is a skinned,\n"
           "animated character (SMPL's 22 joints by name, the A-pose as bind pose, one\n"
           "animation) that game engines, Blender and three.js play.\n\n"
           "options:\n"
           "  --shape NAME     body preset: slim, normal (default) or heavy\n"
           "  --height M       body height, m, 1 to 2.5 (default 1.75)\n"
           "  --res N          mannequin resolution, 32 to 512 (default 110)\n"
           "  --clip NAME      a procedural clip (see 'crease motion --list')\n"
           "  --motion FILE    a .bvh or .npz motion (crease's own or AMASS-style), or a\n"
           "                   rigged CHAR.glb[:MAP]'s own animation\n"
           "  --frames N       clip length (default 120); for a file, the first N frames\n"
           "                   (default all)\n"
           "  --fps F          clip frame rate (default 30); a file is resampled to F (slerp;\n"
           "                   default: the file's rate)\n"
           "  --scale S        metres per BVH unit (default: the rig's known unit or inferred)\n"
           "  --start-frame N  first frame of the file used (default 0; a calibration T-pose\n"
           "                   frame 0 is dropped unless --start-frame is given)\n"
           "  --end-frame N    last frame of the file used (default: the last)\n"
           "  --ease-in S      a file's motion starts at the rest pose (where garments are\n"
           "                   fitted) and eases into its first frame over S s (default 1; 0:\n"
           "                   none)\n"
           "  --ground MODE    clip (default: the body's lowest foot point over the clip on\n"
           "                   y = 0), frame (each frame) or none\n"
           "  --rest POSE      apose (default): the motion is relative to crease's one rest,\n"
           "                   the mannequin's A-pose (every loader retargets onto it); tpose:\n"
           "                   a crease .npz written against SMPL's T-pose by another tool\n"
           "  --json           end with a JSON summary on stdout: frames, fps, vertices,\n"
           "                   faces, paths, seconds\n");
}

typedef struct pose_opts {
    const char *shape, *clip, *motion, *rest, *out;
    float height, fps;
    int res, frames, json, file_set;
    cli_motion_file mf;
} pose_opts;

static int parse(int argc, char **argv, pose_opts *o) {
    static const char *const rests[] = {"apose", "tpose", NULL};
    int npos = 0;
    const cli_opt opts[] = {
        CLI_FLAG("--json", &o->json),
        CLI_STR("--shape", &o->shape),
        CLI_STR("--clip", &o->clip),
        CLI_STR("--motion", &o->motion),
        CLI_CHOICE("--rest", &o->rest, rests),
        CLI_OUTPUT(&o->out),
        CLI_FLOAT("--height", &o->height, 1.0, 2.5),
        CLI_FLOAT("--fps", &o->fps, 1e-3, 1000),
        CLI_INT("--res", &o->res, 32, 512),
        CLI_INT("--frames", &o->frames, 1, 1000000),
        CLI_MOTION_FILE_OPTS(&o->mf),
        CLI_END,
    };
    int rc = cli_parse("pose-body", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (!o->clip == !o->motion)
        return cli_usage("pose-body", "give one of --clip NAME or --motion FILE");
    if (o->clip && !cr_motion_clip_summary(o->clip))
        return cli_usage("pose-body", "unknown clip '%s' (see 'crease motion --list')", o->clip);
    o->mf.fps = o->fps;
    if (o->clip && o->rest) return cli_usage("pose-body", "--rest applies to a --motion file");
    if (o->clip && (o->mf.scale > 0 || o->mf.start_set || o->mf.end_frame >= 0))
        return cli_usage("pose-body",
                         "--scale, --start-frame and --end-frame read a --motion file");
    if (!o->out) return cli_usage("pose-body", "missing -o OUT.pc2 or OUT.glb");
    char ext[16];
    cr_path_ext(o->out, ext, sizeof ext);
    if (strcmp(ext, "pc2") != 0 && strcmp(ext, "glb") != 0)
        return cli_usage("pose-body", "output '%s': expected .pc2 or .glb", o->out);
    return CLI_OK;
}

static cr_status load_motion(const pose_opts *o, const cr_body_model *b, float arm_angle_deg,
                             cr_motion **m, cr_motion_prepare_report *rep, cr_error *err) {
    if (o->clip)
        return cr_motion_clip(o->clip, o->frames ? o->frames : 120, o->fps > 0 ? o->fps : 30.0f, m,
                              err);
    CR_TRY(cli_motion_file_load(o->motion, &o->mf, b, m, rep, err));
    if (o->rest && strcmp(o->rest, "tpose") == 0) {
        float apose[CR_NJOINTS * 3];
        cr_motion_apose_from_tpose(arm_angle_deg, apose);
        cr_motion_rebase(*m, apose);
    }
    if (o->frames && o->frames < (*m)->nframes) (*m)->nframes = o->frames;
    return CR_OK;
}

/* OUT.pc2's rest mesh: the same path with .obj for its extension. */
static void sibling_obj(const char *path, char *out, size_t cap) {
    snprintf(out, cap, "%s", path);
    char *dot = strrchr(out, '.');
    if (dot && (size_t)(dot - out) + 5 <= cap) strcpy(dot, ".obj");
}

int cmd_pose_body(int argc, char **argv) {
    pose_opts o = {.shape = "normal", .mf = cli_motion_file_default(1.0f)};
    int rc = parse(argc, argv, &o);
    if (rc != CLI_OK) return rc;
    cr_error err = {0};
    cr_mannequin_def def = cr_mannequin_default_def();
    if (cr_mannequin_preset(o.shape, &def, &err) != CR_OK)
        return cli_usage("pose-body", "%s", err.msg);
    if (o.height > 0.0f) def.height_m = o.height;
    if (o.res) def.resolution = o.res;

    double t0 = cr_time_now();
    cr_body_model *b = NULL;
    cr_motion *m = NULL;
    float *frames = NULL;
    char obj_path[1024] = "";
    cr_motion_prepare_report rep;
    cr_status st = cr_mannequin_create(&def, &b, &err);
    if (st == CR_OK) st = load_motion(&o, b, def.arm_angle_deg, &m, &rep, &err);
    char ext[16];
    cr_path_ext(o.out, ext, sizeof ext);
    if (st == CR_OK && strcmp(ext, "glb") == 0) {
        st = cr_body_write_glb(o.out, b, m, NULL, NULL, &err);
    } else if (st == CR_OK) {
        st = cr_body_pose_motion(b, m, &frames, &err);
        if (st == CR_OK)
            st = cr_pc2_write(o.out, frames, b->rest->nv, m->nframes, 0.0f, 1.0f, &err);
        sibling_obj(o.out, obj_path, sizeof obj_path);
        if (st == CR_OK) st = cr_mesh_write(obj_path, b->rest, &err);
    }
    double seconds = cr_time_now() - t0;
    if (st == CR_OK && o.json) {
        cJSON *j = cJSON_CreateObject(), *paths = cJSON_CreateArray();
        cJSON_AddStringToObject(j, "command", "pose-body");
        cJSON_AddStringToObject(j, "shape", o.shape);
        if (o.clip)
            cJSON_AddStringToObject(j, "clip", o.clip);
        else
            cJSON_AddStringToObject(j, "motion", o.motion);
        if (o.motion) cli_motion_file_json(j, &rep);
        cJSON_AddNumberToObject(j, "frames", m->nframes);
        cJSON_AddNumberToObject(j, "fps", m->fps);
        cJSON_AddNumberToObject(j, "vertices", b->rest->nv);
        cJSON_AddNumberToObject(j, "faces", b->rest->nf);
        cJSON_AddItemToArray(paths, cJSON_CreateString(o.out));
        if (obj_path[0]) cJSON_AddItemToArray(paths, cJSON_CreateString(obj_path));
        cJSON_AddItemToObject(j, "paths", paths);
        cJSON_AddNumberToObject(j, "seconds", seconds);
        cli_json_print(j);
    } else if (st == CR_OK) {
        fprintf(stderr,
                "pose-body: %d frames of %d vertices at %g fps written to %s%s%s (%.2f s)\n",
                m->nframes, b->rest->nv, (double)m->fps, o.out, obj_path[0] ? " and " : "",
                obj_path, seconds);
    }
    free(frames);
    cr_motion_destroy(m);
    cr_body_model_destroy(b);
    return st == CR_OK ? CLI_OK : cli_fail(&err);
}
