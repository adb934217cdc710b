/* ssim.c: the structural similarity index of two images (Wang, Bovik,
 * Sheikh, Simoncelli, "Image quality assessment: from error visibility to
 * structural similarity", IEEE TIP 2004, eq. 13 with the paper's constants:
 * an 11x11 circular-symmetric Gaussian window of sigma 1.5, K1 = 0.01,
 * K2 = 0.03), per channel, averaged over the channels and over a mask:
 *
 *   SSIM(x, y) = (2 mu_x mu_y + C1)(2 sigma_xy + C2)
 *              / ((mu_x^2 + mu_y^2 + C1)(sigma_x^2 + sigma_y^2 + C2))
 *
 * with local means, variances and covariance from the Gaussian window
 * (separable, borders replicated), C1 = (K1 L)^2, C2 = (K2 L)^2 and L the
 * value range. gdsr (paper 001, App. C) reports it on normal maps.
 *
 * Leaves out: the multi-scale variant, downsampling of large images.
 */
#include "crease/eval.h"

#include <math.h>
#include <stdlib.h>

enum { RADIUS = 5 }; /* 11 taps */
static const double SIGMA = 1.5, K1 = 0.01, K2 = 0.03;

/* Gaussian blur of src (H,W) into dst, separable, borders replicated; tmp (H,W). */
static void blur(const double *src, double *dst, double *tmp, int w, int h, const double *k) {
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double s = 0.0;
            for (int d = -RADIUS; d <= RADIUS; d++) {
                int xx = x + d < 0 ? 0 : x + d >= w ? w - 1 : x + d;
                s += k[d + RADIUS] * src[(size_t)y * w + xx];
            }
            tmp[(size_t)y * w + x] = s;
        }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double s = 0.0;
            for (int d = -RADIUS; d <= RADIUS; d++) {
                int yy = y + d < 0 ? 0 : y + d >= h ? h - 1 : y + d;
                s += k[d + RADIUS] * tmp[(size_t)yy * w + x];
            }
            dst[(size_t)y * w + x] = s;
        }
}

cr_status cr_eval_ssim(const float *a, const float *b, const uint8_t *mask, int width, int height,
                       int channels, float range, double *out, cr_error *err) {
    *out = NAN;
    if (width < 1 || height < 1 || channels < 1 || !(range > 0.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "ssim: %dx%dx%d image, range %g", width, height,
                       channels, (double)range);
    size_t n = (size_t)width * height;
    double *buf = cr_malloc(11 * n * sizeof(double), err);
    if (!buf) return CR_ERR_MEMORY;
    double *x = buf, *y = x + n, *xx = y + n, *yy = xx + n, *xy = yy + n;
    double *mx = xy + n, *my = mx + n, *mxx = my + n, *myy = mxx + n, *mxy = myy + n,
           *tmp = mxy + n;
    double k[2 * RADIUS + 1], ks = 0.0;
    for (int d = -RADIUS; d <= RADIUS; d++)
        ks += k[d + RADIUS] = exp(-(double)d * d / (2.0 * SIGMA * SIGMA));
    for (int d = 0; d < 2 * RADIUS + 1; d++)
        k[d] /= ks;
    const double c1 = (K1 * range) * (K1 * range), c2 = (K2 * range) * (K2 * range);
    double sum = 0.0;
    int64_t count = 0;
    for (int c = 0; c < channels; c++) {
        for (size_t i = 0; i < n; i++) {
            x[i] = a[i * channels + c], y[i] = b[i * channels + c];
            xx[i] = x[i] * x[i], yy[i] = y[i] * y[i], xy[i] = x[i] * y[i];
        }
        blur(x, mx, tmp, width, height, k), blur(y, my, tmp, width, height, k);
        blur(xx, mxx, tmp, width, height, k), blur(yy, myy, tmp, width, height, k);
        blur(xy, mxy, tmp, width, height, k);
        for (size_t i = 0; i < n; i++) {
            if (mask && !mask[i]) continue;
            double vx = mxx[i] - mx[i] * mx[i], vy = myy[i] - my[i] * my[i];
            double cxy = mxy[i] - mx[i] * my[i];
            sum += (2.0 * mx[i] * my[i] + c1) * (2.0 * cxy + c2) /
                   ((mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2));
            count++;
        }
    }
    free(buf);
    *out = count ? sum / (double)count : NAN;
    return CR_OK;
}
