/* test_glb_seq.c: cr_glb_read_sequence reads back what cr_glb_write_sequence
 * wrote: a sphere with a UV seam (seam copies in the file land on their welded
 * vertex), four frames moved differently per vertex, its frame rate; a static
 * glb as one frame; a truncated file named in the error. */
#include "crease/mesh_io.h"
#include "crease/primitives.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *tmp(const char *name) {
    static char path[512];
    snprintf(path, sizeof path, "%s/%s", cr_test_tmpdir(), name);
    return path;
}

CR_TEST(glb_seq, round_trip_with_seams) {
    cr_error err = {0};
    cr_mesh *s = NULL;
    CR_REQUIRE(cr_prim_sphere_uv(0.3f, 16, 8, &s, &err) == CR_OK);
    enum { T = 4 };
    int32_t nv = s->nv;
    float *frames = malloc((size_t)T * nv * 3 * sizeof(float));
    CR_REQUIRE(frames);
    for (int t = 0; t < T; t++)
        for (int i = 0; i < nv; i++)
            for (int k = 0; k < 3; k++)
                frames[((size_t)t * nv + i) * 3 + k] =
                    s->pos[3 * i + k] * (1.0f + 0.1f * t) + 0.001f * (float)((i * 7 + k) % 13) * t;
    const char *path = tmp("seq.glb");
    CR_REQUIRE(cr_glb_write_sequence(path, s, frames, T, 24.0f, &err) == CR_OK);

    cr_mesh *rest = NULL;
    float *got = NULL, fps = 0;
    int32_t nt = 0;
    CR_REQUIRE(cr_glb_read_sequence(path, &rest, &got, &nt, &fps, &err) == CR_OK);
    CR_CHECK(rest->nv == nv && rest->nf == s->nf);
    CR_CHECK(nt == T);
    CR_CHECK(fps == 24.0f);
    double worst = 0;
    for (size_t i = 0; i < (size_t)T * nv * 3; i++)
        worst = fmax(worst, fabs((double)got[i] - (double)frames[i]));
    CR_CHECK_NEAR(worst, 0.0, 1e-6); /* base + (frame - base) in float */
    /* The last frame is not the rest: the morph targets were read, not the base alone. */
    double moved = 0;
    for (int i = 0; i < nv * 3; i++)
        moved = fmax(moved, fabs(got[(size_t)3 * nv * 3 + i] - s->pos[i]));
    CR_CHECK(moved > 0.05);
    cr_mesh_destroy(rest);
    free(got);

    /* A static glb is one frame, the base, with no frame rate. */
    CR_REQUIRE(cr_glb_write(tmp("static.glb"), s, &err) == CR_OK);
    CR_REQUIRE(cr_glb_read_sequence(tmp("static.glb"), &rest, &got, &nt, &fps, &err) == CR_OK);
    CR_CHECK(nt == 1 && fps == 0.0f && rest->nv == nv);
    int same = 1; /* by value: -0 + 0 reads back as +0 */
    for (int i = 0; i < nv * 3; i++)
        same &= got[i] == s->pos[i];
    CR_CHECK(same);
    cr_mesh_destroy(rest);
    free(got);

    /* Truncated: the file is named, nothing is returned. */
    FILE *in = fopen(path, "rb");
    CR_REQUIRE(in);
    char buf[4096];
    size_t n = fread(buf, 1, sizeof buf, in);
    fclose(in);
    FILE *out = fopen(tmp("cut.glb"), "wb");
    CR_REQUIRE(out);
    fwrite(buf, 1, n / 2, out);
    fclose(out);
    cr_status st = cr_glb_read_sequence(tmp("cut.glb"), &rest, &got, &nt, &fps, &err);
    CR_CHECK(st != CR_OK && rest == NULL && got == NULL && nt == 0);
    CR_CHECK(strstr(err.msg, "cut.glb") != NULL);
    cr_mesh_destroy(s);
    free(frames);
}
