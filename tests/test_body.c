/* test_body.c: Rodrigues and forward kinematics against hand-computed poses,
 * linear blend skinning (exact rest pose, rigid motions, a bent elbow), and
 * the mannequin: watertight genus-0 mesh, proportions, A-pose, joints inside,
 * triangle quality, weights that sum to one, change smoothly and keep
 * triangles from collapsing when the arm is raised or the hip flexed, shape
 * parameters, and bad input. */
#include "crease/body.h"
#include "crease/diffgeo.h"
#include "crease/topology.h"
#include "test.h"

#include <stdlib.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

/* ------------------------------------------------------------ rotations -- */

CR_TEST(body, rodrigues_closed_forms) {
    float R[9];
    const float zero[3] = {0, 0, 0};
    cr_body_rodrigues(zero, R);
    const float I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    CR_CHECK(memcmp(R, I, sizeof R) == 0);
    /* 90 degrees about z takes x to y and y to -x. */
    const float qz[3] = {0, 0, (float)(PI / 2)};
    cr_body_rodrigues(qz, R);
    const float Rz[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1};
    for (int i = 0; i < 9; i++)
        CR_CHECK_NEAR(R[i], Rz[i], 1e-7);
    /* 120 degrees about (1,1,1)/sqrt(3) cycles the axes: x -> y -> z. */
    float t = (float)(2.0 * PI / 3.0 / sqrt(3.0));
    const float q3[3] = {t, t, t};
    cr_body_rodrigues(q3, R);
    const float Rc[9] = {0, 0, 1, 1, 0, 0, 0, 1, 0};
    for (int i = 0; i < 9; i++)
        CR_CHECK_NEAR(R[i], Rc[i], 1e-6);
    /* Below the series threshold: R = I + [w]x to first order. */
    const float small[3] = {3e-6f, -2e-6f, 1e-6f};
    cr_body_rodrigues(small, R);
    CR_CHECK_NEAR(R[1], -small[2], 1e-11); /* second-order terms are ~1e-11 */
    CR_CHECK_NEAR(R[2], small[1], 1e-11);
    CR_CHECK_NEAR(R[5], -small[0], 1e-11);
    CR_CHECK_NEAR(R[0], 1.0, 1e-9);
    /* Orthonormal with determinant 1 for an arbitrary vector. */
    const float q[3] = {0.7f, -1.9f, 0.4f};
    cr_body_rodrigues(q, R);
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double d = 0;
            for (int k = 0; k < 3; k++)
                d += (double)R[3 * a + k] * R[3 * b + k];
            CR_CHECK_NEAR(d, a == b, 1e-6);
        }
    double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) +
                 R[2] * (R[3] * R[7] - R[4] * R[6]);
    CR_CHECK_NEAR(det, 1.0, 1e-6);
    for (int a = 0; a < 3; a++) /* the axis is fixed */
        CR_CHECK_NEAR(R[3 * a] * q[0] + R[3 * a + 1] * q[1] + R[3 * a + 2] * q[2], q[a], 1e-6);
}

/* A skeleton with a straight left arm along +x at shoulder height. */
static void test_skeleton(float *J) {
    for (int j = 0; j < CR_NJOINTS; j++)
        J[3 * j] = 0.01f * j, J[3 * j + 1] = 1.0f, J[3 * j + 2] = 0;
    const float pelvis[3] = {0, 1, 0}, S[3] = {0.2f, 1.5f, 0}, E[3] = {0.5f, 1.5f, 0},
                W[3] = {0.8f, 1.5f, 0};
    memcpy(&J[3 * CR_JOINT_PELVIS], pelvis, sizeof pelvis);
    memcpy(&J[3 * CR_JOINT_LEFT_SHOULDER], S, sizeof S);
    memcpy(&J[3 * CR_JOINT_LEFT_ELBOW], E, sizeof E);
    memcpy(&J[3 * CR_JOINT_LEFT_WRIST], W, sizeof W);
}

