/* test_phys_material.c: presets exist and validate with their documented
 * values, unknown presets are refused by name, JSON overrides apply (numbers
 * and the membrane model) and leave the material untouched on failure, an
 * unknown key or out-of-range value is refused by name, and validation names
 * the offending field. */
#include "crease/phys_material.h"
#include "test.h"

#include <stdio.h>
#include <string.h>

static void write_text(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    CR_REQUIRE(f);
    fputs(text, f);
    fclose(f);
}

CR_TEST(phys_material, presets_validate) {
    const char *names[] = {"cotton", "silk", "denim", "knit"};
    cr_error err;
    for (int i = 0; i < 4; i++) {
        cr_material m;
        CR_CHECK_OK(cr_material_preset(names[i], &m, &err), &err);
        CR_CHECK_OK(cr_material_validate(&m, &err), &err);
        CR_CHECK(strcmp(m.name, names[i]) == 0);
        CR_CHECK(m.membrane == CR_MEMBRANE_STVK);
        CR_CHECK_NEAR(m.yield_angle, 0.52, 0.0);
        CR_CHECK_NEAR(m.plastic_gain, 1.0, 0.0);
        /* Baraff-Witkin stiffnesses match StVK at small strain. */
        CR_CHECK_NEAR(m.bw_stretch, 2 * m.lame_mu + m.lame_lambda, 1e-9);
        CR_CHECK_NEAR(m.bw_shear, m.lame_mu, 1e-9);
    }
    cr_material c;
    CR_CHECK_OK(cr_material_preset("cotton", &c, &err), &err);
    /* HOOD/SNUG's fabric. */
    CR_CHECK_NEAR(c.density, 0.20022, 0.0);
    CR_CHECK_NEAR(c.lame_mu, 23600.0, 0.0);
    CR_CHECK_NEAR(c.lame_lambda, 44400.0, 0.0);
    CR_CHECK_NEAR(c.bending, 3.96e-5, 0.0);
    cr_material d;
    CR_CHECK_OK(cr_material_preset("denim", &d, &err), &err);
    CR_CHECK(d.density > c.density && d.bending > c.bending);
    cr_material bad;
    CR_CHECK(cr_material_preset("tweed", &bad, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "tweed") != NULL && strstr(err.msg, "denim") != NULL);
}

CR_TEST(phys_material, json_overrides) {
    cr_error err;
    cr_material m;
    CR_CHECK_OK(cr_material_preset("cotton", &m, &err), &err);
    char path[512];
    snprintf(path, sizeof path, "%s/fabric.json", cr_test_tmpdir());
    write_text(path, "{\"density\": 0.31, \"membrane\": \"baraff_witkin\", \"bw_shear\": 12.5,\n"
                     " \"name\": \"mine\", \"friction\": 0.45}\n");
    CR_CHECK_OK(cr_material_load_json(path, &m, &err), &err);
    CR_CHECK_NEAR(m.density, 0.31, 0.0);
    CR_CHECK(m.membrane == CR_MEMBRANE_BARAFF_WITKIN);
    CR_CHECK_NEAR(m.bw_shear, 12.5, 0.0);
    CR_CHECK_NEAR(m.friction, 0.45, 0.0);
    CR_CHECK_NEAR(m.lame_mu, 23600.0, 0.0); /* untouched */
    CR_CHECK(strcmp(m.name, "mine") == 0);
    CR_CHECK_OK(cr_material_validate(&m, &err), &err);

    const cr_material before = m;
    /* Unknown key: refused by name, nothing changed. */
    CR_CHECK(cr_material_parse_json("{\"density\": 0.5, \"stiffnes\": 3}", "t.json", &m, &err) ==
             CR_ERR_CONFIG);
    CR_CHECK(strstr(err.msg, "stiffnes") != NULL && strstr(err.msg, "t.json") != NULL);
    CR_CHECK(memcmp(&m, &before, sizeof m) == 0);
    /* Out of range, wrong type, unknown model. */
    CR_CHECK(cr_material_parse_json("{\"plastic_gain\": 1.5}", "t.json", &m, &err) ==
             CR_ERR_CONFIG);
    CR_CHECK(strstr(err.msg, "plastic_gain") != NULL);
    CR_CHECK(cr_material_parse_json("{\"bending\": \"stiff\"}", "t.json", &m, &err) ==
             CR_ERR_CONFIG);
    CR_CHECK(strstr(err.msg, "bending") != NULL);
    CR_CHECK(cr_material_parse_json("{\"membrane\": \"neo-hookean\"}", "t.json", &m, &err) ==
             CR_ERR_CONFIG);
    CR_CHECK(strstr(err.msg, "neo-hookean") != NULL);
    CR_CHECK(memcmp(&m, &before, sizeof m) == 0);
    /* Malformed JSON names the line; a missing file is an I/O error. */
    CR_CHECK(cr_material_parse_json("{\n\"density\": }", "t.json", &m, &err) == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "t.json:2") != NULL);
    snprintf(path, sizeof path, "%s/missing.json", cr_test_tmpdir());
    CR_CHECK(cr_material_load_json(path, &m, &err) == CR_ERR_IO);
}

CR_TEST(phys_material, validate_names_field) {
    cr_error err;
    cr_material m;
    CR_CHECK_OK(cr_material_preset("silk", &m, &err), &err);
    cr_material b = m;
    b.density = -1.0;
    CR_CHECK(cr_material_validate(&b, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "density") != NULL);
    b = m;
    b.collision_thickness = NAN;
    CR_CHECK(cr_material_validate(&b, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "collision_thickness") != NULL);
    b = m;
    b.plastic_gain = 2.0;
    CR_CHECK(cr_material_validate(&b, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "plastic_gain") != NULL);
    b = m;
    b.cookie = 0;
    CR_CHECK(cr_material_validate(&b, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "cr_material_preset") != NULL);
    CR_CHECK_NEAR(strcmp(cr_membrane_model_name(CR_MEMBRANE_BARAFF_WITKIN), "baraff_witkin"), 0, 0);
}
