// Stage 5a: de-chirp, zero-pad and FFT each half-sweep in local memory, then its peak
// (peak.cl) and, on request, every echo (cfar.cl; both built into the same program). One work-group per half-sweep, thousands
// per launch. The transform is radix-4 decimation in frequency, in place (one
// complex buffer of nfft: 16 KB at 2048 points, so it fits every GPU's local memory),
// with a last radix-2 stage when log2(nfft) is odd; its output is in digit-reversed
// order, which `perm` undoes while the power is taken. Only the peaks leave the
// device, and the power of bins 0 .. nfft/2 - 1 when `keep_power` asks for it (in the
// rows of `index` when `scatter`: integrate.cl's store of spectra kept between passes).
// De-chirp: x_j * exp(-2 pi i v beta_j), the phase reduced modulo one cycle first so
// that float32 keeps its precision. Twins: fmcw_cl.stages.doppler.measure and
// fmcw_cl.stages.spectrum.power_spectra.

// The device functions of the transform, written once for a scalar type T (the butterfly
// here, the de-chirp's sine and cosine in cycles.cl): float here, float8 in fft_lanes.cl
// (eight transforms in lanes; the files share a program).

// One radix-4 decimation-in-frequency butterfly: the 4-point DFT of a0..a3, outputs
// 1..3 turned by the twiddles w^e, w^2e, w^3e (one for all lanes), written to b, b + q,
// b + 2q, b + 3q.
#define RADIX4(NAME, T)                                                                          \
void NAME(__local T *re, __local T *im, const int b, const int q, const int e,                   \
          const T a0r, const T a0i, const T a1r, const T a1i,                                    \
          const T a2r, const T a2i, const T a3r, const T a3i,                                    \
          __global const float *tw_re, __global const float *tw_im)                              \
{                                                                                                \
    const T s02r = a0r + a2r, s02i = a0i + a2i;                                                  \
    const T d02r = a0r - a2r, d02i = a0i - a2i;                                                  \
    const T s13r = a1r + a3r, s13i = a1i + a3i;                                                  \
    const T d13r = a1r - a3r, d13i = a1i - a3i;                                                  \
    const T y1r = d02r + d13i, y1i = d02i - d13r;    /* d02 - i d13 */                           \
    const T y2r = s02r - s13r, y2i = s02i - s13i;                                                \
    const T y3r = d02r - d13i, y3i = d02i + d13r;    /* d02 + i d13 */                           \
    const float w1r = tw_re[e], w1i = tw_im[e];                                                  \
    const float w2r = tw_re[2 * e], w2i = tw_im[2 * e];                                          \
    const float w3r = tw_re[3 * e], w3i = tw_im[3 * e];                                          \
    re[b] = s02r + s13r;                                                                         \
    im[b] = s02i + s13i;                                                                         \
    re[b + q] = y1r * w1r - y1i * w1i;                                                           \
    im[b + q] = y1r * w1i + y1i * w1r;                                                           \
    re[b + 2 * q] = y2r * w2r - y2i * w2i;                                                       \
    im[b + 2 * q] = y2r * w2i + y2i * w2r;                                                       \
    re[b + 3 * q] = y3r * w3r - y3i * w3i;                                                       \
    im[b + 3 * q] = y3r * w3i + y3i * w3r;                                                       \
}

SINCOS_CYCLES(sincos_cycles, float)
RADIX4(radix4, float)

