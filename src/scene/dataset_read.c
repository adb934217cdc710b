/* dataset_read.c: the one reader of a dataset's manifest.json (what
 * dataset_run.c writes): bodies, garments, motions and sequences with their
 * files, for gdsr, swingar and crease view, so none of them builds a
 * dataset's paths by hand.
 *
 * Leaves out: loading the files themselves (meshes, skins, sequences): each
 * method loads what it needs from the paths, with its own checks.
 */
#include "crease/dataset.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *str(const cJSON *o, const char *key) {
    return cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(o, key));
}

static double num(const cJSON *o, const char *key, double fallback) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsNumber(v) ? v->valuedouble : fallback;
}

/* An array of the manifest into n entries of size bytes each; 0 entries is fine. */
static void *entries(const cJSON *j, const char *key, size_t size, int32_t *n, const char *path,
                     cr_error *err, cr_status *st) {
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(j, key);
    if (!cJSON_IsArray(a)) {
        *st = CR_FAIL(err, CR_ERR_PARSE, "%s: no '%s' list: not a crease dataset manifest", path,
                      key);
        return NULL;
    }
    *n = cJSON_GetArraySize(a);
    void *p = calloc((size_t)*n + 1, size);
    if (!p) *st = CR_FAIL(err, CR_ERR_MEMORY, "%s: out of memory", path);
    return p;
}

cr_status cr_dataset_read(const char *dir, cr_dataset_manifest *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    char path[CR_SCENE_PATH + 16];
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    char *text = NULL;
    size_t len = 0;
    CR_TRY(cr_file_read_all(path, &text, &len, err));
    cr_status st = cr_dataset_parse(text, len, dir, out, err);
    free(text);
    return st;
}

cr_status cr_dataset_parse(const char *text, size_t len, const char *dir, cr_dataset_manifest *out,
                           cr_error *err) {
    memset(out, 0, sizeof *out);
    if ((size_t)snprintf(out->dir, sizeof out->dir, "%s", dir) >= sizeof out->dir)
        return CR_FAIL(err, CR_ERR_RANGE, "dataset %s: path too long", dir);
    char path[CR_SCENE_PATH + 16];
    snprintf(path, sizeof path, "%s/manifest.json", dir);
    cJSON *j = cJSON_ParseWithLength(text, len);
    if (!j) return CR_FAIL(err, CR_ERR_PARSE, "%s: not valid JSON", path);
    out->json = j;
    cr_status st = CR_OK;
    const cJSON *def = cJSON_GetObjectItemCaseSensitive(j, "def");
    if (!cJSON_IsObject(def) || strcmp(str(j, "format") ? str(j, "format") : "", "crease-dataset"))
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: not a crease dataset manifest (format, def)", path);
    if (st == CR_OK) {
        out->frames = (int32_t)num(def, "frames", 0);
        out->fps = (float)num(def, "fps", 30.0);
        out->low_vertices = (int32_t)num(def, "low_vertices", 0);
        out->high_vertices = (int32_t)num(def, "high_vertices", 0);
        out->plastic = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(def, "plastic"));
        out->material = str(def, "material");
        out->bodies = entries(j, "bodies", sizeof *out->bodies, &out->nbodies, path, err, &st);
    }
    if (st == CR_OK)
        out->garments =
            entries(j, "garments", sizeof *out->garments, &out->ngarments, path, err, &st);
    if (st == CR_OK)
        out->motions = entries(j, "motions", sizeof *out->motions, &out->nmotions, path, err, &st);
    if (st == CR_OK)
        out->sequences =
            entries(j, "sequences", sizeof *out->sequences, &out->nsequences, path, err, &st);
    for (int32_t i = 0; st == CR_OK && i < out->nbodies; i++) {
        const cJSON *o = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, "bodies"), i);
        cr_dataset_body_entry *b = &out->bodies[i];
        b->name = str(o, "name"), b->rest = str(o, "rest"), b->skin = str(o, "skin");
        if (!b->name || !b->rest || !b->skin)
            st = CR_FAIL(err, CR_ERR_PARSE, "%s: body %d lacks name, rest or skin", path, i);
    }
    for (int32_t i = 0; st == CR_OK && i < out->ngarments; i++) {
        const cJSON *o = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, "garments"), i);
        cr_dataset_garment_entry *g = &out->garments[i];
        g->type = str(o, "type"), g->label = str(o, "label"), g->body = str(o, "body");
        g->res = str(o, "res"), g->mesh = str(o, "mesh"), g->skin = str(o, "skin");
        g->high_from_low = str(o, "high_from_low");
        if (!g->label) g->label = g->type; /* manifests before variants */
        if (!g->type || !g->body || !g->res || !g->mesh || !g->skin)
            st = CR_FAIL(err, CR_ERR_PARSE,
                         "%s: garment %d lacks one of type, body, res, mesh, skin", path, i);
    }
    for (int32_t i = 0; st == CR_OK && i < out->nmotions; i++) {
        const cJSON *o = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, "motions"), i);
        cr_dataset_motion_entry *m = &out->motions[i];
        m->name = str(o, "name"), m->path = str(o, "path");
        m->frames = (int32_t)num(o, "frames", 0);
        if (!m->name || !m->path)
            st = CR_FAIL(err, CR_ERR_PARSE, "%s: motion %d lacks name or path", path, i);
    }
    for (int32_t i = 0; st == CR_OK && i < out->nsequences; i++) {
        const cJSON *o = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(j, "sequences"), i);
        cr_dataset_sequence_entry *q = &out->sequences[i];
        q->id = str(o, "id"), q->garment = str(o, "garment"), q->res = str(o, "res");
        q->body = str(o, "body"), q->motion = str(o, "motion"), q->status = str(o, "status");
        q->garment_pc2 = str(o, "garment_pc2"), q->body_pc2 = str(o, "body_pc2");
        q->done = q->status && strcmp(q->status, "done") == 0;
        if (!q->id || !q->garment || !q->res || !q->body || !q->motion || !q->status ||
            !q->garment_pc2 || !q->body_pc2)
            st = CR_FAIL(err, CR_ERR_PARSE, "%s: sequence %d lacks a field", path, i);
    }
    if (st != CR_OK) cr_dataset_manifest_free(out);
    return st;
}

