/* view.c: the page `crease view` writes, its inputs (cr_view_write): each
 * panel's spec read into rest meshes and (T,V,3) frames (glb sequences, PC2
 * caches with their rest mesh, static meshes and named objects, a dataset's
 * sequence with its body through cr_dataset_read) and the garment's
 * per-vertex scalar; view_page.c writes the page (docs/view.md).
 *
 * Left out: what view_page.c leaves out, and serving the page (the tool's
 * view_serve.c). */
#include "crease/dataset.h"
#include "crease/mesh_io.h"
#include "crease/npz.h"
#include "crease/scene.h"
#include "view_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define VIEW_COOKIE 0x56494557u /* "VIEW" */

/* Above this many bytes of sequence data the page keeps it in data/: base64
 * grows it by a third, the whole page must be parsed before anything shows,
 * and the decoded string and its bytes sit in memory together (about 2.3x the
 * data); 64 MiB keeps a 150-frame 10k-vertex garment with its body (about
 * 14 MiB) and a few such panels in one double-clickable file. */
static const float DEFAULT_EMBED_MIB = 64.0f;

cr_view_def cr_view_default_def(void) {
    cr_view_def d;
    memset(&d, 0, sizeof d);
    d.embed_max_mib = DEFAULT_EMBED_MIB;
    d.three_dir = "/usr/share/javascript/three";
    d.cookie = VIEW_COOKIE;
    return d;
}

static int has_ext(const char *path, const char *ext) {
    char e[16];
    cr_path_ext(path, e, sizeof e);
    return strcmp(e, ext) == 0;
}

/* One part: "a.glb", "a.pc2[@rest.obj]", "a.obj". */
static cr_status read_part(const char *spec, cr_view_part *p, cr_error *err) {
    if (strlen(spec) >= sizeof p->path)
        return CR_FAIL(err, CR_ERR_INVALID, "%.40s...: path too long", spec);
    memcpy(p->path, spec, strlen(spec) + 1);
    char *at = strchr(p->path, '@');
    char rest[1100] = "";
    if (at) {
        *at = 0;
        snprintf(rest, sizeof rest, "%s", at + 1);
    }
    if (has_ext(p->path, "pc2")) {
        if (!rest[0]) {
            snprintf(rest, sizeof rest, "%.*s.obj", (int)(strlen(p->path) - 4), p->path);
            struct stat sb;
            if (stat(rest, &sb) != 0)
                return CR_FAIL(err, CR_ERR_IO, "%s: a .pc2 needs its rest mesh: write %s@MESH",
                               p->path, p->path);
        }
        cr_pc2 cache = {0};
        CR_TRY(cr_pc2_read(p->path, &cache, err));
        cr_status st = cr_scene_object_create(rest, &p->mesh, err);
        if (st == CR_OK && p->mesh->nv != cache.nv)
            st = CR_FAIL(err, CR_ERR_SHAPE, "%s: has %d points but rest mesh %s has %d vertices",
                         p->path, cache.nv, rest, p->mesh->nv);
        if (st != CR_OK) {
            cr_pc2_free(&cache);
            return st;
        }
        p->frames = cache.frames; /* taken over from the cache */
        p->nframes = cache.nframes;
        return CR_OK;
    }
    if (at) return CR_FAIL(err, CR_ERR_INVALID, "%s: '@MESH' goes only with a .pc2", spec);
    if (has_ext(p->path, "glb"))
        return cr_glb_read_sequence(p->path, &p->mesh, &p->frames, &p->nframes, &p->fps, err);
    CR_TRY(cr_scene_object_create(p->path, &p->mesh, err)); /* a file, or sphere, box, ... */
    p->nframes = 1;
    p->frames = cr_malloc((size_t)p->mesh->nv * 3 * sizeof(float), err);
    if (!p->frames) return CR_ERR_MEMORY;
    memcpy(p->frames, p->mesh->pos, (size_t)p->mesh->nv * 3 * sizeof(float));
    return CR_OK;
}

/* DIR/sequences/ID, or a dataset's root DIR (its first finished sequence), as the
 * two parts "garment.pc2@garment mesh+body.pc2@body rest" (the manifest's paths,
 * cr_dataset_read); 0 when spec is no dataset directory. */
static cr_status dataset_spec(const char *spec, char *out, size_t size, char *label,
                              size_t label_size, int *is_dataset, cr_error *err) {
    *is_dataset = 0;
    struct stat sb;
    if (stat(spec, &sb) != 0 || !S_ISDIR(sb.st_mode)) return CR_OK;
    char root[1100], path[1200], idbuf[256];
    const char *id = NULL, *seq = strstr(spec, "/sequences/");
    snprintf(root, sizeof root, "%.*s", seq ? (int)(seq - spec) : (int)strlen(spec), spec);
    if (seq) {
        snprintf(idbuf, sizeof idbuf, "%s", seq + strlen("/sequences/"));
        idbuf[strcspn(idbuf, "/")] = 0;
        id = idbuf;
    }
    snprintf(path, sizeof path, "%s/manifest.json", root);
    cr_dataset_manifest man;
    if (cr_dataset_read(root, &man, err) != CR_OK)
        return CR_FAIL(err, CR_ERR_IO, "%s: a directory, but no dataset (%s: %s)", spec, path,
                       err ? err->msg : "unreadable");
    const cr_dataset_sequence_entry *q = cr_dataset_find_id(&man, id);
    const cr_dataset_garment_entry *g =
        q && q->done ? cr_dataset_find_garment(&man, q->garment, q->body, q->res) : NULL;
    const cr_dataset_body_entry *b = q ? cr_dataset_find_body(&man, q->body) : NULL;
    cr_status st = CR_OK;
    if (!g || !b)
        st = CR_FAIL(err, CR_ERR_PARSE, "%s: no finished sequence%s%s", path, id ? " " : "",
                     id ? id : "");
    else if ((size_t)snprintf(out, size, "%s/%s@%s/%s+%s/%s@%s/%s", root, q->garment_pc2, root,
                              g->mesh, root, q->body_pc2, root, b->rest) >= size)
        st = CR_FAIL(err, CR_ERR_RANGE, "%s: paths too long", spec);
    if (st == CR_OK) snprintf(label, label_size, "%s", q->id);
    cr_dataset_manifest_free(&man);
    *is_dataset = st == CR_OK;
    return st;
}

