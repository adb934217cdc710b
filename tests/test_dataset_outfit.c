/* test_dataset_outfit.c: a two-layer outfit (t-shirt under a vest) in a
 * dataset: both layers in each resolution's garment, Eq. 1's correspondence
 * within each layer, the layers apart at rest and at the end of a short run
 * with self-contact, and outfits that cannot be built refused by name; and
 * cr_garment_outfit's layout, and its moving out a layer that lies on the
 * one under it. */
#include "crease/body.h"
#include "crease/bvh.h"
#include "crease/dataset.h"
#include "crease/garment.h"
#include "crease/gdsr.h"
#include "crease/mesh_io.h"
#include "crease/npz.h"
#include "test.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Layer k of an outfit mesh at positions pos: its vertices and faces. */
static cr_mesh *layer_mesh(const cr_mesh *m, const int32_t *layer, int32_t k, const float *pos) {
    int32_t *map = malloc(sizeof(int32_t) * (size_t)m->nv);
    int32_t nv = 0, nf = 0;
    for (int32_t v = 0; v < m->nv; v++)
        map[v] = layer[v] == k ? nv++ : -1;
    for (int32_t f = 0; f < m->nf; f++)
        nf += layer[m->tri[3 * f]] == k;
    cr_mesh *out = NULL;
    cr_error err = {0};
    if (cr_mesh_create(nv, nf, 0, &out, &err) != CR_OK) {
        free(map);
        return NULL;
    }
    for (int32_t v = 0; v < m->nv; v++)
        if (map[v] >= 0) memcpy(out->pos + 3 * map[v], pos + 3 * v, 3 * sizeof(float));
    nf = 0;
    for (int32_t f = 0; f < m->nf; f++)
        if (layer[m->tri[3 * f]] == k) {
            for (int c = 0; c < 3; c++)
                out->tri[3 * nf + c] = map[m->tri[3 * f + c]];
            nf++;
        }
    free(map);
    return out;
}

/* Edges of one layer crossing faces of the other, at positions pos. */
static int64_t layer_crossings(const cr_mesh *m, const int32_t *layer, const float *pos) {
    cr_mesh *a = layer_mesh(m, layer, 0, pos), *b = layer_mesh(m, layer, 1, pos);
    cr_error err = {0};
    int64_t n = a && b ? cr_garment_count_crossings(a, b, &err) : -1;
    cr_mesh_destroy(a);
    cr_mesh_destroy(b);
    return n;
}

