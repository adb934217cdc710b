/* gdsr_fixture.h: the small gdsr cases the gdsr tests share (test_gdsr.c,
 * test_gdsr_runtime.c). */
#ifndef CREASE_TESTS_GDSR_FIXTURE_H
#define CREASE_TESTS_GDSR_FIXTURE_H

#include "crease/gdsr.h"

/* A small model: latent 16, 2 steps, 8 features for E and A, a 3-layer WIRE of width 8. */
cr_gdsr_model_def gdsr_tiny_def(void);
/* A 5x5 and a 9x9 sheet (40 cm) sharing UVs, waving over 8 frames; the high
 * one has a ripple the low one cannot hold. The body is a 5 cm sphere 20 cm
 * below. 1 on success. */
int gdsr_tiny_data(cr_gdsr_data *d);
/* Two such sheets 1 cm apart (their UVs side by side), rippling over 6
 * frames: an outfit of two layers. 1 on success. */
int gdsr_two_layer_data(cr_gdsr_data *d);

#endif
