/* mannequin.c: the procedural body: an implicit union of a lofted torso,
 * capsules, ellipsoids and rounded boxes placed on SMPL's skeleton,
 * polygonised by marching cubes and relaxed onto its own surface.
 *
 * Layout (at the reference height of 1.75 m; everything scales with
 * def.height_m): soles on y = 0, top of the head at the height, facing +Z,
 * left on +X. Joints follow the proportions of SMPL's neutral template
 * (hips at about 49% of the height, knees 28%, shoulders 80%, head joint
 * 88%), arms rotated about the shoulder joints by def.arm_angle_deg below
 * horizontal. The torso is a stack of elliptic sections (waist, hip and
 * chest girths of an average adult) splined in height; limbs are tapered
 * capsules, the calves and buttocks ellipsoids, the hands flat rounded boxes
 * with the palms towards the thighs, the feet two rounded boxes and an
 * instep capsule. Each primitive is merged into those before it with a
 * polynomial smooth minimum of its own radius (Quilez, "smooth minimum"), so
 * armpits, crotch and neck get fillets while the arms stay clear of the
 * torso; a smooth maximum with the ground plane cuts the soles flat at y = 0.
 *
 * Shape parameters: girth scales every radius and section (heads, hands and
 * feet by 30% of it) and pushes shoulders and legs outward so arms and
 * thighs stay clear; chest and hips scale the torso's sections near those
 * levels (and hips the buttocks and the hip joints' spread). Presets: slim
 * (girth 0.92, chest 0.97, hips 0.96), normal (1, 1, 1), heavy (1.22, 1.06,
 * 1.10).
 *
 * The field is sampled on a grid of def.resolution cells over the height,
 * polygonised (cr_isosurface_extract: closed, manifold, outward), then
 * relaxed: vertices slide towards their neighbours' mean along the surface
 * and are projected back onto it (cr_isosurface_relax), which evens the
 * triangles marching cubes leaves near grid corners without shrinking the
 * body as plain Laplacian smoothing would. Finally the mesh is shifted so
 * its lowest vertex is at y = 0.
 *
 * Left out: fingers, face features, sex-specific shapes, and SMPL's shape
 * space (load a real SMPL model for those).
 *
 * References: Loper et al. 2015 (SMPL joint layout); Quilez, "distance
 * functions" (round cone, ellipsoid bound, rounded box).
 */
#include "mannequin_internal.h"

#include "base/vec3.h"
#include "crease/diffgeo.h"
#include "crease/isosurface.h"
#include "crease/topology.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MANNEQUIN_COOKIE 0x4d4e514eu
/* Proportions below are in metres for a body of this height. */
#define REF_HEIGHT 1.75f

cr_mannequin_def cr_mannequin_default_def(void) {
    cr_mannequin_def d = {0};
    d.height_m = REF_HEIGHT;
    d.girth = 1.0f;
    d.chest = 1.0f;
    d.hips = 1.0f;
    d.arm_angle_deg = 40.0f;
    d.resolution = 110;
    d.relax_iterations = 10;
    d.blend_m = 0.03f;
    d.cookie = MANNEQUIN_COOKIE;
    return d;
}

cr_status cr_mannequin_preset(const char *name, cr_mannequin_def *def, cr_error *err) {
    static const struct {
        const char *name;
        float girth, chest, hips;
    } presets[] = {{"slim", 0.92f, 0.97f, 0.96f},
                   {"normal", 1.0f, 1.0f, 1.0f},
                   {"heavy", 1.22f, 1.06f, 1.10f}};
    for (size_t i = 0; i < sizeof presets / sizeof presets[0]; i++)
        if (strcmp(name, presets[i].name) == 0) {
            def->girth = presets[i].girth;
            def->chest = presets[i].chest;
            def->hips = presets[i].hips;
            return CR_OK;
        }
    return CR_FAIL(err, CR_ERR_INVALID, "mannequin: unknown shape '%s' (slim, normal, heavy)",
                   name);
}

/* ---------------------------------------------------------- min and max -- */

/* fminf and fmaxf honour NaN rules that keep gcc from inlining them; the
 * field is evaluated millions of times and never sees a NaN. */
static inline float min2(float a, float b) {
    return a < b ? a : b;
}

static inline float max2(float a, float b) {
    return a > b ? a : b;
}

static float smin(float a, float b, float k) {
    float h = max2(k - fabsf(a - b), 0.0f) / k;
    return min2(a, b) - 0.25f * h * h * k;
}

/* ------------------------------------------------------------ distances -- */

/* Exact distance to a capsule with radius ra at a and rb at b (Quilez's
 * round cone), in double: the terms are products of squared lengths. */