void cr_dataset_manifest_free(cr_dataset_manifest *m) {
    if (!m) return;
    cJSON_Delete(m->json);
    free(m->bodies), free(m->garments), free(m->motions), free(m->sequences);
    memset(m, 0, sizeof *m);
}

cr_status cr_dataset_path(const cr_dataset_manifest *m, const char *rel, char *out, size_t size,
                          cr_error *err) {
    if ((size_t)snprintf(out, size, "%s/%s", m->dir, rel) >= size)
        return CR_FAIL(err, CR_ERR_RANGE, "dataset %s: path of %s too long", m->dir, rel);
    return CR_OK;
}

static int same(const char *a, const char *b) {
    return a && b && strcmp(a, b) == 0;
}

const cr_dataset_body_entry *cr_dataset_find_body(const cr_dataset_manifest *m, const char *name) {
    for (int32_t i = 0; i < m->nbodies; i++)
        if (same(m->bodies[i].name, name)) return &m->bodies[i];
    return NULL;
}

const cr_dataset_garment_entry *cr_dataset_find_garment(const cr_dataset_manifest *m,
                                                        const char *label, const char *body,
                                                        const char *res) {
    for (int32_t i = 0; i < m->ngarments; i++) {
        const cr_dataset_garment_entry *g = &m->garments[i];
        if (same(g->label, label) && same(g->body, body) && same(g->res, res)) return g;
    }
    return NULL;
}

const cr_dataset_sequence_entry *cr_dataset_find_sequence(const cr_dataset_manifest *m,
                                                          const char *garment, const char *res,
                                                          const char *body, const char *motion) {
    for (int32_t i = 0; i < m->nsequences; i++) {
        const cr_dataset_sequence_entry *q = &m->sequences[i];
        if (same(q->garment, garment) && same(q->res, res) && same(q->body, body) &&
            same(q->motion, motion))
            return q;
    }
    return NULL;
}

const cr_dataset_sequence_entry *cr_dataset_find_id(const cr_dataset_manifest *m, const char *id) {
    for (int32_t i = 0; i < m->nsequences; i++) {
        const cr_dataset_sequence_entry *q = &m->sequences[i];
        if (id ? same(q->id, id) : q->done) return q;
    }
    return NULL;
}
