// Stage 5e: the energy of a surveyed half-sweep that no sharp echo explains, on the
// spectra where fft.cl left them (plain, and de-chirped at the pair's velocity): one
// work-group per half-sweep, only three numbers come back. The noise floors are the
// spectra's medians over ln 2 (the band copied to local memory, selected by one
// work-item), the rest masked sums (partial sums per work-item, added by one). Only
// straight-line barriers: PoCL compiles it in a moment. Twin: fmcw_cl.echoes.hidden
// (its docstring has the quantities).

#define ABS(v) ((v) < 0.0f ? -(v) : (v))

// One bin's share of the sums, for T float (`hidden`: a work-item's bins of one row) or
// floatL (`hidden_lanes`: LANES rows): k the bin, ed and e the de-chirped and plain
// power over their floors, kt and kp the tracked peak's bins (de-chirped, plain),
// explained: another echo's bins cover k. The target's energy (and its core), the
// energy nothing explains (and its bins), and the weights of its centroid away from the
// plain peak (power over the floor, unclipped). Conditionals only: see hidden_lanes.
#define SURVEY_BIN(T, k, ed, e, kt, kp, explained)                                           \
    {                                                                                        \
        const T off_ = ABS(k - kt);                                                          \
        const T w_ = (explained) ? 0.0f : ((ABS(k - kp) > explain) ? e : 0.0f);               \
        target += off_ <= explain ? ed : 0.0f;                                               \
        near += off_ <= 3.0f ? ed : 0.0f;                                                    \
        excess_sum += (explained) ? 0.0f : e;                                                \
        free_bins += (explained) ? 0.0f : 1.0f;                                              \
        w_sum += w_;                                                                         \
        wk_sum += w_ * k;                                                                    \
    }

// The k-th smallest of s[0 .. n) (Hoare's selection, serial: one work-item, no barrier
// in a loop; a bitonic sort's barriers inside nested loops took PoCL two minutes to
// compile). Afterwards every s[i], i > k, is >= s[k].
float select_kth(__local float *s, const int n, const int k)
{
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        const float pivot = s[(lo + hi) >> 1];
        int i = lo, j = hi;
        while (i <= j) {
            while (s[i] < pivot) ++i;
            while (s[j] > pivot) --j;
            if (i <= j) {
                const float t = s[i];
                s[i] = s[j];
                s[j] = t;
                ++i;
                --j;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break;
    }
    return s[k];
}

// numpy's median of s[0 .. n) (the mean of the two middle values when n is even).
float serial_median(__local float *s, const int n)
{
    const int k = (n - 1) / 2;
    const float a = select_kth(s, n, k);
    if (n & 1) return a;
    float b = s[k + 1];
    for (int i = k + 2; i < n; ++i) b = s[i] < b ? s[i] : b;
    return 0.5f * (a + b);
}

__kernel void hidden(__global const float *plain,      // (rows, half_n)
                     __global const float *dechirped,  // (rows, half_n)
                     const int half_n,
                     const int lo,                     // first bin of the band
                     __global const float *tracked,    // (rows,) tracked peak's bin, de-chirped
                     __global const float *plain_bin,  // (rows,) its bin in the plain spectrum
                     __global const float *others,     // (rows, m) other echoes' bins, NaN: none
                     const int m,
                     const int explain,                // EXPLAIN_BINS
                     const float sharp,                // SHARP
                     const float rival,                // 10^(-RIVAL_DB / 10)
                     const float sigmas,               // HIDDEN_SIGMAS
                     __global float *ratio,            // (rows,) out
                     __global float *centroid,         // (rows,) out, NaN: none
                     __global int *found,              // (rows,) out
                     __local float *s,                 // half_n - lo: the band, for the medians
                     __local float *red,               // 6 per work-item
                     __local float *floors)            // 2
{
    const int r = get_group_id(0);
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    const int n = half_n - lo;
    __global const float *p = plain + (size_t)r * half_n + lo;
    __global const float *d = dechirped + (size_t)r * half_n + lo;
    for (int i = lid; i < n; i += lsz) s[i] = p[i];
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) floors[0] = serial_median(s, n) / 0.69314718f;   // exponential noise: mean = median / ln 2
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int i = lid; i < n; i += lsz) s[i] = d[i];
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) floors[1] = serial_median(s, n) / 0.69314718f;
    barrier(CLK_LOCAL_MEM_FENCE);
    const float floor_p = floors[0], floor_d = floors[1];
    const float kt = rint(tracked[r]);
    const float kp = rint(plain_bin[r]);
    float target = 0.0f, near = 0.0f, excess_sum = 0.0f, free_bins = 0.0f, w_sum = 0.0f, wk_sum = 0.0f;
    for (int i = lid; i < n; i += lsz) {
        const float k = (float)(lo + i);
        int explained = 0;
        for (int j = 0; j < m; ++j) {
            const float b = others[(size_t)r * m + j];
            explained |= !isnan(b) && fabs(k - rint(b)) <= explain;
        }
        SURVEY_BIN(float, k, d[i] - floor_d, p[i] - floor_p, kt, kp, explained)
    }
    __local float *mine = red + 6 * lid;
    mine[0] = target;
    mine[1] = near;
    mine[2] = excess_sum;
    mine[3] = free_bins;
    mine[4] = w_sum;
    mine[5] = wk_sum;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) {
        for (int w = 1; w < lsz; ++w) {
            target += red[6 * w];
            near += red[6 * w + 1];
            excess_sum += red[6 * w + 2];
            free_bins += red[6 * w + 3];
            w_sum += red[6 * w + 4];
            wk_sum += red[6 * w + 5];
        }
        const float unexplained = excess_sum - target;
        const float q = target != 0.0f ? unexplained / target : 0.0f;
        const float noise = floor_p * sqrt(2.0f * free_bins);
        const int hit = target > 0.0f && near >= sharp * target && q >= rival && unexplained > sigmas * noise
                        && w_sum > sigmas * noise;
        ratio[r] = q;
        centroid[r] = hit ? wk_sum / w_sum : NAN;
        found[r] = hit;
    }
}