static float cone_distance(const prim *q, const float p[3]) {
    double ba[3], pa[3];
    for (int d = 0; d < 3; d++)
        ba[d] = q->b[d] - q->a[d], pa[d] = p[d] - q->a[d];
    double l2 = ba[0] * ba[0] + ba[1] * ba[1] + ba[2] * ba[2];
    double rr = (double)q->ra - q->rb, a2 = l2 - rr * rr, il2 = 1.0 / l2;
    double y = pa[0] * ba[0] + pa[1] * ba[1] + pa[2] * ba[2], z = y - l2;
    double x2 = 0.0;
    for (int d = 0; d < 3; d++) {
        double w = pa[d] * l2 - ba[d] * y;
        x2 += w * w;
    }
    double y2 = y * y * l2, z2 = z * z * l2;
    double k = (rr > 0 ? 1.0 : rr < 0 ? -1.0 : 0.0) * rr * rr * x2;
    if ((z > 0 ? 1.0 : z < 0 ? -1.0 : 0.0) * a2 * z2 > k)
        return (float)(sqrt(x2 + z2) * il2 - q->rb);
    if ((y > 0 ? 1.0 : y < 0 ? -1.0 : 0.0) * a2 * y2 < k)
        return (float)(sqrt(x2 + y2) * il2 - q->ra);
    return (float)((sqrt(x2 * a2 * il2) + y * rr) * il2 - q->ra);
}

static void to_local(const prim *q, const float p[3], float l[3]) {
    float d[3] = {p[0] - q->a[0], p[1] - q->a[1], p[2] - q->a[2]};
    for (int r = 0; r < 3; r++)
        l[r] = dot3f(&q->axes[3 * r], d);
}

/* Quilez's first-order ellipsoid distance k0 (k0 - 1) / k1. */
static float ellipse_distance(const float *l, const float *r, int dims) {
    float k0 = 0.0f, k1 = 0.0f, rmin = r[0];
    for (int d = 0; d < dims; d++) {
        float u = l[d] / r[d], w = l[d] / (r[d] * r[d]);
        k0 += u * u, k1 += w * w;
        if (r[d] < rmin) rmin = r[d];
    }
    k0 = sqrtf(k0), k1 = sqrtf(k1);
    if (!(k1 > 1e-12f)) return -rmin;
    return k0 * (k0 - 1.0f) / k1;
}

static float box_distance(const prim *q, const float p[3]) {
    float l[3], out = 0.0f, in = -INFINITY;
    to_local(q, p, l);
    for (int d = 0; d < 3; d++) {
        float e = fabsf(l[d]) - (q->half[d] - q->ra);
        if (e > 0.0f) out += e * e;
        if (e > in) in = e;
    }
    return sqrtf(out) + min2(in, 0.0f) - q->ra;
}

/* Cubic Hermite interpolation of the torso's sections at height y. */
static void torso_section(const torso_profile *t, float y, float *a, float *b, float *c) {
    if (y <= t->y[0]) {
        *a = t->a[0], *b = t->b[0], *c = t->c[0];
        return;
    }
    if (y >= t->y[TORSO_KEYS - 1]) {
        *a = t->a[TORSO_KEYS - 1], *b = t->b[TORSO_KEYS - 1], *c = t->c[TORSO_KEYS - 1];
        return;
    }
    int i = 0;
    while (y > t->y[i + 1])
        i++;
    float h = t->y[i + 1] - t->y[i], s = (y - t->y[i]) / h, s2 = s * s, s3 = s2 * s;
    float h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
    *a = h00 * t->a[i] + h10 * h * t->slope_a[i] + h01 * t->a[i + 1] + h11 * h * t->slope_a[i + 1];
    *b = h00 * t->b[i] + h10 * h * t->slope_b[i] + h01 * t->b[i + 1] + h11 * h * t->slope_b[i + 1];
    *c = h00 * t->c[i] + h10 * h * t->slope_c[i] + h01 * t->c[i + 1] + h11 * h * t->slope_c[i + 1];
}

static float torso_distance(const torso_profile *t, const float p[3]) {
    float a, b, c;
    torso_section(t, p[1], &a, &b, &c);
    float l[2] = {p[0], p[2] - c}, r[2] = {a, b};
    float d = ellipse_distance(l, r, 2);
    /* Smooth maxima with the half-spaces y >= y0 and y <= y1 (smax(a, b) =
     * -smin(-a, -b)); their distances are y0 - y and y - y1. */
    d = -smin(-d, p[1] - t->y0, t->cap);
    return -smin(-d, t->y1 - p[1], t->cap);
}

float cr_mannequin_prim_distance(const mannequin_shape *s, const prim *q, const float p[3]) {
    float l[3];
    switch (q->kind) {
    case PRIM_CONE:
        return cone_distance(q, p);
    case PRIM_ELLIPSOID:
        to_local(q, p, l);
        return ellipse_distance(l, q->half, 3);
    case PRIM_BOX:
        return box_distance(q, p);
    case PRIM_TORSO:
        return torso_distance(&s->torso, p);
    }
    CR_ASSERT(!"unknown primitive kind");
    return 0.0f;
}

/* Whether the primitive's distance at p is at least `level`, judged from
 * its bound cull_a |p - centre| - cull_b (valid where |p - centre| >=
 * cull_min) without a square root. */
