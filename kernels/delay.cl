// Stage 3: the sync-to-optics delay, fitted period by period. The low-passed beat y of
// one period is regressed on the low-passed sync z moved by a lag, its derivative and a
// constant (Gauss-Newton, three steps from the row's coarse lag); one work-item per
// period of every row (the sync delay's stretches). Twin: fmcw_cl.stages.delay.fit_periods.
// Before it, from the low-pass's rows on the device: each row trimmed and its mean
// removed, and its coarse lag, the largest |cross-correlation| (twin: delay.period_delays).

// Each row of the low-passed beat (channel 0) and sync (channel 1), `edge` samples left
// out at each end, less its mean: a work-group a row of a channel, its work-items
// summing every lsz-th sample and then adding their sums in a tree (lsz a power of two).
// With one work-item a group (CPUs) the sum runs in the samples' order.
__kernel void delay_centre(__global const float *y,     // (rows, m): low-passed beat
                           __global const float *z,     // (rows, m): low-passed sync
                           const int m,
                           const int rows,
                           const int edge,
                           __global float *yz,          // (2, rows, n), n = m - 2 edge
                           __local real *part)          // (lsz,)
{
    const int g = get_group_id(0), lid = get_local_id(0), lsz = get_local_size(0);
    const int r = g < rows ? g : g - rows, n = m - 2 * edge;
    __global const float *x = (g < rows ? y : z) + (size_t)r * m + edge;
    real sum = 0;
    for (int i = lid; i < n; i += lsz) sum += (real)x[i];
    part[lid] = sum;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int s = lsz / 2; s > 0; s /= 2) {
        if (lid < s) part[lid] += part[lid + s];
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    const real mean = part[0] / (real)n;
    __global float *o = yz + (size_t)g * n;
    for (int i = lid; i < n; i += lsz) o[i] = (float)((real)x[i] - mean);
}

// The cross-correlation of each row's sync with its beat's middle: c[r, k] = sum_i
// z[r, i + k] y[r, span + i], i < n - 2 span, k = 0 .. 2 span (numpy.correlate's
// "valid"); a work-item a lag of a row. Eight products at a time, flushed to `real`
// every 256 samples.
__kernel void delay_correlate(__global const float *yz, // (2, rows, n)
                              const int n,
                              const int rows,
                              const int span,
                              __global real *c)         // (rows, 2 span + 1)
{
    const int lags = 2 * span + 1;
    const int g = get_global_id(0);
    if (g >= rows * lags) return;
    const int r = g / lags, k = g - r * lags, len = n - 2 * span;
    __global const float *a = yz + (size_t)r * n + span;
    __global const float *b = yz + (size_t)(rows + r) * n + k;
    real acc = 0;
    int i = 0;
    while (i + 8 <= len) {
        float8 block = 0.0f;
        const int end = min(len, i + 256);
        for (; i + 8 <= end; i += 8) block += vload8(0, a + i) * vload8(0, b + i);
        acc += (real)block.s0 + block.s1 + block.s2 + block.s3 + block.s4 + block.s5 + block.s6 + block.s7;
    }
    for (; i < len; ++i) acc += (real)a[i] * b[i];
    c[g] = acc;
}

// Each row's coarse lag: the lag of its largest |c| (the first of equals), less span.
__kernel void delay_coarse(__global const real *c,      // (rows, 2 span + 1)
                           const int rows,
                           const int span,
                           __global float *coarse)      // (rows,)
{
    const int r = get_global_id(0);
    if (r >= rows) return;
    const int lags = 2 * span + 1;
    int best = 0;
    for (int k = 1; k < lags; ++k)
        if (fabs(c[(size_t)r * lags + k]) > fabs(c[(size_t)r * lags + best])) best = k;
    coarse[r] = (float)(best - span);
}

// z at sample i + t of a row of n (t in [0, 1)): linear between samples, held at the
// ends (np.interp on the sample grid). The whole and fractional samples are apart: a
// float sample index near 40000 resolves only 0.004 samples.
float at(__global const float *z, const int n, const int i, const float t)
{
    if (i < 0) return z[0];
    if (i >= n - 1) return z[n - 1];
    return z[i] + t * (z[i + 1] - z[i]);
}

// The template moved by s + t samples, walked along a period of `len` samples from
// sample w of the row: its values at points k - 1, k and k + 1, each computed once; at
// the period's ends the missing neighbour is the point itself.
typedef struct {
    float before, here, after;
} Walk;