CR_TEST(body, forward_kinematics_by_hand) {
    float J[CR_NJOINTS * 3], pose[CR_NJOINTS * 3] = {0}, pos[CR_NJOINTS * 3], rot[CR_NJOINTS * 9];
    test_skeleton(J);
    /* Rest pose: joints where they are, rotations the identity, exactly. */
    cr_body_forward_kinematics(J, pose, NULL, rot, pos);
    CR_CHECK(memcmp(pos, J, sizeof pos) == 0);
    for (int j = 0; j < CR_NJOINTS; j++)
        for (int k = 0; k < 9; k++)
            CR_CHECK(rot[9 * j + k] == (k % 4 == 0 ? 1.0f : 0.0f));

    /* Elbow bent 90 degrees about +z: the forearm (0.3 m along +x) points up. */
    pose[3 * CR_JOINT_LEFT_ELBOW + 2] = (float)(PI / 2);
    cr_body_forward_kinematics(J, pose, NULL, NULL, pos);
    const float *w = &pos[3 * CR_JOINT_LEFT_WRIST];
    CR_CHECK_NEAR(w[0], 0.5, 1e-6);
    CR_CHECK_NEAR(w[1], 1.8, 1e-6);
    CR_CHECK_NEAR(w[2], 0.0, 1e-6);

    /* Shoulder and elbow each 90 degrees about +z: the upper arm points up,
     * the forearm back along -x: elbow (0.2, 1.8, 0), wrist (-0.1, 1.8, 0). */
    pose[3 * CR_JOINT_LEFT_SHOULDER + 2] = (float)(PI / 2);
    cr_body_forward_kinematics(J, pose, NULL, rot, pos);
    CR_CHECK_NEAR(pos[3 * CR_JOINT_LEFT_ELBOW], 0.2, 1e-6);
    CR_CHECK_NEAR(pos[3 * CR_JOINT_LEFT_ELBOW + 1], 1.8, 1e-6);
    CR_CHECK_NEAR(w[0], -0.1, 1e-6);
    CR_CHECK_NEAR(w[1], 1.8, 1e-6);
    /* The wrist's world rotation is 180 degrees about z. */
    CR_CHECK_NEAR(rot[9 * CR_JOINT_LEFT_WRIST], -1.0, 1e-6);
    CR_CHECK_NEAR(rot[9 * CR_JOINT_LEFT_WRIST + 4], -1.0, 1e-6);

    /* Root turned 90 degrees about +y, (x, y, z) -> (z, y, -x) about the
     * pelvis, and translated: the straight arm's wrist, 0.8 m right of and
     * 0.5 m above the pelvis, ends 0.8 m behind it. */
    memset(pose, 0, sizeof pose);
    pose[1] = (float)(PI / 2);
    const float trans[3] = {0.1f, -0.2f, 0.3f};
    cr_body_forward_kinematics(J, pose, trans, NULL, pos);
    CR_CHECK_NEAR(w[0], 0.0 + 0.1, 1e-6);
    CR_CHECK_NEAR(w[1], 1.5 - 0.2, 1e-6);
    CR_CHECK_NEAR(w[2], -0.8 + 0.3, 1e-6);
}

CR_TEST(body, skin_transforms_rest_is_identity) {
    float J[CR_NJOINTS * 3], pose[CR_NJOINTS * 3] = {0}, xf[CR_NJOINTS * 12];
    test_skeleton(J);
    cr_body_skin_transforms(J, pose, NULL, xf);
    for (int j = 0; j < CR_NJOINTS; j++)
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++)
                CR_CHECK(xf[12 * j + 4 * r + c] == (c == r ? 1.0f : 0.0f));
    /* A bent elbow: a point 0.1 m past the elbow, bound to the elbow joint,
     * turns with the forearm: (0.6, 1.5, 0) -> (0.5, 1.6, 0). */
    pose[3 * CR_JOINT_LEFT_ELBOW + 2] = (float)(PI / 2);
    cr_body_skin_transforms(J, pose, NULL, xf);
    const float *M = &xf[12 * CR_JOINT_LEFT_ELBOW];
    const float x[3] = {0.6f, 1.5f, 0};
    float y[3];
    for (int r = 0; r < 3; r++)
        y[r] = M[4 * r] * x[0] + M[4 * r + 1] * x[1] + M[4 * r + 2] * x[2] + M[4 * r + 3];
    CR_CHECK_NEAR(y[0], 0.5, 1e-6);
    CR_CHECK_NEAR(y[1], 1.6, 1e-6);
    CR_CHECK_NEAR(y[2], 0.0, 1e-6);
}