static int prim_beyond(const prim *q, const float p[3], float level) {
    float d[3] = {p[0] - q->centre[0], p[1] - q->centre[1], p[2] - q->centre[2]};
    float t = max2((level + q->cull_b) / q->cull_a, q->cull_min);
    return dot3f(d, d) >= t * t;
}

float cr_mannequin_field(void *ctx, const float p[3]) {
    const mannequin_shape *s = ctx;
    float f = cr_mannequin_prim_distance(s, &s->prims[0], p);
    for (int i = 1; i < s->nprims; i++) {
        const prim *q = &s->prims[i];
        /* Past f + blend the smooth minimum returns f unchanged. */
        if (prim_beyond(q, p, f + q->blend)) continue;
        f = smin(f, cr_mannequin_prim_distance(s, q, p), q->blend);
    }
    /* The smooth unions can bulge below the feet: cut with y >= 0 (smooth
     * maximum with -y), which also makes the soles flat. */
    return -smin(-f, p[1], s->sole_round);
}

/* ------------------------------------------------------------- building -- */

/* Reference torso sections: height, half-width, half-depth, centre z (m at
 * 1.75 m), and how much of the chest and hips factors each takes. */
static const float torso_keys[TORSO_KEYS][6] = {
    {0.800f, 0.132f, 0.088f, -0.008f, 0.0f, 0.7f}, {0.860f, 0.158f, 0.102f, -0.012f, 0.0f, 1.0f},
    {0.930f, 0.168f, 0.108f, -0.012f, 0.0f, 1.0f}, {1.000f, 0.158f, 0.100f, -0.006f, 0.0f, 0.6f},
    {1.070f, 0.145f, 0.097f, 0.000f, 0.0f, 0.2f},  {1.150f, 0.150f, 0.103f, 0.004f, 0.3f, 0.0f},
    {1.230f, 0.160f, 0.110f, 0.008f, 0.8f, 0.0f},  {1.300f, 0.168f, 0.114f, 0.008f, 1.0f, 0.0f},
    {1.370f, 0.172f, 0.107f, 0.000f, 0.7f, 0.0f},  {1.420f, 0.160f, 0.092f, -0.010f, 0.3f, 0.0f},
    {1.470f, 0.090f, 0.070f, -0.018f, 0.0f, 0.0f}};

static prim *add_prim(mannequin_shape *s, prim_kind kind, body_part part, float blend) {
    CR_ASSERT(s->nprims < MAX_PRIMS);
    prim *q = &s->prims[s->nprims++];
    memset(q, 0, sizeof *q);
    q->kind = kind, q->part = part, q->blend = blend;
    return q;
}

static void add_cone(mannequin_shape *s, body_part part, float blend, const float *a, float ra,
                     const float *b, float rb) {
    prim *q = add_prim(s, PRIM_CONE, part, blend);
    memcpy(q->a, a, sizeof q->a);
    memcpy(q->b, b, sizeof q->b);
    q->ra = ra, q->rb = rb;
}

/* Ellipsoid or box with local axes ax (x), ay (y) and their cross product. */
static prim *add_oriented(mannequin_shape *s, prim_kind kind, body_part part, float blend,
                          const float *centre, const float *ax, const float *ay, float hx, float hy,
                          float hz) {
    prim *q = add_prim(s, kind, part, blend);
    memcpy(q->a, centre, sizeof q->a);
    memcpy(&q->axes[0], ax, 3 * sizeof(float));
    memcpy(&q->axes[3], ay, 3 * sizeof(float));
    q->axes[6] = ax[1] * ay[2] - ax[2] * ay[1];
    q->axes[7] = ax[2] * ay[0] - ax[0] * ay[2];
    q->axes[8] = ax[0] * ay[1] - ax[1] * ay[0];
    set3f(q->half, hx, hy, hz);
    return q;
}

static const float X_AXIS[3] = {1, 0, 0}, Y_AXIS[3] = {0, 1, 0};

static void set_plane(chain_plane *pl, const float *p, const float *n, float half) {
    memcpy(pl->p, p, sizeof pl->p);
    memcpy(pl->n, n, sizeof pl->n);
    normalize3f_div(pl->n);
    pl->half = half;
}

