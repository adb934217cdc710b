/* crease/view.h: the page `crease view` writes: garment and body sequences
 * played side by side in a browser, offline, on one timeline with one orbit
 * camera (docs/view.md).
 *
 *   const char *seqs[] = {"out/sim.glb+sphere", "other/sim.pc2@cloth.obj"};
 *   cr_view_def d = cr_view_default_def();
 *   d.panels = seqs, d.npanels = 2, d.out_dir = "page";
 *   cr_view_report r;
 *   CR_TRY(cr_view_write(&d, &r, err));             r.page: page/index.html
 *
 * Each panel is a spec of parts joined by '+' (garment first, then bodies or
 * objects), each a .glb that crease wrote (morph-target sequence or static
 * mesh), a .pc2 with its rest mesh (`sim.pc2@garment.obj`, or the .obj of the
 * same name beside it), a static .obj/.ply, or a named object of
 * cr_scene_object_create; or a crease dataset's sequence folder
 * (DATA/sequences/ID, or DATA for its first finished one) with its body
 * (cr_dataset_read). The sequences are quantised (positions to 16 bits over
 * each part's box, scalars to 8 bits over the colour bar) and written as one
 * binary block per part, embedded in index.html as base64 when all blocks
 * together stay under embed_max_mib, else beside it in data/ (then the page
 * needs http: `crease view --serve DIR`). three.js and its OrbitControls are
 * copied beside the page from three_dir; the page's own HTML and JS
 * (src/scene/view/) are compiled into the library (cmake/embed.cmake).
 *
 * Left out: textures and UVs, normals from the file (the page recomputes
 * them per frame), more than one scalar per panel, serving the page.
 */
#ifndef CREASE_VIEW_H
#define CREASE_VIEW_H

#include "crease/base.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { CR_VIEW_MAX_PANELS = 16, CR_VIEW_MAX_PARTS = 8 };
/* What a colour directory holds: crease eval's per-vertex error, float32 (T,V), m. */
#define CR_VIEW_COLOR_FILE "vertex_error.npy"

typedef struct cr_view_def {
    const char *out_dir;       /* index.html, three.min.js, OrbitControls.js, data/ (required) */
    const char *const *panels; /* (npanels) panel specs, 1 to CR_VIEW_MAX_PANELS */
    int npanels;
    const char *const *labels; /* (nlabels <= npanels) the first panels' labels; the others:
                                  the dataset sequence's id, else the garment's file name */
    int nlabels;
    const char *const *colors; /* (ncolors <= npanels) the first panels' garment colours: a
                                  float .npy (T,V) or (V), or a directory holding
                                  CR_VIEW_COLOR_FILE; "-" leaves a panel plain */
    int ncolors;
    float range[2];        /* the colour bar's range when range_set (range[0] < range[1]) */
    int range_set;         /* 0: min(0, the smallest value) to the largest */
    float fps;             /* frames per second; 0: the first glb's, else 30 */
    float embed_max_mib;   /* embed the sequences up to this size, MiB (default 64) */
    const char *three_dir; /* where three.js lies (default Debian's libjs-three,
                              /usr/share/javascript/three) */
    uint32_t cookie;       /* set by cr_view_default_def; a hand-zeroed def is a bug */
} cr_view_def;
cr_view_def cr_view_default_def(void);

typedef struct cr_view_report {
    char page[1200]; /* out_dir/index.html */
    int panels;
    int32_t frames;    /* the longest part's */
    float fps;         /* the page's rate */
    double data_bytes; /* the sequences' blocks together */
    int embedded;      /* 1: in index.html, 0: in out_dir/data/ */
} cr_view_report;

/* Read every panel and write the page into def->out_dir. Fails naming the
 * spec or file (a missing rest mesh, vertex counts that differ, a colour of
 * the wrong shape, three.js not found). out may be NULL. */
cr_status cr_view_write(const cr_view_def *def, cr_view_report *out, cr_error *err);

#ifdef __cplusplus
}
#endif

#endif