/* ------------------------------------------------------------ mannequin -- */

static cr_body_model *make_body(int32_t resolution, const char *preset) {
    cr_error err = {0};
    cr_mannequin_def def = cr_mannequin_default_def();
    if (resolution) def.resolution = resolution;
    if (preset) CR_CHECK_OK(cr_mannequin_preset(preset, &def, &err), &err);
    cr_body_model *b = NULL;
    CR_CHECK_OK(cr_mannequin_create(&def, &b, &err), &err);
    return b;
}

static double mesh_volume(const cr_mesh *m) {
    double vol = 0.0;
    for (int32_t f = 0; f < m->nf; f++) {
        const float *a = &m->pos[3 * m->tri[3 * f]], *b = &m->pos[3 * m->tri[3 * f + 1]],
                    *c = &m->pos[3 * m->tri[3 * f + 2]];
        vol += (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
                a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) /
               6.0;
    }
    return vol;
}

/* Generalised winding number of the mesh at p (Jacobson et al. 2013): 1
 * inside a closed outward surface, 0 outside. Solid angles by Van Oosterom
 * and Strackee's formula. */
static double winding_number(const cr_mesh *m, const float p[3]) {
    double sum = 0.0;
    for (int32_t f = 0; f < m->nf; f++) {
        double v[3][3], l[3];
        for (int k = 0; k < 3; k++) {
            for (int d = 0; d < 3; d++)
                v[k][d] = (double)m->pos[3 * m->tri[3 * f + k] + d] - p[d];
            l[k] = sqrt(v[k][0] * v[k][0] + v[k][1] * v[k][1] + v[k][2] * v[k][2]);
        }
        double det = v[0][0] * (v[1][1] * v[2][2] - v[1][2] * v[2][1]) -
                     v[0][1] * (v[1][0] * v[2][2] - v[1][2] * v[2][0]) +
                     v[0][2] * (v[1][0] * v[2][1] - v[1][1] * v[2][0]);
        double d01 = v[0][0] * v[1][0] + v[0][1] * v[1][1] + v[0][2] * v[1][2];
        double d02 = v[0][0] * v[2][0] + v[0][1] * v[2][1] + v[0][2] * v[2][2];
        double d12 = v[1][0] * v[2][0] + v[1][1] * v[2][1] + v[1][2] * v[2][2];
        sum += 2.0 * atan2(det, l[0] * l[1] * l[2] + d01 * l[2] + d02 * l[1] + d12 * l[0]);
    }
    return sum / (4.0 * PI);
}

static float joint_weight(const cr_body_model *b, int32_t v, int joint) {
    for (int k = 0; k < 4; k++)
        if (b->skin_joint[4 * v + k] == joint) return b->skin_weight[4 * v + k];
    return 0.0f;
}

/* Weights: four per vertex, non-negative, summing to one, and smooth: along
 * every edge the weight vectors change by at most a bounded amount per metre.
 * The steepest designed blend, a smooth step 6 cm wide, trades two weights at
 * 1.5 / 0.06 per metre each; a hard switch between neighbours would show as
 * 2 / edge length, over 60 per metre with edges under 3 cm. */
static void check_weights(const cr_body_model *b) {
    const cr_mesh *m = b->rest;
    for (int32_t v = 0; v < m->nv; v++) {
        double sum = 0.0;
        for (int k = 0; k < 4; k++) {
            CR_CHECK(b->skin_weight[4 * v + k] >= 0.0f);
            CR_CHECK(b->skin_joint[4 * v + k] >= 0 && b->skin_joint[4 * v + k] < CR_NJOINTS);
            sum += b->skin_weight[4 * v + k];
        }
        CR_CHECK_NEAR(sum, 1.0, 1e-6);
    }
    cr_error err = {0};
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    if (!t) return;
    double worst = 0.0, longest = 0.0;
    for (int32_t e = 0; e < t->ne; e++) {
        int32_t a = t->edge[2 * e], c = t->edge[2 * e + 1];
        double d = 0.0, len2 = 0.0;
        for (int j = 0; j < CR_NJOINTS; j++)
            d += fabs(joint_weight(b, a, j) - joint_weight(b, c, j));
        for (int k = 0; k < 3; k++) {
            double x = (double)m->pos[3 * a + k] - m->pos[3 * c + k];
            len2 += x * x;
        }
        worst = fmax(worst, d / sqrt(len2));
        longest = fmax(longest, sqrt(len2));
    }
    printf("    steepest weight change: %.1f per metre (L1; longest edge %.3f m)\n", worst,
           longest);
    CR_CHECK(longest < 0.03);
    CR_CHECK(worst < 2.0 * 1.5 / 0.06 * 1.1);
    cr_topology_destroy(t);
}

