/* body_fixture.h: the mannequin the garment tests share (test_garment.c,
 * test_garment_params.c), built once per resolution and kept for the run. */
#ifndef CREASE_TESTS_BODY_FIXTURE_H
#define CREASE_TESTS_BODY_FIXTURE_H

#include "crease/body.h"

#include <stdint.h>

/* The default mannequin at grid `resolution` (coarser than the default 110 keeps
 * tests quick); NULL, with the failure recorded at the caller's file:line, when
 * it cannot be built. Owned by the fixture: do not destroy. */
cr_body_model *fixture_mannequin_at(int32_t resolution, const char *file, int line);
#define fixture_mannequin(resolution) fixture_mannequin_at((resolution), __FILE__, __LINE__)

#endif
