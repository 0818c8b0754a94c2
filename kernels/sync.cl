// Stage 2: the sync channel's crossings, from the codes to both line fits of each, with
// no copy between. The coarse search: block sums (and an evenly spaced sample of them),
// the level and the swing from the sample's percentiles, then the hysteresis on the sums'
// 3-block median over spans of blocks, which writes each crossing's fit centre. The
// crossings are then timed by line fits on the full-rate codes, twice in one launch (the
// second centred on the first one's crossing). Twins: fmcw_cl.stages.sync.block_sums,
// levels, changes, coarse_crossings and line_fits (together sync.fitted).

// The fit centres (the coarse crossing's and the second fit's, the first fit's crossing
// rounded) are rounded in double precision where the device has it, as numpy (the same
// centres); without it, in float (a centre may differ by one sample where a crossing
// lies within a float's precision of a half sample).
#pragma OPENCL FP_CONTRACT OFF

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

// The search's header (ints): sync_levels' 20 factor lo, 20 factor hi and the thresholds
// high, low, mid on a block sum.
#define HEADER 8

// Integer sums of whole blocks of `factor` int16 codes, and every `stride`-th of them.
__kernel void block_sum(__global const short *x,
                        const int factor,
                        const int m,              // blocks
                        const int stride,
                        __global int *out,
                        __global int *sampled)
{
    const int j = get_global_id(0);
    if (j >= m) return;
    sum_block(x, factor, stride, j, out, sampled);
}

// The level and the hysteresis band from the percentiles of the sampled block sums, on
// the device so that no copy waits between the block sums and the hysteresis: one
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

