/* cmd_view.c: `crease view SEQ... -o DIR`: an offline HTML page that plays
 * garment and body sequences side by side (docs/view.md).
 *
 * Each SEQ is one panel: parts joined by '+' (garment first, then bodies or
 * objects), each a .glb that crease wrote (morph-target sequence or static
 * mesh), a .pc2 with its rest mesh (`sim.pc2@garment.obj`, or the .obj of the
 * same name beside it), or a static .obj/.ply. The sequences are read here,
 * quantised (positions to 16 bits over each part's box, scalars to 8 bits
 * over the colour bar) and written as one binary block per part, embedded in
 * index.html as base64 when all blocks together stay under --embed-max, else
 * beside it in data/ (then the page needs http: `crease view --serve DIR`,
 * view_serve.c). three.js and its OrbitControls are copied beside the page
 * from Debian's libjs-three; the page's own HTML and JS (src/cli/view/) are
 * compiled into the tool (cmake/embed.cmake).
 *
 * Left out: textures and UVs, normals from the file (the page recomputes
 * them per frame), more than one scalar per panel. */
#include "cli.h"
#include "crease/dataset.h"
#include "crease/mesh_io.h"
#include "crease/npz.h"
#include "crease/scene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* view_assets.c, generated from src/cli/view/ at build time. */
extern const char view_page_html[], view_viewer_js[];
extern const size_t view_page_html_len, view_viewer_js_len;

int view_serve(const char *dir, int port);

enum { MAX_PANELS = 16, MAX_PARTS = 8 };
/* PC2 stores no frame rate, and a static mesh none at all. */
static const float DEFAULT_FPS = 30.0f;
/* Above this many bytes of sequence data the page keeps it in data/: base64
 * grows it by a third, the whole page must be parsed before anything shows,
 * and the decoded string and its bytes sit in memory together (about 2.3x the
 * data); 64 MiB keeps a 150-frame 10k-vertex garment with its body (about
 * 14 MiB) and a few such panels in one double-clickable file. */
static const double DEFAULT_EMBED_MIB = 64.0;
static const char *const DEFAULT_THREE_DIR = "/usr/share/javascript/three";
static const char *const DEFAULT_COLOR_FILE = "vertex_error.npy";

void help_view(void) {
    printf("usage: crease view SEQ... -o DIR [options]\n"
           "       crease view --serve DIR [--port N]\n\n"
           "Write DIR/index.html, a page that plays the sequences side by side in a browser,\n"
           "offline, on one timeline (play/pause, scrub, step, speed, loop) with one orbit\n"
           "camera. Each SEQ is one panel: parts joined by '+', garment first:\n"
           "  sim.glb                    a glb sequence crease wrote (or a static glb)\n"
           "  sim.glb+body.glb           a garment and its body, drawn together\n"
           "  sim.pc2@garment.obj        a PC2 point cache and its rest mesh (without @MESH:\n"
           "                             the .obj of the same name beside it)\n"
           "  sphere.obj                 a static mesh (.obj, .ply, .glb)\n"
           "  sphere, torus, prism, box  the named objects of crease simulate --object\n"
           "  DATA/sequences/ID, DATA    a crease dataset's sequence (DATA: its first) with\n"
           "                             its body\n\n"
           "options:\n"
           "  -o DIR             output directory: index.html, three.min.js, OrbitControls.js,\n"
           "                     and data/ when the sequences are too large to embed\n"
           "  --label TEXT       the next panel's label (repeat, in panel order; default:\n"
           "                     the garment's file name)\n"
           "  --color-by PATH    colour the next panel's garment by a per-vertex scalar: a\n"
           "                     float .npy of shape (T,V) or (V), or a directory holding\n"
           "                     %s (float32 (T,V), m, docs/view.md); '-' skips a panel\n"
           "  --range LO HI      the colour bar's range (default 0 to the largest value)\n"
           "  --fps F            frames per second (default: the first glb's, else 30)\n"
           "  --embed-max MIB    embed the sequences in index.html up to this size (default %g)\n"
           "  --three DIR        where three.js lies (default %s,\n"
           "                     Debian's libjs-three)\n"
           "  --serve            serve DIR on http://127.0.0.1:PORT/ after writing (or alone\n"
           "                     with DIR); stops on Ctrl-C\n"
           "  --port N           the port to serve on (default 8130; 0 picks a free one)\n"
           "  --json             end with a JSON summary on stdout\n",
           DEFAULT_COLOR_FILE, DEFAULT_EMBED_MIB, DEFAULT_THREE_DIR);
}

