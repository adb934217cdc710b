/* view_internal.h: what view.c (the panels, read) hands view_page.c (the
 * page, written). Private to src/scene/. T frames, V vertices, F triangles,
 * S scalar frames (T or 1). */
#ifndef CREASE_VIEW_INTERNAL_H
#define CREASE_VIEW_INTERNAL_H

#include "crease/mesh.h"
#include "crease/view.h"

typedef struct cr_view_part {
    char path[1024];
    cr_mesh *mesh;   /* rest mesh: V vertices, F triangles */
    float *frames;   /* (T,V,3) positions, m */
    int32_t nframes; /* T */
    float fps;       /* 0 when the file has none */
    float *scalar;   /* (S,V) per-vertex values, or NULL */
    int32_t nscalar; /* S */
} cr_view_part;

typedef struct cr_view_panel {
    cr_view_part parts[CR_VIEW_MAX_PARTS]; /* garment first */
    int nparts;
    const char *label;    /* the def's, or NULL */
    char auto_label[256]; /* a dataset sequence's id */
} cr_view_panel;

/* Write def->out_dir's page of the npanels panels read (view_page.c); fills
 * out's figures. */
cr_status cr_view_page_write_(const cr_view_def *def, const cr_view_panel *panels, int npanels,
                              cr_view_report *out, cr_error *err);

#endif
