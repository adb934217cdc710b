/* view_page.c: the page of cr_view_write (docs/view.md): the timeline, the
 * bounds and the colour bar over every panel, each part's block (triangles,
 * positions quantised to 16 bits over the part's box, the scalar to 8 bits
 * over the colour bar), embedded in index.html as base64 or written to
 * data/, and three.js copied beside the page. The page's HTML and JS
 * (src/scene/view/) are compiled in from view_assets.c (cmake/embed.cmake).
 *
 * Left out: textures and UVs, normals (the page recomputes them per frame),
 * more than one scalar per panel. */
#include "view_internal.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* view_assets.c, generated from src/scene/view/ at build time. */
extern const char cr_view_page_html_[], cr_view_viewer_js_[];
extern const size_t cr_view_page_html_len_, cr_view_viewer_js_len_;

/* PC2 stores no frame rate, and a static mesh none at all. */
static const float DEFAULT_FPS = 30.0f;

/* One part's block: tri u32 (F,3) | pos u16 (T,V,3) | val u8 (S,V), each 4-byte aligned. */
typedef struct view_block {
    unsigned char *data;
    size_t len, tri_off, pos_off, val_off;
    float lo[3], step[3];
} view_block;

static size_t align4(size_t n) {
    return (n + 3) & ~(size_t)3;
}

