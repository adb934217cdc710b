/* cmd_motion.c: `crease motion`: write a procedural clip, or bring a BVH or
 * AMASS-style motion into crease's .npz; list the clips. */
#include "cli.h"
#include "crease/motion.h"

#include <string.h>

void help_motion(void) {
    printf("usage: crease motion --clip NAME [options] -o OUT.npz\n"
           "       crease motion --input FILE.bvh|FILE.npz [options] [-o OUT.npz]\n"
           "       crease motion --list\n\n"
           "Write a procedural motion clip (SMPL's 22 joints, starting at the rest pose and\n"
           "easing in), or load a BVH or AMASS-style .npz motion, turn it into crease's frame\n"
           "(+Y up, facing +Z, metres) and write it as crease's motion .npz.\n\n"
           "options:\n"
           "  --clip NAME      walk, run, jump, bend, raise_arms, squat, twist, dance, stairs,\n"
           "                   dodge, reach, lean, stretch (see --list)\n"
           "  --frames N       clip length in frames (default 120)\n"
           "  --fps F          clip frame rate (default 30); for an --input, resample to F\n"
           "                   (slerp; default: the file's rate)\n"
           "  --speed S        clip tempo multiplier, 0.25 to 4 (default 1)\n"
           "  --amplitude A    scale of the clip's angles and displacements, 0 to 1.5 (default 1)\n"
           "  --input FILE     a .bvh or .npz motion, or a rigged CHAR.glb[:MAP]'s own\n"
           "                   animation, to convert\n"
           "  --scale S        metres per BVH unit (default: the rig's known unit, CMU's\n"
           "                   cgspeed 0.0564 or Mixamo's cm, else inferred from its height)\n"
           "  --start-frame N  first frame of the file used (default 0; a calibration T-pose\n"
           "                   frame 0 is dropped unless --start-frame is given)\n"
           "  --end-frame N    last frame used (default: the last)\n"
           "  --ease-in S      seconds from the rest pose into the first frame (default 0 here;\n"
           "                   pose-body and dataset ease in over 1 s)\n"
           "  --ground MODE    clip (default: the posed mannequin's lowest foot point over the\n"
           "                   clip on y = 0), frame (each frame), none (the rig's lowest joint)\n"
           "  --no-recenter    keep a loaded motion where it is (default: frame 0 at the origin\n"
           "                   facing +Z)\n"
           "  -o OUT.npz       output motion (poses (T,66), trans (T,3), mocap_framerate)\n"
           "  --list           list the clips\n"
           "  --json           end with a JSON summary on stdout\n");
}

static int list_clips(int json) {
    int n = 0;
    const char *const *names = cr_motion_clip_names(&n);
    if (!json) {
        for (int i = 0; i < n; i++)
            printf("%-11s %s\n", names[i], cr_motion_clip_summary(names[i]));
        return CLI_OK;
    }
    cJSON *j = cJSON_CreateObject(), *arr = cJSON_CreateArray();
    cJSON_AddStringToObject(j, "command", "motion");
    for (int i = 0; i < n; i++) {
        cJSON *c = cJSON_CreateObject();
        cJSON_AddStringToObject(c, "name", names[i]);
        cJSON_AddStringToObject(c, "summary", cr_motion_clip_summary(names[i]));
        cJSON_AddItemToArray(arr, c);
    }
    cJSON_AddItemToObject(j, "clips", arr);
    cli_json_print(j);
    return CLI_OK;
}

