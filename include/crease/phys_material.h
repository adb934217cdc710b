/* crease/phys_material.h: cloth materials for the physics energies.
 *
 * A material holds every constant the energies in phys_energies.h read: area
 * density, the membrane model and its stiffnesses, bending stiffness, the
 * plastic yield angle and gain, collision thickness and stiffness, and the
 * friction coefficient. Presets `cotton`, `silk`, `denim` and `knit` carry
 * values from published cloth simulators; docs/physics.md cites the source of
 * every number. A JSON file overrides any field by name.
 *
 *   cr_material m;
 *   CR_TRY(cr_material_preset("denim", &m, err));
 *   CR_TRY(cr_material_load_json("my_fabric.json", &m, err));  // optional overrides
 *   CR_TRY(cr_material_validate(&m, err));
 *
 * Stiffnesses are per rest area with the thickness folded in (the SNUG/HOOD
 * convention): membrane energy density in J/m^2 = Pa*m, bending in N*m = J.
 */
#ifndef CREASE_PHYS_MATERIAL_H
#define CREASE_PHYS_MATERIAL_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum cr_membrane_model {
    CR_MEMBRANE_STVK = 0,     /* St. Venant-Kirchhoff on Green strain (lame_mu, lame_lambda) */
    CR_MEMBRANE_BARAFF_WITKIN /* stretch/shear of w_u, w_v (bw_stretch, bw_shear) */
} cr_membrane_model;

/* Stamped by cr_material_preset: energies assert it to catch hand-zeroed structs. */
#define CR_MATERIAL_COOKIE 0x4d415431u

typedef struct cr_material {
    char name[32];
    double density; /* kg/m^2, area density */
    cr_membrane_model membrane;
    double lame_mu, lame_lambda; /* StVK Lame parameters, Pa*m (energy per rest area) */
    double bw_stretch, bw_shear; /* Baraff-Witkin stretch (w_u = w_v) and shear stiffness, J/m^2 */
    double bending;              /* k_b, N*m (J) */
    double yield_angle;          /* rad, plastic yield of |theta - theta_rest| */
    double plastic_gain;         /* 0..1, 1 = perfect plasticity */
    double collision_thickness;  /* m, eps: the penalty acts where d < eps */
    double collision_stiffness;  /* J/m^3: E = k max(eps - d, 0)^3 per vertex */
    double friction;             /* Coulomb coefficient against the collider, >= 0 */
    uint32_t cookie;
} cr_material;

/* Fill `out` with the named preset ("cotton", "silk", "denim", "knit").
 * CR_ERR_INVALID naming the known presets when `name` is not one. */
cr_status cr_material_preset(const char *name, cr_material *out, cr_error *err);

/* Override fields of `inout` from a JSON object whose keys are the field names
 * above ("density", "membrane": "stvk" | "baraff_witkin", "lame_mu", ...).
 * Unknown keys, wrong types and out-of-range values are refused by name
 * (CR_ERR_CONFIG); `inout` is left unchanged on failure. */
cr_status cr_material_load_json(const char *path, cr_material *inout, cr_error *err);
/* The same from JSON text; `source` names it in messages. */
cr_status cr_material_parse_json(const char *json_text, const char *source, cr_material *inout,
                                 cr_error *err);

/* CR_OK when every field is finite and in range; otherwise CR_ERR_INVALID
 * naming the field and its value. */
cr_status cr_material_validate(const cr_material *m, cr_error *err);

/* "stvk" or "baraff_witkin". */
const char *cr_membrane_model_name(cr_membrane_model model);

#ifdef __cplusplus
}
#endif
#endif