/* One arm and one leg; side = +1 for the left (+X), -1 for the right. */
static void build_limbs(mannequin_shape *s, const cr_mannequin_def *def, float side) {
    const float g = def->girth, hs = 1.0f + 0.3f * (def->girth - 1.0f);
    const int L = side > 0;
    float *J = s->joints;
    const float *S = &J[3 * (L ? CR_JOINT_LEFT_SHOULDER : CR_JOINT_RIGHT_SHOULDER)];
    const float *C = &J[3 * (L ? CR_JOINT_LEFT_COLLAR : CR_JOINT_RIGHT_COLLAR)];
    const float *E = &J[3 * (L ? CR_JOINT_LEFT_ELBOW : CR_JOINT_RIGHT_ELBOW)];
    const float *W = &J[3 * (L ? CR_JOINT_LEFT_WRIST : CR_JOINT_RIGHT_WRIST)];
    const float *H = &J[3 * (L ? CR_JOINT_LEFT_HIP : CR_JOINT_RIGHT_HIP)];
    const float *K = &J[3 * (L ? CR_JOINT_LEFT_KNEE : CR_JOINT_RIGHT_KNEE)];
    const float *A = &J[3 * (L ? CR_JOINT_LEFT_ANKLE : CR_JOINT_RIGHT_ANKLE)];
    const float *F = &J[3 * (L ? CR_JOINT_LEFT_FOOT : CR_JOINT_RIGHT_FOOT)];
    body_part arm = L ? PART_ARM_L : PART_ARM_R, leg = L ? PART_LEG_L : PART_LEG_R;

    /* Arm: trapezius from the neck's base, upper arm, forearm, hand. */
    float ang = def->arm_angle_deg * (float)M_PI / 180.0f;
    float dir[3] = {side * cosf(ang), -sinf(ang), 0.0f};
    float palm[3] = {side * sinf(ang), cosf(ang), 0.0f}; /* thin axis of the hand */
    float trap[3] = {0.0f, 1.445f, -0.035f};
    add_cone(s, arm, 0.05f, trap, 0.050f * g, S, 0.048f * g);
    add_cone(s, arm, 0.03f, S, 0.050f * g, E, 0.038f * g);
    add_cone(s, arm, 0.02f, E, 0.040f * g, W, 0.027f * g);
    float hc[3];
    for (int d = 0; d < 3; d++)
        hc[d] = W[d] + 0.085f * dir[d];
    prim *hand =
        add_oriented(s, PRIM_BOX, arm, 0.015f, hc, dir, palm, 0.085f, 0.0155f * hs, 0.044f * hs);
    hand->ra = 0.015f * hs;

    /* Leg: thigh, shin, calf muscle, heel-and-midfoot, toes. */
    add_cone(s, leg, 0.035f, H, 0.082f * g, K, 0.053f * g);
    add_cone(s, leg, 0.025f, K, 0.050f * g, A, 0.033f * g);
    float calf[3] = {K[0] - side * 0.003f, 0.36f, K[2] - 0.02f};
    float shin[3] = {A[0] - K[0], A[1] - K[1], A[2] - K[2]};
    normalize3f_div(shin);
    float shin_x[3] = {-shin[1], shin[0], 0.0f};
    normalize3f_div(shin_x);
    add_oriented(s, PRIM_ELLIPSOID, leg, 0.03f, calf, shin_x, shin, 0.050f * g, 0.11f, 0.052f * g);
    float u[3] = {F[0] - A[0], 0.0f, F[2] - A[2]};
    normalize3f_div(u);
    float across[3] = {u[2], 0.0f, -u[0]};
    /* Both boxes reach below y = 0, where the field's ground cut flattens the soles. */
    float heel_c[3] = {A[0] + 0.025f * u[0], 0.022f, A[2] + 0.025f * u[2]};
    float toe_c[3] = {A[0] + 0.14f * u[0], 0.012f, A[2] + 0.14f * u[2]};
    prim *heel =
        add_oriented(s, PRIM_BOX, leg, 0.02f, heel_c, across, Y_AXIS, 0.040f * hs, 0.038f, 0.09f);
    heel->ra = 0.028f;
    prim *toe =
        add_oriented(s, PRIM_BOX, leg, 0.04f, toe_c, across, Y_AXIS, 0.047f * hs, 0.024f, 0.05f);
    toe->ra = 0.018f;
    /* The instep: from the ankle down to the ball of the foot. */
    float ball[3] = {F[0], F[1] + 0.012f, F[2]};
    add_cone(s, leg, 0.03f, A, 0.036f * hs, ball, 0.026f * hs);

    /* Skinning chains. Arm: spine3 | collar | shoulder | elbow | wrist. */
    float bw = def->blend_m / 0.03f; /* the chains' step widths scale with blend_m */
    float cs[3] = {S[0] - C[0], S[1] - C[1], S[2] - C[2]};
    body_chain *ca = &s->chain[arm];
    ca->nplanes = 4;
    set_plane(&ca->plane[0], C, cs, 0.03f * bw);
    set_plane(&ca->plane[1], S, dir, 0.09f * bw);
    set_plane(&ca->plane[2], E, dir, 0.035f * bw);
    set_plane(&ca->plane[3], W, dir, 0.03f * bw);
    int8_t arm_bones[5] = {CR_JOINT_SPINE3,
                           (int8_t)(L ? CR_JOINT_LEFT_COLLAR : CR_JOINT_RIGHT_COLLAR),
                           (int8_t)(L ? CR_JOINT_LEFT_SHOULDER : CR_JOINT_RIGHT_SHOULDER),
                           (int8_t)(L ? CR_JOINT_LEFT_ELBOW : CR_JOINT_RIGHT_ELBOW),
                           (int8_t)(L ? CR_JOINT_LEFT_WRIST : CR_JOINT_RIGHT_WRIST)};
    memcpy(ca->bone, arm_bones, sizeof arm_bones);
    /* Leg: pelvis | hip | knee | ankle | foot. */
    float thigh[3] = {K[0] - H[0], K[1] - H[1], K[2] - H[2]};
    body_chain *cl = &s->chain[leg];
    cl->nplanes = 4;
    set_plane(&cl->plane[0], H, thigh, 0.05f * bw);
    set_plane(&cl->plane[1], K, shin, 0.04f * bw);
    set_plane(&cl->plane[2], A, shin, 0.03f * bw);
    set_plane(&cl->plane[3], F, u, 0.03f * bw);
    int8_t leg_bones[5] = {CR_JOINT_PELVIS, (int8_t)(L ? CR_JOINT_LEFT_HIP : CR_JOINT_RIGHT_HIP),
                           (int8_t)(L ? CR_JOINT_LEFT_KNEE : CR_JOINT_RIGHT_KNEE),
                           (int8_t)(L ? CR_JOINT_LEFT_ANKLE : CR_JOINT_RIGHT_ANKLE),
                           (int8_t)(L ? CR_JOINT_LEFT_FOOT : CR_JOINT_RIGHT_FOOT)};
    memcpy(cl->bone, leg_bones, sizeof leg_bones);
}

