// Stage 2: the sync channel's crossings. Two kernels; the hysteresis on the short
// stream of block means and the turning-point grid stay on the host (cheap).
// Twins: fmcw_cl.stages.sync.block_means and line_fit_sums.

// Sums of whole blocks of `factor` int16 codes (exact in float32: |sum| < 2^24 for
// factor <= 512); the host divides in float64.
__kernel void block_sum(__global const short *x,
                        const int factor,
                        __global float *out)
{
    const int j = get_global_id(0);
    __global const short *p = x + (size_t)j * factor;
    float s = 0.0f;
    for (int k = 0; k < factor; ++k) s += (float)p[k];
    out[j] = s;
}

// Integer sums of x and (i - c) x over x[c - hw .. c + hw], one work-group per
// crossing centre c, each sample first replaced by the median of its 5-sample
// neighbourhood when more than `spike` codes off it (a sync glitch). A spike is off at
// least 3 of its 4 neighbours, hence off one of the two adjacent ones: the main loop
// only counts such candidates (branch-free, so it vectorises), and a work-item that
// saw one corrects its sums in a second loop. Integer sums make the result exact and
// equal to the numpy twin's.
#define CSWAP(a, b) { const int lo_ = a < b ? a : b; b = a < b ? b : a; a = lo_; }

__kernel void line_fit(__global const short *x,
                       __global const int *centre,
                       const int hw,             // half-width of the window
                       const int spike,          // codes
                       const int flush,          // samples per int32 partial sum
                       __global long *sum0,      // sum x
                       __global long *sum1,      // sum (i - c) x
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
    if (candidates) {
        for (int k = lid - hw; k <= hw; k += lsz) {
            const int i = c + k;
            const int v = x[i];
            int m0 = x[i - 2], m1 = x[i - 1], m2 = v, m3 = x[i + 1], m4 = x[i + 2];
            if (abs(v - m1) > spike || abs(v - m3) > spike) {
                CSWAP(m0, m1); CSWAP(m3, m4); CSWAP(m2, m4); CSWAP(m2, m3); CSWAP(m1, m4);
                CSWAP(m0, m3); CSWAP(m0, m2); CSWAP(m1, m3); CSWAP(m1, m2);
                if (abs(v - m2) > spike) {
                    a0 += m2 - v;
                    a1 += (long)k * (m2 - v);
                }
            }
        }
    }
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
        sum0[g] = l0[0];
        sum1[g] = l1[0];
    }
}