/* ---- inputs ---------------------------------------------------------------------------- */

typedef struct view_part {
    char path[1024];
    cr_mesh *mesh; /* rest mesh: V vertices, F triangles */
    float *frames; /* (T,V,3) positions, m */
    int32_t nframes;
    float fps;       /* 0 when the file has none */
    float *scalar;   /* (S,V) per-vertex values, or NULL */
    int32_t nscalar; /* S: T or 1 */
} view_part;

typedef struct view_panel {
    view_part parts[MAX_PARTS];
    int nparts;
    const char *label;
    char auto_label[256]; /* a dataset sequence's id */
} view_panel;

typedef struct view_list {
    const char *v[MAX_PANELS];
    int n;
} view_list;

static int parse_append(const char *cmd, const char *opt, const char *const *values, void *dst) {
    view_list *l = dst;
    if (l->n >= MAX_PANELS) return cli_usage(cmd, "%s: at most %d", opt, MAX_PANELS);
    l->v[l->n++] = values[0];
    return CLI_OK;
}

static int parse_range(const char *cmd, const char *opt, const char *const *values, void *dst) {
    float *r = dst;
    if (!cli_parse_float(cmd, opt, values[0], -1e30, 1e30, &r[0]) ||
        !cli_parse_float(cmd, opt, values[1], -1e30, 1e30, &r[1]))
        return CLI_USAGE;
    if (!(r[1] > r[0]))
        return cli_usage(cmd, "%s expects LO < HI, got %s %s", opt, values[0], values[1]);
    return CLI_OK;
}

static int has_ext(const char *path, const char *ext) {
    char e[16];
    cr_path_ext(path, e, sizeof e);
    return strcmp(e, ext) == 0;
}