/* The default body: everything the issue asks of the rest mesh. */
CR_TEST(body, mannequin_default_mesh) {
    double t0 = cr_time_now();
    cr_body_model *b = make_body(0, NULL);
    double seconds = cr_time_now() - t0;
    CR_REQUIRE(b);
    const cr_mesh *m = b->rest;
    printf("    mannequin: %d vertices, %d faces, %.3f s\n", m->nv, m->nf, seconds);
    CR_CHECK(m->nv >= 7000 && m->nv <= 12000);
    cr_error err = {0};
    CR_CHECK_OK(cr_body_model_validate(b, "mannequin", &err), &err);
    cr_topology *t = NULL;
    CR_CHECK_OK(cr_topology_build(m, &t, &err), &err);
    CR_REQUIRE(t);
    CR_CHECK_OK(cr_topology_require_manifold(t, "mannequin", &err), &err);
    CR_CHECK(t->n_boundary_edges == 0);
    CR_CHECK(cr_topology_euler_characteristic(t) == 2); /* one closed genus-0 surface */

    /* Height, soles on the ground, +Y up. */
    float lo[3], hi[3];
    cr_mesh_bounds(m, lo, hi);
    CR_CHECK(lo[1] == 0.0f);
    CR_CHECK_NEAR(hi[1], 1.75, 0.005);
    int32_t on_ground = 0, toe = -1, heel = -1, top = 0, tip = 0;
    for (int32_t v = 0; v < m->nv; v++) {
        const float *p = &m->pos[3 * v];
        on_ground += p[1] < 1e-4f;
        if (p[1] < 0.1f && (toe < 0 || p[2] > m->pos[3 * toe + 2])) toe = v;
        if (p[1] < 0.1f && (heel < 0 || p[2] < m->pos[3 * heel + 2])) heel = v;
        if (p[1] > m->pos[3 * top + 1]) top = v;
        if (p[0] > m->pos[3 * tip]) tip = v;
    }
    CR_CHECK(on_ground > 50); /* flat soles */
    /* Facing +Z: toes well in front of the ankles, heels just behind. */
    CR_CHECK(m->pos[3 * toe + 2] > 0.12f);
    CR_CHECK(m->pos[3 * heel + 2] > -0.15f && m->pos[3 * heel + 2] < -0.05f);
    /* Left on +X; arms 40 degrees below horizontal. */
    const float *S = &b->joints[3 * CR_JOINT_LEFT_SHOULDER],
                *E = &b->joints[3 * CR_JOINT_LEFT_ELBOW];
    CR_CHECK(S[0] > 0.1f && b->joints[3 * CR_JOINT_RIGHT_SHOULDER] < -0.1f);
    CR_CHECK_NEAR(atan2(S[1] - E[1], E[0] - S[0]) * 180.0 / PI, 40.0, 0.01);
    CR_CHECK(m->pos[3 * tip] > 0.6f);
    /* Every joint inside the body. */
    for (int j = 0; j < CR_NJOINTS; j++) {
        double wn = winding_number(m, &b->joints[3 * j]);
        if (fabs(wn - 1.0) > 1e-3)
            printf("    joint %s: winding number %g\n", cr_joint_name[j], wn);
        CR_CHECK_NEAR(wn, 1.0, 1e-3);
    }
    /* A human volume (about 70 litres), outward orientation. */
    double vol = mesh_volume(m);
    printf("    volume %.1f litres\n", vol * 1e3);
    CR_CHECK(vol > 0.05 && vol < 0.10);
    /* Triangles fit for physics. */
    cr_quality_stats q;
    CR_CHECK_OK(cr_mesh_quality_stats(m, &q, &err), &err);
    printf("    min angle %.1f deg, %.2f%% above 20 deg\n", q.min_deg, 100.0 * q.frac_above_20);
    CR_CHECK(q.frac_above_20 > 0.99f);
    CR_CHECK(q.min_deg > 5.0f);
    CR_CHECK(m->normal != NULL);
    check_weights(b);
    /* Parts where they belong. */
    CR_CHECK(joint_weight(b, top, CR_JOINT_HEAD) > 0.99f);
    CR_CHECK(joint_weight(b, tip, CR_JOINT_LEFT_WRIST) > 0.99f);
    CR_CHECK(joint_weight(b, toe, CR_JOINT_LEFT_FOOT) + joint_weight(b, toe, CR_JOINT_RIGHT_FOOT) >
             0.99f);
    cr_topology_destroy(t);
    cr_body_model_destroy(b);
}