// ---- hidden on CPU devices: LANES rows a work-item (lanes.cl), in the lanes of a
// floatL (PoCL vectorises no work-item loop that holds a loop, see fft_lanes.cl). The
// bands are copied to local memory a bin per floatL, and each median is found exactly,
// with no sort, by bisection on the bit pattern of non-negative floats (which orders
// like their values): the least pattern with at least k + 1 values at or below it is
// the k-th smallest value; the medians are most of its time (PoCL, 2-core Sapphire
// Rapids, 520 rows of 1024 bins: 16 lanes 1.28 ms, 8 lanes 1.47). Counts are
// floatL and comparisons only feed float conditionals, & and |: Oclgrind evaluates !v,
// arithmetic on a vector comparison and integer vector conditionals against the
// specification (!-1 is -2, a true 1 ? 1 : 0 is 255).

// numpy's median of each lane of s[0 .. n)
floatL lanes_median(__local const floatL *s, const int n)
{
    const int k = (n - 1) / 2;
    intL lo = 0, hi = 0x7f800000;                  // +0 .. +inf
    for (int it = 0; it < 31; ++it) {
        const intL mid = lo + ((hi - lo) >> 1);
        floatL count = 0.0f;
        for (int i = 0; i < n; ++i) count += AS_INTL(s[i]) <= mid ? 1.0f : 0.0f;
        const floatL enough = count >= (float)(k + 1) ? 1.0f : 0.0f;
        hi = AS_INTL(enough > 0.5f ? AS_FLOATL(mid) : AS_FLOATL(hi));
        lo = AS_INTL(enough > 0.5f ? AS_FLOATL(lo) : AS_FLOATL(mid + 1));
    }
    const floatL a = AS_FLOATL(lo);
    if (n & 1) return a;
    floatL at_or_below = 0.0f;                     // the (k+1)-th smallest: a again, or the next
    floatL next = INFINITY;
    for (int i = 0; i < n; ++i) {
        const floatL v = s[i];
        at_or_below += v <= a ? 1.0f : 0.0f;
        next = ((v > a) & (v < next)) ? v : next;
    }
    return 0.5f * (a + (at_or_below >= (float)(k + 2) ? a : next));
}

