// Stage 2: the sync channel's crossings, four kernels. The coarse search: block sums
// (and an evenly spaced sample of them), the level and the swing from the sample's
// percentiles, then where the sums' 3-block median changes its band or its side of the
// level: a few entries a half-period, which the host turns into crossings. The
// crossings are then timed by line fits on the full-rate codes, twice in one launch (the
// second centred on the first one's crossing). Twins: fmcw_cl.stages.sync.block_sums,
// levels, changes and line_fits.

// The second fit's centre is the first fit's crossing rounded: in double precision where
// the device has it, as numpy (the same centres); without it, in float (a centre may
// differ by one sample where the crossing lies within a float's precision of a half sample).
#pragma OPENCL FP_CONTRACT OFF
#if defined(cl_khr_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double real;
#else
typedef float real;
#endif

// The integer sum of block j of `factor` codes, kept in `sampled` too when j is a
// multiple of `stride`.
void sum_block(__global const short *x, const int factor, const int stride, const int j,
               __global int *out, __global int *sampled)
{
    __global const short *p = x + (size_t)j * factor;
    int s = 0;
    for (int k = 0; k < factor; ++k) s += p[k];
    out[j] = s;
    const int q = j / stride;       // (not j % stride: Oclgrind cannot follow the code made of it)
    if (q * stride == j) sampled[q] = s;
}

// crossing_changes' output: a header (the counts of its two lists, then sync_levels'
// 20 factor lo, 20 factor hi, and the thresholds high, low, mid), then the lists.
#define HEADER 8

// Integer sums of whole blocks of `factor` int16 codes, and every `stride`-th of them;
// work-item 0 also zeroes crossing_changes' two counters (this kernel always runs first).
__kernel void block_sum(__global const short *x,
                        const int factor,
                        const int m,              // blocks
                        const int stride,
                        __global int *out,
                        __global int *sampled,
                        __global int *counters)
{
    const int j = get_global_id(0);
    if (j >= m) return;
    sum_block(x, factor, stride, j, out, sampled);
    if (j == 0) {
        counters[0] = 0;
        counters[1] = 0;
    }
}

// The level and the hysteresis band from the percentiles of the sampled block sums, on
// the device so that no copy waits between block_sum and crossing_changes: one
// work-group. The 5 and 95 percentiles interpolate order statistics of ranks (n - 1) / 20
// and 19 (n - 1) / 20 (numpy's linear percentile) with weights in twentieths, so
// 20 factor lo and 20 factor hi are integers (a, b), and so are the thresholds on a sum:
// high = floor((7a + 11b) / 360) + 1, low = ceil((11a + 7b) / 360), mid = floor((a + b) /
// 40) + 1 (see the twin, stages.sync.levels).
#define LEVEL_BITS 11                      // two radix passes over 22-bit values
#define LEVEL_BINS (1 << LEVEL_BITS)
#define LEVEL_OFFSET (1 << 21)             // |a sum of 64 int16 codes| <= 2^21: offset, >= 0

