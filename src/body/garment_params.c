/* garment_params.c: the garment templates' shape parameters by key (the
 * table behind the CLI options, variant specs and the manifest), seeded
 * random variants, and the quality targets every variant is held to.
 *
 * The sampled ranges are narrower than the accepted ones where the
 * construction stops changing the garment (trousers stop above the ankles)
 * or stops looking like the type; the tests hold 20 seeds of every type to
 * cr_garment_check (measured in docs/garments.md). A draw that fails is
 * replaced by the next attempt's draw, from a stream of its own, so what a
 * seed gives does not depend on other seeds.
 */
#include "garment_internal.h"

#include <ctype.h>
#include <inttypes.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* Types in enum order: tshirt, longsleeve, skirt, dress, trousers, vest, jumpsuit. */
static const cr_garment_param params[CR_GARMENT_NPARAMS] = {
    {"length",
     "length_scale",
     "x",
     "hem, leg and t-shirt sleeve length as a multiple of the type's default (tops past the "
     "crotch: long shirts)",
     0.5,
     1.5,
     {0.7f, 0.7f, 0.6f, 0.6f, 0.5f, 0.8f, 0.6f},
     {1.4f, 1.4f, 1.5f, 1.5f, 1.0f, 1.1f, 1.0f}},
    {"sleeve",
     "sleeve_scale",
     "x",
     "sleeve length as a multiple of the default (t-shirt, long sleeve)",
     0.5,
     1.5,
     {0.6f, 0.6f, 0, 0, 0, 0, 0},
     {1.4f, 1.0f, 0, 0, 0, 0, 0}},
    {"flare",
     "flare_deg",
     "deg",
     "skirt, dress and long shirts: half-angle of the cone below the waist",
     0.0,
     45.0,
     {0.0f, 0.0f, 0.0f, 0.0f, 0, 0, 0},
     {15.0f, 15.0f, 30.0f, 30.0f, 0, 0, 0}},
    {"clearance",
     "clearance_m",
     "m",
     "width: offset of the tight parts (and a skirt's hips) from the body",
     0.005,
     0.1,
     {0.008f, 0.008f, 0.01f, 0.008f, 0.01f, 0.015f, 0.01f},
     {0.025f, 0.02f, 0.025f, 0.02f, 0.025f, 0.03f, 0.025f}},
    {"neck",
     "neck_m",
     "m",
     "neckline: added to the radius of the sphere cutting it",
     -0.02,
     0.08,
     {-0.005f, -0.005f, 0, 0.0f, 0, 0.0f, 0.0f},
     {0.04f, 0.04f, 0, 0.05f, 0, 0.04f, 0.04f}},
};

static const size_t offsets[CR_GARMENT_NPARAMS] = {
    offsetof(cr_garment_def, length_scale), offsetof(cr_garment_def, sleeve_scale),
    offsetof(cr_garment_def, flare_deg), offsetof(cr_garment_def, clearance_m),
    offsetof(cr_garment_def, neck_m)};

static float *field(cr_garment_def *d, int i) {
    return (float *)((char *)d + offsets[i]);
}

const cr_garment_param *cr_garment_param_at(int i) {
    return i >= 0 && i < CR_GARMENT_NPARAMS ? &params[i] : NULL;
}

int cr_garment_param_find(const char *key) {
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
        if (!strcmp(key, params[i].key)) return i;
    return -1;
}

float cr_garment_param_get(const cr_garment_def *def, int i) {
    CR_ASSERT(i >= 0 && i < CR_GARMENT_NPARAMS);
    return *field((cr_garment_def *)def, i);
}

int cr_garment_in_range(double v, double lo, double hi) {
    return v >= lo - 1e-6 * fabs(lo) && v <= hi + 1e-6 * fabs(hi);
}

cr_status cr_garment_params_check(const cr_garment_def *d, cr_error *err) {
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++) {
        double v = cr_garment_param_get(d, i);
        if (!cr_garment_in_range(v, params[i].lo, params[i].hi))
            return CR_FAIL(err, CR_ERR_INVALID, "garment: %s (key %s) = %g (need %g to %g)",
                           params[i].field, params[i].key, v, params[i].lo, params[i].hi);
    }
    return CR_OK;
}

cr_status cr_garment_param_set(cr_garment_def *def, const char *key, double value, cr_error *err) {
    int i = cr_garment_param_find(key);
    if (i < 0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "garment: unknown parameter '%s' (length, sleeve, flare, clearance, neck)",
                       key);
    if (!cr_garment_in_range(value, params[i].lo, params[i].hi))
        return CR_FAIL(err, CR_ERR_INVALID, "garment: %s = %g is out of range (need %g to %g %s)",
                       key, value, params[i].lo, params[i].hi, params[i].unit);
    *field(def, i) = (float)value;
    return CR_OK;
}