__kernel void hidden_lanes(__global const float *plain, __global const float *dechirped, const int half_n,
                           const int lo, const int rows, __global const float *tracked,
                           __global const float *plain_bin, __global const float *others, const int m,
                           const int explain, const float sharp, const float rival, const float sigmas,
                           __global float *ratio, __global float *centroid, __global int *found,
                           __local floatL *sp,       // half_n - lo: the plain band, lane by lane
                           __local floatL *sd,       // half_n - lo: the de-chirped band
                           __local floatL *nearest)  // m: the other echoes' bins (NaN: none)
{
    const int r0 = LANES * get_group_id(0);
    const int n = half_n - lo;
    int row[LANES];
    float t[LANES], q[LANES];
    for (int l = 0; l < LANES; ++l) {
        row[l] = r0 + l < rows ? r0 + l : rows - 1;          // idle lanes repeat the last row
        t[l] = rint(tracked[row[l]]);
        q[l] = rint(plain_bin[row[l]]);
    }
    for (int i = 0; i < n; ++i) {
        float a[LANES], b[LANES];
        for (int l = 0; l < LANES; ++l) {
            a[l] = plain[(size_t)row[l] * half_n + lo + i];
            b[l] = dechirped[(size_t)row[l] * half_n + lo + i];
        }
        sp[i] = VLOADL(0, a);
        sd[i] = VLOADL(0, b);
    }
    for (int j = 0; j < m; ++j) {
        float o[LANES];
        for (int l = 0; l < LANES; ++l) o[l] = rint(others[(size_t)row[l] * m + j]);
        nearest[j] = VLOADL(0, o);
    }
    const floatL floor_p = lanes_median(sp, n) / 0.69314718f;      // exponential noise: mean = median / ln 2
    const floatL floor_d = lanes_median(sd, n) / 0.69314718f;
    const floatL kt = VLOADL(0, t), kp = VLOADL(0, q);
    floatL target = 0.0f, near = 0.0f, excess_sum = 0.0f, free_bins = 0.0f, w_sum = 0.0f, wk_sum = 0.0f;
    for (int i = 0; i < n; ++i) {
        const float k = (float)(lo + i);
        intL explained = 0;
        for (int j = 0; j < m; ++j) {
            const floatL b = nearest[j];
            explained |= (b == b) & (ABS(k - b) <= explain);      // b == b: not NaN
        }
        SURVEY_BIN(floatL, k, sd[i] - floor_d, sp[i] - floor_p, kt, kp, explained)
    }
    const floatL unexplained = excess_sum - target;
    const floatL qr = target != 0.0f ? unexplained / target : 0.0f;
    const floatL noise = floor_p * sqrt(2.0f * free_bins);
    const intL hit = (target > 0.0f) & (near >= sharp * target) & (qr >= rival) & (unexplained > sigmas * noise)
                     & (w_sum > sigmas * noise);
    const floatL cen = hit ? wk_sum / w_sum : NAN;
    float qv[LANES], cv[LANES];
    int hv[LANES];
    VSTOREL(qr, 0, qv);
    VSTOREL(cen, 0, cv);
    VSTOREL(hit, 0, hv);
    for (int l = 0; l < LANES && r0 + l < rows; ++l) {
        ratio[r0 + l] = qv[l];
        centroid[r0 + l] = cv[l];
        found[r0 + l] = hv[l] != 0;
    }
}

// The plain spectra of the surveyed half-sweeps summed in blocks of `block` rows (the
// last one shorter), for their mean spectra: one work-item a bin of a block, its rows
// read down a column (neighbouring work-items read neighbouring bins). Twin:
// fmcw_cl.echoes.block_sums.
__kernel void block_sums(__global const float *plain,  // (rows, half_n)
                         const int half_n, const int rows, const int block,
                         __global float *sums)          // (ceil(rows / block), half_n)
{
    const int k = get_global_id(0), b = get_global_id(1);
    if (k >= half_n) return;
    const int stop = min(rows, (b + 1) * block);
    float s = 0.0f;
    for (int r = b * block; r < stop; ++r) s += plain[(size_t)r * half_n + k];
    sums[(size_t)b * half_n + k] = s;
}
