/* body_fixture.c: see body_fixture.h. */
#include "body_fixture.h"

#include "test.h"

enum { FIXTURE_MAX_RESOLUTIONS = 4 };

cr_body_model *fixture_mannequin_at(int32_t resolution, const char *file, int line) {
    static struct {
        int32_t resolution;
        cr_body_model *body;
    } cache[FIXTURE_MAX_RESOLUTIONS];
    int slot = 0;
    for (; slot < FIXTURE_MAX_RESOLUTIONS && cache[slot].body; slot++)
        if (cache[slot].resolution == resolution) return cache[slot].body;
    if (slot == FIXTURE_MAX_RESOLUTIONS) {
        cr_test_fail_here(file, line, "body fixture: more than %d resolutions",
                          FIXTURE_MAX_RESOLUTIONS);
        return NULL;
    }
    cr_error err = {0};
    cr_mannequin_def def = cr_mannequin_default_def();
    def.resolution = resolution;
    if (cr_mannequin_create(&def, &cache[slot].body, &err) != CR_OK) {
        cr_test_fail_here(file, line, "mannequin at resolution %d: %s", (int)resolution, err.msg);
        return NULL;
    }
    cache[slot].resolution = resolution;
    return cache[slot].body;
}
