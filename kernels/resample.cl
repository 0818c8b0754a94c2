// Stage 4: resample half-sweeps at the instants of uniform optical frequency.
// Cubic convolution (Keys, a = -0.5) straight from the int16 codes, then mean
// removal and the window. Plain a*b+c code: PoCL's fma/mad builtins are slow.
// Positions: start + u_j L = base + lut_int_j + (offset + lut_frac_j + u_j dlen), where
// lut_int + lut_frac = u_j L0 was split in float64 on the host and dlen = L - L0 is tiny,
// so float32 keeps 1e-6 sample precision (u_j L in float32 would lose 2e-4). Sweeps in
// runs (`runs` > 1: the chunks of one pass of the delay's trials) each have their run's
// L0 (`run`: each sweep's; the LUT split once a run, one table after another), so that a
// run's rows are those it would have alone.
// Two variants: `resample` (GPUs) a work-group per half-sweep, its work-items striding
// over the points; `resample_lanes` (CPUs) a work-item per half-sweep, eight points at a
// time in float8 lanes (PoCL vectorises across work-items only where a kernel has no
// loop, which this one has; 2-core EPYC: 2.3x faster than `resample` there).
// Twin: fmcw_cl.stages.resample.resample.

// The cubic-convolution value at fraction f past c1 of codes c0..c3.
#define KEYS(NAME, T)                                                              \
T NAME(const T f, const T c0, const T c1, const T c2, const T c3)                  \
{                                                                                  \
    const T f2 = f * f;                                                            \
    const T f3 = f2 * f;                                                           \
    return (-0.5f * f3 + f2 - 0.5f * f) * c0 + (1.5f * f3 - 2.5f * f2 + 1.0f) * c1 \
         + (-1.5f * f3 + 2.0f * f2 + 0.5f * f) * c2 + (0.5f * f3 - 0.5f * f2) * c3;  \
}
KEYS(keys, float)
KEYS(keys8, float8)

// Point j of the half-sweep starting at sample b + off, dl samples longer than nominal.
float point(__global const short *codes, const int b, const float off, const float dl,
            __global const int *lut_int, __global const float *lut_frac, __global const float *u,
            const int j)
{
    const float p = off + lut_frac[j] + u[j] * dl;
    const int i = (int)(p + 16.0f) - 16;    // floor for p > -16 (PoCL's floor() is slow)
    const int k = b + lut_int[j] + i;
    return keys(p - (float)i, codes[k - 1], codes[k], codes[k + 1], codes[k + 2]);
}

__kernel void resample(__global const short *codes,
                       __global const int *base,      // integer sample of each sweep start
                       __global const float *offset,  // start - base, in [0, 1)
                       __global const float *dlen,    // length - L0, samples
                       __global const int *lut_int,   // floor(u_j L0)
                       __global const float *lut_frac,// u_j L0 - floor(u_j L0)
                       __global const int *run,       // each sweep's run, read where runs > 1
                       const int runs,
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
    const size_t at = runs > 1 ? (size_t)run[s] * points : 0;
    __global float *row = out + (size_t)s * points;
    float acc = 0.0f;
    for (int j = lid; j < points; j += lsz) {
        const float y = point(codes, b, off, dl, lut_int + at, lut_frac + at, u, j);
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

// Codes k + d of the eight lanes of k, as floats (one vector built from eight loads:
// scalar stores read back as a vector would stall on store forwarding).
#define GATHER8(k, d)                                                                            \
    convert_float8((short8)(codes[k.s0 + d], codes[k.s1 + d], codes[k.s2 + d], codes[k.s3 + d],  \
                            codes[k.s4 + d], codes[k.s5 + d], codes[k.s6 + d], codes[k.s7 + d]))

__kernel void resample_lanes(__global const short *codes,
                             __global const int *base,
                             __global const float *offset,
                             __global const float *dlen,
                             __global const int *lut_int,
                             __global const float *lut_frac,
                             __global const int *run,
                             const int runs,
                             __global const float *u,
                             __global const float *win,
                             const int points,
                             __global float *out)
{
    const int s = get_global_id(0);
    const int b = base[s];
    const float off = offset[s];
    const float dl = dlen[s];
    const size_t at = runs > 1 ? (size_t)run[s] * points : 0;
    __global const int *li = lut_int + at;
    __global const float *lf = lut_frac + at;
    __global float *row = out + (size_t)s * points;
    const int whole = points & ~7;
    float8 acc = 0.0f;
    for (int j = 0; j < whole; j += 8) {
        const float8 p = off + vload8(0, lf + j) + vload8(0, u + j) * dl;
        const int8 i = convert_int8(p + 16.0f) - 16;      // floor, as in `point`
        const int8 k = b + vload8(0, li + j) + i;
        const float8 y = keys8(p - convert_float8(i), GATHER8(k, -1), GATHER8(k, 0), GATHER8(k, 1),
                               GATHER8(k, 2));
        vstore8(y, 0, row + j);
        acc += y;
    }
    float total = sum8(acc);
    for (int j = whole; j < points; ++j) {
        const float y = point(codes, b, off, dl, li, lf, u, j);
        row[j] = y;
        total += y;
    }
    const float mean = total / (float)points;
    for (int j = 0; j < whole; j += 8) vstore8((vload8(0, row + j) - mean) * vload8(0, win + j), 0, row + j);
    for (int j = whole; j < points; ++j) row[j] = (row[j] - mean) * win[j];
}
