/* eval_internal.h: what metrics.c takes from folds.c (the fold measures
 * that do not care where exactly a fold lies, and the hem's swing). Private
 * to src/eval/. H hinges (cr_topology order), V vertices, T frames. */
#ifndef CREASE_EVAL_INTERNAL_H
#define CREASE_EVAL_INTERNAL_H

#include "crease/eval.h"
#include "crease/topology.h"

/* Each hinge's neighbourhood within `ring` rings, as CSR: hinge h's list
 * idx[off[h] .. off[h+1]) holds h and every hinge whose stencil (its edge's
 * two ends and the two opposite vertices) shares a vertex with h's stencil
 * grown by ring - 1 rings of vertices. Ring 1: the hinges sharing a vertex
 * with h; on a grid, the parallel hinges one line over on either side. Freed
 * with free(). */
cr_status cr_eval_hinge_rings(const cr_topology *t, int ring, int32_t **off, int32_t **idx,
                              cr_error *err);

/* mean over h in sel (nsel of them; sel NULL: every hinge, nsel = H) of
 * min_{h' in N(h)} |a[h'] - b[h]|: a matched to b within the rings. */
double cr_eval_ring_match(const double *a, const double *b, const int32_t *sel, int32_t nsel,
                          const int32_t *off, const int32_t *idx);

/* Location-free: the k largest |a| sorted against the k largest |b|, mean
 * |difference| (k in 1..n). scratch (2n) doubles. */
double cr_eval_sorted_top(const double *a, const double *b, int32_t n, int32_t k, double *scratch);

/* Share of the n values with |a| > threshold. */
double cr_eval_fold_share(const double *a, int32_t n, double threshold);

/* The hem's swing of pred and ref into r (has_hem and the hem_* fields). */
cr_status cr_eval_hem_swing(const cr_eval_def *def, const cr_eval_input *in, const cr_topology *t,
                            cr_eval_result *r, cr_error *err);

struct cJSON;
/* v under key, null when not finite (report.c). */
void cr_eval_json_number(struct cJSON *o, const char *key, double v);
/* o on one line in a malloc'd string (free() it), o deleted; NULL when out of memory
 * (report.c). */
char *cr_eval_json_text(struct cJSON *o);
/* text written to path atomically (report.c). */
cr_status cr_eval_write_text_(const char *path, const char *text, cr_error *err);

/* Mean rest edge length of the garment, m. */
double cr_eval_mean_edge(const cr_mesh *g, const cr_topology *t);

#endif
