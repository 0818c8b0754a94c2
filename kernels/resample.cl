// Stage 4: resample half-sweeps at the instants of uniform optical frequency.
// One work-group per half-sweep; work-items stride over the N points.
// Cubic convolution (Keys, a = -0.5) straight from the int16 codes, then mean
// removal (a local-memory reduction) and the window. Plain scalar a*b+c code:
// PoCL vectorises across work-items, and its fma/mad builtins are slow.
// Positions: start + u_j L = base + lut_int_j + (offset + lut_frac_j + u_j dlen), where
// lut_int + lut_frac = u_j L0 was split in float64 on the host and dlen = L - L0 is tiny,
// so float32 keeps 1e-6 sample precision (u_j L in float32 would lose 2e-4).

__kernel void resample(__global const short *codes,
                       __global const int *base,      // integer sample of each sweep start
                       __global const float *offset,  // start - base, in [0, 1)
                       __global const float *dlen,    // length - L0, samples
                       __global const int *lut_int,   // floor(u_j L0)
                       __global const float *lut_frac,// u_j L0 - floor(u_j L0)
                       __global const float *u,       // LUT: fractions of the half-sweep
                       __global const float *win,     // window
                       const int points,
                       __global float *out,           // (sweeps, points)
                       __local float *scratch)
{
    const int s = get_group_id(0);
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    const int b = base[s];
    const float off = offset[s];
    const float dl = dlen[s];
    __global float *row = out + (size_t)s * points;
    float acc = 0.0f;
    for (int j = lid; j < points; j += lsz) {
        const float p = off + lut_frac[j] + u[j] * dl;
        const int i = (int)(p + 16.0f) - 16;    // floor for p > -16 (PoCL's floor() is slow)
        const float f = p - (float)i;
        const int k = b + lut_int[j] + i;
        const float f2 = f * f;
        const float f3 = f2 * f;
        const float y = (-0.5f * f3 + f2 - 0.5f * f) * (float)codes[k - 1]
                      + (1.5f * f3 - 2.5f * f2 + 1.0f) * (float)codes[k]
                      + (-1.5f * f3 + 2.0f * f2 + 0.5f * f) * (float)codes[k + 1]
                      + (0.5f * f3 - 0.5f * f2) * (float)codes[k + 2];
        row[j] = y;
        acc += y;
    }
    scratch[lid] = acc;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int w = lsz / 2; w > 0; w >>= 1) {
        if (lid < w) scratch[lid] += scratch[lid + w];
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    const float mean = scratch[0] / (float)points;
    // each work-item rewrites only the points it wrote: no global barrier needed
    for (int j = lid; j < points; j += lsz) row[j] = (row[j] - mean) * win[j];
}