cr_garment_def cr_garment_random_def(cr_garment_type type, uint64_t seed, int32_t attempt) {
    cr_garment_def d = cr_garment_default_def(type);
    cr_rng r = cr_rng_make(seed, (uint64_t)type + (uint64_t)CR_GARMENT_TYPE_COUNT * attempt);
    for (int i = 0; i < CR_GARMENT_NPARAMS; i++) {
        float lo = params[i].sample_lo[type], hi = params[i].sample_hi[type];
        if (lo == 0.0f && hi == 0.0f) continue; /* the type does not use it */
        *field(&d, i) = lo + (hi - lo) * cr_rng_uniformf(&r);
    }
    return d;
}

/* ------------------------------------------------------------- variants -- */

static cr_status parse_number(const char *spec, const char *key, const char *s, double *out,
                              cr_error *err) {
    char *end = NULL;
    *out = strtod(s, &end);
    if (!*s || *end || !isfinite(*out))
        return CR_FAIL(err, CR_ERR_INVALID, "garment variant '%s': %s expects a number, got '%s'",
                       spec, key, s);
    return CR_OK;
}

cr_status cr_garment_variant_parse(const char *spec, cr_garment_variant *out, cr_error *err) {
    memset(out, 0, sizeof *out);
    char buf[256];
    if (strlen(spec) >= sizeof buf)
        return CR_FAIL(err, CR_ERR_INVALID, "garment variant '%.40s...': too long", spec);
    snprintf(buf, sizeof buf, "%s", spec);
    char *save = NULL, *tok = strtok_r(buf, ":", &save);
    cr_garment_type type;
    if (!tok) return CR_FAIL(err, CR_ERR_INVALID, "garment variant '%s': no type", spec);
    CR_TRY(cr_garment_type_parse(tok, &type, err));
    out->def = cr_garment_default_def(type);
    size_t len = (size_t)snprintf(out->label, sizeof out->label, "%s", tok);
    for (tok = strtok_r(NULL, ":", &save); tok; tok = strtok_r(NULL, ":", &save)) {
        char *eq = strchr(tok, '=');
        if (!eq)
            return CR_FAIL(err, CR_ERR_INVALID, "garment variant '%s': '%s' is not key=value", spec,
                           tok);
        *eq = '\0';
        const char *key = tok, *val = eq + 1;
        double v;
        CR_TRY(parse_number(spec, key, val, &v, err));
        if (!strcmp(key, "seed")) {
            if (!(v >= 0 && v <= 4294967295.0 && v == floor(v)))
                return CR_FAIL(err, CR_ERR_INVALID,
                               "garment variant '%s': seed = %s (need an integer, 0 to 4294967295)",
                               spec, val);
            out->random = 1, out->seed = (uint64_t)v;
        } else if (!strcmp(key, "res")) {
            if (!(v >= 500 && v <= 100000 && v == floor(v)))
                return CR_FAIL(err, CR_ERR_INVALID,
                               "garment variant '%s': res = %s (need an integer, 500 to 100000)",
                               spec, val);
            out->def.target_vertices = (int32_t)v;
        } else {
            cr_error e = {0};
            cr_status st = cr_garment_param_set(&out->def, key, v, &e);
            if (st != CR_OK) /* e.msg after its "garment: " */
                return CR_FAIL(err, st, "garment variant '%s': %s", spec, e.msg + 9);
            out->given |= 1u << cr_garment_param_find(key);
        }
        /* Label: "_" key value, keeping only file-name safe characters. */
        len += (size_t)snprintf(out->label + len,
                                len < sizeof out->label ? sizeof out->label - len : 0, "_%s", key);
        for (const char *c = val; *c && len + 1 < sizeof out->label; c++)
            if (isalnum((unsigned char)*c) || *c == '.' || *c == '-') out->label[len++] = *c;
        if (len + 1 >= sizeof out->label)
            return CR_FAIL(err, CR_ERR_INVALID, "garment variant '%s': too long for a label", spec);
        out->label[len] = '\0';
    }
    return CR_OK;
}

void cr_garment_def_spec(const cr_garment_def *def, char *out, size_t cap) {
    size_t n = (size_t)snprintf(out, cap, "%s", cr_garment_type_name(def->type));
    cr_garment_def d0 = cr_garment_default_def(def->type);
    for (int i = 0; i < CR_GARMENT_NPARAMS && n < cap; i++)
        if (params[i].sample_lo[def->type] != 0.0f || params[i].sample_hi[def->type] != 0.0f ||
            cr_garment_param_get(def, i) != cr_garment_param_get(&d0, i))
            n += (size_t)snprintf(out + n, cap - n, ":%s=%.9g", params[i].key,
                                  (double)cr_garment_param_get(def, i));
    if (n < cap) snprintf(out + n, cap - n, ":res=%d", def->target_vertices);
}