/* One part: "a.glb", "a.pc2[@rest.obj]", "a.obj". */
static cr_status read_part(const char *spec, view_part *p, cr_error *err) {
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

static cr_status read_panel(const char *spec, view_panel *panel, cr_error *err) {
    char buf[4096];
    int is_dataset;
    CR_TRY(dataset_spec(spec, buf, sizeof buf, panel->auto_label, sizeof panel->auto_label,
                        &is_dataset, err));
    if (!is_dataset) snprintf(buf, sizeof buf, "%s", spec);
    for (char *s = buf, *next; s; s = next) {
        next = strchr(s, '+');
        if (next) *next++ = 0;
        if (!*s) return CR_FAIL(err, CR_ERR_INVALID, "'%s': an empty part", spec);
        if (panel->nparts == MAX_PARTS)
            return CR_FAIL(err, CR_ERR_RANGE, "'%s': at most %d parts", spec, MAX_PARTS);
        CR_TRY(read_part(s, &panel->parts[panel->nparts++], err));
    }
    return CR_OK;
}

/* The per-vertex scalar of a panel's garment: (T,V) or (V) float .npy. */
static cr_status read_scalar(const char *path, view_part *g, cr_error *err) {
    char file[1200];
    struct stat sb;
    if (stat(path, &sb) == 0 && S_ISDIR(sb.st_mode))
        snprintf(file, sizeof file, "%s/%s", path, DEFAULT_COLOR_FILE);
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

static void panels_free(view_panel *panels, int n) {
    for (int i = 0; i < n; i++)
        for (int k = 0; k < panels[i].nparts; k++) {
            cr_mesh_destroy(panels[i].parts[k].mesh);
            free(panels[i].parts[k].frames);
            free(panels[i].parts[k].scalar);
        }
}

/* ---- output ---------------------------------------------------------------------------- */

/* One part's block: tri u32 (F,3) | pos u16 (T,V,3) | val u8 (S,V), each 4-byte aligned. */
typedef struct view_block {
    unsigned char *data;
    size_t len, tri_off, pos_off, val_off;
    float lo[3], step[3];
} view_block;

static size_t align4(size_t n) {
    return (n + 3) & ~(size_t)3;
}

static cr_status make_block(const view_part *p, const float range[2], view_block *b,
                            cr_error *err) {
    int64_t nv = p->mesh->nv, nf = p->mesh->nf, nt = p->nframes;
    b->tri_off = 0;
    b->pos_off = align4((size_t)nf * 12);
    b->val_off = align4(b->pos_off + (size_t)(nt * nv * 3) * 2);
    b->len = align4(b->val_off + (p->scalar ? (size_t)(p->nscalar * nv) : 0));
    b->data = calloc(1, b->len);
    if (!b->data) return CR_FAIL(err, CR_ERR_MEMORY, "%s: %zu bytes", p->path, b->len);
    memcpy(b->data, p->mesh->tri, (size_t)nf * 12); /* int32 >= 0 reads as uint32 */
    float hi[3];
    for (int k = 0; k < 3; k++)
        b->lo[k] = hi[k] = p->frames[k];
    for (int64_t i = 0; i < nt * nv; i++)
        for (int k = 0; k < 3; k++) {
            b->lo[k] = fminf(b->lo[k], p->frames[3 * i + k]);
            hi[k] = fmaxf(hi[k], p->frames[3 * i + k]);
        }
    uint16_t *q = (uint16_t *)(b->data + b->pos_off);
    for (int k = 0; k < 3; k++)
        b->step[k] = (hi[k] - b->lo[k]) / 65535.0f;
    for (int64_t i = 0; i < nt * nv; i++)
        for (int k = 0; k < 3; k++) {
            float s = b->step[k] > 0 ? (p->frames[3 * i + k] - b->lo[k]) / b->step[k] : 0.0f;
            q[3 * i + k] = (uint16_t)fminf(65535.0f, fmaxf(0.0f, roundf(s)));
        }
    if (p->scalar) {
        unsigned char *v = b->data + b->val_off;
        for (int64_t i = 0; i < (int64_t)p->nscalar * nv; i++) {
            float s = (p->scalar[i] - range[0]) / (range[1] - range[0]) * 255.0f;
            v[i] = (unsigned char)fminf(255.0f, fmaxf(0.0f, roundf(s)));
        }
    }
    return CR_OK;
}

static void put_base64(FILE *f, const unsigned char *d, size_t n) {
    static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    char line[4 * 1024 + 8];
    size_t w = 0;
    for (size_t i = 0; i < n; i += 3) {
        uint32_t x = (uint32_t)d[i] << 16 | (i + 1 < n ? (uint32_t)d[i + 1] << 8 : 0) |
                     (i + 2 < n ? d[i + 2] : 0);
        line[w++] = tab[x >> 18 & 63];
        line[w++] = tab[x >> 12 & 63];
        line[w++] = i + 1 < n ? tab[x >> 6 & 63] : '=';
        line[w++] = i + 2 < n ? tab[x & 63] : '=';
        if (w >= 4 * 1024) {
            line[w++] = '\n';
            fwrite(line, 1, w, f);
            w = 0;
        }
    }
    fwrite(line, 1, w, f);
}

static cr_status write_bytes(const char *path, const void *d, size_t n, cr_error *err) {
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    if (fwrite(d, 1, n, f.fp) != n) {
        cr_atomic_abort(&f);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
    }
    return cr_atomic_commit(&f, err);
}

static cr_status copy_file(const char *from, const char *to, cr_error *err) {
    char *d;
    size_t n;
    cr_status st = cr_file_read_all(from, &d, &n, err);
    if (st != CR_OK)
        return CR_FAIL(err, CR_ERR_IO,
                       "%s: not found: the page needs three.js (Debian: apt-get install "
                       "libjs-three, or --three DIR)",
                       from);
    st = write_bytes(to, d, n, err);
    free(d);
    return st;
}

/* JSON that may sit inside <script>: every '<' becomes \u003c (only strings hold one). */
static void put_json(FILE *f, const char *json) {
    for (const char *c = json; *c; c++)
        if (*c == '<')
            fputs("\\u003c", f);
        else
            fputc(*c, f);
}

static const char *base_name(const char *path) {
    const char *s = strrchr(path, '/');
    return s ? s + 1 : path;
}

typedef struct view_opts {
    const char *out, *three;
    view_list labels, colors;
    float range[2], fps;
    float embed_mib;
    int serve, port, json, range_set;
} view_opts;

/* Write the page; fills the summary. */
static cr_status write_page(const view_opts *o, view_panel *panels, int npanels, cJSON *summary,
                            cr_error *err) {
    CR_TRY(cr_mkdir_p(o->out, err));
    char path[1200], from[1200];
    snprintf(from, sizeof from, "%s/build/three.min.js", o->three);
    snprintf(path, sizeof path, "%s/three.min.js", o->out);
    CR_TRY(copy_file(from, path, err));
    snprintf(from, sizeof from, "%s/examples/js/controls/OrbitControls.js", o->three);
    snprintf(path, sizeof path, "%s/OrbitControls.js", o->out);
    CR_TRY(copy_file(from, path, err));

    /* Timeline, bounds and the colour range. */
    int32_t frames = 1;
    float fps = o->fps;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    float range[2] = {o->range[0], o->range[1]}, smax = -INFINITY, smin = INFINITY;
    int any_scalar = 0;
    for (int i = 0; i < npanels; i++)
        for (int k = 0; k < panels[i].nparts; k++) {
            const view_part *p = &panels[i].parts[k];
            if (p->nframes > frames) frames = p->nframes;
            if (fps <= 0 && p->fps > 0) fps = p->fps;
            for (int64_t j = 0; j < (int64_t)p->nframes * p->mesh->nv; j++)
                for (int c = 0; c < 3; c++) {
                    lo[c] = fminf(lo[c], p->frames[3 * j + c]);
                    hi[c] = fmaxf(hi[c], p->frames[3 * j + c]);
                }
            for (int64_t j = 0; p->scalar && j < (int64_t)p->nscalar * p->mesh->nv; j++) {
                smax = fmaxf(smax, p->scalar[j]);
                smin = fminf(smin, p->scalar[j]);
            }
            any_scalar |= p->scalar != NULL;
        }
    if (fps <= 0) fps = DEFAULT_FPS;
    if (any_scalar && !o->range_set) {
        range[0] = fminf(0.0f, smin);
        range[1] = smax > range[0] ? smax : range[0] + 1.0f;
    }
    float center[3], radius = 0;
    for (int c = 0; c < 3; c++) {
        center[c] = 0.5f * (lo[c] + hi[c]);
        radius += 0.25f * (hi[c] - lo[c]) * (hi[c] - lo[c]);
    }
    radius = fmaxf(sqrtf(radius), 1e-3f);

    /* Blocks, then the decision to embed them. */
    view_block blocks[MAX_PANELS][MAX_PARTS];
    memset(blocks, 0, sizeof blocks);
    size_t total = 0;
    cr_status st = CR_OK;
    for (int i = 0; st == CR_OK && i < npanels; i++)
        for (int k = 0; st == CR_OK && k < panels[i].nparts; k++) {
            st = make_block(&panels[i].parts[k], range, &blocks[i][k], err);
            total += blocks[i][k].len;
        }
    int embed = (double)total <= (double)o->embed_mib * 1024.0 * 1024.0;

    cJSON *meta = cJSON_CreateObject(), *jp = cJSON_AddArrayToObject(meta, "panels");
    cJSON_AddNumberToObject(meta, "fps", fps);
    cJSON_AddNumberToObject(meta, "frames", frames);
    cJSON_AddItemToObject(meta, "center", cli_json_float_array(center, 3));
    cJSON_AddNumberToObject(meta, "radius", radius);
    if (any_scalar) {
        cJSON *cb = cJSON_AddObjectToObject(meta, "colorbar");
        cJSON_AddNumberToObject(cb, "lo", range[0]);
        cJSON_AddNumberToObject(cb, "hi", range[1]);
        char name[256] = "value";
        for (int i = 0; i < o->colors.n; i++)
            if (strcmp(o->colors.v[i], "-") != 0) {
                /* the file's stem: "vertex_error" for an eval directory */
                struct stat sb;
                const char *b = stat(o->colors.v[i], &sb) == 0 && S_ISDIR(sb.st_mode)
                                    ? DEFAULT_COLOR_FILE
                                    : base_name(o->colors.v[i]);
                snprintf(name, sizeof name, "%.*s", (int)strcspn(b, "."), b);
                break;
            }
        cJSON_AddStringToObject(cb, "name", name);
        cJSON_AddStringToObject(cb, "unit", "m");
    }
    if (st == CR_OK && !embed) {
        snprintf(path, sizeof path, "%s/data", o->out);
        st = cr_mkdir_p(path, err);
    }
    for (int i = 0; st == CR_OK && i < npanels; i++) {
        cJSON *pan = cJSON_CreateObject(), *parts = cJSON_AddArrayToObject(pan, "parts");
        cJSON_AddItemToArray(jp, pan);
        cJSON_AddStringToObject(pan, "label",
                                panels[i].label           ? panels[i].label
                                : panels[i].auto_label[0] ? panels[i].auto_label
                                                          : base_name(panels[i].parts[0].path));
        for (int k = 0; st == CR_OK && k < panels[i].nparts; k++) {
            const view_part *p = &panels[i].parts[k];
            const view_block *b = &blocks[i][k];
            cJSON *jq = cJSON_CreateObject();
            cJSON_AddItemToArray(parts, jq);
            cJSON_AddStringToObject(jq, "role", k == 0 ? "garment" : "body");
            cJSON_AddStringToObject(jq, "source", base_name(p->path));
            cJSON_AddNumberToObject(jq, "vertices", p->mesh->nv);
            cJSON_AddNumberToObject(jq, "faces", p->mesh->nf);
            cJSON_AddNumberToObject(jq, "frames", p->nframes);
            cJSON_AddNumberToObject(jq, "tri_offset", (double)b->tri_off);
            cJSON_AddNumberToObject(jq, "pos_offset", (double)b->pos_off);
            cJSON_AddItemToObject(jq, "lo", cli_json_float_array(b->lo, 3));
            cJSON_AddItemToObject(jq, "step", cli_json_float_array(b->step, 3));
            if (p->scalar) {
                cJSON *js = cJSON_AddObjectToObject(jq, "scalar");
                cJSON_AddNumberToObject(js, "offset", (double)b->val_off);
                cJSON_AddNumberToObject(js, "frames", p->nscalar);
            }
            if (embed) {
                cJSON_AddNullToObject(jq, "file");
            } else {
                char name[64];
                snprintf(name, sizeof name, "data/p%d_%d.bin", i, k);
                cJSON_AddStringToObject(jq, "file", name);
                snprintf(path, sizeof path, "%s/%s", o->out, name);
                st = write_bytes(path, b->data, b->len, err);
            }
        }
    }

    char *json = cJSON_PrintUnformatted(meta);
    cJSON_Delete(meta);
    snprintf(path, sizeof path, "%s/index.html", o->out);
    const char *mark = strstr(view_page_html, "<!--crease-data-->");
    CR_ASSERT(mark);
    cr_atomic_file f;
    if (st == CR_OK && !json) st = CR_FAIL(err, CR_ERR_MEMORY, "%s: the page's JSON", path);
    if (st == CR_OK) st = cr_atomic_open(&f, path, err);
    if (st == CR_OK) {
        fwrite(view_page_html, 1, (size_t)(mark - view_page_html), f.fp);
        fputs("<script id=\"crease-meta\" type=\"application/json\">", f.fp);
        put_json(f.fp, json);
        fputs("</script>\n", f.fp);
        for (int i = 0; embed && i < npanels; i++)
            for (int k = 0; k < panels[i].nparts; k++) {
                fprintf(f.fp, "<script id=\"crease-part-%d-%d\" type=\"application/octet-stream\">",
                        i, k);
                put_base64(f.fp, blocks[i][k].data, blocks[i][k].len);
                fputs("</script>\n", f.fp);
            }
        fputs("<script>\n", f.fp);
        fwrite(view_viewer_js, 1, view_viewer_js_len, f.fp);
        fputs("</script>\n", f.fp);
        fputs(mark + strlen("<!--crease-data-->\n"), f.fp);
        st = ferror(f.fp) ? CR_FAIL(err, CR_ERR_IO, "%s: write failed", path) : CR_OK;
        if (st == CR_OK)
            st = cr_atomic_commit(&f, err);
        else
            cr_atomic_abort(&f);
    }
    free(json);
    for (int i = 0; i < npanels; i++)
        for (int k = 0; k < panels[i].nparts; k++)
            free(blocks[i][k].data);
    if (st != CR_OK) return st;

    cJSON_AddStringToObject(summary, "page", path);
    cJSON_AddNumberToObject(summary, "panels", npanels);
    cJSON_AddNumberToObject(summary, "frames", frames);
    cJSON_AddNumberToObject(summary, "fps", fps);
    cJSON_AddNumberToObject(summary, "data_bytes", (double)total);
    cJSON_AddBoolToObject(summary, "embedded", embed);
    fprintf(stderr, "view: wrote %s: %d panel%s, %d frames at %g fps, %.1f MiB of sequences %s\n",
            path, npanels, npanels > 1 ? "s" : "", frames, fps, (double)total / 1048576.0,
            embed ? "embedded (opens from file://)" : "in data/ (serve it: crease view --serve)");
    return CR_OK;
}

int cmd_view(int argc, char **argv) {
    view_opts o = {.three = DEFAULT_THREE_DIR, .embed_mib = (float)DEFAULT_EMBED_MIB, .port = 8130};
    const char *pos[MAX_PANELS + 1];
    int npos = 0;
    const cli_opt opts[] = {
        CLI_OUTPUT(&o.out),
        CLI_CUSTOM("--label", parse_append, &o.labels, 1),
        CLI_CUSTOM("--color-by", parse_append, &o.colors, 1),
        {.name = "--range",
         .kind = CLI_OPT_CUSTOM,
         .fn = parse_range,
         .dst = o.range,
         .nvalues = 2,
         .seen = &o.range_set},
        CLI_FLOAT("--fps", &o.fps, 0.01, 100000),
        CLI_FLOAT("--embed-max", &o.embed_mib, 0, 4096),
        CLI_STR("--three", &o.three),
        CLI_FLAG("--serve", &o.serve),
        CLI_INT("--port", &o.port, 0, 65535),
        CLI_FLAG("--json", &o.json),
        CLI_END,
    };
    int rc = cli_parse("view", argc, argv, opts, pos, MAX_PANELS + 1, &npos);
    if (rc != CLI_OK) return rc;
    if (o.serve && npos == 1 && !o.out) return view_serve(pos[0], o.port);
    if (npos == 0) return cli_usage("view", "expected at least one sequence");
    if (npos > MAX_PANELS) return cli_usage("view", "at most %d panels", MAX_PANELS);
    if (!o.out) return cli_usage("view", "missing -o DIR");
    if (o.labels.n > npos || o.colors.n > npos)
        return cli_usage("view", "%d --label and %d --color-by for %d panels", o.labels.n,
                         o.colors.n, npos);

    view_panel *panels = calloc(MAX_PANELS, sizeof *panels);
    if (!panels) return cli_usage("view", "out of memory");
    cr_error err = {0};
    cr_status st = CR_OK;
    for (int i = 0; st == CR_OK && i < npos; i++) {
        panels[i].label = i < o.labels.n ? o.labels.v[i] : NULL;
        st = read_panel(pos[i], &panels[i], &err);
        if (st == CR_OK && i < o.colors.n && strcmp(o.colors.v[i], "-") != 0)
            st = read_scalar(o.colors.v[i], &panels[i].parts[0], &err);
    }
    cJSON *summary = cJSON_CreateObject();
    cJSON_AddStringToObject(summary, "command", "view");
    if (st == CR_OK) st = write_page(&o, panels, npos, summary, &err);
    panels_free(panels, npos);
    free(panels);
    if (st != CR_OK) {
        cJSON_Delete(summary);
        return cli_fail(&err);
    }
    if (o.json)
        cli_json_print(summary);
    else
        cJSON_Delete(summary);
    return o.serve ? view_serve(o.out, o.port) : CLI_OK;
}
