// Stage 4: resample half-sweeps at the instants of uniform optical frequency.
// Cubic convolution (Keys, a = -0.5) straight from the int16 codes, then mean
// removal and the window. Plain a*b+c code: PoCL's fma/mad builtins are slow.
// Positions: start + u_j L = base + lut_int_j + (offset + lut_frac_j + u_j dlen), where
// lut_int + lut_frac = u_j L0 was split in float64 on the host and dlen = L - L0 is tiny,
// so float32 keeps 1e-6 sample precision (u_j L in float32 would lose 2e-4). Sweeps in
// runs (`runs` > 1: the chunks of one pass of the delay's trials) each have their run's
// L0 (`run`: each sweep's; the LUT split once a run, one table after another), so that a
// run's rows are those it would have alone.
// Three variants: `resample` (GPUs) a work-group per half-sweep, its work-items striding
// over the points; `resample_lanes` (CPUs) a work-item per half-sweep, eight points at a
// time in float8 lanes (PoCL vectorises across work-items only where a kernel has no
// loop, which this one has; 2-core EPYC: 2.3x faster than `resample` there), where
// `resample_rows` (CPUs, below: a row a lane, a launch a run) finds no room in local
// memory.
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


// resample_lanes with its lanes across rows, for devices with local memory to spare
// (CPUs): LANES half-sweeps of one run a work-item, one a lane, bit for bit the rows of
// resample_lanes; a launch a run (`lut_int`, `lut_frac`: its tables; rows [row0, sweeps)).
// Its four scalar loads a point and row cost resample_lanes half its time. Here the
// rows' points share the LUT's whole samples m_j, and a lane's fraction moves its taps
// by -1 .. 2 samples (a point where some lane's moves farther is taken a lane at a time,
// from the codes), so each tap is one of seven vectors t[m_j - 2 ..
// m_j + 4], picked by two selects on the bits of the move. The rows' codes are first
// transposed into local memory (lane l of t[m - mlo] is code m past row l's base,
// LANES x LANES at a time: lanes.cl's transpose_lanes), and the rows go back transposed. Local memory: t
// (m_count floatL) and the rows before their mean is removed (points floatL). Oclgrind's
// uninitialised-value check reports any vector built from components, its values right
// (a five-line kernel shows it), and then crashes, so this kernel is checked on PoCL
// against resample_lanes, bit for bit.
KEYS(keysL, floatL)

// Point j of the LANES rows: resample_lanes' `point` in each lane.
inline floatL rows_point(__global const short *codes, __local const floatL *t, const int mlo, const int *bl,
                         const floatL off, const floatL dl, __global const int *lut_int,
                         __global const float *lut_frac, __global const float *u, const int j)
{
    const int m = lut_int[j];
    const floatL p = off + lut_frac[j] + u[j] * dl;
    const intL i = CONVERT_INTL(p + 16.0f) - 16;      // floor, as in `point`
    const floatL f = p - CONVERT_FLOATL(i);
    if (!any_lanes((i < -1) | (i > 2))) {
        // a lane's tap d (-1 .. 2) is t[m + i + d - mlo] = a[(i + 1) + (d + 1)]
        __local const floatL *a = t + (m - 2 - mlo);
        const intL e = i + 1;
        const intL odd = (e & 1) != 0, high = (e & 2) != 0;
        floatL w[6];
#pragma unroll
        for (int q = 0; q < 6; ++q) w[q] = odd ? a[q + 1] : a[q];
        return keysL(f, high ? w[2] : w[0], high ? w[3] : w[1], high ? w[4] : w[2], high ? w[5] : w[3]);
    }
    float yl[LANES], fl[LANES];
    VSTOREL(f, 0, fl);
    VSTOREL(CONVERT_FLOATL(i), 0, yl);
    for (int l = 0; l < LANES; ++l) {
        const int k = bl[l] + m + (int)yl[l];
        yl[l] = keys(fl[l], codes[k - 1], codes[k], codes[k + 1], codes[k + 2]);
    }
    return VLOADL(0, yl);
}

