// Stage 2: the sync channel's crossings, three kernels. The coarse search: block sums
// (and an evenly spaced sample of them, from which the host takes the level and the
// swing), then where their 3-block median changes its band or its side of the level:
// a few entries a half-period, which the host turns into crossings. The crossings are
// then timed by line fits on the full-rate codes. Twins: fmcw_cl.stages.sync.block_sums,
// changes and line_fit_sums.

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
// block_sum zeroed: out = [events, sides, (block, band) x cap_events, (block, before,
// after) x cap_sides]; past a capacity only the count grows (the host then redoes it).
// Block i's entries, from its filtered sum b and the previous block's a (i = 0: its own).
void record_changes(const int i, const int a, const int b, const int high, const int low, const int mid,
                    const int cap_events, const int cap_sides, __global int *out)
{
    const int e = band(b, high, low);
    if (i == 0 || e != band(a, high, low)) {
        const int k = atomic_inc(out);
        if (k < cap_events) {
            out[2 + 2 * k] = i;
            out[3 + 2 * k] = e;
        }
    }
    if (i > 0 && (b >= mid) != (a >= mid)) {
        const int k = atomic_inc(out + 1);
        if (k < cap_sides) {
            __global int *o = out + 2 + 2 * cap_events + 3 * k;
            o[0] = i;
            o[1] = a;
            o[2] = b;
        }
    }
}

__kernel void crossing_changes(__global const int *sums,
                               const int m,
                               const int high,
                               const int low,
                               const int mid,
                               const int cap_events,
                               const int cap_sides,
                               __global int *out)
{
    const int i = get_global_id(0);
    if (i >= m) return;
    const int b = filtered(sums, m, i);
    record_changes(i, i > 0 ? filtered(sums, m, i - 1) : b, b, high, low, mid, cap_events, cap_sides, out);
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

__kernel void line_fit(__global const short *x,
                       __global const int *centre,
                       const int hw,             // half-width of the window
                       const int spike,          // codes
                       const int flush,          // samples per int32 partial sum
                       __global long *sums,      // (sum x, sum (i - c) x) per centre
                       __local long *l0,
                       __local long *l1)
{
    const int g = get_group_id(0);
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    const int c = centre[g];
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
    if (lid == 0) {
        sums[2 * g] = l0[0];
        sums[2 * g + 1] = l1[0];
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
                                    const int high,
                                    const int low,
                                    const int mid,
                                    const int cap_events,
                                    const int cap_sides,
                                    const int span,
                                    __global int *out)
{
    const int i0 = get_global_id(0) * span;
    if (i0 >= m) return;
    const int i1 = i0 + span < m ? i0 + span : m;
    int a = filtered(sums, m, i0 > 0 ? i0 - 1 : 0);
    for (int i = i0; i < i1; ++i) {
        const int b = filtered(sums, m, i);
        record_changes(i, a, b, high, low, mid, cap_events, cap_sides, out);
        a = b;
    }
}

// line_fit on CPU devices: one work-item a centre, eight codes a step in the lanes of an
// int8 (PoCL vectorises no work-item loop that holds a loop, see fft_lanes.cl; wider
// vectors than AVX2's change its builtins' ABI); the same sums, flushed every `flush`
// steps (each lane takes one code a step).
__kernel void line_fit_lanes(__global const short *x,
                             __global const int *centre,
                             const int hw,
                             const int spike,
                             const int flush,
                             __global long *sums)
{
    const int g = get_global_id(0);
    const int c = centre[g];
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
    sums[2 * g] = a0;
    sums[2 * g + 1] = a1;
}
