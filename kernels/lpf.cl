// Stage 1: the low-pass that keeps the laser intensity triangle of the beat channel,
// at the decimated rate only (a full-rate FIR would cost more than everything else).
// Twin: fmcw_cl.stages.lpf.intensity.

// Three cascaded boxcars of `factor` samples, kept every `factor`-th output (a CIC
// decimator, sinc^3): out[j] = sum_k h[k] x[j factor + k], h the boxcars' convolution.
__kernel void cic_decimate(__global const short *x,
                           __global const float *h,     // (taps,)
                           const int taps,
                           const int factor,
                           __global float *out)
{
    const int j = get_global_id(0);
    __global const short *p = x + (size_t)j * factor;
    float acc = 0.0f;
    for (int k = 0; k < taps; ++k) acc += h[k] * (float)p[k];
    out[j] = acc;
}

// Symmetric (zero-phase) FIR, centred, zero outside [0, n): numpy.convolve(..., "same").
__kernel void fir_same(__global const float *x,
                       const int n,
                       __global const float *taps,      // (2 half + 1,)
                       const int half_taps,
                       __global float *out)
{
    const int j = get_global_id(0);
    const int a = j - half_taps < 0 ? half_taps - j : 0;
    const int b = j + half_taps >= n ? half_taps + (n - 1 - j) : 2 * half_taps;
    float acc = 0.0f;
    for (int t = a; t <= b; ++t) acc += taps[t] * x[j + t - half_taps];
    out[j] = acc;
}