/* Rest joints at the reference height, before scaling. */
static void build_joints(float *J, const cr_mannequin_def *def) {
    const float g = def->girth - 1.0f, hp = def->hips - 1.0f, ch = def->chest - 1.0f;
    float ang = def->arm_angle_deg * (float)M_PI / 180.0f;
    set3f(&J[3 * CR_JOINT_PELVIS], 0.0f, 0.955f, -0.005f);
    set3f(&J[3 * CR_JOINT_SPINE1], 0.0f, 1.065f, -0.020f);
    set3f(&J[3 * CR_JOINT_SPINE2], 0.0f, 1.190f, -0.012f);
    set3f(&J[3 * CR_JOINT_SPINE3], 0.0f, 1.250f, -0.005f);
    set3f(&J[3 * CR_JOINT_NECK], 0.0f, 1.465f, -0.020f);
    set3f(&J[3 * CR_JOINT_HEAD], 0.0f, 1.535f, 0.000f);
    for (int side = 0; side < 2; side++) {
        float sx = side == 0 ? 1.0f : -1.0f; /* left joints are on +X */
        int l = side == 0;
        float shoulder_out = 0.06f * g + 0.03f * ch, hip_out = 0.05f * g + 0.04f * hp;
        float *C = &J[3 * (l ? CR_JOINT_LEFT_COLLAR : CR_JOINT_RIGHT_COLLAR)];
        float *S = &J[3 * (l ? CR_JOINT_LEFT_SHOULDER : CR_JOINT_RIGHT_SHOULDER)];
        float *E = &J[3 * (l ? CR_JOINT_LEFT_ELBOW : CR_JOINT_RIGHT_ELBOW)];
        float *W = &J[3 * (l ? CR_JOINT_LEFT_WRIST : CR_JOINT_RIGHT_WRIST)];
        set3f(C, sx * (0.075f + 0.5f * shoulder_out), 1.370f, -0.020f);
        set3f(S, sx * (0.175f + shoulder_out), 1.405f, -0.020f);
        float dir[3] = {sx * cosf(ang), -sinf(ang), 0.0f};
        for (int d = 0; d < 3; d++)
            E[d] = S[d] + 0.27f * dir[d];
        for (int d = 0; d < 3; d++)
            W[d] = E[d] + 0.26f * dir[d];
        set3f(&J[3 * (l ? CR_JOINT_LEFT_HIP : CR_JOINT_RIGHT_HIP)], sx * (0.085f + hip_out), 0.865f,
              0.0f);
        set3f(&J[3 * (l ? CR_JOINT_LEFT_KNEE : CR_JOINT_RIGHT_KNEE)], sx * (0.095f + 0.05f * g),
              0.490f, 0.010f);
        float ax = sx * (0.088f + 0.03f * g);
        set3f(&J[3 * (l ? CR_JOINT_LEFT_ANKLE : CR_JOINT_RIGHT_ANKLE)], ax, 0.080f, -0.035f);
        set3f(&J[3 * (l ? CR_JOINT_LEFT_FOOT : CR_JOINT_RIGHT_FOOT)], ax + sx * 0.02f, 0.025f,
              0.090f);
    }
}

void cr_mannequin_rest_joints(const cr_mannequin_def *def, float J[CR_NJOINTS * 3]) {
    build_joints(J, def);
}

