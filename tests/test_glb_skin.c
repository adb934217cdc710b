/* test_glb_skin.c: skinned, animated glb characters (src/geom/io_glb_skin.c)
 * round-trip: what cr_glb_write_skinned writes, cr_glb_read_sequence poses
 * back as crease's own linear blend skinning does, for the mannequin and for
 * a skeleton with other joint names; bad input is refused by name. */
#include "crease/body.h"
#include "crease/mesh_io.h"
#include "crease/motion.h"
#include "crease/primitives.h"
#include "test.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *tmp(const char *name) {
    static char path[512];
    snprintf(path, sizeof path, "%s/%s", cr_test_tmpdir(), name);
    return path;
}

/* The file's JSON chunk, parsed. */
static cJSON *file_json(const char *path) {
    char *buf = NULL;
    size_t len = 0;
    cr_error err = {0};
    if (cr_file_read_all(path, &buf, &len, &err) != CR_OK || len < 20) return NULL;
    uint32_t jlen;
    memcpy(&jlen, buf + 12, 4);
    cJSON *j = cJSON_ParseWithLength(buf + 20, jlen);
    free(buf);
    return j;
}

/* The mannequin walking: the file posed by its skin and animation is where
 * cr_body_pose_motion puts every vertex, to float rounding; the joints carry
 * SMPL's names, parents and rest offsets. */
CR_TEST(glb_skin, mannequin_round_trip) {
    cr_error err = {0};
    cr_mannequin_def def = cr_mannequin_default_def();
    def.resolution = 48;
    cr_body_model *b = NULL;
    cr_motion *m = NULL;
    CR_CHECK_OK(cr_mannequin_create(&def, &b, &err), &err);
    CR_CHECK_OK(cr_motion_clip("walk", 12, 24.0f, &m, &err), &err);
    CR_REQUIRE(b && m);
    for (int32_t t = 0; t < m->nframes; t++)
        m->trans[3 * t] = 0.05f * t; /* the root moves too */
    float *want = NULL;
    CR_CHECK_OK(cr_body_pose_motion(b, m, &want, &err), &err);
    CR_CHECK_OK(cr_body_write_glb(tmp("walk.glb"), b, m, NULL, NULL, &err), &err);
    cr_mesh *rest = NULL;
    float *got = NULL, fps = 0.0f;
    int32_t nt = 0;
    CR_CHECK_OK(cr_glb_read_sequence(tmp("walk.glb"), &rest, &got, &nt, &fps, &err), &err);
    CR_REQUIRE(rest && got && want);
    CR_CHECK(nt == m->nframes && fps == 24.0f && rest->nv == b->rest->nv);
    double worst = 0.0, moved = 0.0;
    for (int64_t i = 0; i < (int64_t)nt * rest->nv * 3; i++) {
        worst = fmax(worst, fabs(got[i] - want[i]));
        moved = fmax(moved, fabs(want[i] - b->rest->pos[i % (3 * (int64_t)rest->nv)]));
    }
    printf("    %d frames of %d vertices: largest difference %.2e m (the body moved %.2f m)\n", nt,
           rest->nv, worst, moved);
    CR_CHECK(moved > 0.3);
    CR_CHECK(worst < 2e-5);
    cJSON *j = file_json(tmp("walk.glb"));
    CR_REQUIRE(j);
    const cJSON *skin = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "skins"), 0);
    const cJSON *nodes = cJSON_GetObjectItem(j, "nodes");
    CR_CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(skin, "joints")) == CR_NJOINTS);
    CR_CHECK(cJSON_GetArraySize(nodes) == 1 + CR_NJOINTS);
    for (int k = 0; k < CR_NJOINTS; k++) {
        const cJSON *n = cJSON_GetArrayItem(nodes, 1 + k);
        CR_CHECK(strcmp(cJSON_GetStringValue(cJSON_GetObjectItem(n, "name")), cr_joint_name[k]) ==
                 0);
    }
    /* The left knee is a child of the left hip; its offset is the rest one. */
    const cJSON *hip = cJSON_GetArrayItem(nodes, 1 + CR_JOINT_LEFT_HIP);
    const cJSON *knee = cJSON_GetArrayItem(nodes, 1 + CR_JOINT_LEFT_KNEE);
    const cJSON *kids = cJSON_GetObjectItem(hip, "children");
    CR_CHECK(cJSON_GetArraySize(kids) == 1 &&
             cJSON_GetArrayItem(kids, 0)->valueint == 1 + CR_JOINT_LEFT_KNEE);
    const cJSON *kt = cJSON_GetObjectItem(knee, "translation");
    for (int k = 0; k < 3; k++)
        CR_CHECK_NEAR(cJSON_GetArrayItem(kt, k)->valuedouble,
                      b->joints[3 * CR_JOINT_LEFT_KNEE + k] - b->joints[3 * CR_JOINT_LEFT_HIP + k],
                      1e-6);
    const cJSON *anim = cJSON_GetArrayItem(cJSON_GetObjectItem(j, "animations"), 0);
    CR_CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(anim, "channels")) == 1 + CR_NJOINTS);
    cJSON_Delete(j);
    free(want), free(got);
    cr_mesh_destroy(rest);
    cr_motion_destroy(m);
    cr_body_model_destroy(b);
}