int cmd_motion(int argc, char **argv) {
    cr_motion_clip_def def = cr_motion_clip_default_def();
    cli_motion_file mf = cli_motion_file_default(0.0f);
    const char *clip = NULL, *input = NULL, *out_path = NULL;
    int json = 0, list = 0, clip_only = 0, npos = 0, fps_set = 0;
    float fps = 0.0f;
    /* clip_only: set by the options that shape a procedural clip */
    const cli_opt opts[] = {
        CLI_FLAG("--json", &json),
        CLI_FLAG("--list", &list),
        CLI_FLAG("--no-recenter", &mf.no_recenter),
        CLI_STR("--clip", &clip),
        CLI_STR("--input", &input),
        CLI_OUTPUT(&out_path),
        {.name = "--frames",
         .kind = CLI_OPT_INT,
         .dst = &def.nframes,
         .lo = 1,
         .hi = 1000000,
         .seen = &clip_only},
        {.name = "--fps",
         .kind = CLI_OPT_FLOAT,
         .dst = &fps,
         .lo = 1e-3,
         .hi = 1000,
         .seen = &fps_set},
        {.name = "--speed",
         .kind = CLI_OPT_FLOAT,
         .dst = &def.speed,
         .lo = 0.25,
         .hi = 4,
         .seen = &clip_only},
        {.name = "--amplitude",
         .kind = CLI_OPT_FLOAT,
         .dst = &def.amplitude,
         .lo = 0,
         .hi = 1.5,
         .seen = &clip_only},
        CLI_MOTION_FILE_OPTS(&mf),
        CLI_END,
    };
    int rc = cli_parse("motion", argc, argv, opts, NULL, 0, &npos);
    if (rc != CLI_OK) return rc;
    if (list) return list_clips(json);
    if (!clip == !input) return cli_usage("motion", "give one of --clip NAME or --input FILE");
    if (input && clip_only)
        return cli_usage("motion", "--frames, --speed and --amplitude shape a --clip");
    if (clip && (mf.scale > 0 || mf.start_set || mf.end_frame >= 0 || mf.ease_in > 0))
        return cli_usage("motion", "--scale, --start-frame, --end-frame and --ease-in read a file");
    if (fps_set) def.fps = mf.fps = fps;
    if (clip && !cr_motion_clip_summary(clip))
        return cli_usage("motion", "unknown clip '%s' (see --list)", clip);
    if (clip && !out_path) return cli_usage("motion", "missing -o OUT.npz");
    cr_error err = {0};
    cr_motion *m = NULL;
    cr_motion_prepare_report rep;
    cr_status st;
    if (clip) {
        def.name = clip;
        st = cr_motion_clip_make(&def, &m, &err);
    } else {
        st = cli_motion_file_load(input, &mf, NULL, &m, &rep, &err);
    }
    if (st == CR_OK && out_path) st = cr_motion_save(out_path, m, &err);
    if (st != CR_OK) {
        cr_motion_destroy(m);
        return cli_fail(&err);
    }
    int joint = 0;
    float speed = cr_motion_max_angular_speed(m, &joint);
    if (json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "command", "motion");
        if (clip)
            cJSON_AddStringToObject(j, "clip", clip);
        else
            cJSON_AddStringToObject(j, "input", input);
        cJSON_AddNumberToObject(j, "frames", m->nframes);
        cJSON_AddNumberToObject(j, "fps", m->fps);
        cJSON_AddNumberToObject(j, "seconds", m->nframes / m->fps);
        if (out_path)
            cJSON_AddStringToObject(j, "output", out_path);
        else
            cJSON_AddNullToObject(j, "output");
        cJSON_AddNumberToObject(j, "max_angular_speed_rad_s", speed);
        cJSON_AddStringToObject(j, "max_angular_speed_joint", cr_joint_name[joint]);
        if (input) cli_motion_file_json(j, &rep);
        cli_json_print(j);
    } else {
        fprintf(stderr,
                "motion: %d frames at %g fps (%.2f s), fastest joint %s at %.2f rad/s%s%s\n",
                m->nframes, (double)m->fps, m->nframes / m->fps, cr_joint_name[joint],
                (double)speed, out_path ? ", written to " : "", out_path ? out_path : "");
    }
    cr_motion_destroy(m);
    return CLI_OK;
}
