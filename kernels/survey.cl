// Stage 5e: the energy of a surveyed half-sweep that no sharp echo explains, on the
// spectra where fft.cl left them (plain, and de-chirped at the pair's velocity): one
// work-group per half-sweep, only three numbers come back. The noise floors are the
// spectra's medians over ln 2 (the band copied to local memory, selected by one
// work-item), the rest masked sums (partial sums per work-item, added by one). Only
// straight-line barriers: PoCL compiles it in a moment. Twin: fmcw_cl.echoes.hidden
// (its docstring has the quantities).

#define ABS(v) ((v) < 0.0f ? -(v) : (v))

// One bin's share of the sums, for T float (`hidden`: a work-item's bins of one row) or
// float8 (`hidden_lanes`: eight rows): k the bin, ed and e the de-chirped and plain
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

// ---- hidden on CPU devices: eight rows a work-item, in the lanes of a float8 (PoCL
// vectorises no work-item loop that holds a loop, see fft_lanes.cl). The bands are
// copied to local memory a bin per float8, and each median is found exactly, with no
// sort, by bisection on the bit pattern of non-negative floats (which orders like their
// values): the least pattern with at least k + 1 values at or below it is the k-th
// smallest value. Counts are float8 and comparisons only feed float conditionals, & and
// |: Oclgrind evaluates !v, arithmetic on a vector comparison and integer vector
// conditionals against the specification (!-1 is -2, a true 1 ? 1 : 0 is 255).

// numpy's median of each lane of s[0 .. n)
float8 lanes_median(__local const float8 *s, const int n)
{
    const int k = (n - 1) / 2;
    int8 lo = 0, hi = 0x7f800000;                  // +0 .. +inf
    for (int it = 0; it < 31; ++it) {
        const int8 mid = lo + ((hi - lo) >> 1);
        float8 count = 0.0f;
        for (int i = 0; i < n; ++i) count += as_int8(s[i]) <= mid ? 1.0f : 0.0f;
        const float8 enough = count >= (float)(k + 1) ? 1.0f : 0.0f;
        hi = as_int8(enough > 0.5f ? as_float8(mid) : as_float8(hi));
        lo = as_int8(enough > 0.5f ? as_float8(lo) : as_float8(mid + 1));
    }
    const float8 a = as_float8(lo);
    if (n & 1) return a;
    float8 at_or_below = 0.0f;                     // the (k+1)-th smallest: a again, or the next
    float8 next = INFINITY;
    for (int i = 0; i < n; ++i) {
        const float8 v = s[i];
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
                           __local float8 *sp,       // half_n - lo: the plain band, lane by lane
                           __local float8 *sd,       // half_n - lo: the de-chirped band
                           __local float8 *nearest)  // m: the other echoes' bins (NaN: none)
{
    const int r0 = 8 * get_group_id(0);
    const int n = half_n - lo;
    int row[8];
    float t[8], q[8];
    for (int l = 0; l < 8; ++l) {
        row[l] = r0 + l < rows ? r0 + l : rows - 1;          // idle lanes repeat the last row
        t[l] = rint(tracked[row[l]]);
        q[l] = rint(plain_bin[row[l]]);
    }
    for (int i = 0; i < n; ++i) {
        float a[8], b[8];
        for (int l = 0; l < 8; ++l) {
            a[l] = plain[(size_t)row[l] * half_n + lo + i];
            b[l] = dechirped[(size_t)row[l] * half_n + lo + i];
        }
        sp[i] = vload8(0, a);
        sd[i] = vload8(0, b);
    }
    for (int j = 0; j < m; ++j) {
        float o[8];
        for (int l = 0; l < 8; ++l) o[l] = rint(others[(size_t)row[l] * m + j]);
        nearest[j] = vload8(0, o);
    }
    const float8 floor_p = lanes_median(sp, n) / 0.69314718f;      // exponential noise: mean = median / ln 2
    const float8 floor_d = lanes_median(sd, n) / 0.69314718f;
    const float8 kt = vload8(0, t), kp = vload8(0, q);
    float8 target = 0.0f, near = 0.0f, excess_sum = 0.0f, free_bins = 0.0f, w_sum = 0.0f, wk_sum = 0.0f;
    for (int i = 0; i < n; ++i) {
        const float k = (float)(lo + i);
        int8 explained = 0;
        for (int j = 0; j < m; ++j) {
            const float8 b = nearest[j];
            explained |= (b == b) & (ABS(k - b) <= explain);      // b == b: not NaN
        }
        SURVEY_BIN(float8, k, sd[i] - floor_d, sp[i] - floor_p, kt, kp, explained)
    }
    const float8 unexplained = excess_sum - target;
    const float8 qr = target != 0.0f ? unexplained / target : 0.0f;
    const float8 noise = floor_p * sqrt(2.0f * free_bins);
    const int8 hit = (target > 0.0f) & (near >= sharp * target) & (qr >= rival) & (unexplained > sigmas * noise)
                     & (w_sum > sigmas * noise);
    const float8 cen = hit ? wk_sum / w_sum : NAN;
    float qv[8], cv[8];
    int hv[8];
    vstore8(qr, 0, qv);
    vstore8(cen, 0, cv);
    vstore8(hit, 0, hv);
    for (int l = 0; l < 8 && r0 + l < rows; ++l) {
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