/* A skeleton that is not SMPL's: three joints named as another tool names
 * them, a tube bent at its middle joint by 90 degrees in the second frame.
 * The tip's vertices, bound to the last joint alone, turn rigidly about it. */
CR_TEST(glb_skin, other_skeleton) {
    cr_error err = {0};
    cr_mesh *tube = NULL;
    CR_CHECK_OK(cr_prim_cylinder(0.05f, 1.0f, 8, 10, 0, &tube, &err), &err);
    CR_REQUIRE(tube);
    const char *names[3] = {"Hips", "mixamorig:Spine", "mixamorig:Spine1"};
    const int32_t parent[3] = {-1, 0, 1};
    const float joints[9] = {0, -0.5f, 0, 0, 0, 0, 0, 0.25f, 0};
    int32_t *sj = calloc((size_t)tube->nv * 4, sizeof(int32_t));
    float *sw = calloc((size_t)tube->nv * 4, sizeof(float));
    for (int32_t v = 0; v < tube->nv; v++) {
        float y = tube->pos[3 * v + 1];
        sj[4 * v] = y < 0.0f ? 0 : y < 0.25f ? 1 : 2;
        sw[4 * v] = 1.0f;
    }
    float rot[2 * 3 * 4] = {0}, trans[6] = {0};
    for (int k = 0; k < 6; k++)
        rot[4 * k + 3] = 1.0f;
    rot[4 * (3 + 1) + 2] = (float)sin(M_PI / 4), rot[4 * (3 + 1) + 3] = (float)cos(M_PI / 4);
    cr_glb_skin skin = {3, names, parent, joints, sj, sw};
    cr_glb_skin_motion mo = {2, 10.0f, rot, trans};
    CR_CHECK_OK(cr_glb_write_skinned(tmp("tube.glb"), tube, &skin, &mo, NULL, &err), &err);
    cr_mesh *rest = NULL;
    float *got = NULL, fps = 0.0f;
    int32_t nt = 0;
    CR_CHECK_OK(cr_glb_read_sequence(tmp("tube.glb"), &rest, &got, &nt, &fps, &err), &err);
    CR_REQUIRE(rest && got);
    CR_CHECK(nt == 2 && fps == 10.0f);
    double worst0 = 0.0, worst1 = 0.0;
    for (int32_t v = 0; v < rest->nv; v++) {
        const float *p = rest->pos + 3 * v, *a = got + 3 * v, *c = got + 3 * (rest->nv + v);
        for (int k = 0; k < 3; k++)
            worst0 = fmax(worst0, fabs(a[k] - p[k]));
        double want[3] = {p[0], p[1], p[2]};
        if (p[1] >= 0.0f) { /* about z through the middle joint (0, 0, 0) by 90 degrees */
            want[0] = -p[1], want[1] = p[0];
        }
        for (int k = 0; k < 3; k++)
            worst1 = fmax(worst1, fabs(c[k] - want[k]));
    }
    printf("    frame 0 off the rest by %.2e m, frame 1 off the bend by %.2e m\n", worst0, worst1);
    CR_CHECK(worst0 < 1e-6 && worst1 < 1e-5);
    /* A garment beside the body on the same timeline: a second mesh, one
     * morph target a frame, a weights channel in the same animation. */
    float *cf = malloc(sizeof(float) * 2 * 3 * (size_t)tube->nv);
    for (int64_t i = 0; i < 3 * (int64_t)tube->nv; i++)
        cf[i] = tube->pos[i], cf[3 * (int64_t)tube->nv + i] = tube->pos[i] + 0.01f;
    cr_glb_cloth cloth = {tube, cf};
    CR_CHECK_OK(cr_glb_write_skinned(tmp("both.glb"), tube, &skin, &mo, &cloth, &err), &err);
    cJSON *j = file_json(tmp("both.glb"));
    CR_REQUIRE(j);
    const cJSON *meshes = cJSON_GetObjectItem(j, "meshes");
    const cJSON *tg = cJSON_GetObjectItem(
        cJSON_GetArrayItem(cJSON_GetObjectItem(cJSON_GetArrayItem(meshes, 1), "primitives"), 0),
        "targets");
    const cJSON *chs = cJSON_GetObjectItem(
        cJSON_GetArrayItem(cJSON_GetObjectItem(j, "animations"), 0), "channels");
    const cJSON *last = cJSON_GetArrayItem(chs, cJSON_GetArraySize(chs) - 1);
    CR_CHECK(cJSON_GetArraySize(meshes) == 2 && cJSON_GetArraySize(tg) == 2);
    CR_CHECK(strcmp(cJSON_GetStringValue(
                        cJSON_GetObjectItem(cJSON_GetObjectItem(last, "target"), "path")),
                    "weights") == 0);
    cJSON_Delete(j);
    free(cf);
    /* Refusals name the file and what is wrong. */
    const int32_t late[3] = {-1, 2, 1};
    skin.parent = late;
    CR_CHECK(cr_glb_write_skinned(tmp("bad.glb"), tube, &skin, &mo, NULL, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "bad.glb") && strstr(err.msg, "mixamorig:Spine"));
    skin.parent = parent;
    sj[5] = 7;
    CR_CHECK(cr_glb_write_skinned(tmp("bad.glb"), tube, &skin, &mo, NULL, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "vertex 1") != NULL);
    free(sj), free(sw), free(got);
    cr_mesh_destroy(rest);
    cr_mesh_destroy(tube);
}
