/* runtime_heap.c: the heap calls a runtime's step makes (issue 51: "no heap
 * allocation after create"), counted by wrapping malloc, calloc, realloc and
 * aligned_alloc at link time (CMakeLists.txt: -Wl,--wrap=...): calls from
 * the library's code are counted, the C library's and OpenMP's own are not.
 * An epnet runtime (2,000 garment vertices, untrained), a swingar tiny
 * runtime (a 2,000-vertex dress) and a gdsr runtime (an untrained default
 * model, a t-shirt pair of about 500 -> 2,000 vertices, the low one held at
 * rest while the walking body moves through it, so the handling pushes) each
 * step 10 frames of the walk to size themselves, then 20 counted ones; 0
 * calls is the pass. Exit 1 otherwise. */
#include "crease/body.h"
#include "crease/epnet.h"
#include "crease/garment.h"
#include "crease/gdsr.h"
#include "crease/motion.h"
#include "crease/swingar.h"

#include <stdio.h>
#include <stdlib.h>

enum { WARM = 10, COUNTED = 20 };

static long calls;
static int counting;

void *__real_malloc(size_t n);
void *__real_calloc(size_t n, size_t size);
void *__real_realloc(void *p, size_t n);
void *__real_aligned_alloc(size_t align, size_t n);

static void count(void) {
    if (counting) __atomic_add_fetch(&calls, 1, __ATOMIC_RELAXED);
}
void *__wrap_malloc(size_t n) {
    count();
    return __real_malloc(n);
}
void *__wrap_calloc(size_t n, size_t size) {
    count();
    return __real_calloc(n, size);
}
void *__wrap_realloc(void *p, size_t n) {
    count();
    return __real_realloc(p, n);
}
void *__wrap_aligned_alloc(size_t align, size_t n) {
    count();
    return __real_aligned_alloc(align, n);
}

static int fail(const char *what, const cr_error *err) {
    fprintf(stderr, "runtime_heap: %s: %s\n", what, err->msg);
    return 1;
}

/* Counted calls of WARM + COUNTED steps of step(ctx, t). */
static long steps(cr_status (*step)(void *ctx, int t, cr_error *err), void *ctx, cr_error *err) {
    calls = 0;
    for (int t = 0; t < WARM + COUNTED; t++) {
        counting = t >= WARM;
        if (step(ctx, t, err) != CR_OK) {
            counting = 0;
            return -1;
        }
    }
    counting = 0;
    return calls;
}

typedef struct epnet_ctx {
    cr_epnet_runtime *rt;
    const cr_motion *mo;
    float *x;
} epnet_ctx;

static cr_status epnet_step(void *vctx, int t, cr_error *err) {
    epnet_ctx *c = vctx;
    return cr_epnet_runtime_step(c->rt, c->mo->poses + (size_t)t * CR_NJOINTS * 3,
                                 c->mo->trans + 3 * t, c->x, err);
}

typedef struct swingar_ctx {
    cr_swingar_runtime *rt;
    const cr_motion *mo;
    float *x;
} swingar_ctx;

static cr_status swingar_step(void *vctx, int t, cr_error *err) {
    swingar_ctx *c = vctx;
    return cr_swingar_runtime_step(c->rt, c->mo->poses + (size_t)t * CR_NJOINTS * 3,
                                   c->mo->trans + 3 * t, c->x, err);
}

typedef struct gdsr_ctx {
    cr_gdsr_runtime *rt;
    const float *low, *posed; /* (Vl,3) every frame; (T,Vb,3) */
    int32_t Vb;
    float *x;
} gdsr_ctx;

static cr_status gdsr_step(void *vctx, int t, cr_error *err) {
    gdsr_ctx *c = vctx;
    return cr_gdsr_runtime_step(c->rt, c->low, c->posed + (size_t)t * c->Vb * 3, c->x, err);
}

