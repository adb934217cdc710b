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