CR_TEST(body, skinning_rest_rigid_and_elbow) {
    cr_body_model *b = make_body(64, NULL);
    CR_REQUIRE(b);
    const cr_mesh *m = b->rest;
    cr_error err = {0};
    float pose[CR_NJOINTS * 3] = {0};
    float *out = malloc((size_t)m->nv * 3 * sizeof(float));
    CR_REQUIRE(out);
    /* The zero pose reproduces the rest mesh bit for bit. */
    CR_CHECK_OK(cr_body_pose(b, pose, NULL, out, &err), &err);
    CR_CHECK(memcmp(out, m->pos, (size_t)m->nv * 3 * sizeof(float)) == 0);

    /* A global rotation of 90 degrees about +y about the pelvis plus a
     * translation moves the whole body rigidly: (x, y, z) -> (z, y, -x). */
    pose[1] = (float)(PI / 2);
    const float trans[3] = {0.5f, 0.1f, -0.2f};
    const float *P = &b->joints[0];
    CR_CHECK_OK(cr_body_pose(b, pose, trans, out, &err), &err);
    double worst = 0.0;
    for (int32_t v = 0; v < m->nv; v++) {
        const float *x = &m->pos[3 * v];
        double want[3] = {P[0] + (x[2] - P[2]) + trans[0], x[1] + trans[1],
                          P[2] - (x[0] - P[0]) + trans[2]};
        for (int d = 0; d < 3; d++)
            worst = fmax(worst, fabs(out[3 * v + d] - want[d]));
    }
    CR_CHECK(worst < 2e-6);

    /* Left elbow bent 90 degrees about +z. By hand: the elbow's subtree
     * (elbow, wrist) turns about the elbow, (dx, dy) -> (-dy, dx), and every
     * other joint stays, so a vertex moves by its subtree weight times that
     * displacement. Hand vertices follow the forearm rigidly. */
    memset(pose, 0, sizeof pose);
    pose[3 * CR_JOINT_LEFT_ELBOW + 2] = (float)(PI / 2);
    CR_CHECK_OK(cr_body_pose(b, pose, NULL, out, &err), &err);
    const float *E = &b->joints[3 * CR_JOINT_LEFT_ELBOW];
    int32_t hand = 0;
    worst = 0.0;
    for (int32_t v = 0; v < m->nv; v++) {
        const float *x = &m->pos[3 * v];
        double w =
            joint_weight(b, v, CR_JOINT_LEFT_ELBOW) + joint_weight(b, v, CR_JOINT_LEFT_WRIST);
        double moved[3] = {E[0] - (x[1] - E[1]), E[1] + (x[0] - E[0]), x[2]};
        for (int d = 0; d < 3; d++)
            worst = fmax(worst, fabs(out[3 * v + d] - (x[d] + w * (moved[d] - x[d]))));
        hand += joint_weight(b, v, CR_JOINT_LEFT_WRIST) > 0.999f;
    }
    CR_CHECK(hand > 20);
    CR_CHECK(worst < 2e-6);
    free(out);
    cr_body_model_destroy(b);
}

/* Area of each face after posing over its rest area, for faces with a
 * corner within `radius` of `centre`: min and max. */
