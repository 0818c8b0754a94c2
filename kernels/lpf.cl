// Stage 1: the low-pass that keeps the laser intensity triangle of the beat channel,
// at the decimated rate only (a full-rate FIR would cost more than everything else).
// Each output is a dot product over contiguous inputs, taken eight at a time in float8
// (PoCL vectorises across work-items only where a kernel has no loop; these have one).
// Both take rows of one length (the sync delay's stretches, one launch for all), each
// filtered alone. Twin: fmcw_cl.stages.lpf.intensity.

// Three cascaded boxcars of `factor` samples, kept every `factor`-th output (a CIC
// decimator, sinc^3): out[j] = sum_k h[k] x[j factor + k], h the boxcars' convolution.
__kernel void cic_decimate(__global const short *x,     // (rows, stride)
                           __global const float *h,     // (taps,)
                           const int taps,
                           const int factor,
                           const int m,                 // outputs a row
                           const int rows,
                           const int stride,            // input samples a row
                           __global float *out)         // (rows, m)
{
    const int i = get_global_id(0);
    if (i >= rows * m) return;
    const int r = i / m, j = i - r * m;
    __global const short *p = x + (size_t)r * stride + (size_t)j * factor;
    float8 acc8 = 0.0f;
    int k = 0;
    for (; k + 8 <= taps; k += 8) acc8 += vload8(0, h + k) * convert_float8(vload8(0, p + k));
    float acc = 0.0f;
    for (; k < taps; ++k) acc += h[k] * (float)p[k];
    out[i] = acc + sum8(acc8);
}

// Symmetric (zero-phase) FIR, centred, zero outside each row's [0, n):
// numpy.convolve(..., "same") of every row.
__kernel void fir_same(__global const float *x,         // (rows, n)
                       const int n,
                       const int rows,
                       __global const float *taps,      // (2 half + 1,)
                       const int half_taps,
                       __global float *out)             // (rows, n)
{
    const int i = get_global_id(0);
    if (i >= rows * n) return;
    const int j = i - (i / n) * n;
    const int a = j - half_taps < 0 ? half_taps - j : 0;
    const int b = j + half_taps >= n ? half_taps + (n - 1 - j) : 2 * half_taps;
    __global const float *p = x + i - half_taps;
    float8 acc8 = 0.0f;
    int t = a;
    for (; t + 8 <= b + 1; t += 8) acc8 += vload8(0, taps + t) * vload8(0, p + t);
    float acc = 0.0f;
    for (; t <= b; ++t) acc += taps[t] * p[t];
    out[i] = acc + sum8(acc8);
}
