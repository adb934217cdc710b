/* cli_motion.c: the options every command that reads a motion file shares
 * (cli.h, cli_motion_file), turned into the library's cr_motion_resolve_def:
 * every command takes a motion by cr_motion_resolve, a clip name or a file. */
#include "cli.h"
#include "crease/motion.h"

#include <string.h>

const char *const cli_ground_choices[] = {"clip", "frame", "none", NULL};

cli_motion_file cli_motion_file_default(float ease_in) {
    cli_motion_file mf;
    memset(&mf, 0, sizeof mf);
    mf.ease_in = ease_in;
    mf.end_frame = -1;
    mf.ground = "clip";
    return mf;
}

void cli_motion_file_defs(const cli_motion_file *mf, cr_motion_import_def *imp,
                          cr_motion_prepare_def *pd) {
    *imp = cr_motion_import_default_def();
    imp->bvh_scale = mf->scale;
    imp->recenter = !mf->no_recenter;
    *pd = cr_motion_prepare_default_def();
    pd->fps = mf->fps;
    pd->start_frame = mf->start_frame;
    pd->end_frame = mf->end_frame;
    pd->drop_calibration = !mf->start_set;
    pd->ease_in_s = mf->ease_in;
    pd->ground = !strcmp(mf->ground, "clip")    ? CR_MOTION_GROUND_CLIP
                 : !strcmp(mf->ground, "frame") ? CR_MOTION_GROUND_FRAME
                                                : CR_MOTION_GROUND_NONE;
}

cr_motion_resolve_def cli_motion_resolve_def(const cli_motion_file *mf, const cr_body_model *b) {
    cr_motion_resolve_def rd = cr_motion_resolve_default_def();
    cli_motion_file_defs(mf, &rd.import, &rd.prepare);
    rd.fps = mf->fps, rd.body = b;
    return rd;
}

cr_status cli_motion_file_load(const char *path, const cli_motion_file *mf, const cr_body_model *b,
                               cr_motion **out, cr_motion_prepare_report *rep, cr_error *err) {
    cr_motion_resolve_def rd = cli_motion_resolve_def(mf, b);
    return cr_motion_resolve(path, &rd, out, rep, err);
}

void cli_motion_file_json(cJSON *j, const cr_motion_prepare_report *rep) {
    cJSON_AddNumberToObject(j, "source_fps", rep->source_fps);
    cJSON_AddNumberToObject(j, "source_frames", rep->source_frames);
    cJSON_AddNumberToObject(j, "first_frame", rep->first_frame);
    cJSON_AddNumberToObject(j, "last_frame", rep->last_frame);
    cJSON_AddBoolToObject(j, "calibration_dropped", rep->calibration_dropped);
    cJSON_AddNumberToObject(j, "ease_in_frames", rep->ease_frames);
    cJSON_AddNumberToObject(j, "ground_shift_m", rep->ground_shift_m);
}