/* One draw built and checked; *out the template when it passed. */
static cr_status build_checked(const cr_garment_def *d, const cr_body_model *body,
                               cr_garment_template **out, cr_garment_quality *q, cr_error *err) {
    *out = NULL;
    cr_garment_template *t = NULL;
    CR_TRY(cr_garment_template_create(d, body, &t, err));
    cr_garment *g = NULL;
    cr_status st = cr_garment_template_instantiate(t, d->target_vertices, body, &g, err);
    if (st == CR_OK) st = cr_garment_check(g, body, q, err);
    cr_garment_destroy(g);
    if (st != CR_OK)
        cr_garment_template_destroy(t);
    else
        *out = t;
    return st;
}

cr_status cr_garment_variant_build(cr_garment_variant *v, const cr_body_model *body,
                                   cr_garment_template **out, cr_error *err) {
    if (out) *out = NULL;
    v->rejected[0] = '\0';
    cr_garment_template *t = NULL;
    if (!v->random) {
        v->attempts = 1;
        CR_TRY(build_checked(&v->def, body, &t, &v->quality, err));
    } else {
        cr_status st = CR_OK;
        for (int32_t a = 0; a < CR_GARMENT_RANDOM_ATTEMPTS; a++) {
            cr_garment_def d = cr_garment_random_def(v->def.type, v->seed, a);
            d.target_vertices = v->def.target_vertices;
            d.grid_m = v->def.grid_m;
            d.remesh_iterations = v->def.remesh_iterations;
            for (int i = 0; i < CR_GARMENT_NPARAMS; i++)
                if (v->given >> i & 1u) *field(&d, i) = cr_garment_param_get(&v->def, i);
            st = build_checked(&d, body, &t, &v->quality, err);
            v->attempts = a + 1;
            if (st == CR_OK) {
                v->def = d;
                break;
            }
            if (st == CR_ERR_MEMORY) return st;
            snprintf(v->rejected, sizeof v->rejected, "%.159s", err ? err->msg : "");
        }
        if (st != CR_OK)
            return CR_FAIL(err, CR_ERR_TOPOLOGY,
                           "garment %s seed %" PRIu64
                           ": no draw of %d passed the checks (last: %s)",
                           cr_garment_type_name(v->def.type), v->seed, CR_GARMENT_RANDOM_ATTEMPTS,
                           err ? err->msg : "?");
    }
    if (out)
        *out = t;
    else
        cr_garment_template_destroy(t);
    return CR_OK;
}

/* ------------------------------------------------------------- checks -- */

int32_t cr_garment_openings(cr_garment_type type) {
    static const int32_t n[CR_GARMENT_USER] = {4, 4, 2, 4, 3, 4, 5};
    return type >= 0 && type < CR_GARMENT_USER ? n[type] : -1;
}

cr_status cr_garment_check(const cr_garment *g, const cr_body_model *body, cr_garment_quality *q,
                           cr_error *err) {
    cr_garment_quality local;
    if (!q) q = &local;
    CR_TRY(cr_garment_measure(g, body, q, err));
    const char *name = cr_garment_type_name(g->type);
    if (!(q->share_min_angle_above_20deg >= 0.99f))
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "garment %s: %.2f%% of faces have every angle above 20 deg (need 99%%)",
                       name, 100.0 * q->share_min_angle_above_20deg);
    if (!(q->min_clearance_m >= 0.005f))
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "garment %s: a vertex is %.1f mm from the body (need 5 mm out)", name,
                       1000.0 * q->min_clearance_m);
    if (!q->manifold)
        return CR_FAIL(err, CR_ERR_TOPOLOGY, "garment %s: not an oriented 2-manifold", name);
    int32_t want = cr_garment_openings(g->type);
    if (want >= 0 && q->boundary_loops != want)
        return CR_FAIL(err, CR_ERR_TOPOLOGY, "garment %s: %d openings (need %d)", name,
                       q->boundary_loops, want);
    if (!(q->share_outward >= 0.99f))
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "garment %s: %.2f%% of faces face away from the body (need 99%%)", name,
                       100.0 * q->share_outward);
    if (!cr_mesh_has_uv(g->mesh) || q->uv_flipped > 0 || !(q->uv_area_error < 0.03f))
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "garment %s: UVs: %d flipped faces, panel area error %.2f%% (need none "
                       "and under 3%%)",
                       name, q->uv_flipped, 100.0 * q->uv_area_error);
    if (!(q->max_weight_sum_error < 1e-5f) || q->bad_joints > 0)
        return CR_FAIL(err, CR_ERR_TOPOLOGY,
                       "garment %s: skin weights: sum off by %g, %d bad joint indices", name,
                       (double)q->max_weight_sum_error, q->bad_joints);
    return CR_OK;
}