// The k-th smallest (from 0) of s[0 .. n), by a radix select: a histogram of the upper 11
// bits finds the bin holding rank k, a histogram of the lower 11 bits of that bin's values
// the value. hist: LEVEL_BINS + 2 ints of local memory.
int kth_smallest(__global const int *s, const int n, const int k, __local int *hist)
{
    const int lid = get_local_id(0), lsz = get_local_size(0);
    int prefix = 0;
    int rank = k;
    for (int pass = 0; pass < 2; ++pass) {
        const int shift = pass == 0 ? LEVEL_BITS : 0;
        for (int b = lid; b < LEVEL_BINS; b += lsz) hist[b] = 0;
        barrier(CLK_LOCAL_MEM_FENCE);
        for (int q = lid; q < n; q += lsz) {
            const int u = s[q] + LEVEL_OFFSET;
            if (pass == 0 || (u >> LEVEL_BITS) == prefix) atomic_inc(hist + ((u >> shift) & (LEVEL_BINS - 1)));
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        if (lid == 0) {                    // the bin of the rank: 2048 steps, one work-item
            int below = 0, b = 0;
            while (b < LEVEL_BINS - 1 && below + hist[b] <= rank) below += hist[b++];
            hist[LEVEL_BINS] = b;
            hist[LEVEL_BINS + 1] = rank - below;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        prefix = (prefix << LEVEL_BITS) | hist[LEVEL_BINS];
        rank = hist[LEVEL_BINS + 1];
        barrier(CLK_LOCAL_MEM_FENCE);      // hist is cleared next
    }
    return prefix - LEVEL_OFFSET;
}

long floor_div(const long x, const long d)   // d > 0
{
    return x >= 0 ? x / d : -((-x + d - 1) / d);
}

// out[2 .. 6] = a, b, high, low, mid of the n >= 1 sampled sums (one work-group).
__kernel void sync_levels(__global const int *sampled,
                          const int n,
                          __global int *out,
                          __local int *hist)
{
    const int last = n - 1;
    const int i = last / 20, r = last - 20 * i;
    const int j = 19 * last / 20, t = 19 * last - 20 * j;
    const long a = (long)kth_smallest(sampled, n, i, hist) * (20 - r)
                   + (long)kth_smallest(sampled, n, min(i + 1, last), hist) * r;
    const long b = (long)kth_smallest(sampled, n, j, hist) * (20 - t)
                   + (long)kth_smallest(sampled, n, min(j + 1, last), hist) * t;
    if (get_local_id(0) == 0) {
        out[2] = (int)a;
        out[3] = (int)b;
        out[4] = (int)(floor_div(7 * a + 11 * b, 360) + 1);
        out[5] = (int)(-floor_div(-11 * a - 7 * b, 360));
        out[6] = (int)(floor_div(a + b, 40) + 1);
    }
}

int median3(const int p, const int q, const int r)
{
    const int lo = p < q ? p : q, hi = p < q ? q : p;
    return hi < r ? hi : (lo > r ? lo : r);
}

// The filtered sum of block i (ends unfiltered).
int filtered(__global const int *sums, const int m, const int i)
{
    return i == 0 || i == m - 1 ? sums[i] : median3(sums[i - 1], sums[i], sums[i + 1]);
}

int band(const int b, const int high, const int low)
{
    return b >= high ? 1 : (b < low ? -1 : 0);
}

// Where the filtered sums change band (+1 at or above `high`, -1 below `low`; block 0
// always) and side of the level (`mid`), appended in any order through counters that
// block_sum zeroed: out = [header, (block, band) x cap_events, (block, before, after) x
// cap_sides]; past a capacity only the count grows (the host then redoes it).
// Block i's entries, from its filtered sum b and the previous block's a (i = 0: its own).
void record_changes(const int i, const int a, const int b, const int high, const int low, const int mid,
                    const int cap_events, const int cap_sides, __global int *out)
{
    const int e = band(b, high, low);
    if (i == 0 || e != band(a, high, low)) {
        const int k = atomic_inc(out);
        if (k < cap_events) {
            out[HEADER + 2 * k] = i;
            out[HEADER + 1 + 2 * k] = e;
        }
    }
    if (i > 0 && (b >= mid) != (a >= mid)) {
        const int k = atomic_inc(out + 1);
        if (k < cap_sides) {
            __global int *o = out + HEADER + 2 * cap_events + 3 * k;
            o[0] = i;
            o[1] = a;
            o[2] = b;
        }
    }
}

__kernel void crossing_changes(__global const int *sums,
                               const int m,
                               const int cap_events,
                               const int cap_sides,
                               __global int *out)
{
    const int i = get_global_id(0);
    if (i >= m) return;
    const int b = filtered(sums, m, i);
    record_changes(i, i > 0 ? filtered(sums, m, i - 1) : b, b, out[4], out[5], out[6], cap_events, cap_sides,
                   out);
}

// Integer sums of x and (i - c) x over x[c - hw .. c + hw], one work-group per
// crossing centre c, each sample first replaced by the median of its 5-sample
// neighbourhood when more than `spike` codes off it (a sync glitch). A spike is off at
// least 3 of its 4 neighbours, hence off one of the two adjacent ones: the main loop
// only counts such candidates (branch-free, so it vectorises), and a work-item that
// saw one corrects its sums in a second loop. Integer sums make the result exact and
// equal to the numpy twin's.
#define CSWAP(a, b) { const int lo_ = a < b ? a : b; b = a < b ? b : a; a = lo_; }

// The spikes' corrections to the sums, over samples c + k, k = first, first + step, ..
// <= hw: a sample more than `spike` off the median of its 5-sample neighbourhood is
// replaced by that median.
void despike(__global const short *x, const int c, const int first, const int hw, const int step,
             const int spike, long *a0, long *a1)
{
    for (int k = first; k <= hw; k += step) {
        const int i = c + k;
        const int v = x[i];
        int m0 = x[i - 2], m1 = x[i - 1], m2 = v, m3 = x[i + 1], m4 = x[i + 2];
        if (abs(v - m1) > spike || abs(v - m3) > spike) {
            CSWAP(m0, m1); CSWAP(m3, m4); CSWAP(m2, m4); CSWAP(m2, m3); CSWAP(m1, m4);
            CSWAP(m0, m3); CSWAP(m0, m2); CSWAP(m1, m3); CSWAP(m1, m2);
            if (abs(v - m2) > spike) {
                *a0 += m2 - v;
                *a1 += (long)k * (m2 - v);
            }
        }
    }
}

// The centre of the second fit from the first one's sums at centre c (twin:
// sync.line_fit_crossing, rounded): -1 where the crossing is not finite or its window
// would leave the codes [0, n).
int next_centre(const long s0, const long s1, const int c, const int hw, const real level, const int n)
{
    const real m = (real)(2 * hw + 1);
    const real s2 = (real)((long)hw * (hw + 1) * (2 * hw + 1)) / (real)3.0;
    const real d = ((real)s0 / m - level) / ((real)s1 / s2);
#if defined(cl_khr_fp64)
    const real g = (real)c - d;         // numpy's order of operations
    if (!isfinite(g)) return -1;
    const real r = rint(g);
#else
    if (!isfinite(d)) return -1;        // a float holds a centre exactly only below 2^24
    const real r = (real)c - rint(d);
#endif
    return r - hw >= 2 && r + hw < n - 2 ? (int)r : -1;
}

// The group's sums of x and (i - c) x over the window of centre c into l0[0], l1[0]
// (every work-item of the group calls it).
void group_sums(__global const short *x, const int c, const int hw, const int spike, const int flush,
                __local long *l0, __local long *l1)
{
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    // int32 partial sums, flushed into 64-bit ones every `flush` samples (|k x| < 2^31
    // / flush): int64 arithmetic in the inner loop is slow on CPUs
    long a0 = 0;
    long a1 = 0;
    int b0 = 0;
    int b1 = 0;
    int n = 0;
    int candidates = 0;
    for (int k = lid - hw; k <= hw; k += lsz) {
        const int i = c + k;
        const int v = x[i];
        b0 += v;
        b1 += k * v;
        candidates += (abs(v - x[i - 1]) > spike) | (abs(v - x[i + 1]) > spike);
        if (++n == flush) {
            a0 += b0;
            a1 += b1;
            b0 = 0;
            b1 = 0;
            n = 0;
        }
    }
    a0 += b0;
    a1 += b1;
    if (candidates) despike(x, c, lid - hw, hw, lsz, spike, &a0, &a1);
    barrier(CLK_LOCAL_MEM_FENCE);       // the previous call's totals are read
    l0[lid] = a0;
    l1[lid] = a1;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int w = lsz / 2; w > 0; w >>= 1) {
        if (lid < w) {
            l0[lid] += l0[lid + w];
            l1[lid] += l1[lid + w];
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
}

// Both line fits of each crossing, a work-group each: the sums at the first centre,
// then, where the first fit's crossing rounds to another centre, at that one. out =
// (centre, sum x, sum (i - c) x) of the last fit per crossing, centre -1 where the
// crossing left the codes (dropped).
__kernel void line_fit(__global const short *x,
                       __global const int *centre,
                       const int hw,             // half-width of the window
                       const int spike,          // codes
                       const int flush,          // samples per int32 partial sum
                       const real level,         // the crossing level (codes)
                       const int n,              // codes in x
                       __global long *out,
                       __local long *l0,
                       __local long *l1)
{
    const int g = get_group_id(0);
    const int c = centre[g];
    group_sums(x, c, hw, spike, flush, l0, l1);
    const long s0 = l0[0], s1 = l1[0];
    const int c2 = next_centre(s0, s1, c, hw, level, n);
    long t0 = s0, t1 = s1;
    if (c2 >= 0 && c2 != c) {           // the same for the whole group: uniform barriers
        group_sums(x, c2, hw, spike, flush, l0, l1);
        t0 = l0[0];
        t1 = l1[0];
    }
    if (get_local_id(0) == 0) {
        out[3 * g] = c2;
        out[3 * g + 1] = t0;
        out[3 * g + 2] = t1;
    }
}

long hsum8(const int8 v)
{
    return (long)v.s0 + v.s1 + v.s2 + v.s3 + v.s4 + v.s5 + v.s6 + v.s7;
}

// block_sum and crossing_changes on CPU devices: a work-item a span of `span` blocks
// in order (PoCL vectorises no work-item loop that holds a loop, and the one-block
// kernels hold one or branch to atomics; a span's codes are contiguous, which the
// compiler vectorises itself: 2x, where int8 loads were slower than one block an item).
// crossing_changes_span carries the previous block's filtered sum, so each median is
// taken once. The same entries; the host sorts them.
__kernel void block_sum_span(__global const short *x,
                             const int factor,
                             const int m,
                             const int stride,
                             const int span,
                             __global int *out,
                             __global int *sampled,
                             __global int *counters)
{
    const int j0 = get_global_id(0) * span;
    if (j0 >= m) return;
    const int j1 = j0 + span < m ? j0 + span : m;
    if (j0 == 0) {
        counters[0] = 0;
        counters[1] = 0;
    }
    for (int j = j0; j < j1; ++j) sum_block(x, factor, stride, j, out, sampled);
}

__kernel void crossing_changes_span(__global const int *sums,
                                    const int m,
                                    const int cap_events,
                                    const int cap_sides,
                                    const int span,
                                    __global int *out)
{
    const int i0 = get_global_id(0) * span;
    if (i0 >= m) return;
    const int i1 = i0 + span < m ? i0 + span : m;
    const int high = out[4], low = out[5], mid = out[6];
    int a = filtered(sums, m, i0 > 0 ? i0 - 1 : 0);
    for (int i = i0; i < i1; ++i) {
        const int b = filtered(sums, m, i);
        record_changes(i, a, b, high, low, mid, cap_events, cap_sides, out);
        a = b;
    }
}

// line_fit on CPU devices: one work-item a crossing, eight codes a step in the lanes of
// an int8 (PoCL vectorises no work-item loop that holds a loop, see fft_lanes.cl; wider
// vectors than AVX2's change its builtins' ABI); the same sums, flushed every `flush`
// steps (each lane takes one code a step).
void lane_sums(__global const short *x, const int c, const int hw, const int spike, const int flush,
               long *s0, long *s1)
{
    const int8 lane = (int8)(0, 1, 2, 3, 4, 5, 6, 7);
    long a0 = 0;
    long a1 = 0;
    int8 seen = 0;
    int k = -hw;
    while (k + 8 <= hw + 1) {
        int8 b0 = 0, b1 = 0;
        for (int n = 0; n < flush && k + 8 <= hw + 1; ++n, k += 8) {
            __global const short *p = x + c + k;
            const int8 v = convert_int8(vload8(0, p));
            const int8 dl = v - convert_int8(vload8(0, p - 1));
            const int8 dr = v - convert_int8(vload8(0, p + 1));
            b0 += v;
            b1 += (k + lane) * v;
            seen |= (dl > spike) | (dl < -spike) | (dr > spike) | (dr < -spike);
        }
        a0 += hsum8(b0);
        a1 += hsum8(b1);
    }
    int candidates = any(seen);
    for (; k <= hw; ++k) {
        const int i = c + k;
        const int v = x[i];
        a0 += v;
        a1 += (long)k * v;
        candidates |= (abs(v - x[i - 1]) > spike) | (abs(v - x[i + 1]) > spike);
    }
    if (candidates) despike(x, c, -hw, hw, 1, spike, &a0, &a1);
    *s0 = a0;
    *s1 = a1;
}

__kernel void line_fit_lanes(__global const short *x,
                             __global const int *centre,
                             const int hw,
                             const int spike,
                             const int flush,
                             const real level,
                             const int n,
                             __global long *out)
{
    const int g = get_global_id(0);
    const int c = centre[g];
    long s0, s1;
    lane_sums(x, c, hw, spike, flush, &s0, &s1);
    const int c2 = next_centre(s0, s1, c, hw, level, n);
    if (c2 >= 0 && c2 != c) lane_sums(x, c2, hw, spike, flush, &s0, &s1);
    out[3 * g] = c2;
    out[3 * g + 1] = s0;
    out[3 * g + 2] = s1;
}
