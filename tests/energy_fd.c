/* energy_fd.c: see energy_fd.h. */
#include "energy_fd.h"

#include <math.h>
#include <string.h>

double fd_kval(const cr_energy_term *t, int32_t e, const double *x) {
    return t->kernel(t->data, e, x, NULL, NULL);
}

double fd_max_abs(const double *a, int n) {
    double m = 0.0;
    for (int i = 0; i < n; i++)
        m = fmax(m, fabs(a[i]));
    return m;
}

double fd_grad_rel_error(const cr_energy_term *t, int32_t e, const double *x0, double h) {
    const int n = 3 * t->nvert;
    double x[3 * CR_ENERGY_MAX_VERTS], g[3 * CR_ENERGY_MAX_VERTS], err = 0.0;
    t->kernel(t->data, e, x0, g, NULL);
    memcpy(x, x0, sizeof(double) * (size_t)n);
    for (int i = 0; i < n; i++) {
        x[i] = x0[i] + h;
        const double ep = fd_kval(t, e, x);
        x[i] = x0[i] - h;
        const double em = fd_kval(t, e, x);
        x[i] = x0[i];
        err = fmax(err, fabs(g[i] - (ep - em) / (2.0 * h)));
    }
    return err / fmax(fd_max_abs(g, n), 1e-300);
}

fd_block_errors fd_vertex_block_errors(const cr_energy_term *t, int32_t e, const double *x0,
                                       double h) {
    enum { N = 3 * CR_ENERGY_MAX_VERTS };
    const int n = 3 * t->nvert;
    fd_block_errors r = {0.0, 0.0, 0.0, 0.0, 1};
    double g[N], H[N * N], x[N];
    const double v = t->kernel(t->data, e, x0, g, H);
    const double gs = fmax(fd_max_abs(g, n), 1e-300), hs = fmax(fd_max_abs(H, n * n), 1e-300);
    for (int k = 0; k < t->nvert; k++) {
        double gb[3], Hb[9], gp[3], gm[3];
        const double vb = t->vertex_block(t->data, e, k, x0, gb, Hb);
        r.value_same =
            r.value_same && vb == v && t->vertex_block(t->data, e, k, x0, NULL, NULL) == v;
        memcpy(x, x0, sizeof(double) * (size_t)n);
        for (int a = 0; a < 3; a++) {
            r.grad = fmax(r.grad, fabs(gb[a] - g[3 * k + a]) / gs);
            for (int c = 0; c < 3; c++)
                r.hess = fmax(r.hess, fabs(Hb[3 * a + c] - H[(3 * k + a) * n + 3 * k + c]) / hs);
            const int i = 3 * k + a;
            x[i] = x0[i] + h;
            const double ep = t->vertex_block(t->data, e, k, x, gp, NULL);
            x[i] = x0[i] - h;
            const double em = t->vertex_block(t->data, e, k, x, gm, NULL);
            x[i] = x0[i];
            r.fd_grad = fmax(r.fd_grad, fabs(gb[a] - (ep - em) / (2.0 * h)) / gs);
            for (int c = 0; c < 3; c++)
                r.fd_hess = fmax(r.fd_hess, fabs(Hb[3 * c + a] - (gp[c] - gm[c]) / (2.0 * h)) / hs);
        }
    }
    return r;
}