static void build_torso(torso_profile *t, const cr_mannequin_def *def) {
    for (int i = 0; i < TORSO_KEYS; i++) {
        const float *k = torso_keys[i];
        float f =
            def->girth * (1.0f + k[4] * (def->chest - 1.0f)) * (1.0f + k[5] * (def->hips - 1.0f));
        t->y[i] = k[0], t->a[i] = k[1] * f, t->b[i] = k[2] * f, t->c[i] = k[3];
    }
    /* Slopes: three-point differences inside, one-sided at the ends. */
    for (int i = 0; i < TORSO_KEYS; i++) {
        int lo = i > 0 ? i - 1 : i, hi = i + 1 < TORSO_KEYS ? i + 1 : i;
        float h = t->y[hi] - t->y[lo];
        t->slope_a[i] = (t->a[hi] - t->a[lo]) / h;
        t->slope_b[i] = (t->b[hi] - t->b[lo]) / h;
        t->slope_c[i] = (t->c[hi] - t->c[lo]) / h;
    }
    t->y0 = torso_keys[0][0];
    t->y1 = torso_keys[TORSO_KEYS - 1][0];
    t->cap = 0.03f;
}

/* Scale the shape's geometry by k (the reference body is 1.75 m); the
 * skinning blend widths are def.blend_m's, in metres at any height. */
static void scale_shape(mannequin_shape *s, float k) {
    for (int i = 0; i < CR_NJOINTS * 3; i++)
        s->joints[i] *= k;
    for (int i = 0; i < s->nprims; i++) {
        prim *q = &s->prims[i];
        for (int d = 0; d < 3; d++)
            q->a[d] *= k, q->b[d] *= k, q->half[d] *= k;
        q->ra *= k, q->rb *= k, q->blend *= k;
    }
    torso_profile *t = &s->torso;
    for (int i = 0; i < TORSO_KEYS; i++)
        t->y[i] *= k, t->a[i] *= k, t->b[i] *= k, t->c[i] *= k;
    t->y0 *= k, t->y1 *= k, t->cap *= k;
    s->sole_round *= k;
    for (int c = 0; c < PART_COUNT; c++)
        for (int i = 0; i < s->chain[c].nplanes; i++) {
            chain_plane *pl = &s->chain[c].plane[i];
            for (int d = 0; d < 3; d++)
                pl->p[d] *= k;
        }
}

/* Bounding spheres of the primitives and the box around the whole solid. */
static void compute_bounds(mannequin_shape *s) {
    for (int d = 0; d < 3; d++)
        s->lo[d] = INFINITY, s->hi[d] = -INFINITY;
    for (int i = 0; i < s->nprims; i++) {
        prim *q = &s->prims[i];
        float lo[3], hi[3];
        if (q->kind == PRIM_CONE) {
            for (int d = 0; d < 3; d++) {
                q->centre[d] = 0.5f * (q->a[d] + q->b[d]);
                lo[d] = min2(q->a[d] - q->ra, q->b[d] - q->rb);
                hi[d] = max2(q->a[d] + q->ra, q->b[d] + q->rb);
            }
            float hl[3] = {q->b[0] - q->a[0], q->b[1] - q->a[1], q->b[2] - q->a[2]};
            q->r = 0.5f * sqrtf(dot3f(hl, hl)) + max2(q->ra, q->rb);
            q->cull_a = 1.0f, q->cull_b = q->r, q->cull_min = 0.0f; /* an exact distance */
        } else if (q->kind == PRIM_TORSO) {
            const torso_profile *t = &s->torso;
            float amax = 0.0f, zlo = INFINITY, zhi = -INFINITY;
            for (int k = 0; k < TORSO_KEYS; k++) {
                amax = max2(amax, t->a[k]);
                zlo = min2(zlo, t->c[k] - t->b[k]), zhi = max2(zhi, t->c[k] + t->b[k]);
            }
            set3f(lo, -amax, t->y0, zlo);
            set3f(hi, amax, t->y1, zhi);
            for (int d = 0; d < 3; d++)
                q->centre[d] = 0.5f * (lo[d] + hi[d]);
            q->r = INFINITY;
            q->cull_a = 1.0f, q->cull_b = INFINITY, q->cull_min = 0.0f; /* never skipped */
        } else {
            memcpy(q->centre, q->a, sizeof q->centre);
            q->r = sqrtf(dot3f(q->half, q->half));
            if (q->kind == PRIM_BOX) {
                q->cull_a = 1.0f, q->cull_b = q->r, q->cull_min = 0.0f;
            } else {
                /* Quilez's ellipsoid estimate k0 (k0 - 1) / k1 with k1 <= k0 / r_min and
                 * k0 >= |p| / r_max is at least (|p| / r_max - 1) r_min past r_max. */
                float rmax = max2(q->half[0], max2(q->half[1], q->half[2]));
                float rmin = min2(q->half[0], min2(q->half[1], q->half[2]));
                q->cull_a = rmin / rmax, q->cull_b = rmin, q->cull_min = rmax;
            }
            for (int d = 0; d < 3; d++)
                lo[d] = q->a[d] - q->r, hi[d] = q->a[d] + q->r;
        }
        for (int d = 0; d < 3; d++)
            s->lo[d] = min2(s->lo[d], lo[d]), s->hi[d] = max2(s->hi[d], hi[d]);
    }
}