static cr_status read_panel(const char *spec, cr_view_panel *panel, cr_error *err) {
    char buf[4096];
    int is_dataset;
    CR_TRY(dataset_spec(spec, buf, sizeof buf, panel->auto_label, sizeof panel->auto_label,
                        &is_dataset, err));
    if (!is_dataset) snprintf(buf, sizeof buf, "%s", spec);
    for (char *s = buf, *next; s; s = next) {
        next = strchr(s, '+');
        if (next) *next++ = 0;
        if (!*s) return CR_FAIL(err, CR_ERR_INVALID, "'%s': an empty part", spec);
        if (panel->nparts == CR_VIEW_MAX_PARTS)
            return CR_FAIL(err, CR_ERR_RANGE, "'%s': at most %d parts", spec, CR_VIEW_MAX_PARTS);
        CR_TRY(read_part(s, &panel->parts[panel->nparts++], err));
    }
    return CR_OK;
}

/* The per-vertex scalar of a panel's garment: (T,V) or (V) float .npy. */
static cr_status read_scalar(const char *path, cr_view_part *g, cr_error *err) {
    char file[1200];
    struct stat sb;
    if (stat(path, &sb) == 0 && S_ISDIR(sb.st_mode))
        snprintf(file, sizeof file, "%s/%s", path, CR_VIEW_COLOR_FILE);
    else
        snprintf(file, sizeof file, "%s", path);
    cr_npy a = {0};
    CR_TRY(cr_npy_read(file, CR_NPY_AS_F32, &a, err));
    int64_t nv = g->mesh->nv;
    int ok = (a.ndim == 1 && a.shape[0] == nv) ||
             (a.ndim == 2 && a.shape[1] == nv && (a.shape[0] == g->nframes || a.shape[0] == 1));
    if (!ok) {
        char got[96] = "";
        for (int d = 0; d < a.ndim; d++)
            snprintf(got + strlen(got), sizeof got - strlen(got), "%s%lld", d ? "," : "",
                     (long long)a.shape[d]);
        cr_npy_free(&a);
        return CR_FAIL(err, CR_ERR_SHAPE, "%s: expected shape (%d,%lld) or (%lld), got (%s)", file,
                       g->nframes, (long long)nv, (long long)nv, got);
    }
    g->nscalar = a.ndim == 1 ? 1 : (int32_t)a.shape[0];
    g->scalar = a.f32; /* taken over */
    return CR_OK;
}

static void panels_free(cr_view_panel *panels, int n) {
    for (int i = 0; i < n; i++)
        for (int k = 0; k < panels[i].nparts; k++) {
            cr_mesh_destroy(panels[i].parts[k].mesh);
            free(panels[i].parts[k].frames);
            free(panels[i].parts[k].scalar);
        }
}

cr_status cr_view_write(const cr_view_def *def, cr_view_report *out, cr_error *err) {
    CR_ASSERT(def && def->cookie == VIEW_COOKIE); /* made by cr_view_default_def */
    const int n = def->npanels;
    if (out) memset(out, 0, sizeof *out);
    if (!def->out_dir || !def->panels || n < 1 || n > CR_VIEW_MAX_PANELS)
        return CR_FAIL(err, CR_ERR_INVALID, "view: needs an output folder and 1 to %d panels",
                       CR_VIEW_MAX_PANELS);
    if (def->nlabels > n || def->ncolors > n)
        return CR_FAIL(err, CR_ERR_INVALID, "view: %d labels and %d colours for %d panels",
                       def->nlabels, def->ncolors, n);
    if (def->range_set && !(def->range[1] > def->range[0]))
        return CR_FAIL(err, CR_ERR_INVALID, "view: colour range %g to %g", (double)def->range[0],
                       (double)def->range[1]);
    cr_view_panel *panels = calloc(CR_VIEW_MAX_PANELS, sizeof *panels);
    if (!panels) return CR_FAIL(err, CR_ERR_MEMORY, "view: out of memory");
    cr_status st = CR_OK;
    for (int i = 0; st == CR_OK && i < n; i++) {
        panels[i].label = i < def->nlabels ? def->labels[i] : NULL;
        st = read_panel(def->panels[i], &panels[i], err);
        if (st == CR_OK && i < def->ncolors && strcmp(def->colors[i], "-") != 0)
            st = read_scalar(def->colors[i], &panels[i].parts[0], err);
    }
    cr_view_report r = {0};
    if (st == CR_OK) st = cr_view_page_write_(def, panels, n, &r, err);
    panels_free(panels, n);
    free(panels);
    if (st == CR_OK && out) *out = r;
    return st;
}