// head[0 .. 4] = a, b, high, low, mid of the n >= 1 sampled sums (one work-group).
__kernel void sync_levels(__global const int *sampled,
                          const int n,
                          __global int *head,
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
        head[0] = (int)a;
        head[1] = (int)b;
        head[2] = (int)(floor_div(7 * a + 11 * b, 360) + 1);
        head[3] = (int)(-floor_div(-11 * a - 7 * b, 360));
        head[4] = (int)(floor_div(a + b, 40) + 1);
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

// The hysteresis, in three launches over spans of `span` blocks (a work-item each): the
// band's state flips where the filtered sums leave the band on the side opposite to the
// one they last left (block i with band e != 0 whose last nonzero band before it is -e),
// and the crossing is the last change of side of the level at or before the flip,
// interpolated between the two blocks around it (twin: stages.sync.changes and
// coarse_crossings). span_ends takes each span's last nonzero band and last change of
// side; span_carries what the spans before each leave (one work-item, in order);
// span_crossings replays each span from its carry and writes its crossings' fit centres
// and directions, in order, into `cap` slots of its own.

// A change of side carried across spans: its block (-1: none yet) and the filtered sums
// either side of it.
typedef struct { int last; int at; int before; int after; } Carry;

// Carry s of an (spans, 4) array, and back
Carry load_carry(__global const int *e, const int s)
{
    const Carry c = {e[4 * s], e[4 * s + 1], e[4 * s + 2], e[4 * s + 3]};
    return c;
}

void store_carry(__global int *e, const int s, const Carry c)
{
    e[4 * s] = c.last;
    e[4 * s + 1] = c.at;
    e[4 * s + 2] = c.before;
    e[4 * s + 3] = c.after;
}

// The crossing level (codes) of the header's percentiles: (a + b) / (40 factor)
real head_level(__global const int *head, const int factor)
{
    return (real)((long)head[0] + head[1]) / (real)(40 * factor);
}

void span_walk(__global const int *sums, const int m, const int i0, const int i1, __global const int *head,
               Carry *c, const int emit, const int factor, const int hw, const int n, const int cap,
               __global int *centre, __global int *direction)
{
    const int high = head[2], low = head[3], mid = head[4];
    const real level = head_level(head, factor);
    int a = filtered(sums, m, i0 > 0 ? i0 - 1 : 0);
    int found = 0;
    for (int i = i0; i < i1; ++i) {
        const int b = filtered(sums, m, i);
        if (i > 0 && (b >= mid) != (a >= mid)) {
            c->at = i;
            c->before = a;
            c->after = b;
        }
        const int e = band(b, high, low);
        if (e != 0) {
            if (emit && c->last == -e && c->at >= 0) {
                if (found < cap) {
                    // numpy's order of operations (FP contraction off): the crossing in
                    // blocks, the fit centre in samples, rounded half to even, its reach
                    const real xa = (real)c->before / (real)factor - level;
                    const real xb = (real)c->after / (real)factor - level;
                    const real q = xa / (xa - xb);
                    const real frac = isnan(q) ? (real)0 : (q < (real)0 ? (real)0 : (q > (real)1 ? (real)1 : q));
                    const real block = (real)(c->at - 1) + frac;
                    real pos = block * (real)factor + (real)0.5 * (real)(factor - 1);
                    pos = pos < (real)-1 ? (real)-1 : (pos > (real)n ? (real)n : pos);
                    const int r = (int)rint(pos);
                    centre[found] = r - hw >= 2 && r + hw < n - 2 ? r : -1;
                    direction[found] = e;
                }
                ++found;
            }
            c->last = e;
        }
        a = b;
    }
    if (emit) {
        for (int k = found; k < cap; ++k) centre[k] = -1;   // the empty slots: no fit
        direction[cap] = found;                             // the count (past cap: overflow)
    }
}

__kernel void span_ends(__global const int *sums,
                        const int m,
                        const int span,
                        __global const int *head,
                        __global int *ends)       // (spans, 4): a Carry each
{
    const int s = get_global_id(0);
    const int i0 = s * span;
    if (i0 >= m) return;
    Carry c = {0, -1, 0, 0};
    span_walk(sums, m, i0, min(i0 + span, m), head, &c, 0, 1, 0, 0, 0, 0, 0);
    store_carry(ends, s, c);
}

// In place: each span's ends become what the spans before it leave. One work-item; also
// the line fits' parameters (level and spike threshold, codes) from the header.
__kernel void span_carries(__global int *ends,
                           const int spans,
                           __global const int *head,
                           const int factor,
                           const real spike_share,
                           __global real *params)
{
    Carry c = {0, -1, 0, 0};
    for (int s = 0; s < spans; ++s) {
        const Carry e = load_carry(ends, s);
        store_carry(ends, s, c);
        if (e.last != 0) c.last = e.last;
        if (e.at >= 0) {
            c.at = e.at;
            c.before = e.before;
            c.after = e.after;
        }
    }
    params[0] = head_level(head, factor);
    params[1] = spike_share * ((real)((long)head[1] - head[0]) / (real)(18 * factor));
}

// Slots of span s: centre[s cap ..] (-1: empty or out of reach), direction[s (cap + 1) ..],
// the span's count last.
__kernel void span_crossings(__global const int *sums,
                             const int m,
                             const int span,
                             __global const int *head,
                             __global const int *carries,
                             const int factor,
                             const int hw,
                             const int n,
                             const int cap,
                             __global int *centre,
                             __global int *direction)
{
    const int s = get_global_id(0);
    const int i0 = s * span;
    if (i0 >= m) return;
    Carry c = load_carry(carries, s);
    span_walk(sums, m, i0, min(i0 + span, m), head, &c, 1, factor, hw, n, cap, centre + (size_t)s * cap,
              direction + (size_t)s * (cap + 1));
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
// crossing left the codes or there was none (a centre of -1: an empty slot; dropped).
__kernel void line_fit(__global const short *x,
                       __global const int *centre,
                       const int hw,             // half-width of the window
                       __global const real *params,  // the crossing level, the spike threshold (codes)
                       const int flush,          // samples per int32 partial sum
                       const int n,              // codes in x
                       __global long *out,
                       __local long *l0,
                       __local long *l1)
{
    const int g = get_group_id(0);
    const int c = centre[g];
    int c2 = -1;
    long t0 = 0, t1 = 0;
    if (c >= 0) {                       // the same for the whole group: uniform barriers
        const real level = params[0];   // (PoCL hangs where a group returns before them)
        const int spike = (int)floor(params[1]);
        group_sums(x, c, hw, spike, flush, l0, l1);
        t0 = l0[0];
        t1 = l1[0];
        c2 = next_centre(t0, t1, c, hw, level, n);
        if (c2 >= 0 && c2 != c) {
            group_sums(x, c2, hw, spike, flush, l0, l1);
            t0 = l0[0];
            t1 = l1[0];
        }
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

// block_sum on CPU devices: a work-item a span of `span` blocks in order (PoCL
// vectorises no work-item loop that holds a loop; a span's codes are contiguous, which
// the compiler vectorises itself: 2x, where int8 loads were slower than one block an item).
__kernel void block_sum_span(__global const short *x,
                             const int factor,
                             const int m,
                             const int stride,
                             const int span,
                             __global int *out,
                             __global int *sampled)
{
    const int j0 = get_global_id(0) * span;
    if (j0 >= m) return;
    const int j1 = j0 + span < m ? j0 + span : m;
    for (int j = j0; j < j1; ++j) sum_block(x, factor, stride, j, out, sampled);
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
            // a code's step to its right neighbour is the next code's step to its left:
            // the lanes take the steps to the left; the window's count of codes is odd, so
            // the tail below always runs, and its steps to both sides close the set
            const int8 dl = v - convert_int8(vload8(0, p - 1));
            b0 += v;
            b1 += (k + lane) * v;
            seen |= (dl > spike) | (dl < -spike);
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
                             __global const real *params,
                             const int flush,
                             const int n,
                             __global long *out)
{
    const int g = get_global_id(0);
    const int c = centre[g];
    if (c < 0) {
        out[3 * g] = -1;
        return;
    }
    const real level = params[0];
    const int spike = (int)floor(params[1]);
    long s0, s1;
    lane_sums(x, c, hw, spike, flush, &s0, &s1);
    const int c2 = next_centre(s0, s1, c, hw, level, n);
    if (c2 >= 0 && c2 != c) lane_sums(x, c2, hw, spike, flush, &s0, &s1);
    out[3 * g] = c2;
    out[3 * g + 1] = s0;
    out[3 * g + 2] = s1;
}