static void build_shape(mannequin_shape *s, const cr_mannequin_def *def) {
    memset(s, 0, sizeof *s);
    const float g = def->girth, hs = 1.0f + 0.3f * (def->girth - 1.0f), hp = def->hips;
    build_joints(s->joints, def);
    build_torso(&s->torso, def);
    const float *J = s->joints;

    add_prim(s, PRIM_TORSO, PART_TORSO, 0.0f);
    /* Buttocks belong to the legs: the hip plane then splits each from the
     * pelvis across its middle, and the gluteal fold bends smoothly. */
    for (int side = -1; side <= 1; side += 2) {
        float c[3] = {side * 0.068f * hp, 0.905f, -0.05f};
        add_oriented(s, PRIM_ELLIPSOID, side > 0 ? PART_LEG_L : PART_LEG_R, 0.04f, c, X_AXIS,
                     Y_AXIS, 0.080f * g * hp, 0.095f, 0.070f * g * hp);
    }
    float neck_lo[3] = {0.0f, 1.42f, -0.025f}, neck_hi[3] = {0.0f, 1.56f, 0.0f};
    add_cone(s, PART_HEAD, 0.03f, neck_lo, 0.058f * g, neck_hi, 0.053f * g);
    float jaw[3] = {0.0f, 1.575f, 0.035f}, skull[3] = {0.0f, 1.635f, 0.012f};
    add_oriented(s, PRIM_ELLIPSOID, PART_HEAD, 0.025f, jaw, X_AXIS, Y_AXIS, 0.055f * hs, 0.045f,
                 0.060f * hs);
    /* The skull's top is the body's height: its vertical semi-axis does not scale. */
    add_oriented(s, PRIM_ELLIPSOID, PART_HEAD, 0.02f, skull, X_AXIS, Y_AXIS, 0.077f * hs,
                 REF_HEIGHT - skull[1], 0.097f * hs);
    build_limbs(s, def, 1.0f);
    build_limbs(s, def, -1.0f);

    /* Torso chain: pelvis | spine1 | spine2 | spine3 | neck, across
     * horizontal planes through the spine joints. */
    float bw = def->blend_m / 0.03f;
    body_chain *ct = &s->chain[PART_TORSO];
    ct->nplanes = 4;
    set_plane(&ct->plane[0], &J[3 * CR_JOINT_SPINE1], Y_AXIS, 0.04f * bw);
    set_plane(&ct->plane[1], &J[3 * CR_JOINT_SPINE2], Y_AXIS, 0.035f * bw);
    set_plane(&ct->plane[2], &J[3 * CR_JOINT_SPINE3], Y_AXIS, 0.03f * bw);
    set_plane(&ct->plane[3], &J[3 * CR_JOINT_NECK], Y_AXIS, 0.03f * bw);
    int8_t torso_bones[5] = {CR_JOINT_PELVIS, CR_JOINT_SPINE1, CR_JOINT_SPINE2, CR_JOINT_SPINE3,
                             CR_JOINT_NECK};
    memcpy(ct->bone, torso_bones, sizeof torso_bones);
    /* Neck and head: spine3 | neck | head. */
    const float *N = &J[3 * CR_JOINT_NECK], *Hd = &J[3 * CR_JOINT_HEAD];
    float up[3] = {Hd[0] - N[0], Hd[1] - N[1], Hd[2] - N[2]};
    body_chain *ch = &s->chain[PART_HEAD];
    ch->nplanes = 2;
    set_plane(&ch->plane[0], N, Y_AXIS, 0.03f * bw);
    set_plane(&ch->plane[1], Hd, up, 0.03f * bw);
    ch->bone[0] = CR_JOINT_SPINE3, ch->bone[1] = CR_JOINT_NECK, ch->bone[2] = CR_JOINT_HEAD;

    s->membership_temp = def->blend_m;
    s->sole_round = 0.01f;
    scale_shape(s, def->height_m / REF_HEIGHT);
    compute_bounds(s);
}

/* -------------------------------------------------------------- create -- */

static cr_status check_def(const cr_mannequin_def *d, cr_error *err) {
    CR_ASSERT(d->cookie == MANNEQUIN_COOKIE);
    struct {
        const char *name;
        double v, lo, hi;
    } f[] = {{"height_m", d->height_m, 1.0, 2.5},
             {"girth", d->girth, 0.6, 1.6},
             {"chest", d->chest, 0.7, 1.5},
             {"hips", d->hips, 0.7, 1.5},
             {"arm_angle_deg", d->arm_angle_deg, 0, 80},
             {"resolution", d->resolution, 32, 512},
             {"relax_iterations", d->relax_iterations, 0, 100},
             {"blend_m", d->blend_m, 1e-3, 0.1}};
    for (size_t i = 0; i < sizeof f / sizeof f[0]; i++)
        if (!(f[i].v >= f[i].lo && f[i].v <= f[i].hi))
            return CR_FAIL(err, CR_ERR_INVALID, "mannequin: %s = %g (need %g to %g)", f[i].name,
                           f[i].v, f[i].lo, f[i].hi);
    return CR_OK;
}

