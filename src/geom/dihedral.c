/* dihedral.c: signed dihedral angles of hinges and their gradients.
 *
 * The angle is atan2 of the normals' cross product projected on the edge
 * against their dot product, with unnormalised normals (both arguments scale
 * by |NA||NB|, which atan2 ignores), so it stays accurate at 0 and at +-pi.
 * The gradient is the closed form of Bridson, Marino & Fedkiw, "Simulation
 * of clothing with folds and wrinkles" (SCA 2003, sec. 4.2) as written in
 * Tamstorf & Grinspun, "Discrete bending forces and their Jacobians" (2013):
 * only the normal component of an opposite vertex's motion turns its face,
 * by (motion / height); the edge vertices carry the reaction that makes the
 * gradient invariant under translation and rotation.
 *
 * Left out: the Hessian (Tamstorf & Grinspun eq. 11 onwards); bending energies
 * that need it live in phys/.
 */
#include "base/vec3.h"
#include "crease/diffgeo.h"

#include <math.h>
#include <string.h>

/* Shared by the value and the gradient: unnormalised normals NA of (x0,x1,x2)
 * and NB of (x1,x0,x3), the edge e = x1 - x0, and theta. Returns 0 (and
 * theta = 0) when a face or the edge is degenerate. */
typedef struct hinge_geom {
    double e[3], na[3], nb[3];
    double elen, na2, nb2;
    double theta;
} hinge_geom;

static int hinge_setup(const float x0[3], const float x1[3], const float x2[3], const float x3[3],
                       hinge_geom *g) {
    double a2[3], b0[3], b3[3];
    sub3fd(x1, x0, g->e);
    sub3fd(x2, x0, a2);
    sub3fd(x0, x1, b0);
    sub3fd(x3, x1, b3);
    cross3d(g->e, a2, g->na);
    cross3d(b0, b3, g->nb);
    g->elen = sqrt(dot3d(g->e, g->e));
    g->na2 = dot3d(g->na, g->na);
    g->nb2 = dot3d(g->nb, g->nb);
    g->theta = 0.0;
    if (g->elen == 0.0 || g->na2 == 0.0 || g->nb2 == 0.0) return 0;
    double c[3];
    cross3d(g->nb, g->na, c);
    g->theta = atan2(dot3d(c, g->e) / g->elen, dot3d(g->na, g->nb));
    return 1;
}

float cr_dihedral_angle(const float x0[3], const float x1[3], const float x2[3],
                        const float x3[3]) {
    hinge_geom g;
    hinge_setup(x0, x1, x2, x3, &g);
    return (float)g.theta;
}

float cr_dihedral_angle_grad(const float x0[3], const float x1[3], const float x2[3],
                             const float x3[3], float grad[12]) {
    hinge_geom g;
    if (!hinge_setup(x0, x1, x2, x3, &g)) {
        memset(grad, 0, 12 * sizeof(float));
        return 0.0f;
    }
    /* nA / hA = NA |e| / |NA|^2, since |NA| = |e| hA. */
    double sa = g.elen / g.na2, sb = g.elen / g.nb2;
    double d2[3] = {g.na[0] * sa, g.na[1] * sa, g.na[2] * sa};
    double d3[3] = {g.nb[0] * sb, g.nb[1] * sb, g.nb[2] * sb};
    double a2[3], a3[3];
    sub3fd(x2, x0, a2);
    sub3fd(x3, x0, a3);
    double e2 = g.elen * g.elen;
    double ta = dot3d(a2, g.e) / e2, tb = dot3d(a3, g.e) / e2;
    for (int d = 0; d < 3; d++) {
        grad[0 + d] = (float)(-(1.0 - ta) * d2[d] - (1.0 - tb) * d3[d]);
        grad[3 + d] = (float)(-ta * d2[d] - tb * d3[d]);
        grad[6 + d] = (float)d2[d];
        grad[9 + d] = (float)d3[d];
    }
    return (float)g.theta;
}

typedef struct hinge_ctx {
    const float *pos;
    const int32_t *hinge;
    float *theta;
} hinge_ctx;

static void hinge_range(void *vctx, int64_t begin, int64_t end) {
    const hinge_ctx *c = vctx;
    for (int64_t h = begin; h < end; h++) {
        const int32_t *x = &c->hinge[4 * h];
        c->theta[h] = cr_dihedral_angle(&c->pos[3 * (size_t)x[0]], &c->pos[3 * (size_t)x[1]],
                                        &c->pos[3 * (size_t)x[2]], &c->pos[3 * (size_t)x[3]]);
    }
}

void cr_mesh_hinge_angles(const cr_mesh *m, const cr_topology *t, float *theta) {
    CR_ASSERT(t->nv == m->nv);
    hinge_ctx c = {m->pos, t->hinge, theta};
    cr_parallel_for(t->nh, 4096, hinge_range, &c);
}