static void area_ratios(const cr_mesh *m, const float *posed, const float *centre, float radius,
                        double *lo, double *hi) {
    *lo = INFINITY, *hi = 0.0;
    for (int32_t f = 0; f < m->nf; f++) {
        int near = 0;
        for (int k = 0; k < 3; k++) {
            const float *p = &m->pos[3 * m->tri[3 * f + k]];
            float d[3] = {p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]};
            near |= d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < radius * radius;
        }
        if (!near) continue;
        const int32_t *t = &m->tri[3 * f];
        float n[3];
        double a0 = cr_triangle_normal(&m->pos[3 * t[0]], &m->pos[3 * t[1]], &m->pos[3 * t[2]], n);
        double a1 = cr_triangle_normal(&posed[3 * t[0]], &posed[3 * t[1]], &posed[3 * t[2]], n);
        *lo = fmin(*lo, a1 / a0), *hi = fmax(*hi, a1 / a0);
    }
}

/* Faces whose posed normal points against their rest normal turned by the
 * weights' blend of their corners' rotations: folded-over triangles. */
static int32_t flipped_faces(const cr_body_model *b, const float *pose, const float *posed) {
    const cr_mesh *m = b->rest;
    float xf[CR_NJOINTS * 12];
    cr_body_skin_transforms(b->joints, pose, NULL, xf);
    int32_t flips = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *t = &m->tri[3 * f];
        float n0[3], n1[3], R[9] = {0};
        cr_triangle_normal(&m->pos[3 * t[0]], &m->pos[3 * t[1]], &m->pos[3 * t[2]], n0);
        cr_triangle_normal(&posed[3 * t[0]], &posed[3 * t[1]], &posed[3 * t[2]], n1);
        for (int k = 0; k < 3; k++)
            for (int q = 0; q < 4; q++) {
                const float *M = &xf[12 * b->skin_joint[4 * t[k] + q]];
                float w = b->skin_weight[4 * t[k] + q] / 3.0f;
                for (int r = 0; r < 3; r++)
                    for (int c = 0; c < 3; c++)
                        R[3 * r + c] += w * M[4 * r + c];
            }
        double dot = 0.0;
        for (int r = 0; r < 3; r++)
            dot += (double)n1[r] * (R[3 * r] * n0[0] + R[3 * r + 1] * n0[1] + R[3 * r + 2] * n0[2]);
        flips += dot <= 0.0;
    }
    return flips;
}

typedef struct joint_case {
    const char *what;
    int joint;       /* measured around this joint */
    float radius;    /* m */
    float rot[3][4]; /* up to three (joint, axis-angle) rotations; joint -1 ends */
    double lo, hi;   /* bounds on the face area ratios near the joint */
} joint_case;

/* Poses a garment motion reaches must not fold triangles over or collapse
 * them near the joint: the symptoms of bad weights (candy-wrapping, volume
 * loss). Arms: raised by 90 degrees (to 50 degrees above horizontal) with
 * the shoulder alone, and with the collar taking a third as real shoulders
 * do; hips: flexed 60 degrees (a running stride), extended and abducted 45.
 * The bounds leave room for the compression a bend puts on its inner side. */