/* The body must come out as one closed genus-0 surface; at too coarse a
 * grid thin parts (wrists, hands) break off or close into handles. */
static cr_status check_one_sphere(const cr_mesh *m, int32_t resolution, cr_error *err) {
    cr_topology *t = NULL;
    CR_TRY(cr_topology_build(m, &t, err));
    int32_t *stack = cr_malloc((size_t)m->nv * sizeof(int32_t), err);
    uint8_t *seen = cr_calloc((size_t)m->nv, 1, err);
    cr_status st = stack && seen ? CR_OK : CR_ERR_MEMORY;
    int32_t pieces = 0;
    for (int32_t v0 = 0; v0 < m->nv && st == CR_OK; v0++) {
        if (seen[v0]) continue;
        pieces++;
        int32_t n = 0;
        stack[n++] = v0, seen[v0] = 1;
        while (n > 0) {
            int32_t v = stack[--n];
            for (int32_t q = t->vv_off[v]; q < t->vv_off[v + 1]; q++)
                if (!seen[t->vv[q]]) seen[t->vv[q]] = 1, stack[n++] = t->vv[q];
        }
    }
    int64_t chi = cr_topology_euler_characteristic(t);
    if (st == CR_OK && (pieces != 1 || chi != 2 || t->n_boundary_edges != 0))
        st = CR_FAIL(err, CR_ERR_TOPOLOGY,
                     "mannequin: resolution %d is too coarse for this shape (the surface came out "
                     "in %d pieces, Euler characteristic %lld); raise the resolution",
                     resolution, pieces, (long long)chi);
    free(stack);
    free(seen);
    cr_topology_destroy(t);
    return st;
}

static cr_status polygonise(const mannequin_shape *s, const cr_mannequin_def *def, cr_mesh **out,
                            cr_error *err) {
    float h = def->height_m / (float)def->resolution;
    cr_iso_grid g = {0};
    int32_t n[3];
    for (int d = 0; d < 3; d++) {
        /* Two cells of margin, plus what the smooth unions may add. */
        float lo = s->lo[d] - 2.0f * h - 0.01f, hi = s->hi[d] + 2.0f * h + 0.01f;
        n[d] = (int32_t)ceilf((hi - lo) / h) + 1;
        g.origin[d] = lo;
    }
    g.nx = n[0], g.ny = n[1], g.nz = n[2], g.spacing = h;
    float *values = cr_malloc((size_t)n[0] * n[1] * n[2] * sizeof(float), err);
    if (!values) return CR_ERR_MEMORY;
    cr_status st = cr_isosurface_sample(&g, cr_mannequin_field, (void *)s, values, err);
    g.values = values;
    if (st == CR_OK) st = cr_isosurface_extract(&g, 0.0f, out, err);
    free(values);
    if (st == CR_OK) st = check_one_sphere(*out, def->resolution, err);
    if (st == CR_OK)
        st = cr_isosurface_relax(*out, cr_mannequin_field, (void *)s, 0.0f, def->relax_iterations,
                                 0.1f * h, err);
    if (st != CR_OK) {
        cr_mesh_destroy(*out);
        *out = NULL;
    }
    return st;
}

cr_status cr_mannequin_create(const cr_mannequin_def *def, cr_body_model **out, cr_error *err) {
    *out = NULL;
    CR_TRY(check_def(def, err));
    mannequin_shape *s = cr_malloc(sizeof *s, err);
    if (!s) return CR_ERR_MEMORY;
    build_shape(s, def);
    cr_body_model *b = cr_calloc(1, sizeof *b, err);
    cr_status st = b ? CR_OK : CR_ERR_MEMORY;
    if (st == CR_OK) st = polygonise(s, def, &b->rest, err);
    if (st == CR_OK) {
        int32_t nv = b->rest->nv;
        b->skin_joint = cr_malloc((size_t)nv * 4 * sizeof(int32_t), err);
        b->skin_weight = cr_malloc((size_t)nv * 4 * sizeof(float), err);
        if (!b->skin_joint || !b->skin_weight) st = CR_ERR_MEMORY;
    }
    if (st == CR_OK) st = cr_mannequin_skin_weights(s, b->rest, b->skin_joint, b->skin_weight, err);
    if (st == CR_OK) {
        /* Soles exactly on y = 0. */
        float lo[3], hi[3];
        cr_mesh_bounds(b->rest, lo, hi);
        float shift[3] = {0.0f, -lo[1], 0.0f};
        cr_mesh_transform(b->rest, 1.0f, shift);
        memcpy(b->joints, s->joints, sizeof b->joints);
        for (int j = 0; j < CR_NJOINTS; j++)
            b->joints[3 * j + 1] -= lo[1];
        st = cr_mesh_compute_normals(b->rest, err);
    }
    free(s);
    if (st != CR_OK) {
        cr_body_model_destroy(b);
        return st;
    }
    *out = b;
    return CR_OK;
}
