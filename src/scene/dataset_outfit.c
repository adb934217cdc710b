/* dataset_outfit.c: two-layer (or more) outfits in a dataset. A garment
 * spec of '+'-joined variants, innermost first ("tshirt+vest",
 * "tshirt:length=0.9+vest:seed=4"), is one outfit: each part is built as a
 * garment of its own on the body (its template, each resolution), and the
 * parts are merged per resolution by cr_garment_outfit into one garment of
 * one connected component per layer, which the simulator runs as one cloth
 * with self-contact on (dataset_run.c), so the layers collide with each
 * other. The merged layout keeps each layer's UVs in a strip of its own, so
 * Eq. 1's correspondence (dataset.c) maps each high layer onto its own low
 * layer.
 *
 * Clearance: a part whose clearance is not given is built at least
 * OUTFIT_LAYER_CLEARANCE_M outside the part under it: the parts are level
 * sets of one blurred distance field on one grid (garment.c), so a larger
 * clearance nests it outside, and 10 mm is more than the self-contact's
 * query radius (8 mm), so the layers start as layers, not rest neighbours.
 * cr_garment_outfit then checks the built meshes and moves a layer out if
 * they still cross or overlap.
 *
 * Left out: skirts and trousers as parts (their waistband pin finds the
 * highest boundary loop of the whole garment, which in an outfit may be
 * another layer's), refused by name.
 */
#include "dataset_internal.h"

#include <stdlib.h>
#include <string.h>

#define OUTFIT_LAYER_CLEARANCE_M 0.01f

cr_status cr_dataset_outfit_parse(const char *spec, dataset_outfit *o, cr_garment_variant *v,
                                  cr_error *err) {
    memset(o, 0, sizeof *o);
    if (!strchr(spec, '+')) return cr_garment_variant_parse(spec, v, err);
    char buf[256];
    if (strlen(spec) >= sizeof buf)
        return CR_FAIL(err, CR_ERR_INVALID, "dataset: outfit '%.40s...': too long", spec);
    snprintf(buf, sizeof buf, "%s", spec);
    char label[128] = "";
    size_t len = 0;
    for (char *save = NULL, *tok = strtok_r(buf, "+", &save); tok;
         tok = strtok_r(NULL, "+", &save)) {
        if (o->nparts == CR_GARMENT_OUTFIT_MAX_LAYERS)
            return CR_FAIL(err, CR_ERR_INVALID, "dataset: outfit '%s': more than %d layers", spec,
                           CR_GARMENT_OUTFIT_MAX_LAYERS);
        cr_garment_variant *p = &o->part[o->nparts];
        CR_TRY(cr_garment_variant_parse(tok, p, err));
        if (p->def.type == CR_GARMENT_SKIRT || p->def.type == CR_GARMENT_TROUSERS)
            return CR_FAIL(err, CR_ERR_INVALID,
                           "dataset: outfit '%s': a %s cannot be a layer yet (its waistband "
                           "pin would not find its own waist in an outfit)",
                           spec, cr_garment_type_name(p->def.type));
        int ci = cr_garment_param_find("clearance");
        if (o->nparts > 0 && !(p->given >> ci & 1u)) {
            float lo = o->part[o->nparts - 1].def.clearance_m + OUTFIT_LAYER_CLEARANCE_M;
            if (p->def.clearance_m < lo) p->def.clearance_m = lo;
        }
        len += (size_t)snprintf(label + len, len < sizeof label ? sizeof label - len : 0, "%s%s",
                                o->nparts ? "+" : "", p->label);
        if (len >= sizeof label)
            return CR_FAIL(err, CR_ERR_INVALID, "dataset: outfit '%s': too long for a label", spec);
        o->nparts++;
    }
    if (o->nparts < 2)
        return CR_FAIL(err, CR_ERR_INVALID, "dataset: outfit '%s': need two layers or more", spec);
    *v = o->part[0];
    v->random = 0; /* the parts draw their own */
    snprintf(v->label, sizeof v->label, "%s", label);
    return CR_OK;
}

cr_status cr_dataset_outfit_build(dataset *ds, int b, int g, cr_error *err) {
    dataset_outfit *o = &ds->outfit[g];
    const int nres = ds->def.nres;
    cr_garment *part[CR_GARMENT_OUTFIT_MAX_LAYERS][2] = {{NULL}};
    cr_status st = CR_OK;
    for (int k = 0; k < o->nparts && st == CR_OK; k++) {
        /* as a single garment: drawn and checked at the lowest resolution */
        cr_garment_variant *v = &o->built[b][k];
        *v = o->part[k];
        v->def.target_vertices = ds->res_vertices[0];
        for (int r = 1; r < nres; r++)
            if (ds->res_vertices[r] < v->def.target_vertices)
                v->def.target_vertices = ds->res_vertices[r];
        cr_garment_template *t = NULL;
        st = v->random ? cr_garment_variant_build(v, ds->body[b], &t, err)
                       : cr_garment_template_create(&v->def, ds->body[b], &t, err);
        for (int r = 0; r < nres && st == CR_OK; r++)
            st = cr_garment_template_instantiate(t, ds->res_vertices[r], ds->body[b], &part[k][r],
                                                 err);
        cr_garment_template_destroy(t);
    }
    for (int r = 0; r < nres && st == CR_OK; r++) {
        const cr_garment *layers[CR_GARMENT_OUTFIT_MAX_LAYERS];
        for (int k = 0; k < o->nparts; k++)
            layers[k] = part[k][r];
        st = cr_garment_outfit(layers, o->nparts, &ds->garment[b][g][r], o->offset_m[b][r], err);
        if (st != CR_OK)
            st = CR_FAIL(err, st, "dataset: outfit '%s' on %s at %s resolution: %s",
                         ds->def.garments[g], ds->body_label[b], ds->def.res[r], err->msg);
    }
    for (int k = 0; k < o->nparts; k++)
        for (int r = 0; r < 2; r++)
            cr_garment_destroy(part[k][r]);
    return st;
}

cr_status cr_dataset_garment_label(const char *spec, char *out, size_t size, cr_error *err) {
    dataset_outfit *o = cr_calloc(1, sizeof *o, err); /* large: its per-body copies */
    if (!o) return err ? err->status : CR_ERR_MEMORY;
    cr_garment_variant v;
    cr_status st = cr_dataset_outfit_parse(spec, o, &v, err);
    if (st == CR_OK) snprintf(out, size, "%s", v.label);
    free(o);
    return st;
}
