/* material.c: cloth material presets, JSON overrides and validation.
 *
 * The presets' numbers and where each comes from are listed in
 * docs/physics.md ("Material presets"); the short version sits beside each
 * value below. Leaves out anisotropy and strain-dependent stiffness (ARCSim's
 * data-driven tables): one isotropic membrane per material.
 *
 * References: Santesteban et al. 2022 (SNUG) and Grigorev et al. 2023 (HOOD)
 * for the cotton-like fabric; Wang, Ramamoorthi & O'Brien 2011, "Data-driven
 * elastic models for cloth" (ARCSim) for denim and knit;
 * the EPNet code for the plastic yield angle.
 */
#include "crease/phys_material.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* HOOD/SNUG's fabric: Lame parameters per rest area (thickness folded in). */
#define HOOD_MU 23600.0     /* Pa*m */
#define HOOD_LAMBDA 44400.0 /* Pa*m */
/* Knit membrane = HOOD's times the ratio of the mean tensile stiffness of
 * ARCSim's gray-interlock (a cotton/polyester jersey) to royal-target (a
 * cotton/polyester woven): 182.6 / 2111.8 N/m (docs/physics.md). */
#define KNIT_SCALE 0.0865

typedef struct preset {
    const char *name;
    double density, mu, lambda, bending;
} preset;

/* Constant table: name, density kg/m^2, mu, lambda Pa*m, k_b N*m. */
static const preset PRESETS[] = {
    /* HOOD/SNUG defaults. */
    {"cotton", 0.20022, HOOD_MU, HOOD_LAMBDA, 3.96e-5},
    /* 16-momme silk charmeuse (1 momme = 4.340 g/m^2); woven, so HOOD's
     * membrane; bending a tenth of cotton's (scaled, see the docs). */
    {"silk", 0.0694, HOOD_MU, HOOD_LAMBDA, 3.96e-6},
    /* ARCSim 11oz-black-denim: density, mean of its 15 bending samples. */
    {"denim", 0.324, HOOD_MU, HOOD_LAMBDA, 7.23e-5},
    /* ARCSim gray-interlock: density, mean of its 15 bending samples. */
    {"knit", 0.187, HOOD_MU *KNIT_SCALE, HOOD_LAMBDA *KNIT_SCALE, 2.18e-5},
};
enum { NPRESETS = (int)(sizeof PRESETS / sizeof PRESETS[0]) };

/* EPNet code: yield angle 0.52 rad, gain 1 (perfect plasticity). */
#define YIELD_ANGLE 0.52
#define PLASTIC_GAIN 1.0
/* Collision: ten times HOOD's maximal penalty weight 1e5 on
 * max(eps - d, 0)^3 (docs/physics.md says why) and a thickness between
 * HOOD's 1 mm and NCS's 4 mm. */
#define COLLISION_THICKNESS 2e-3 /* m */
#define COLLISION_STIFFNESS 1e6  /* J/m^3 */
/* Fabric on dry skin: 0.2-0.6 (Derler & Gerhardt 2012); no per-fabric data. */
#define FRICTION 0.3

cr_status cr_material_preset(const char *name, cr_material *out, cr_error *err) {
    CR_ASSERT(out);
    const preset *p = NULL;
    for (int i = 0; name && i < NPRESETS; i++)
        if (strcmp(PRESETS[i].name, name) == 0) p = &PRESETS[i];
    if (!p)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "material: unknown preset '%s' (known: cotton, silk, denim, knit)",
                       name ? name : "(null)");
    cr_material m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "%s", p->name);
    m.density = p->density;
    m.membrane = CR_MEMBRANE_STVK;
    m.lame_mu = p->mu;
    m.lame_lambda = p->lambda;
    /* Baraff-Witkin stiffnesses that match StVK at small strain: uniaxial
     * stretch psi = (mu + lambda/2) e^2 = k_s/2 e^2, shear psi = mu/2 g^2. */
    m.bw_stretch = 2.0 * p->mu + p->lambda;
    m.bw_shear = p->mu;
    m.bending = p->bending;
    m.yield_angle = YIELD_ANGLE;
    m.plastic_gain = PLASTIC_GAIN;
    m.collision_thickness = COLLISION_THICKNESS;
    m.collision_stiffness = COLLISION_STIFFNESS;
    m.friction = FRICTION;
    m.cookie = CR_MATERIAL_COOKIE;
    *out = m;
    return CR_OK;
}

const char *cr_membrane_model_name(cr_membrane_model model) {
    switch (model) {
    case CR_MEMBRANE_STVK:
        return "stvk";
    case CR_MEMBRANE_BARAFF_WITKIN:
        return "baraff_witkin";
    }
    return "?";
}

/* The JSON view of a material: the enum travels as a string. */
typedef struct material_json {
    cr_material m;
    char membrane[32];
} material_json;