// The stages of blocks of lb points and smaller (lb = n: the whole transform), in place.
void fft_dif(__local float *re, __local float *im, const int n, int lb,
             __global const float *tw_re, __global const float *tw_im)  // exp(-2 pi i m / n), m < n
{
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    for (; lb >= 4; lb >>= 2) {
        const int q = lb >> 2;
        const int step = n / lb;
        for (int t = lid; t < (n >> 2); t += lsz) {
            const int j = t & (q - 1);
            const int b = ((t - j) << 2) + j;
            radix4(re, im, b, q, j * step, re[b], im[b], re[b + q], im[b + q],
                   re[b + 2 * q], im[b + 2 * q], re[b + 3 * q], im[b + 3 * q], tw_re, tw_im);
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (lb == 2) {
        for (int t = lid; t < (n >> 1); t += lsz) {
            const int b = t << 1;
            const float a0r = re[b], a0i = im[b];
            const float a1r = re[b + 1], a1i = im[b + 1];
            re[b] = a0r + a1r;
            im[b] = a0i + a1i;
            re[b + 1] = a0r - a1r;
            im[b + 1] = a0i - a1i;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
}

// Sample j of the transform's input: a half-sweep de-chirped, x_j exp(-2 pi i v beta_j),
// or two plain (real) half-sweeps packed as a + i b.
void load(__global const float *ra, __global const float *rb, __global const float *beta,
          const float v, const int dechirp, const int j, float *re, float *im)
{
    const float xr = ra[j];
    if (dechirp) {
        float c, sn;
        sincos_cycles(v * beta[j], &sn, &c);
        *re = xr * c;
        *im = -xr * sn;
    } else {
        *re = xr;
        *im = rb ? rb[j] : 0.0f;
    }
}

// A plain (real) half-sweep's spectrum is Hermitian, so plain rows go two to a
// transform, Z = FFT(a + i b): A_k = (Z_k + conj Z_-k) / 2, B_k = (Z_k - conj Z_-k) / 2i.
// Rows pair within their group (a chunk of the delay's trials), from its first row on,
// a group's odd last row alone: a row's float rounding then depends on its group only.

// The first sweep of plain transform g and the end of its group (`first`: the groups'
// first rows, ascending from 0; `n`: all rows).
int plain_transform(const int g, __global const int *first, const int groups, const int n, int *end)
{
    int t = g, a = 0;
    *end = n;
    for (int k = 0; k < groups; ++k) {
        a = first[k];
        *end = k + 1 < groups ? first[k + 1] : n;
        const int c = (*end - a + 1) >> 1;          // the group's transforms
        if (t < c) break;
        t -= c;
    }
    return a + 2 * t;
}

// A launch measures one job or two (a pair's rising and falling half-sweeps): the second
// job's rows, Doppler basis, bands and outputs, taken by work-group row 1 (both spectrum
// kernels).
#define SECOND_JOB                                                                      \
    __global const float *x_b, __global const float *beta_b, __global const int *band_b, \
    __global float *bin_b,                                                              \
    __global float *snr_b, __global float *power_b, __global float *echo_bin_b,        \
    __global float *echo_snr_b, __global int *echo_count_b
#define TO_SECOND_JOB                                                                   \
    if (get_group_id(1)) {                                                              \
        x = x_b;                                                                        \
        beta = beta_b;                                                                  \
        band = band_b;                                                                  \
        bin = bin_b;                                                                    \
        snr = snr_b;                                                                    \
        power = power_b;                                                                \
        echo_bin = echo_bin_b;                                                          \
        echo_snr = echo_snr_b;                                                          \
        echo_count = echo_count_b;                                                      \
    }

// De-chirped rows are complex: one per transform, of the rows listed in `index` when
// `indexed` (the tracker's later passes re-measure only the pairs whose velocity moved).
__kernel void spectrum_peak(__global const float *x,          // (rows, points)
                            const int sweeps,                 // transforms' rows (plain: all)
                            const int points,
                            __global const int *index,        // de-chirp: row of each sweep
                            const int indexed,                // 0: sweep s is row s
                            __global const float *beta,       // cycles per m/s, (points,)
                            __global const float *velocity,   // m/s, one per sweep
                            const int dechirp,                // 0: plain spectra, packed
                            __global const float *tw_re,      // (nfft,)
                            __global const float *tw_im,
                            __global const int *perm,         // bin k sits at perm[k], k < nfft
                            const int nfft,
                            const int lo,
                            const int hi,
                            __global const int *band,         // banded: [lo, hi) of each row
                            const int banded,
                            const int guard,
                            __global float *bin,              // (sweeps,)
                            __global float *snr,              // (sweeps,)
                            __global float *power,            // (sweeps, nfft/2) if keep_power
                            const int keep_power,
                            const int scatter,                // power of sweep s in row index[s]
                            const int echoes,                 // 1: list every echo (cfar.cl)
                            const int cfar_guard,
                            const int train,
                            __global const float *scale,      // CFAR factor per training count
                            const int max_echoes,
                            __global float *echo_bin,         // (sweeps, max_echoes)
                            __global float *echo_snr,         // (sweeps, max_echoes)
                            __global int *echo_count,         // (sweeps,)
                            __global const int *listed,       // counted: listed[0] sweeps at most
                            const int counted,                // (the tracker's list, kernels/track.cl)
                            __global const int *group_first,  // plain: each group's first row
                            const int groups,
                            const int plain,                  // plain: the transforms
                            SECOND_JOB,
                            __local float *re,                // nfft
                            __local float *im,                // nfft
                            __local float *pw,                // nfft/2
                            __local float *scratch,           // 3 per work-item
                            __local uchar *flag)              // nfft/2 when echoes
{
    TO_SECOND_JOB
    const int n = counted ? min(sweeps, listed[0]) : sweeps;
    // a transform a group; a counted launch has fewer groups than transforms, each
    // taking every get_num_groups-th (uniform in the group: barriers are safe)
    for (int g = get_group_id(0); g < (dechirp ? n : plain); g += get_num_groups(0)) {
        const int lid = get_local_id(0);
        const int lsz = get_local_size(0);
        int end = n;
        const int s = dechirp ? g : plain_transform(g, group_first, groups, n, &end);   // its first sweep
        const int rows = dechirp || s + 1 == end ? 1 : 2;
        const float v = dechirp ? velocity[s] : 0.0f;
        __global const float *ra = x + (size_t)(indexed ? index[s] : s) * points;
        __global const float *rb = rows == 2 ? ra + points : 0;
        // the first radix-4 stage straight from the input: its upper half is the zero
        // padding (points <= nfft / 2), so each butterfly has two inputs
        const int q = nfft >> 2;
        for (int j = lid; j < q; j += lsz) {
            float a0r = 0.0f, a0i = 0.0f, a1r = 0.0f, a1i = 0.0f;
            if (j < points) load(ra, rb, beta, v, dechirp, j, &a0r, &a0i);
            if (j + q < points) load(ra, rb, beta, v, dechirp, j + q, &a1r, &a1i);
            radix4(re, im, j, q, j, a0r, a0i, a1r, a1i, 0.0f, 0.0f, 0.0f, 0.0f, tw_re, tw_im);
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        fft_dif(re, im, nfft, q, tw_re, tw_im);
        const int half_n = nfft >> 1;
        for (int r = 0; r < rows; ++r) {                  // uniform in the group: barriers are safe
            __global float *out = power + (size_t)(scatter ? index[s] : s + r) * half_n;
            for (int k = lid; k < half_n; k += lsz) {
                const int p = perm[k];
                float e;
                if (dechirp) {
                    e = re[p] * re[p] + im[p] * im[p];
                } else {
                    const int m = perm[(nfft - k) & (nfft - 1)];
                    const float cr = r == 0 ? re[p] + re[m] : im[p] + im[m];
                    const float ci = r == 0 ? im[p] - im[m] : re[p] - re[m];
                    e = 0.25f * (cr * cr + ci * ci);
                }
                pw[k] = e;
                if (keep_power) out[k] = e;
            }
            barrier(CLK_LOCAL_MEM_FENCE);
            // the row's own band where the search has one (a pair's along its object)
            const int row = (indexed ? index[s] : s) + r;
            local_peak(pw, half_n, banded ? band[2 * row] : lo, banded ? band[2 * row + 1] : hi, guard, scratch,
                       (__local int *)(scratch + lsz), scratch + 2 * lsz, bin + s + r, snr + s + r);
            if (echoes) {
                const size_t e = (size_t)(s + r) * max_echoes;
                // every echo above the minimum range, the band's top (--max-range) aside
                local_cfar(pw, half_n, lo, half_n, cfar_guard, train, scale, max_echoes, flag,
                           (__local int *)scratch, echo_bin + e, echo_snr + e, echo_count + s + r);
            }
            barrier(CLK_LOCAL_MEM_FENCE);
        }
    }
}