CR_TEST(body, raised_arms_and_moved_hips_keep_triangles) {
    cr_body_model *b = make_body(64, NULL);
    CR_REQUIRE(b);
    const cr_mesh *m = b->rest;
    cr_error err = {0};
    float *out = malloc((size_t)m->nv * 3 * sizeof(float));
    CR_REQUIRE(out);
    const float q = (float)(PI / 2), t = (float)(PI / 3), s = (float)(PI / 6), e = (float)(PI / 4);
    const joint_case cases[] = {
        {"shoulder raise 90",
         CR_JOINT_LEFT_SHOULDER,
         0.15f,
         {{CR_JOINT_LEFT_SHOULDER, 0, 0, q}, {CR_JOINT_RIGHT_SHOULDER, 0, 0, -q}, {-1}},
         0.05,
         3.0},
        {"collar 30 + shoulder 60",
         CR_JOINT_LEFT_SHOULDER,
         0.15f,
         {{CR_JOINT_LEFT_COLLAR, 0, 0, s}, {CR_JOINT_LEFT_SHOULDER, 0, 0, t}, {-1}},
         0.3,
         3.0},
        {"hip flexion 60",
         CR_JOINT_LEFT_HIP,
         0.2f,
         {{CR_JOINT_LEFT_HIP, -t, 0, 0}, {-1}},
         0.1,
         3.0},
        {"hip extension 45",
         CR_JOINT_LEFT_HIP,
         0.2f,
         {{CR_JOINT_LEFT_HIP, e, 0, 0}, {-1}},
         0.2,
         3.0},
        {"hip abduction 45",
         CR_JOINT_LEFT_HIP,
         0.2f,
         {{CR_JOINT_LEFT_HIP, 0, 0, e}, {-1}},
         0.2,
         3.0},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        float pose[CR_NJOINTS * 3] = {0};
        for (int k = 0; k < 3 && cases[c].rot[k][0] >= 0; k++)
            for (int d = 0; d < 3; d++)
                pose[3 * (int)cases[c].rot[k][0] + d] = cases[c].rot[k][1 + d];
        CR_CHECK_OK(cr_body_pose(b, pose, NULL, out, &err), &err);
        int finite = 1;
        for (int64_t i = 0; i < 3 * (int64_t)m->nv; i++)
            finite &= isfinite(out[i]) != 0;
        CR_CHECK(finite);
        double lo, hi;
        area_ratios(m, out, &b->joints[3 * cases[c].joint], cases[c].radius, &lo, &hi);
        int32_t flips = flipped_faces(b, pose, out);
        printf("    %s: face area ratios %.3f .. %.3f, %d folded\n", cases[c].what, lo, hi, flips);
        CR_CHECK(flips == 0);
        CR_CHECK(lo > cases[c].lo && hi < cases[c].hi);
    }
    free(out);
    cr_body_model_destroy(b);
}

CR_TEST(body, pose_motion_matches_single_poses) {
    cr_body_model *b = make_body(64, NULL);
    CR_REQUIRE(b);
    cr_error err = {0};
    cr_motion *mo = NULL;
    CR_CHECK_OK(cr_motion_create(3, 30.0f, &mo, &err), &err);
    CR_REQUIRE(mo);
    for (int t = 0; t < 3; t++) {
        mo->poses[t * CR_NJOINTS * 3 + 3 * CR_JOINT_LEFT_KNEE] = 0.4f * t;
        mo->poses[t * CR_NJOINTS * 3 + 3 * CR_JOINT_SPINE2 + 1] = -0.2f * t;
        mo->trans[3 * t + 2] = 0.1f * t;
    }
    float *seq = NULL;
    CR_CHECK_OK(cr_body_pose_motion(b, mo, &seq, &err), &err);
    CR_REQUIRE(seq);
    int32_t nv = b->rest->nv;
    float *one = malloc((size_t)nv * 3 * sizeof(float));
    CR_REQUIRE(one);
    for (int t = 0; t < 3; t++) {
        CR_CHECK_OK(cr_body_pose(b, &mo->poses[t * CR_NJOINTS * 3], &mo->trans[3 * t], one, &err),
                    &err);
        CR_CHECK(memcmp(one, &seq[(size_t)t * nv * 3], (size_t)nv * 3 * sizeof(float)) == 0);
    }
    free(seq);
    mo->poses[2 * CR_NJOINTS * 3 + 5] = NAN;
    CR_CHECK(cr_body_pose_motion(b, mo, &seq, &err) == CR_ERR_NAN && seq == NULL);
    CR_CHECK(strstr(err.msg, "frame 2") != NULL);
    mo->poses[2 * CR_NJOINTS * 3 + 5] = 0.0f;
    mo->trans[4] = INFINITY;
    CR_CHECK(cr_body_pose(b, mo->poses, &mo->trans[3], one, &err) == CR_ERR_NAN);
    free(one);
    cr_motion_destroy(mo);
    cr_body_model_destroy(b);
}

/* Depth of the torso at a height: the z extent of vertices within 1 cm of y
 * and 3 cm of the midline x = 0. */
static float depth_at(const cr_mesh *m, float y) {
    float lo = INFINITY, hi = -INFINITY;
    for (int32_t v = 0; v < m->nv; v++) {
        const float *p = &m->pos[3 * v];
        if (fabsf(p[1] - y) < 0.01f && fabsf(p[0]) < 0.03f)
            lo = fminf(lo, p[2]), hi = fmaxf(hi, p[2]);
    }
    return hi - lo;
}