CR_TEST(dataset_outfit, two_layer_outfit_collides_and_keeps_its_layers) {
    char dir[512];
    snprintf(dir, sizeof dir, "%s/dataset_outfit", cr_test_tmpdir());
    const char *garments[] = {"tshirt+vest"}, *motions[] = {"raise_arms"};
    const char *bodies[] = {"normal"}, *res[] = {"low", "high"};
    cr_dataset_def d = cr_dataset_default_def();
    d.out_dir = dir;
    d.garments = garments, d.ngarments = 1;
    d.motions = motions, d.nmotions = 1;
    d.bodies = bodies, d.nbodies = 1;
    d.res = res, d.nres = 2;
    d.low_vertices = 500, d.high_vertices = 1000;
    d.frames = 3;
    d.quiet = 1;
    cr_error err = {0};
    cr_dataset_result r;
    CR_CHECK_OK(cr_dataset_generate(&d, &r, &err), &err);
    printf("    outfit, 2 sequences of 3 frames: %.1f s, inside share %.4f\n", r.seconds,
           r.max_inside_share[0]);
    CR_CHECK(r.sequences == 2 && r.done == 2 && r.failed == 0);

    char path[700];
    cr_mesh *mesh[2] = {NULL, NULL};
    int32_t *layer[2] = {NULL, NULL};
    for (int k = 0; k < 2; k++) {
        snprintf(path, sizeof path, "%s/garments/normal/tshirt+vest_%s.obj", dir, res[k]);
        CR_CHECK_OK(cr_mesh_read(path, &mesh[k], &err), &err);
        CR_REQUIRE(mesh[k]);
        layer[k] = malloc(sizeof(int32_t) * (size_t)mesh[k]->nv);
        /* both layers present: two components, the t-shirt's vertices first */
        CR_CHECK(cr_gdsr_mesh_layers(mesh[k], layer[k]) == 2);
        CR_CHECK(layer[k][0] == 0 && layer[k][mesh[k]->nv - 1] == 1);
        /* at rest the layers do not cross */
        CR_CHECK(layer_crossings(mesh[k], layer[k], mesh[k]->pos) == 0);
    }
    /* Eq. 1 per layer: every high vertex on a low face of its own layer */
    snprintf(path, sizeof path, "%s/garments/normal/tshirt+vest_high_from_low.npz", dir);
    cr_npz *z = NULL;
    CR_CHECK_OK(cr_npz_open(path, &z, &err), &err);
    cr_npy f = {0};
    CR_CHECK_OK(cr_npz_get(z, "face", CR_NPY_AS_I32, &f, &err), &err);
    cr_npz_close(z);
    CR_REQUIRE(f.count == mesh[1]->nv);
    int32_t wrong = 0;
    for (int32_t v = 0; v < mesh[1]->nv; v++)
        wrong += layer[0][mesh[0]->tri[3 * f.i32[v]]] != layer[1][v];
    CR_CHECK(wrong == 0);
    cr_npy_free(&f);

    /* the last frame of each run: the layers still do not cross */
    for (int k = 0; k < 2; k++) {
        snprintf(path, sizeof path, "%s/sequences/tshirt+vest_%s_normal_raise_arms/garment.pc2",
                 dir, res[k]);
        cr_pc2 p = {0};
        CR_CHECK_OK(cr_pc2_read(path, &p, &err), &err);
        CR_REQUIRE(p.nv == mesh[k]->nv && p.nframes == 4);
        int64_t worst = 0; /* edge-face crossings between the layers, any frame */
        for (int t = 0; t < p.nframes; t++) {
            int64_t c = layer_crossings(mesh[k], layer[k], p.frames + 3 * (size_t)p.nv * t);
            worst = c < 0 || c > worst ? c : worst;
        }
        CR_CHECK(worst == 0);
        const float *last = p.frames + 3 * (size_t)p.nv * (size_t)(p.nframes - 1);
        int64_t between = layer_crossings(mesh[k], layer[k], last);
        cr_bvh *b = NULL;
        CR_CHECK_OK(cr_bvh_build(last, p.nv, mesh[k]->tri, mesh[k]->nf, &b, &err), &err);
        int64_t all = b ? cr_bvh_self_intersections(b) : -1;
        cr_bvh_destroy(b);
        double moved = 0.0;
        for (int64_t i = 0; i < 3 * (int64_t)p.nv; i++)
            moved = fmax(moved, fabs(last[i] - mesh[k]->pos[i]));
        printf("    %s: %d vertices, last frame: %lld edge-face crossings between the layers, "
               "%lld crossing triangle pairs in all, moved up to %.3f m\n",
               res[k], p.nv, (long long)between, (long long)all, moved);
        CR_CHECK(between == 0);
        CR_CHECK(moved > 0.005); /* it did move */
        cr_pc2_free(&p);
    }
    for (int k = 0; k < 2; k++) {
        cr_mesh_destroy(mesh[k]);
        free(layer[k]);
    }

    /* outfits that cannot be built are refused by name */
    snprintf(dir, sizeof dir, "%s/dataset_outfit_bad", cr_test_tmpdir());
    garments[0] = "tshirt+skirt";
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "tshirt+skirt") && strstr(err.msg, "skirt cannot be a layer"));
    garments[0] = "tshirt+";
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "need two layers"));
    garments[0] = "tshirt+cape";
    CR_CHECK(cr_dataset_generate(&d, &r, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "cape"));
    /* the files' name of a spec, as gdsr run --simulate finds them */
    char label[128];
    CR_CHECK_OK(cr_dataset_garment_label("tshirt:length=0.9+vest", label, sizeof label, &err),
                &err);
    CR_CHECK(!strcmp(label, "tshirt_length0.9+vest"));
    CR_CHECK_OK(cr_dataset_garment_label("dress:seed=3", label, sizeof label, &err), &err);
    CR_CHECK(!strcmp(label, "dress_seed3"));
    CR_CHECK(cr_dataset_garment_label("tshirt+skirt", label, sizeof label, &err) == CR_ERR_INVALID);
}