#define KEY_D(field, lo, hi, help)                                                                 \
    { #field, CR_CFG_DOUBLE, offsetof(material_json, m.field), 0, lo, hi, help, NULL, NULL }

static const cr_config_key KEYS[] = {
    {"name", CR_CFG_STRING, offsetof(material_json, m.name), sizeof(((cr_material *)0)->name), 1, 0,
     "label", NULL, NULL},
    {"membrane", CR_CFG_STRING, offsetof(material_json, membrane),
     sizeof(((material_json *)0)->membrane), 1, 0, "stvk | baraff_witkin", NULL, NULL},
    KEY_D(density, 0.0, 1e3, "kg/m^2"),
    KEY_D(lame_mu, 0.0, 1e12, "Pa*m"),
    KEY_D(lame_lambda, 0.0, 1e12, "Pa*m"),
    KEY_D(bw_stretch, 0.0, 1e12, "J/m^2"),
    KEY_D(bw_shear, 0.0, 1e12, "J/m^2"),
    KEY_D(bending, 0.0, 1e3, "N*m"),
    KEY_D(yield_angle, 0.0, 6.3, "rad"),
    KEY_D(plastic_gain, 0.0, 1.0, "0..1"),
    KEY_D(collision_thickness, 0.0, 1.0, "m"),
    KEY_D(collision_stiffness, 0.0, 1e15, "J/m^3"),
    KEY_D(friction, 0.0, 10.0, "coefficient"),
};
enum { NKEYS = (int)(sizeof KEYS / sizeof KEYS[0]) };

cr_status cr_material_parse_json(const char *json_text, const char *source, cr_material *inout,
                                 cr_error *err) {
    CR_ASSERT(json_text && inout);
    material_json j;
    j.m = *inout;
    snprintf(j.membrane, sizeof j.membrane, "%s", cr_membrane_model_name(inout->membrane));
    CR_TRY(cr_config_parse(json_text, source, KEYS, NKEYS, &j, err));
    if (strcmp(j.membrane, "stvk") == 0)
        j.m.membrane = CR_MEMBRANE_STVK;
    else if (strcmp(j.membrane, "baraff_witkin") == 0)
        j.m.membrane = CR_MEMBRANE_BARAFF_WITKIN;
    else
        return CR_FAIL(err, CR_ERR_CONFIG,
                       "%s: key 'membrane' must be \"stvk\" or \"baraff_witkin\", got \"%s\"",
                       source, j.membrane);
    *inout = j.m;
    return CR_OK;
}

cr_status cr_material_load_json(const char *path, cr_material *inout, cr_error *err) {
    char *text = NULL;
    CR_TRY(cr_file_read_all(path, &text, NULL, err));
    cr_status st = cr_material_parse_json(text, path, inout, err);
    free(text);
    return st;
}

static cr_status check(const char *field, double v, double lo, double hi, int lo_open,
                       cr_error *err) {
    if (!isfinite(v) || v < lo || v > hi || (lo_open && v == lo))
        return CR_FAIL(err, CR_ERR_INVALID, "material: %s = %g must be finite and in %c%g, %g]",
                       field, v, lo_open ? '(' : '[', lo, hi);
    return CR_OK;
}

cr_status cr_material_validate(const cr_material *m, cr_error *err) {
    CR_ASSERT(m);
    if (m->cookie != CR_MATERIAL_COOKIE)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "material: not made by cr_material_preset (cookie 0x%08x)", m->cookie);
    if (m->membrane != CR_MEMBRANE_STVK && m->membrane != CR_MEMBRANE_BARAFF_WITKIN)
        return CR_FAIL(err, CR_ERR_INVALID, "material: membrane = %d is not a model",
                       (int)m->membrane);
    CR_TRY(check("density", m->density, 0.0, 1e3, 1, err));
    CR_TRY(check("lame_mu", m->lame_mu, 0.0, 1e12, 0, err));
    CR_TRY(check("lame_lambda", m->lame_lambda, 0.0, 1e12, 0, err));
    CR_TRY(check("bw_stretch", m->bw_stretch, 0.0, 1e12, 0, err));
    CR_TRY(check("bw_shear", m->bw_shear, 0.0, 1e12, 0, err));
    CR_TRY(check("bending", m->bending, 0.0, 1e3, 0, err));
    CR_TRY(check("yield_angle", m->yield_angle, 0.0, 6.3, 0, err));
    CR_TRY(check("plastic_gain", m->plastic_gain, 0.0, 1.0, 0, err));
    CR_TRY(check("collision_thickness", m->collision_thickness, 0.0, 1.0, 0, err));
    CR_TRY(check("collision_stiffness", m->collision_stiffness, 0.0, 1e15, 0, err));
    CR_TRY(check("friction", m->friction, 0.0, 10.0, 0, err));
    if (m->membrane == CR_MEMBRANE_STVK && m->lame_mu == 0.0)
        return CR_FAIL(err, CR_ERR_INVALID, "material: lame_mu = 0 leaves StVK without stiffness");
    if (m->membrane == CR_MEMBRANE_BARAFF_WITKIN && m->bw_stretch == 0.0)
        return CR_FAIL(err, CR_ERR_INVALID,
                       "material: bw_stretch = 0 leaves Baraff-Witkin without stiffness");
    return CR_OK;
}