__kernel void resample_rows(__global const short *codes,
                            const int n_codes,
                            __global const int *base,
                            __global const float *offset,
                            __global const float *dlen,
                            __global const int *lut_int,   // the runs' tables, one after another
                            __global const float *lut_frac,
                            const int lut_at,              // this run's: lut_int + lut_at
                            __global const float *u,
                            __global const float *win,
                            const int points,
                            const int row0,              // the run's rows: [row0, sweeps)
                            const int sweeps,
                            __global float *out,
                            const int mlo,               // min(lut_int) - 2
                            const int m_count,           // >= max(lut_int) + 4 - mlo + 1, LANES-fold
                            __local floatL *t,           // m_count
                            __local floatL *y)           // points
{
    const int first = row0 + (int)get_global_id(0) * LANES;
    lut_int += lut_at;
    lut_frac += lut_at;
    int bl[LANES], sl[LANES];
    float ol[LANES], dll[LANES];
    for (int l = 0; l < LANES; ++l) {
        const int s = first + l < sweeps ? first + l : sweeps - 1;    // idle lanes: the last row again
        sl[l] = s;
        bl[l] = base[s];
        ol[l] = offset[s];
        dll[l] = dlen[s];
    }
    const floatL off = VLOADL(0, ol), dl = VLOADL(0, dll);
    int b_lo = bl[0], b_hi = bl[0];
    for (int l = 1; l < LANES; ++l) {
        b_lo = IMIN(b_lo, bl[l]);
        b_hi = IMAX(b_hi, bl[l]);
    }
    for (int m0 = 0; m0 < m_count; m0 += LANES) {
        floatL v[LANES];
        if (b_lo + mlo + m0 >= 0 && b_hi + mlo + m0 + LANES <= n_codes) {
            // every row's codes inside: one test for all rows, the loads unrolled (PoCL,
            // 2-core Sapphire Rapids: 2 x 8321 rows of 1000 points 16.4 to 14.4 ms)
#pragma unroll
            for (int l = 0; l < LANES; ++l) v[l] = CONVERT_FLOATL(VLOADSL(0, codes + bl[l] + mlo + m0));
        } else {
            for (int l = 0; l < LANES; ++l) {
                const int k = bl[l] + mlo + m0;
                if (k >= 0 && k + LANES <= n_codes) {
                    v[l] = CONVERT_FLOATL(VLOADSL(0, codes + k));
                } else {                                 // the codes' ends: codes no point reads
                    float e[LANES];
                    for (int q = 0; q < LANES; ++q)
                        e[q] = k + q >= 0 && k + q < n_codes ? (float)codes[k + q] : 0.0f;
                    v[l] = VLOADL(0, e);
                }
            }
        }
        transpose_lanes(v);
        for (int q = 0; q < LANES; ++q) t[m0 + q] = v[q];
    }
    // resample_lanes' sum: the points' eight lanes (j mod 8) pairwise, then the points past them
    const int whole = points & ~7;
    floatL acc[8];
    for (int r = 0; r < 8; ++r) acc[r] = 0.0f;
    for (int j = 0; j < whole; j += 8) {
        for (int r = 0; r < 8; ++r) {
            const floatL v = rows_point(codes, t, mlo, bl, off, dl, lut_int, lut_frac, u, j + r);
            y[j + r] = v;
            acc[r] += v;
        }
    }
    floatL total = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
    for (int j = whole; j < points; ++j) {
        const floatL v = rows_point(codes, t, mlo, bl, off, dl, lut_int, lut_frac, u, j);
        y[j] = v;
        total += v;
    }
    const floatL mean = total / (float)points;
    const int tiles = points - points % LANES;
    // every lane a row: the stores unrolled, without a test a row (those rows 14.4 to 13.4 ms)
    const int whole_rows = first + LANES <= sweeps;
    for (int j0 = 0; j0 < tiles; j0 += LANES) {
        floatL v[LANES];
#pragma unroll
        for (int q = 0; q < LANES; ++q) v[q] = y[j0 + q] - mean;
        transpose_lanes(v);
        const floatL w = VLOADL(0, win + j0);
        if (whole_rows) {
#pragma unroll
            for (int l = 0; l < LANES; ++l) VSTOREL(v[l] * w, 0, out + (size_t)sl[l] * points + j0);
        } else {
            for (int l = 0; l < LANES; ++l)
                if (first + l < sweeps) VSTOREL(v[l] * w, 0, out + (size_t)sl[l] * points + j0);
        }
    }
    float ml[LANES];
    VSTOREL(mean, 0, ml);
    for (int l = 0; l < LANES && first + l < sweeps; ++l)
        for (int j = tiles; j < points; ++j)
            out[(size_t)sl[l] * points + j] = (((__local const float *)(y + j))[l] - ml[l]) * win[j];
}