static cr_status make_block(const cr_view_part *p, const float range[2], view_block *b,
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

static cJSON *json_floats(const float *v, int n) {
    cJSON *arr = cJSON_CreateArray();
    for (int i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, cJSON_CreateNumber(v[i]));
    return arr;
}

/* The whole page's figures: timeline, bounds and the colour bar. */
typedef struct view_frame {
    int32_t frames;
    float fps, center[3], radius, range[2];
    int any_scalar;
} view_frame;

static view_frame frame_panels(const cr_view_def *def, const cr_view_panel *panels, int npanels) {
    view_frame v = {.frames = 1, .fps = def->fps, .range = {def->range[0], def->range[1]}};
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    float smax = -INFINITY, smin = INFINITY;
    for (int i = 0; i < npanels; i++)
        for (int k = 0; k < panels[i].nparts; k++) {
            const cr_view_part *p = &panels[i].parts[k];
            if (p->nframes > v.frames) v.frames = p->nframes;
            if (v.fps <= 0 && p->fps > 0) v.fps = p->fps;
            for (int64_t j = 0; j < (int64_t)p->nframes * p->mesh->nv; j++)
                for (int c = 0; c < 3; c++) {
                    lo[c] = fminf(lo[c], p->frames[3 * j + c]);
                    hi[c] = fmaxf(hi[c], p->frames[3 * j + c]);
                }
            for (int64_t j = 0; p->scalar && j < (int64_t)p->nscalar * p->mesh->nv; j++) {
                smax = fmaxf(smax, p->scalar[j]);
                smin = fminf(smin, p->scalar[j]);
            }
            v.any_scalar |= p->scalar != NULL;
        }
    if (v.fps <= 0) v.fps = DEFAULT_FPS;
    if (v.any_scalar && !def->range_set) {
        v.range[0] = fminf(0.0f, smin);
        v.range[1] = smax > v.range[0] ? smax : v.range[0] + 1.0f;
    }
    v.radius = 0;
    for (int c = 0; c < 3; c++) {
        v.center[c] = 0.5f * (lo[c] + hi[c]);
        v.radius += 0.25f * (hi[c] - lo[c]) * (hi[c] - lo[c]);
    }
    v.radius = fmaxf(sqrtf(v.radius), 1e-3f);
    return v;
}

/* The colour bar: its range and the colour file's stem ("vertex_error" for an eval
 * directory). */
static void add_colorbar(cJSON *meta, const cr_view_def *def, const float range[2]) {
    cJSON *cb = cJSON_AddObjectToObject(meta, "colorbar");
    cJSON_AddNumberToObject(cb, "lo", range[0]);
    cJSON_AddNumberToObject(cb, "hi", range[1]);
    char name[256] = "value";
    for (int i = 0; i < def->ncolors; i++)
        if (strcmp(def->colors[i], "-") != 0) {
            struct stat sb;
            const char *b = stat(def->colors[i], &sb) == 0 && S_ISDIR(sb.st_mode)
                                ? CR_VIEW_COLOR_FILE
                                : base_name(def->colors[i]);
            snprintf(name, sizeof name, "%.*s", (int)strcspn(b, "."), b);
            break;
        }
    cJSON_AddStringToObject(cb, "name", name);
    cJSON_AddStringToObject(cb, "unit", "m");
}

/* A part's entry in the page's JSON; its block into data/ when not embedded. */
static cr_status add_part(cJSON *parts, const cr_view_def *def, int i, int k, const cr_view_part *p,
                          const view_block *b, int embed, cr_error *err) {
    cJSON *jq = cJSON_CreateObject();
    cJSON_AddItemToArray(parts, jq);
    cJSON_AddStringToObject(jq, "role", k == 0 ? "garment" : "body");
    cJSON_AddStringToObject(jq, "source", base_name(p->path));
    cJSON_AddNumberToObject(jq, "vertices", p->mesh->nv);
    cJSON_AddNumberToObject(jq, "faces", p->mesh->nf);
    cJSON_AddNumberToObject(jq, "frames", p->nframes);
    cJSON_AddNumberToObject(jq, "tri_offset", (double)b->tri_off);
    cJSON_AddNumberToObject(jq, "pos_offset", (double)b->pos_off);
    cJSON_AddItemToObject(jq, "lo", json_floats(b->lo, 3));
    cJSON_AddItemToObject(jq, "step", json_floats(b->step, 3));
    if (p->scalar) {
        cJSON *js = cJSON_AddObjectToObject(jq, "scalar");
        cJSON_AddNumberToObject(js, "offset", (double)b->val_off);
        cJSON_AddNumberToObject(js, "frames", p->nscalar);
    }
    if (embed) {
        cJSON_AddNullToObject(jq, "file");
        return CR_OK;
    }
    char name[64], path[1200];
    snprintf(name, sizeof name, "data/p%d_%d.bin", i, k);
    cJSON_AddStringToObject(jq, "file", name);
    snprintf(path, sizeof path, "%s/%s", def->out_dir, name);
    return write_bytes(path, b->data, b->len, err);
}

/* index.html: the page's head, the JSON, the embedded blocks, the viewer, the tail. */
static cr_status write_html(const char *path, const char *json, const view_block *blocks,
                            const cr_view_panel *panels, int npanels, int embed, cr_error *err) {
    const char *mark = strstr(cr_view_page_html_, "<!--crease-data-->");
    CR_ASSERT(mark);
    cr_atomic_file f;
    CR_TRY(cr_atomic_open(&f, path, err));
    fwrite(cr_view_page_html_, 1, (size_t)(mark - cr_view_page_html_), f.fp);
    fputs("<script id=\"crease-meta\" type=\"application/json\">", f.fp);
    put_json(f.fp, json);
    fputs("</script>\n", f.fp);
    for (int i = 0; embed && i < npanels; i++)
        for (int k = 0; k < panels[i].nparts; k++) {
            fprintf(f.fp, "<script id=\"crease-part-%d-%d\" type=\"application/octet-stream\">", i,
                    k);
            const view_block *b = &blocks[i * CR_VIEW_MAX_PARTS + k];
            put_base64(f.fp, b->data, b->len);
            fputs("</script>\n", f.fp);
        }
    fputs("<script>\n", f.fp);
    fwrite(cr_view_viewer_js_, 1, cr_view_viewer_js_len_, f.fp);
    fputs("</script>\n", f.fp);
    fputs(mark + strlen("<!--crease-data-->\n"), f.fp);
    if (ferror(f.fp)) {
        cr_atomic_abort(&f);
        return CR_FAIL(err, CR_ERR_IO, "%s: write failed", path);
    }
    return cr_atomic_commit(&f, err);
}

cr_status cr_view_page_write_(const cr_view_def *def, const cr_view_panel *panels, int npanels,
                              cr_view_report *out, cr_error *err) {
    const char *dir = def->out_dir;
    CR_TRY(cr_mkdir_p(dir, err));
    char path[1200], from[1200];
    snprintf(from, sizeof from, "%s/build/three.min.js", def->three_dir);
    snprintf(path, sizeof path, "%s/three.min.js", dir);
    CR_TRY(copy_file(from, path, err));
    snprintf(from, sizeof from, "%s/examples/js/controls/OrbitControls.js", def->three_dir);
    snprintf(path, sizeof path, "%s/OrbitControls.js", dir);
    CR_TRY(copy_file(from, path, err));
    view_frame v = frame_panels(def, panels, npanels);

    /* Blocks, then the decision to embed them. */
    view_block *blocks = calloc((size_t)npanels * CR_VIEW_MAX_PARTS, sizeof *blocks);
    if (!blocks) return CR_FAIL(err, CR_ERR_MEMORY, "view: out of memory");
    size_t total = 0;
    cr_status st = CR_OK;
    for (int i = 0; st == CR_OK && i < npanels; i++)
        for (int k = 0; st == CR_OK && k < panels[i].nparts; k++) {
            view_block *b = &blocks[i * CR_VIEW_MAX_PARTS + k];
            st = make_block(&panels[i].parts[k], v.range, b, err);
            total += b->len;
        }
    int embed = (double)total <= (double)def->embed_max_mib * 1024.0 * 1024.0;

    cJSON *meta = cJSON_CreateObject(), *jp = cJSON_AddArrayToObject(meta, "panels");
    cJSON_AddNumberToObject(meta, "fps", v.fps);
    cJSON_AddNumberToObject(meta, "frames", v.frames);
    cJSON_AddItemToObject(meta, "center", json_floats(v.center, 3));
    cJSON_AddNumberToObject(meta, "radius", v.radius);
    if (v.any_scalar) add_colorbar(meta, def, v.range);
    if (st == CR_OK && !embed) {
        snprintf(path, sizeof path, "%s/data", dir);
        st = cr_mkdir_p(path, err);
    }
    for (int i = 0; st == CR_OK && i < npanels; i++) {
        cJSON *pan = cJSON_CreateObject(), *parts = cJSON_AddArrayToObject(pan, "parts");
        cJSON_AddItemToArray(jp, pan);
        cJSON_AddStringToObject(pan, "label",
                                panels[i].label           ? panels[i].label
                                : panels[i].auto_label[0] ? panels[i].auto_label
                                                          : base_name(panels[i].parts[0].path));
        for (int k = 0; st == CR_OK && k < panels[i].nparts; k++)
            st = add_part(parts, def, i, k, &panels[i].parts[k], &blocks[i * CR_VIEW_MAX_PARTS + k],
                          embed, err);
    }

    char *json = cJSON_PrintUnformatted(meta);
    cJSON_Delete(meta);
    snprintf(path, sizeof path, "%s/index.html", dir);
    if (st == CR_OK && !json) st = CR_FAIL(err, CR_ERR_MEMORY, "%s: the page's JSON", path);
    if (st == CR_OK) st = write_html(path, json, blocks, panels, npanels, embed, err);
    free(json);
    for (int i = 0; i < npanels * CR_VIEW_MAX_PARTS; i++)
        free(blocks[i].data);
    free(blocks);
    if (st != CR_OK) return st;
    snprintf(out->page, sizeof out->page, "%s", path);
    out->panels = npanels;
    out->frames = v.frames;
    out->fps = v.fps;
    out->data_bytes = (double)total;
    out->embedded = embed;
    return CR_OK;
}