int main(void) {
    cr_error err = {0};
    cr_motion *mo = NULL;
    cr_motion_resolve_def rd = cr_motion_resolve_default_def();
    rd.clip_frames = WARM + COUNTED;
    if (cr_motion_resolve("walk", &rd, &mo, NULL, &err) != CR_OK) return fail("walk", &err);
    int rc = 0;
    /* epnet */
    cr_epnet_def ed = cr_epnet_default_def();
    ed.garment_vertices = 2000;
    cr_epnet *em = NULL;
    epnet_ctx ec = {.mo = mo};
    if (cr_epnet_create(&ed, &em, &err) != CR_OK) return fail("epnet", &err);
    if (cr_epnet_runtime_create(em, NULL, NULL, &ec.rt, &err) != CR_OK) return fail("epnet", &err);
    ec.x = malloc(sizeof(float) * 3 * (size_t)cr_epnet_runtime_vertices(ec.rt));
    long n = ec.x ? steps(epnet_step, &ec, &err) : -1;
    if (n < 0) return fail("epnet step", &err);
    printf("runtime_heap: epnet (%d vertices): %ld heap calls in %d steps\n",
           cr_epnet_runtime_vertices(ec.rt), n, COUNTED);
    rc |= n != 0;
    free(ec.x);
    cr_epnet_runtime_destroy(ec.rt);
    cr_epnet_destroy(em);
    /* swingar tiny on a dress */
    cr_body_model *body = NULL;
    cr_mannequin_def md = cr_mannequin_default_def();
    md.resolution = 64;
    if (cr_mannequin_create(&md, &body, &err) != CR_OK) return fail("mannequin", &err);
    cr_garment_def gd = cr_garment_default_def(CR_GARMENT_DRESS);
    gd.target_vertices = 2000;
    cr_garment *g = NULL;
    if (cr_garment_create(&gd, body, &g, &err) != CR_OK) return fail("dress", &err);
    cr_swingar_def sd = cr_swingar_default_def();
    if (cr_swingar_size_def("tiny", &sd, &err) != CR_OK) return fail("swingar", &err);
    float desc[256] = {0}; /* the descriptor's values do not change the step's calls */
    cr_swingar *sm = NULL;
    cr_swingar_garment *sg = NULL;
    swingar_ctx sc = {.mo = mo};
    if (cr_swingar_create(&sd, 1, &sm, &err) != CR_OK ||
        cr_swingar_garment_create(g->mesh, g->skin_joint, g->skin_weight, body, desc,
                                  sd.descriptor_len, &sg, &err) != CR_OK ||
        cr_swingar_runtime_create(sm, sg, body->joints, 0, &sc.rt, &err) != CR_OK)
        return fail("swingar", &err);
    sc.x = malloc(sizeof(float) * 3 * (size_t)g->mesh->nv);
    n = sc.x ? steps(swingar_step, &sc, &err) : -1;
    if (n < 0) return fail("swingar step", &err);
    printf("runtime_heap: swingar tiny (%d vertices): %ld heap calls in %d steps\n", g->mesh->nv, n,
           COUNTED);
    rc |= n != 0;
    free(sc.x);
    /* gdsr on a t-shirt pair */
    cr_garment_def td = cr_garment_default_def(CR_GARMENT_TSHIRT);
    td.target_vertices = 500;
    cr_garment_template *tp = NULL;
    cr_garment *low = NULL, *high = NULL;
    cr_gdsr_data gdata = {0};
    cr_gdsr_model_def gmd = cr_gdsr_model_default_def();
    cr_gdsr_model *gm = NULL;
    gdsr_ctx gc = {.Vb = body->rest->nv};
    float *posed = NULL;
    if (cr_garment_template_create(&td, body, &tp, &err) != CR_OK ||
        cr_garment_template_instantiate(tp, 500, body, &low, &err) != CR_OK ||
        cr_garment_template_instantiate(tp, 2000, body, &high, &err) != CR_OK ||
        cr_gdsr_data_from_arrays(low->mesh, high->mesh, body->rest, 1, low->mesh->pos,
                                 high->mesh->pos, body->rest->pos, &gdata, &err) != CR_OK ||
        cr_gdsr_model_create(&gmd, &gm, &err) != CR_OK ||
        cr_gdsr_runtime_create(gm, &gdata, NULL, &gc.rt, &err) != CR_OK ||
        cr_body_pose_motion(body, mo, &posed, &err) != CR_OK)
        return fail("gdsr", &err);
    gc.low = low->mesh->pos, gc.posed = posed;
    gc.x = malloc(sizeof(float) * 3 * (size_t)high->mesh->nv);
    n = gc.x ? steps(gdsr_step, &gc, &err) : -1;
    if (n < 0) return fail("gdsr step", &err);
    printf("runtime_heap: gdsr (%d -> %d vertices): %ld heap calls in %d steps\n", low->mesh->nv,
           high->mesh->nv, n, COUNTED);
    rc |= n != 0;
    free(gc.x), free(posed);
    cr_gdsr_runtime_destroy(gc.rt);
    cr_gdsr_model_destroy(gm);
    cr_gdsr_data_free(&gdata);
    cr_garment_destroy(low), cr_garment_destroy(high);
    cr_garment_template_destroy(tp);
    cr_swingar_runtime_destroy(sc.rt);
    cr_swingar_garment_destroy(sg);
    cr_swingar_destroy(sm);
    cr_garment_destroy(g);
    cr_body_model_destroy(body);
    cr_motion_destroy(mo);
    return rc;
}