Walk walk_start(__global const float *z, const int n, const int w, const int len, const int s, const float t)
{
    Walk v;
    v.here = at(z, n, w + s, t);
    v.before = v.here;
    v.after = len > 1 ? at(z, n, w + s + 1, t) : v.here;
    return v;
}

// The template (zs) and its derivative along the period (dz, np.gradient's: one-sided at
// the ends) at point k.
void walk_point(const Walk v, const int k, const int len, float *zs, float *dz)
{
    *zs = v.here;
    *dz = (k > 0 && k + 1 < len) ? 0.5f * (v.after - v.before) : v.after - v.before;
}

// From point k to k + 1.
void walk_next(__global const float *z, const int n, const int w, const int len, const int s, const float t,
               const int k, Walk *v)
{
    v->before = v->here;
    v->here = v->after;
    v->after = k + 2 < len ? at(z, n, w + s + k + 2, t) : v->here;
}

__kernel void delay_fit(__global const float *yz,     // (2, rows, n): beat, sync; each row's mean removed
                        const int n,
                        const int rows,
                        const int periods,            // periods a row
                        const int len,                // samples a period
                        const int span,               // the first period's first sample
                        __global const float *coarse, // (rows,) the row's coarse lag
                        __global float *out)          // (2, rows, periods): lag (NaN: no
                                                      // triangle), misfit
{
    const int g = get_global_id(0);
    if (g >= rows * periods) return;
    const int r = g / periods;
    const int w = span + (g - r * periods) * len;
    __global const float *yr = yz + (size_t)r * n;
    __global const float *zr = yz + (size_t)(rows + r) * n;
    float shift = coarse[r], c0 = 0.0f, c1 = 0.0f, c2 = 0.0f, step = 0.0f;
    int s = 0;
    float t = 0.0f;
    for (int it = 0; it < 3; ++it) {
        s = (int)floor(shift);
        t = shift - floor(shift);
        // the normal equations of (1, zs, dz): sums over the period
        float sz = 0.0f, sd = 0.0f, szz = 0.0f, szd = 0.0f, sdd = 0.0f, sy = 0.0f, szy = 0.0f, sdy = 0.0f;
        Walk v = walk_start(zr, n, w, len, s, t);
        for (int k = 0; k < len; ++k) {
            float zs, dz;
            walk_point(v, k, len, &zs, &dz);
            walk_next(zr, n, w, len, s, t, k, &v);
            const float yk = yr[w + k];
            sz += zs;
            sd += dz;
            szz += zs * zs;
            szd += zs * dz;
            sdd += dz * dz;
            sy += yk;
            szy += zs * yk;
            sdy += dz * yk;
        }
        // the 3x3 symmetric system by elimination (the template is nearly orthogonal to
        // its derivative and the constant over a period: well conditioned)
        const float a00 = (float)len, m1 = sz / a00, m2 = sd / a00;
        const float a11 = szz - m1 * sz, a12 = szd - m1 * sd, b1 = szy - m1 * sy;
        const float a21 = szd - m2 * sz, a22 = sdd - m2 * sd, b2 = sdy - m2 * sy;
        const float m3 = a21 / a11;
        c2 = (b2 - m3 * b1) / (a22 - m3 * a12);
        c1 = (b1 - a12 * c2) / a11;
        c0 = (sy - sz * c1 - sd * c2) / a00;
        step = fabs(c1) > 0.0f ? c2 / c1 : NAN;
        // a step that is not finite is not taken, and none leaves the row (numpy's
        // nan_to_num moves an overflowing one to the float's end: no lag either way)
        if (isfinite(step)) shift = fmin(fmax(shift + step, (float)-n), (float)n);
    }
    float rr = 0.0f, tt = 0.0f;                 // the last step's residual and triangle
    Walk v = walk_start(zr, n, w, len, s, t);
    for (int k = 0; k < len; ++k) {
        float zs, dz;
        walk_point(v, k, len, &zs, &dz);
        walk_next(zr, n, w, len, s, t, k, &v);
        const float e = yr[w + k] - (c0 + c1 * zs + c2 * dz);
        rr += e * e;
        tt += (c1 * zs) * (c1 * zs);
    }
    out[g] = isfinite(step) ? shift : NAN;
    out[rows * periods + g] = sqrt(rr / tt);
}