CR_TEST(body, shape_parameters) {
    cr_error err = {0};
    cr_body_model *slim = make_body(64, "slim"), *normal = make_body(64, "normal"),
                  *heavy = make_body(64, "heavy");
    CR_REQUIRE(slim && normal && heavy);
    double vs = mesh_volume(slim->rest), vn = mesh_volume(normal->rest),
           vh = mesh_volume(heavy->rest);
    printf("    volumes: slim %.1f, normal %.1f, heavy %.1f litres\n", vs * 1e3, vn * 1e3,
           vh * 1e3);
    CR_CHECK(vs < 0.9 * vn && vh > 1.2 * vn);
    cr_body_model_destroy(slim);
    cr_body_model_destroy(heavy);

    cr_mannequin_def def = cr_mannequin_default_def();
    def.resolution = 64;
    def.height_m = 1.6f;
    def.chest = 1.2f;
    def.hips = 1.2f;
    cr_body_model *b = NULL;
    CR_CHECK_OK(cr_mannequin_create(&def, &b, &err), &err);
    CR_REQUIRE(b);
    float lo[3], hi[3];
    cr_mesh_bounds(b->rest, lo, hi);
    CR_CHECK_NEAR(hi[1] - lo[1], 1.6, 0.01);
    /* Chest and hips measured at the scaled heights of their sections. */
    float k = 1.6f / 1.75f;
    CR_CHECK(depth_at(b->rest, 1.30f * k) > 1.12f * k * depth_at(normal->rest, 1.30f));
    CR_CHECK(depth_at(b->rest, 0.93f * k) > 1.12f * k * depth_at(normal->rest, 0.93f));
    CR_CHECK(depth_at(b->rest, 1.07f * k) < 1.05f * k * depth_at(normal->rest, 1.07f)); /* waist */
    CR_CHECK_OK(cr_body_model_validate(b, "tall", &err), &err);
    cr_body_model_destroy(b);
    cr_body_model_destroy(normal);
}

CR_TEST(body, bad_input) {
    cr_error err = {0};
    cr_mannequin_def def = cr_mannequin_default_def();
    CR_CHECK(cr_mannequin_preset("athletic", &def, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "athletic") != NULL);
    cr_body_model *b = NULL;
    def.height_m = 3.0f;
    CR_CHECK(cr_mannequin_create(&def, &b, &err) == CR_ERR_INVALID && b == NULL);
    CR_CHECK(strstr(err.msg, "height_m") != NULL);
    def = cr_mannequin_default_def();
    def.girth = NAN;
    CR_CHECK(cr_mannequin_create(&def, &b, &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "girth") != NULL);
    def = cr_mannequin_default_def();
    def.resolution = 10;
    CR_CHECK(cr_mannequin_create(&def, &b, &err) == CR_ERR_INVALID);
    /* Too coarse for thin wrists: refused rather than returned in pieces. */
    def.resolution = 40;
    def.girth = 0.7f;
    CR_CHECK(cr_mannequin_create(&def, &b, &err) == CR_ERR_TOPOLOGY && b == NULL);
    CR_CHECK(strstr(err.msg, "resolution 40") != NULL);

    /* validate: weights that do not sum to one, joints out of range. */
    b = make_body(64, NULL);
    CR_REQUIRE(b);
    CR_CHECK_OK(cr_body_model_validate(b, "m", &err), &err);
    b->skin_weight[4 * 7] += 0.01f;
    CR_CHECK(cr_body_model_validate(b, "m", &err) == CR_ERR_INVALID);
    CR_CHECK(strstr(err.msg, "vertex 7") != NULL);
    b->skin_weight[4 * 7] -= 0.01f;
    b->skin_joint[4 * 9 + 1] = CR_NJOINTS;
    CR_CHECK(cr_body_model_validate(b, "m", &err) == CR_ERR_RANGE);
    b->skin_joint[4 * 9 + 1] = 0;
    b->joints[4] = NAN;
    CR_CHECK(cr_body_model_validate(b, "m", &err) == CR_ERR_NAN);
    cr_body_model_destroy(b);
    cr_body_model_destroy(NULL);
}
