/* test_nn_checkpoint.c: the safetensors writer checked byte by byte against
 * the spec, exact round trips, the other dtypes, malformed files, loading
 * into a parameter store, and resuming a training run bit-identically. */
#include "crease/nn_checkpoint.h"
#include "test.h"

#include <cjson/cJSON.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static void tmp_path(char *out, size_t cap, const char *name) {
    snprintf(out, cap, "%s/%s", cr_test_tmpdir(), name);
}

static uint64_t u64le(const unsigned char *b) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = (v << 8) | b[i];
    return v;
}

/* Store "w" (2,3) and "b" (3) holding i * 0.37 - 1 and a few specials. */
static cr_nn_params *small_model(void) {
    cr_error err;
    cr_nn_params *p = NULL;
    cr_tensor *w, *b;
    CR_CHECK_OK(cr_nn_params_create(&p, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(p, "w", 2, (int64_t[]){2, 3}, &w, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(p, "b", 1, (int64_t[]){3}, &b, &err), &err);
    for (int i = 0; i < 6; i++)
        w->data[i] = (float)i * 0.37f - 1.0f;
    b->data[0] = -0.0f;
    b->data[1] = 1e-40f; /* subnormal */
    b->data[2] = 3.4e38f;
    return p;
}

CR_TEST(nn_checkpoint, file_layout_follows_spec) {
    char path[512];
    tmp_path(path, sizeof path, "layout.safetensors");
    cr_error err;
    cr_nn_params *p = small_model();
    CR_REQUIRE(p);
    cr_st_meta meta[] = {{"format", "pt"}, {"note", "quote \" and \\ and \n"}};
    CR_CHECK_OK(cr_safetensors_save_params(path, p, meta, 2, &err), &err);
    char *buf = NULL;
    size_t len = 0;
    CR_CHECK_OK(cr_file_read_all(path, &buf, &len, &err), &err);
    CR_REQUIRE(buf && len >= 8);
    const unsigned char *u = (const unsigned char *)buf;
    uint64_t n = u64le(u);
    CR_CHECK((8 + n) % 8 == 0);           /* data 8-byte aligned */
    CR_CHECK(len == 8 + n + (6 + 3) * 4); /* nothing but header and data */
    CR_REQUIRE(n < len);
    CR_CHECK(buf[8] == '{');
    size_t end = 8 + n;
    while (end > 8 && buf[end - 1] == ' ')
        end--; /* padding is spaces only */
    CR_CHECK(buf[end - 1] == '}' && 8 + n - end < 8);
    cJSON *root = cJSON_ParseWithLength(buf + 8, end - 8);
    CR_REQUIRE(root);
    CR_CHECK(cJSON_GetArraySize(root) == 3);
    cJSON *md = cJSON_GetObjectItemCaseSensitive(root, "__metadata__");
    CR_CHECK(md && strcmp(cJSON_GetObjectItemCaseSensitive(md, "note")->valuestring,
                          "quote \" and \\ and \n") == 0);
    const char *names[2] = {"w", "b"};
    const int shapes[2][2] = {{2, 3}, {3, 0}};
    const int ndims[2] = {2, 1};
    double at = 0;
    for (int k = 0; k < 2; k++) {
        cJSON *e = cJSON_GetObjectItemCaseSensitive(root, names[k]);
        CR_REQUIRE(e);
        CR_CHECK(strcmp(cJSON_GetObjectItemCaseSensitive(e, "dtype")->valuestring, "F32") == 0);
        cJSON *shape = cJSON_GetObjectItemCaseSensitive(e, "shape");
        CR_CHECK(cJSON_GetArraySize(shape) == ndims[k]);
        for (int d = 0; d < ndims[k]; d++)
            CR_CHECK(cJSON_GetArrayItem(shape, d)->valuedouble == shapes[k][d]);
        cJSON *off = cJSON_GetObjectItemCaseSensitive(e, "data_offsets");
        CR_CHECK(cJSON_GetArrayItem(off, 0)->valuedouble == at); /* contiguous from 0 */
        at += (k == 0 ? 6 : 3) * 4;
        CR_CHECK(cJSON_GetArrayItem(off, 1)->valuedouble == at);
    }
    cJSON_Delete(root);
    /* the data: parameters in order, each float little-endian */
    const unsigned char *data = u + 8 + n;
    for (int k = 0, j = 0; k < 2; k++) {
        cr_tensor *t = cr_nn_params_find(p, names[k]);
        for (int64_t i = 0; i < t->numel; i++, j++) {
            uint32_t bits;
            memcpy(&bits, &t->data[i], 4);
            for (int q = 0; q < 4; q++)
                CR_CHECK(data[4 * j + q] == ((bits >> (8 * q)) & 0xff));
        }
    }
    free(buf);
    cr_nn_params_destroy(p);
}

CR_TEST(nn_checkpoint, round_trip_is_exact) {
    char path[512];
    tmp_path(path, sizeof path, "roundtrip.safetensors");
    cr_error err;
    cr_nn_params *p = small_model();
    CR_REQUIRE(p);
    cr_tensor *b = cr_nn_params_find(p, "b");
    b->data[0] = NAN;
    cr_st_meta meta[] = {{"k\xc3\xa9y", "v\xe2\x82\xac"}};
    CR_CHECK_OK(cr_safetensors_save_params(path, p, meta, 1, &err), &err);
    cr_safetensors st;
    CR_CHECK_OK(cr_safetensors_read(path, &st, &err), &err);
    CR_REQUIRE(st.ntensors == 2);
    CR_CHECK(strcmp(st.tensors[0].name, "w") == 0); /* data-offset order */
    CR_CHECK(st.tensors[0].ndim == 2 && st.tensors[0].shape[1] == 3 && st.tensors[0].numel == 6);
    const cr_st_tensor *tb = cr_safetensors_find(&st, "b");
    CR_REQUIRE(tb && tb->dtype == CR_ST_F32);
    CR_CHECK(memcmp(tb->data, b->data, 3 * sizeof(float)) == 0); /* NaN bits, -0, subnormal */
    CR_CHECK(cr_safetensors_meta(&st, "k\xc3\xa9y") &&
             strcmp(cr_safetensors_meta(&st, "k\xc3\xa9y"), "v\xe2\x82\xac") == 0);
    cr_safetensors_free(&st);

    cr_nn_params *q = NULL;
    cr_tensor *w2, *b2;
    CR_CHECK_OK(cr_nn_params_create(&q, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(q, "b", 1, (int64_t[]){3}, &b2, &err), &err); /* other order */
    CR_CHECK_OK(cr_nn_params_add(q, "w", 2, (int64_t[]){2, 3}, &w2, &err), &err);
    /* the file keeps the NaN; a parameter store refuses it */
    CR_CHECK(cr_safetensors_load_params(path, q, 0, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, path) && strstr(err.msg, "'b'") && strstr(err.msg, "element 0"));
    CR_CHECK(w2->data[0] == 0.0f); /* nothing written */
    b->data[0] = -0.0f;
    CR_CHECK_OK(cr_safetensors_save_params(path, p, meta, 1, &err), &err);
    CR_CHECK_OK(cr_safetensors_load_params(path, q, 0, &err), &err);
    CR_CHECK(memcmp(w2->data, cr_nn_params_find(p, "w")->data, 6 * sizeof(float)) == 0);
    CR_CHECK(memcmp(b2->data, b->data, 3 * sizeof(float)) == 0);
    cr_nn_params_destroy(q);

    /* empty file: no tensors, header "{}" padded */
    CR_CHECK_OK(cr_safetensors_write(path, NULL, 0, NULL, 0, &err), &err);
    CR_CHECK_OK(cr_safetensors_read(path, &st, &err), &err);
    CR_CHECK(st.ntensors == 0 && st.nmeta == 0);
    cr_safetensors_free(&st);
    cr_nn_params_destroy(p);
}

/* A file assembled by hand from a header and a data buffer; `hlen` overrides
 * the header length field when not zero. */
static size_t assemble(unsigned char *out, const char *header, uint64_t hlen, const void *data,
                       size_t dlen) {
    size_t n = strlen(header);
    uint64_t field = hlen ? hlen : n;
    for (int i = 0; i < 8; i++)
        out[i] = (unsigned char)(field >> (8 * i));
    memcpy(out + 8, header, n);
    if (dlen) memcpy(out + 8 + n, data, dlen);
    return 8 + n + dlen;
}

CR_TEST(nn_checkpoint, other_dtypes) {
    /* F16 1, -0.5, 65504, 2^-24; BF16 1, -2; F64 2.5; I64 7 */
    const unsigned char data[] = {0x00, 0x3c, 0x00, 0xb8, 0xff, 0x7b, 0x01, 0x00, /* F16 */
                                  0x80, 0x3f, 0x00, 0xc0,                         /* BF16 */
                                  0,    0,    0,    0,    0,    0,    0x04, 0x40, /* F64 */
                                  7,    0,    0,    0,    0,    0,    0,    0};   /* I64 */
    const char *hdr = "{\"h\":{\"dtype\":\"F16\",\"shape\":[4],\"data_offsets\":[0,8]},"
                      "\"bf\":{\"dtype\":\"BF16\",\"shape\":[1,2],\"data_offsets\":[8,12]},"
                      "\"d\":{\"dtype\":\"F64\",\"shape\":[],\"data_offsets\":[12,20]},"
                      "\"n\":{\"dtype\":\"I64\",\"shape\":[1],\"data_offsets\":[20,28]},"
                      "\"z\":{\"dtype\":\"F32\",\"shape\":[0,5],\"data_offsets\":[28,28]}}  ";
    unsigned char file[512];
    size_t len = assemble(file, hdr, 0, data, sizeof data);
    cr_error err;
    cr_safetensors st;
    CR_CHECK_OK(cr_safetensors_read_mem(file, len, "mem.safetensors", &st, &err), &err);
    CR_REQUIRE(st.ntensors == 5);
    const cr_st_tensor *h = cr_safetensors_find(&st, "h"), *bf = cr_safetensors_find(&st, "bf");
    const cr_st_tensor *d = cr_safetensors_find(&st, "d"), *n = cr_safetensors_find(&st, "n");
    const cr_st_tensor *z = cr_safetensors_find(&st, "z");
    CR_REQUIRE(h && bf && d && n && z);
    CR_CHECK(h->data[0] == 1.0f && h->data[1] == -0.5f && h->data[2] == 65504.0f);
    CR_CHECK(h->data[3] == ldexpf(1.0f, -24));
    CR_CHECK(bf->data[0] == 1.0f && bf->data[1] == -2.0f && bf->ndim == 2);
    CR_CHECK(d->ndim == 0 && d->numel == 1 && d->data[0] == 2.5f);
    CR_CHECK(n->dtype == CR_ST_I64 && n->data == NULL);
    CR_CHECK(z->numel == 0 && z->ndim == 2);
    /* an I64 tensor cannot fill a parameter */
    cr_nn_params *p = NULL;
    cr_tensor *t;
    CR_CHECK_OK(cr_nn_params_create(&p, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(p, "n", 1, (int64_t[]){1}, &t, &err), &err);
    CR_CHECK(cr_safetensors_to_params(&st, "mem.safetensors", p, 1, &err) == CR_ERR_UNSUPPORTED);
    CR_CHECK(strstr(err.msg, "'n'") && strstr(err.msg, "I64"));
    cr_nn_params_destroy(p);
    cr_safetensors_free(&st);
}

CR_TEST(nn_checkpoint, malformed_files_fail_clearly) {
    static const struct {
        const char *what, *header;
        uint64_t hlen; /* 0: the header's length */
        size_t dlen;   /* data bytes after the header */
        cr_status st;
        const char *needle; /* expected in the message */
    } cases[] = {
        {"bad json", "{\"w\":{\"dtype\":\"F32\",", 0, 0, CR_ERR_PARSE, "JSON"},
        {"length past end", "{}", 4096, 0, CR_ERR_PARSE, "exceeds"},
        {"2^60 length", "{}", (uint64_t)1 << 60, 0, CR_ERR_PARSE, "1152921504606846976"},
        {"overlap",
         "{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8]},"
         "\"b\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[4,12]}}",
         0, 12, CR_ERR_PARSE, "overlap"},
        {"hole", "{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[4,8]}}", 0, 8,
         CR_ERR_PARSE, "hole"},
        {"uncovered tail", "{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]}}", 0, 8,
         CR_ERR_PARSE, "cover"},
        {"shape vs offsets", "{\"a\":{\"dtype\":\"F32\",\"shape\":[3],\"data_offsets\":[0,8]}}", 0,
         8, CR_ERR_PARSE, "'a'"},
        {"shape too small", "{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,8]}}", 0,
         8, CR_ERR_PARSE, "span 8 bytes"},
        {"unknown dtype", "{\"a\":{\"dtype\":\"F31\",\"shape\":[1],\"data_offsets\":[0,4]}}", 0, 4,
         CR_ERR_UNSUPPORTED, "F31"},
        {"offset past data", "{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]}}", 0,
         2, CR_ERR_PARSE, "outside"},
        {"duplicate",
         "{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]},"
         "\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[4,8]}}",
         0, 8, CR_ERR_PARSE, "twice"},
        {"negative dim", "{\"a\":{\"dtype\":\"F32\",\"shape\":[-1],\"data_offsets\":[0,4]}}", 0, 4,
         CR_ERR_PARSE, "shape"},
        {"huge shape",
         "{\"a\":{\"dtype\":\"F32\",\"shape\":[4294967296,4294967296],\"data_offsets\":[0,4]}}", 0,
         4, CR_ERR_PARSE, "exceeds"},
        {"metadata not string", "{\"__metadata__\":{\"k\":1}}", 0, 0, CR_ERR_PARSE, "'k'"},
        {"not utf-8", "{\"\xff\":{}}", 0, 0, CR_ERR_PARSE, "UTF-8"},
        {"trailing bytes", "{} x", 0, 0, CR_ERR_PARSE, "after"},
        {"not an object", "[1, 2]", 0, 0, CR_ERR_PARSE, "'{'"},
    };
    cr_error err;
    char path[512];
    tmp_path(path, sizeof path, "bad.safetensors");
    unsigned char file[1024], zeros[16] = {0};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        size_t len = assemble(file, cases[c].header, cases[c].hlen, zeros, cases[c].dlen);
        FILE *fp = fopen(path, "wb");
        CR_REQUIRE(fp);
        fwrite(file, 1, len, fp);
        fclose(fp);
        cr_safetensors st;
        cr_status s = cr_safetensors_read(path, &st, &err);
        if (s != cases[c].st || !strstr(err.msg, cases[c].needle) || !strstr(err.msg, path))
            cr_test_fail_here(__FILE__, __LINE__, "%s: got %s \"%s\"", cases[c].what,
                              cr_status_str(s), s == CR_OK ? "" : err.msg);
        CR_CHECK(st.ntensors == 0 && st.tensors == NULL);
    }
    /* truncation of a good file at every length fails, naming the source */
    cr_nn_params *p = small_model();
    CR_REQUIRE(p);
    CR_CHECK_OK(cr_safetensors_save_params(path, p, NULL, 0, &err), &err);
    char *buf;
    size_t len;
    CR_CHECK_OK(cr_file_read_all(path, &buf, &len, &err), &err);
    for (size_t cut = 0; cut < len; cut++) {
        cr_safetensors st;
        cr_status s = cr_safetensors_read_mem(buf, cut, "cut.safetensors", &st, &err);
        if (s == CR_OK || !strstr(err.msg, "cut.safetensors"))
            cr_test_fail_here(__FILE__, __LINE__, "cut at %zu: %s", cut, err.msg);
    }
    free(buf);
    cr_nn_params_destroy(p);
    tmp_path(path, sizeof path, "does-not-exist.safetensors");
    cr_safetensors st;
    CR_CHECK(cr_safetensors_read(path, &st, &err) == CR_ERR_IO && strstr(err.msg, path));
}

CR_TEST(nn_checkpoint, load_params_checks_names_and_shapes) {
    char path[512];
    tmp_path(path, sizeof path, "shapes.safetensors");
    cr_error err;
    cr_nn_params *p = small_model();
    CR_REQUIRE(p);
    CR_CHECK_OK(cr_safetensors_save_params(path, p, NULL, 0, &err), &err);
    cr_nn_params *q = NULL;
    cr_tensor *w, *b;
    CR_CHECK_OK(cr_nn_params_create(&q, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(q, "b", 1, (int64_t[]){3}, &b, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(q, "w", 2, (int64_t[]){3, 2}, &w, &err), &err);
    CR_CHECK(cr_safetensors_load_params(path, q, 0, &err) == CR_ERR_SHAPE);
    CR_CHECK(strstr(err.msg, "'w'") && strstr(err.msg, "(2,3)") && strstr(err.msg, "(3,2)"));
    CR_CHECK(b->data[1] == 0.0f); /* nothing written on failure */
    cr_nn_params_destroy(q);

    CR_CHECK_OK(cr_nn_params_create(&q, &err), &err); /* "w" only: "b" is extra */
    CR_CHECK_OK(cr_nn_params_add(q, "w", 2, (int64_t[]){2, 3}, &w, &err), &err);
    CR_CHECK(cr_safetensors_load_params(path, q, 0, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "'b'") != NULL && w->data[1] == 0.0f);
    CR_CHECK_OK(cr_safetensors_load_params(path, q, 1, &err), &err);
    CR_CHECK(w->data[1] == cr_nn_params_find(p, "w")->data[1]);
    cr_tensor *c;
    CR_CHECK_OK(cr_nn_params_add(q, "c", 1, (int64_t[]){1}, &c, &err), &err);
    CR_CHECK(cr_safetensors_load_params(path, q, 1, &err) == CR_ERR_PARSE);
    CR_CHECK(strstr(err.msg, "'c'") && strstr(err.msg, path));
    cr_nn_params_destroy(q);
    cr_nn_params_destroy(p);
}

/* ------------------------------------------------------------- resume -- */

/* A 1-16-1 tanh net fitting sin on [-pi, pi], trained on mini-batches drawn
 * by shuffling with the run's RNG, with clipping and a warm-up + cosine
 * schedule: every piece of state a resume must restore. */
enum { NS = 64, NB = 16, HID = 16 };

typedef struct run {
    cr_nn_params *p;
    cr_tensor *w1, *b1, *w2, *b2;
    cr_optim *opt;
    cr_rng rng;
    float loss;
} run;

static void run_make(run *r, cr_optim_kind kind, int init) {
    cr_error err;
    memset(r, 0, sizeof *r);
    CR_CHECK_OK(cr_nn_params_create(&r->p, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(r->p, "fc1.weight", 2, (int64_t[]){HID, 1}, &r->w1, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(r->p, "fc1.bias", 1, (int64_t[]){HID}, &r->b1, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(r->p, "fc2.weight", 2, (int64_t[]){1, HID}, &r->w2, &err), &err);
    CR_CHECK_OK(cr_nn_params_add(r->p, "fc2.bias", 1, (int64_t[]){1}, &r->b2, &err), &err);
    if (init) {
        cr_rng init_rng = cr_rng_make(7, 0);
        cr_nn_fill_uniform(r->w1, &init_rng, -1.0f, 1.0f);
        cr_nn_fill_uniform(r->b1, &init_rng, -1.0f, 1.0f);
        cr_nn_fill_uniform(r->w2, &init_rng, -0.5f, 0.5f);
    }
    cr_optim_def d = cr_optim_default_def(kind);
    d.lr.base = kind == CR_OPTIM_SGD ? 0.05f : 0.01f;
    d.lr.kind = CR_LR_COSINE;
    d.lr.warmup_steps = 3;
    d.lr.total_steps = 17;
    d.lr.final = 1e-4f;
    d.momentum = kind == CR_OPTIM_SGD ? 0.9f : 0.0f;
    d.nesterov = kind == CR_OPTIM_SGD;
    CR_CHECK_OK(cr_optim_create(&d, r->p, &r->opt, &err), &err);
    r->rng = cr_rng_make(init ? 1234 : 99, 1);
}

static void run_free(run *r) {
    cr_optim_destroy(r->opt);
    cr_nn_params_destroy(r->p);
}

static void train(run *r, cr_nn_ctx *ctx, int steps) {
    cr_error err;
    float xs[NS], ys[NS], bx[NB], by[NB];
    for (int i = 0; i < NS; i++) {
        xs[i] = -3.14159265f + 6.2831853f * (float)i / (NS - 1);
        ys[i] = sinf(xs[i]);
    }
    for (int s = 0; s < steps; s++) {
        int32_t idx[NS];
        for (int i = 0; i < NS; i++)
            idx[i] = i;
        cr_rng_shuffle_i32(&r->rng, idx, NS);
        for (int i = 0; i < NB; i++)
            bx[i] = xs[idx[i]], by[i] = ys[idx[i]];
        cr_nn_ctx_reset(ctx);
        cr_tensor *x = cr_nn_from(ctx, 2, (int64_t[]){NB, 1}, bx);
        cr_tensor *y = cr_nn_from(ctx, 2, (int64_t[]){NB, 1}, by);
        cr_tensor *h = cr_nn_tanh(ctx, cr_nn_linear(ctx, x, r->w1, r->b1));
        cr_tensor *out = cr_nn_linear(ctx, h, r->w2, r->b2);
        cr_tensor *loss = cr_nn_mean(ctx, cr_nn_square(ctx, cr_nn_sub(ctx, out, y)));
        cr_nn_params_zero_grad(r->p);
        CR_CHECK_OK(cr_nn_backward(ctx, loss, &err), &err);
        if (!loss) return;
        r->loss = loss->data[0];
        CR_CHECK_OK(cr_clip_grad_norm(r->p, 0.5f, NULL, &err), &err);
        CR_CHECK_OK(cr_optim_step(r->opt, &err), &err);
    }
}

/* Field by field: the struct has padding. */
static int same_rng(const cr_rng *a, const cr_rng *b) {
    return a->seed == b->seed && a->stream == b->stream && a->counter == b->counter &&
           a->used == b->used && memcmp(a->block, b->block, sizeof a->block) == 0;
}

static int same_params(run *a, run *b) {
    int64_t n, m;
    float *x = cr_nn_params_data(a->p, &n), *y = cr_nn_params_data(b->p, &m);
    return n == m && memcmp(x, y, (size_t)n * sizeof(float)) == 0;
}

static void check_resume(cr_optim_kind kind) {
    cr_error err;
    char path[512];
    tmp_path(path, sizeof path, "resume.safetensors");
    cr_nn_ctx_def cd = cr_nn_ctx_default_def();
    cd.arena_bytes = (size_t)4 << 20;
    cr_nn_ctx *ctx = NULL;
    CR_CHECK_OK(cr_nn_ctx_create(&cd, &ctx, &err), &err);
    CR_REQUIRE(ctx);

    run straight, first, resumed;
    run_make(&straight, kind, 1);
    train(&straight, ctx, 20);

    run_make(&first, kind, 1);
    train(&first, ctx, 10);
    cr_checkpoint_meta meta = {.epoch = 2,
                               .step = 10,
                               .seed = 1234,
                               .rng = first.rng,
                               .loss = first.loss,
                               .config_json = "{\"lr\": 0.01, \"name\": \"sin\"}"};
    CR_CHECK(first.rng.used != 4); /* the save lands mid-block */
    CR_CHECK_OK(cr_checkpoint_save(path, first.p, first.opt, &meta, &err), &err);

    run_make(&resumed, kind, 0); /* zero weights, another seed: all must come from the file */
    cr_checkpoint_meta back;
    memset(&back, 0, sizeof back);
    CR_CHECK_OK(cr_checkpoint_load(path, resumed.p, resumed.opt, &back, &err), &err);
    CR_CHECK(back.epoch == 2 && back.step == 10 && back.seed == 1234);
    CR_CHECK(memcmp(&back.loss, &first.loss, sizeof(float)) == 0);
    CR_CHECK(same_rng(&back.rng, &first.rng));
    CR_CHECK(back.config_json && strcmp(back.config_json, meta.config_json) == 0);
    CR_CHECK(cr_optim_step_count(resumed.opt) == 10);
    CR_CHECK(same_params(&resumed, &first));
    resumed.rng = back.rng;
    free(back.config_json);
    train(&resumed, ctx, 10);
    CR_CHECK(cr_optim_step_count(resumed.opt) == 20);
    CR_CHECK(same_params(&resumed, &straight));
    int64_t n;
    cr_nn_params_data(straight.p, &n);
    for (int k = 0; k < cr_optim_state_count(straight.opt); k++)
        CR_CHECK(memcmp(cr_optim_state(straight.opt, k, NULL), cr_optim_state(resumed.opt, k, NULL),
                        (size_t)n * sizeof(float)) == 0);

    /* the test can tell: a fresh RNG, or fresh optimiser state, diverges */
    run norng, noopt;
    run_make(&norng, kind, 0);
    CR_CHECK_OK(cr_checkpoint_load(path, norng.p, norng.opt, NULL, &err), &err);
    train(&norng, ctx, 10);
    CR_CHECK(!same_params(&norng, &straight));
    run_make(&noopt, kind, 0);
    CR_CHECK_OK(cr_checkpoint_load(path, noopt.p, NULL, NULL, &err), &err);
    noopt.rng = first.rng;
    train(&noopt, ctx, 10);
    CR_CHECK(!same_params(&noopt, &straight));

    run_free(&noopt);
    run_free(&norng);
    run_free(&resumed);
    run_free(&first);
    run_free(&straight);
    cr_nn_ctx_destroy(ctx);
}

CR_TEST(nn_checkpoint, resume_is_bit_identical_adamw) {
    check_resume(CR_OPTIM_ADAMW);
}

CR_TEST(nn_checkpoint, resume_is_bit_identical_sgd_nesterov) {
    check_resume(CR_OPTIM_SGD);
}

/* The run's model with fc1 one row wider: another layer width. */
static cr_status wider_params(cr_nn_params **q, cr_error *err) {
    cr_tensor *t;
    CR_TRY(cr_nn_params_create(q, err));
    CR_TRY(cr_nn_params_add(*q, "fc1.weight", 2, (int64_t[]){HID + 1, 1}, &t, err));
    CR_TRY(cr_nn_params_add(*q, "fc1.bias", 1, (int64_t[]){HID}, &t, err));
    CR_TRY(cr_nn_params_add(*q, "fc2.weight", 2, (int64_t[]){1, HID}, &t, err));
    return cr_nn_params_add(*q, "fc2.bias", 1, (int64_t[]){1}, &t, err);
}

CR_TEST(nn_checkpoint, checkpoint_mismatches_change_nothing) {
    cr_error err;
    char path[512];
    tmp_path(path, sizeof path, "mismatch.safetensors");
    run a, b;
    run_make(&a, CR_OPTIM_ADAMW, 1);
    cr_checkpoint_meta meta = {.epoch = -1,
                               .step = INT64_MAX,
                               .seed = UINT64_MAX,
                               .rng = cr_rng_make(UINT64_MAX, 3),
                               .loss = 0.1f};
    CR_CHECK_OK(cr_checkpoint_save(path, a.p, a.opt, &meta, &err), &err);
    /* extremes survive the decimal strings; a fresh generator (counter 0) too */
    run_make(&b, CR_OPTIM_ADAMW, 0);
    cr_checkpoint_meta back;
    CR_CHECK_OK(cr_checkpoint_load(path, b.p, b.opt, &back, &err), &err);
    CR_CHECK(back.epoch == -1 && back.step == INT64_MAX && back.seed == UINT64_MAX);
    CR_CHECK(back.loss == 0.1f && back.config_json == NULL);
    CR_CHECK(same_rng(&back.rng, &meta.rng));
    run_free(&b);

    /* an SGD optimiser cannot take AdamW state; nothing is written */
    run_make(&b, CR_OPTIM_SGD, 0);
    CR_CHECK(cr_checkpoint_load(path, b.p, b.opt, NULL, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "adamw") && strstr(err.msg, "sgd"));
    CR_CHECK(b.w1->data[0] == 0.0f);
    run_free(&b);

    /* weights-only file into an optimiser: refused */
    CR_CHECK_OK(cr_checkpoint_save(path, a.p, NULL, NULL, &err), &err);
    run_make(&b, CR_OPTIM_ADAMW, 0);
    CR_CHECK(cr_checkpoint_load(path, b.p, b.opt, NULL, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "no optimiser state") != NULL && b.w1->data[0] == 0.0f);
    CR_CHECK_OK(cr_checkpoint_load(path, b.p, NULL, NULL, &err), &err);
    CR_CHECK(same_params(&a, &b));
    run_free(&b);

    /* a model with another layer width */
    cr_nn_params *q = NULL;
    CR_CHECK_OK(wider_params(&q, &err), &err);
    CR_CHECK(cr_checkpoint_load(path, q, NULL, NULL, &err) == CR_ERR_SHAPE);
    CR_CHECK(strstr(err.msg, "fc1.weight") && strstr(err.msg, "(16,1)") &&
             strstr(err.msg, "(17,1)"));
    cr_nn_params_destroy(q);
    run_free(&a);
}

/* A resume into another width names both shapes, optimiser tensors included;
 * a non-finite weight or moment is refused by tensor and element, and nothing
 * is written. */
CR_TEST(nn_checkpoint, resume_refuses_other_shapes_and_non_finite_values) {
    cr_error err;
    char path[512];
    tmp_path(path, sizeof path, "nonfinite.safetensors");
    run a, b;
    run_make(&a, CR_OPTIM_ADAMW, 1);
    CR_CHECK_OK(cr_checkpoint_save(path, a.p, a.opt, NULL, &err), &err);
    cr_nn_params *q = NULL;
    cr_optim *qo = NULL;
    CR_CHECK_OK(wider_params(&q, &err), &err);
    cr_optim_def od = cr_optim_default_def(CR_OPTIM_ADAMW);
    CR_CHECK_OK(cr_optim_create(&od, q, &qo, &err), &err);
    CR_CHECK(cr_checkpoint_load(path, q, qo, NULL, &err) == CR_ERR_SHAPE);
    CR_CHECK(strstr(err.msg, "fc1.weight") && strstr(err.msg, "(16,1)") &&
             strstr(err.msg, "(17,1)"));
    cr_optim_destroy(qo);
    cr_nn_params_destroy(q);

    a.b1->data[5] = INFINITY;
    CR_CHECK_OK(cr_checkpoint_save(path, a.p, a.opt, NULL, &err), &err);
    run_make(&b, CR_OPTIM_ADAMW, 0);
    CR_CHECK(cr_checkpoint_load(path, b.p, b.opt, NULL, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, path) && strstr(err.msg, "'fc1.bias' element 5"));
    CR_CHECK(b.w1->data[0] == 0.0f);
    a.b1->data[5] = 0.5f;
    const char *buffer;
    float *v = cr_optim_state(a.opt, 1, &buffer); /* mirrors the parameter block */
    v[a.b1->data - cr_nn_params_data(a.p, NULL) + 2] = NAN;
    CR_CHECK_OK(cr_checkpoint_save(path, a.p, a.opt, NULL, &err), &err);
    CR_CHECK(cr_checkpoint_load(path, b.p, b.opt, NULL, &err) == CR_ERR_NAN);
    CR_CHECK(strstr(err.msg, "fc1.bias' element 2") && strstr(err.msg, buffer));
    CR_CHECK(b.w1->data[0] == 0.0f);
    CR_CHECK_OK(cr_checkpoint_load(path, b.p, NULL, NULL, &err), &err); /* weights alone load */
    run_free(&b);
    run_free(&a);
}