CR_TEST(dataset_outfit, outfit_moves_out_a_layer_given_inside) {
    cr_mannequin_def md = cr_mannequin_default_def();
    cr_body_model *body = NULL;
    cr_error err = {0};
    CR_CHECK_OK(cr_mannequin_create(&md, &body, &err), &err);
    CR_REQUIRE(body);
    cr_garment_def defs[2] = {cr_garment_default_def(CR_GARMENT_VEST),
                              cr_garment_default_def(CR_GARMENT_TSHIRT)};
    cr_garment *g[2] = {NULL, NULL}, *out = NULL;
    for (int k = 0; k < 2; k++) {
        defs[k].target_vertices = 500;
        CR_CHECK_OK(cr_garment_create(&defs[k], body, &g[k], &err), &err);
        CR_REQUIRE(g[k]);
    }
    /* in order (t-shirt, then the vest 10 mm out): nothing moves */
    float off[2] = {-1, -1};
    const cr_garment *in_order[2] = {g[1], g[0]};
    CR_CHECK_OK(cr_garment_outfit(in_order, 2, &out, off, &err), &err);
    CR_CHECK(off[0] == 0.0f && off[1] == 0.0f);
    CR_REQUIRE(out);
    CR_CHECK(out->mesh->nv == g[0]->mesh->nv + g[1]->mesh->nv);
    CR_CHECK(out->npanels == g[0]->npanels + g[1]->npanels);
    /* uv * uv_scale_m is still metres along the cloth: the first face's UV
     * edge keeps its length */
    const cr_mesh *t = g[1]->mesh;
    float du = (t->uv[2 * t->tri_uv[1]] - t->uv[2 * t->tri_uv[0]]) * g[1]->uv_scale_m;
    float dv = (t->uv[2 * t->tri_uv[1] + 1] - t->uv[2 * t->tri_uv[0] + 1]) * g[1]->uv_scale_m;
    const cr_mesh *o = out->mesh;
    float ou = (o->uv[2 * o->tri_uv[1]] - o->uv[2 * o->tri_uv[0]]) * out->uv_scale_m;
    float ov = (o->uv[2 * o->tri_uv[1] + 1] - o->uv[2 * o->tri_uv[0] + 1]) * out->uv_scale_m;
    CR_CHECK(fabsf(du - ou) < 1e-5f && fabsf(dv - ov) < 1e-5f);
    /* the layers' UVs in strips of their own */
    for (int32_t u = 0; u < o->nuv; u++)
        CR_CHECK((u < t->nuv) == (o->uv[2 * u] < 0.5f));
    cr_garment_destroy(out);
    /* the vest given under the t-shirt: the t-shirt is moved out past it, or
     * refused naming it */
    cr_status st = cr_garment_outfit((const cr_garment *const *)g, 2, &out, off, &err);
    printf("    t-shirt over the vest: %s, moved out %.3f m\n", cr_status_str(st), off[1]);
    if (st == CR_OK)
        CR_CHECK(off[1] >= 0.01f);
    else
        CR_CHECK(st == CR_ERR_TOPOLOGY && strstr(err.msg, "layer 1 (tshirt)"));
    cr_garment_destroy(out);
    out = NULL;
    /* a t-shirt over the same t-shirt: moved out just past the gap */
    const cr_garment *twice[2] = {g[1], g[1]};
    CR_CHECK_OK(cr_garment_outfit(twice, 2, &out, off, &err), &err);
    printf("    a t-shirt over itself: moved out %.3f m\n", off[1]);
    CR_CHECK(off[0] == 0.0f && off[1] >= CR_GARMENT_OUTFIT_MIN_GAP &&
             off[1] <= CR_GARMENT_OUTFIT_MIN_GAP + 0.002f);
    cr_garment_destroy(out);
    cr_garment_destroy(g[0]);
    cr_garment_destroy(g[1]);
    cr_body_model_destroy(body);
}
