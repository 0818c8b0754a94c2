// Stage 5a on CPU devices: what fft.cl's spectrum_peak computes (the de-chirp, the
// zero-padded FFT, the power, the peak and, on request, every CFAR echo and the power
// itself), LANES transforms per work-item, one in each lane of a floatL. PoCL turns a
// work-group's work-items into a loop that it vectorises only when the kernel body has
// no loop of its own, which an FFT has: spectrum_peak runs as scalar code there. Here
// the lanes are explicit, every load and store of the transform is a whole floatL and
// every twiddle is one value for all lanes (PoCL, 2-core EPYC: a 2048-point transform
// 2.5 us a row against 11-14 us). One work-item a group, its transforms in local memory.
// LANES: lanes.cl (PoCL, 2-core Skylake-SP: 16 lanes 15-20 % faster than 8).
// Twins: fmcw_cl.stages.doppler.measure, stages.spectrum.power_spectra and find_peaks,
// stages.cfar.detect.

SINCOS_CYCLES(sincos_lanes, floatL)
RADIX4(radix4_lanes, floatL)

// Sample j of the LANES rows r, as one vector built from scalar loads (scalar stores
// read back as a vector would stall on store forwarding).
#define ROWS8(r, j, o) r[o][j], r[o + 1][j], r[o + 2][j], r[o + 3][j], r[o + 4][j], r[o + 5][j], r[o + 6][j], \
    r[o + 7][j]
#if LANES == 16
#define ROWS(r, j) ((floatL)(ROWS8(r, j, 0), ROWS8(r, j, 8)))
#elif LANES == 4
#define ROWS(r, j) ((floatL)(r[0][j], r[1][j], r[2][j], r[3][j]))
#else
#define ROWS(r, j) ((floatL)(ROWS8(r, j, 0)))
#endif

// Sample x of each lane turned by -v b cycles (the de-chirp of load in fft.cl).
void dechirp_lanes(const floatL x, const floatL v, const float b, floatL *re, floatL *im)
{
    floatL c, s;
    sincos_lanes(v * b, &s, &c);
    *re = x * c;
    *im = -x * s;
}

// Sample j < points of each lane's transform input (load in fft.cl).
void load_lanes(__global const float *const *ra, __global const float *const *rb,
                     __global const float *beta, const floatL v, const int dechirp, const int j, floatL *re, floatL *im)
{
    const floatL xa = ROWS(ra, j);
    if (dechirp) {
        dechirp_lanes(xa, v, beta[j], re, im);
    } else {
        *im = ROWS(rb, j);
        *re = xa;
    }
}

// Samples j .. j + LANES - 1 (< points) of each lane's transform input, as load_lanes
// gives them one at a time: each row's LANES samples by one vector load, transposed in
// registers (PoCL, 2-core Sapphire Rapids: 8321 plain 2048-point transforms of 1000-point
// rows 13.5 to 11.8 ms).
void load_block(__global const float *const *ra, __global const float *const *rb,
                __global const float *beta, const floatL v, const int dechirp, const int j, floatL *re, floatL *im)
{
#pragma unroll
    for (int l = 0; l < LANES; ++l) re[l] = VLOADL(0, ra[l] + j);
    transpose_lanes(re);
    if (dechirp) {
        for (int i = 0; i < LANES; ++i) dechirp_lanes(re[i], v, beta[j + i], &re[i], &im[i]);
    } else {
#pragma unroll
        for (int l = 0; l < LANES; ++l) im[l] = VLOADL(0, rb[l] + j);
        transpose_lanes(im);
    }
}

// Lane l's value of bin k of a floatL array in local memory.
float lane(__local const floatL *a, const int k, const int l)
{
    return ((__local const float *)a)[LANES * k + l];
}

// peak_position (peak.cl) of lane l
float peak_position_lane(__local const floatL *pw, const int half_n, const int kk, const int l)
{
    return peak_position_strided((__local const float *)pw + l, LANES, half_n, kk);
}

// local_peak (peak.cl) of every lane, each in its band [lo[l], hi[l]): the band's arg-max
// (ties: the lowest bin), then the floor as the mean of the band outside +-guard of it,
// summed apart (no difference of two large sums).
void lanes_peak(__local const floatL *pw, const int half_n, const int *lo, const int *hi, const int guard,
                const int *sweep, __global float *bin, __global float *snr)
{
    int k0 = half_n, k1 = 0;                       // the lanes' bands' union
    for (int l = 0; l < LANES; ++l) {
        k0 = IMIN(k0, lo[l]);
        k1 = IMAX(k1, hi[l]);
    }
    const intL vlo = VLOADL(0, lo), vhi = VLOADL(0, hi);
    floatL best = -1.0f, total = 0.0f;
    intL arg = vlo;
    for (int k = k0; k < k1; ++k) {
        const floatL p = pw[k];
        const intL in = ((intL)k >= vlo) & ((intL)k < vhi);
        const intL gt = in & (p > best);
        best = gt ? p : best;
        arg = gt ? (intL)k : arg;
        total += in ? p : (floatL)0.0f;
    }
    intL kk = arg < 1 ? (intL)1 : arg;
    kk = kk > half_n - 2 ? (intL)(half_n - 2) : kk;
    const intL g0 = kk - guard, g1 = kk + guard;
    floatL outside = 0.0f;
    for (int k = k0; k < k1; ++k) {
        const intL in = ((intL)k >= vlo) & ((intL)k < vhi);
        outside += (in & (((intL)k < g0) | ((intL)k > g1))) ? pw[k] : (floatL)0.0f;
    }
    float o[LANES], t[LANES];
    int c[LANES];
    VSTOREL(outside, 0, o);
    VSTOREL(total, 0, t);
    VSTOREL(kk, 0, c);
    for (int l = 0; l < LANES; ++l) {
        if (sweep[l] < 0) continue;
        const int a = IMAX(c[l] - guard, lo[l]), b = IMIN(c[l] + guard, hi[l] - 1);
        const int n_out = (hi[l] - lo[l]) - (b - a + 1);
        const float floor_level = n_out > 0 ? o[l] / (float)n_out : t[l] / (float)(hi[l] - lo[l]);
        bin[sweep[l]] = peak_position_lane(pw, half_n, c[l], l);
        snr[sweep[l]] = 10.0f * log10(lane(pw, c[l], l) / (floor_level > 1.0e-30f ? floor_level : 1.0e-30f));
    }
}

// The echoes among bin k of every lane (`echo`; power p over the training mean `mean`)
// appended to their lanes' lists, at most max_echoes each.
void lanes_record(__local const floatL *pw, const int half_n, const int k, const floatL p, const floatL mean,
                  const intL echo, const int max_echoes, const int *sweep, int *count,
                  __global float *echo_bin, __global float *echo_snr)
{
    int hit[LANES];
    float pv[LANES], mv[LANES];
    VSTOREL(echo, 0, hit);
    VSTOREL(p, 0, pv);
    VSTOREL(mean, 0, mv);
    for (int l = 0; l < LANES; ++l) {
        if (sweep[l] < 0 || !hit[l] || count[l] >= max_echoes) continue;
        const size_t e = (size_t)sweep[l] * max_echoes + count[l];
        echo_bin[e] = peak_position_lane(pw, half_n, k, l);
        echo_snr[e] = 10.0f * log10(pv[l] / mv[l]);
        ++count[l];
    }
}

// The sum and maximum of the 4 bins from j into s8[j] and mx[j], and, where `fold`,
// into those of the 8 from j - 4 (lanes_cfar's tables).
void cfar_fours(__local const floatL *pw, __local floatL *s8, __local floatL *mx, const int j, const int fold)
{
    const floatL s4 = (pw[j] + pw[j + 1]) + (pw[j + 2] + pw[j + 3]);
    const floatL m4 = fmax(fmax(pw[j], pw[j + 1]), fmax(pw[j + 2], pw[j + 3]));
    s8[j] = s4;
    mx[j] = m4;
    if (fold) {
        s8[j - 4] += s4;
        mx[j - 4] = fmax(mx[j - 4], m4);
    }
}

// local_cfar (cfar.cl) of every lane, bins [lo, half_n). Each bin's guard maxima and
// training sums come from tables of running maxima of 8 bins (mx) and sums of 16
// (sm) where the windows are whole (guard 8 and train 16, stages.cfar's), taken
// directly near the band's ends or for other widths. The bins whose windows are all
// whole run a loop of their own, without a branch on where they lie (PoCL, 2-core EPYC:
// the echo test 1.6x faster).
void lanes_cfar(__local const floatL *pw, const int half_n, const int lo, const int guard, const int train,
                __global const float *scale, const int max_echoes, __local floatL *mx, __local floatL *sm,
                const int *sweep, __global float *echo_bin, __global float *echo_snr, __global int *echo_count)
{
    const int tables = guard == 8 && train == 16;
    // One pass: the sum and maximum of the 4 bins from j (pairs of pairs), folded in place
    // into those of the 8 from j - 4 (s8: the second half of mx's buffer), whose sums
    // from j - 12 and j - 4 give the 16 from j - 12; the same tree of pairwise sums as a
    // pass a level, three passes over the tables fewer (PoCL, 2-core Skylake-SP: the echo
    // test of 6000 plain rows 3.7 to 3.0 ms). An entry is valid where its window lies
    // inside [0, half_n).
    __local floatL *s8 = mx + half_n;
    int j = 0;
    for (; j < 4 && j + 3 < half_n; ++j) cfar_fours(pw, s8, mx, j, 0);
    for (; j < 12 && j + 3 < half_n; ++j) cfar_fours(pw, s8, mx, j, 1);
    for (; j + 3 < half_n; ++j) {
        cfar_fours(pw, s8, mx, j, 1);
        sm[j - 12] = s8[j - 12] + s8[j - 4];
    }
    int count[LANES] = {0};
    // [k0, k1): every window whole and inside [lo, half_n)
    const int reach = guard + train;
    const int k0 = tables ? IMIN(lo + reach, half_n) : half_n;
    const int k1 = tables ? IMAX(k0, half_n - reach) : half_n;
    for (int k = lo; k < half_n; ++k) {
        if (k == k0) {
            const int n = 2 * train;
            const float limit = scale[n];
            for (; k < k1; ++k) {
                const floatL p = pw[k];
                floatL sum = sm[k - reach];
                sum += sm[k + guard + 1];
                const intL echo = (p > mx[k - guard]) & (p >= mx[k + 1]) & (p * (float)n > limit * sum);
                if (any_lanes(echo))
                    lanes_record(pw, half_n, k, p, sum / (float)n, echo, max_echoes, sweep, count, echo_bin,
                                 echo_snr);
            }
            if (k == half_n) break;
        }
        const floatL p = pw[k];
        floatL left = -1.0f, right = -1.0f;        // powers are >= 0: an empty side passes
        if (tables && k - guard >= 0) {
            left = mx[k - guard];
        } else {
            for (int j = IMAX(k - guard, 0); j < k; ++j) left = fmax(left, pw[j]);
        }
        if (tables && k + guard < half_n) {
            right = mx[k + 1];
        } else {
            for (int j = k + 1; j < IMIN(k + guard + 1, half_n); ++j) right = fmax(right, pw[j]);
        }
        const int a0 = IMAX(k - guard - train, lo), a1 = IMAX(k - guard, lo);
        const int b0 = IMIN(k + guard + 1, half_n), b1 = IMIN(k + guard + train + 1, half_n);
        floatL sum = 0.0f;
        if (tables && a1 - a0 == train) {
            sum = sm[a0];
        } else {
            for (int j = a0; j < a1; ++j) sum += pw[j];
        }
        if (tables && b1 - b0 == train) {
            sum += sm[b0];
        } else {
            for (int j = b0; j < b1; ++j) sum += pw[j];
        }
        const int n = (a1 - a0) + (b1 - b0);
        // p > scale[n] * sum / n, without a division per bin (n = 0: scale is infinite)
        const intL echo = (p > left) & (p >= right) & (p * (float)n > scale[n] * sum);
        if (any_lanes(echo))
            lanes_record(pw, half_n, k, p, sum / (float)n, echo, max_echoes, sweep, count, echo_bin, echo_snr);
    }
    for (int l = 0; l < LANES; ++l) {
        if (sweep[l] < 0) continue;
        echo_count[sweep[l]] = count[l];
        for (int i = count[l]; i < max_echoes; ++i) {
            echo_bin[(size_t)sweep[l] * max_echoes + i] = NAN;
            echo_snr[(size_t)sweep[l] * max_echoes + i] = NAN;
        }
    }
}

#define BLOCK_POINTS (512 / LANES)

// Butterflies t0 .. t1 - 1 of the radix-4 stage of blocks of lb points (fft.cl's fft_dif)
void stage_lanes(__local floatL *re, __local floatL *im, const int nfft, const int lb, const int t0, const int t1,
                 __global const float *tw_re, __global const float *tw_im)
{
    const int qq = lb >> 2;
    const int step = nfft / lb;
    for (int t = t0; t < t1; ++t) {
        const int j = t & (qq - 1);
        const int b = ((t - j) << 2) + j;
        radix4_lanes(re, im, b, qq, j * step, re[b], im[b], re[b + qq], im[b + qq],
                     re[b + 2 * qq], im[b + 2 * qq], re[b + 3 * qq], im[b + 3 * qq], tw_re, tw_im);
    }
}

// The arguments of spectrum_peak but its local buffers: one work-group of one
// work-item per LANES transforms (plain rows two to a transform, as there).
__kernel void spectrum_lanes(__global const float *x, const int sweeps, const int points,
                             __global const int *index, const int indexed,
                             __global const float *beta, __global const float *velocity, const int dechirp,
                             __global const float *tw_re, __global const float *tw_im,
                             __global const int *perm, const int nfft, const int lo, const int hi,
                             __global const int *band, const int banded,
                             const int guard, __global float *bin, __global float *snr,
                             __global float *power, const int keep_power, const int scatter,
                             const int echoes, const int cfar_guard, const int train,
                             __global const float *scale, const int max_echoes,
                             __global float *echo_bin, __global float *echo_snr, __global int *echo_count,
                             __global const int *listed, const int counted,
                             __global const int *group_first, const int groups, const int plain,
                             SECOND_JOB,
                             __local floatL *re,       // nfft
                             __local floatL *im,       // nfft
                             __local floatL *pw)       // nfft: the power of a transform's two rows
{
    TO_SECOND_JOB
    const int n = counted ? min(sweeps, listed[0]) : sweeps;
    const int transforms = dechirp ? n : plain;
    // LANES transforms a group; a counted launch has fewer groups than blocks, each
    // taking every get_num_groups-th block (a listed few spread over all cores)
    for (int w = get_group_id(0); LANES * w < transforms; w += get_num_groups(0)) {
        __global const float *ra[LANES];
        __global const float *rb[LANES];
        int first[LANES];                                  // first sweep of each lane, -1: idle lane
        int two[LANES];                                    // whether its plain transform has two rows
        float vl[LANES];
        for (int l = 0; l < LANES; ++l) {
            const int g = LANES * w + l;
            const int active = g < transforms;
            int end = n;
            const int s = dechirp || !active ? g : plain_transform(g, group_first, groups, n, &end);
            first[l] = active ? s : -1;
            two[l] = !dechirp && active && s + 1 < end;
            const int row = active ? (indexed ? index[s] : s) : 0;
            ra[l] = x + (size_t)row * points;
            // a plain row's partner; a group's lone last row pairs with itself (the copy is
            // not reported)
            rb[l] = two[l] ? ra[l] + points : ra[l];
            vl[l] = dechirp && active ? velocity[s] : 0.0f;
        }
        const floatL v = VLOADL(0, vl);
        const int q = nfft >> 2;
        // the first stage straight from the input (see fft.cl), whose second half is zero:
        // inputs j and j + q up to n1, j alone up to n0 (points), none after; three loops,
        // no test of j in any (PoCL: a branch on where a sample lies costs a loop's speed)
        const int n0 = IMIN(q, points), n1 = IMIN(q, IMAX(points - q, 0));
        int j = 0;
#if SHUFFLES
        for (; j + LANES <= n1; j += LANES) {
            floatL a0r[LANES], a0i[LANES], a1r[LANES], a1i[LANES];
            load_block(ra, rb, beta, v, dechirp, j, a0r, a0i);
            load_block(ra, rb, beta, v, dechirp, j + q, a1r, a1i);
#pragma unroll
            for (int i = 0; i < LANES; ++i)
                radix4_lanes(re, im, j + i, q, j + i, a0r[i], a0i[i], a1r[i], a1i[i], 0.0f, 0.0f, 0.0f, 0.0f,
                             tw_re, tw_im);
        }
#endif
        for (; j < n1; ++j) {
            floatL a0r, a0i, a1r, a1i;
            load_lanes(ra, rb, beta, v, dechirp, j, &a0r, &a0i);
            load_lanes(ra, rb, beta, v, dechirp, j + q, &a1r, &a1i);
            radix4_lanes(re, im, j, q, j, a0r, a0i, a1r, a1i, 0.0f, 0.0f, 0.0f, 0.0f, tw_re, tw_im);
        }
#if SHUFFLES
        for (; j + LANES <= n0; j += LANES) {
            floatL a0r[LANES], a0i[LANES];
            load_block(ra, rb, beta, v, dechirp, j, a0r, a0i);
#pragma unroll
            for (int i = 0; i < LANES; ++i)
                radix4_lanes(re, im, j + i, q, j + i, a0r[i], a0i[i], 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, tw_re,
                             tw_im);
        }
#endif
        for (; j < n0; ++j) {
            floatL a0r, a0i;
            load_lanes(ra, rb, beta, v, dechirp, j, &a0r, &a0i);
            radix4_lanes(re, im, j, q, j, a0r, a0i, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, tw_re, tw_im);
        }
        for (; j < q; ++j) radix4_lanes(re, im, j, q, j, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, tw_re, tw_im);
        // the later stages block by block: from blocks of BLOCK_POINTS points on, each block
        // is a transform of its own, done whole while it is in L1 (the same butterflies in
        // another order; those 8321 transforms 11.8 to 10.5 ms at 32 points, 10.9 at 128)
        int lb = q;
        for (; lb >= 4 && lb > BLOCK_POINTS; lb >>= 2) stage_lanes(re, im, nfft, lb, 0, nfft >> 2, tw_re, tw_im);
        for (int base = 0; lb >= 2 && base < nfft; base += lb) {
            int l = lb;
            for (; l >= 4; l >>= 2) stage_lanes(re, im, nfft, l, base >> 2, (base + lb) >> 2, tw_re, tw_im);
            if (l == 2) {
                for (int b = base; b < base + lb; b += 2) {
                    const floatL a0r = re[b], a0i = im[b], a1r = re[b + 1], a1i = im[b + 1];
                    re[b] = a0r + a1r;
                    im[b] = a0i + a1i;
                    re[b + 1] = a0r - a1r;
                    im[b + 1] = a0i - a1i;
                }
            }
        }
        const int half_n = nfft >> 1;
        const int rows = dechirp ? 1 : 2;
        if (dechirp) {
            for (int k = 0; k < half_n; ++k) {
                const int p = perm[k];
                pw[k] = re[p] * re[p] + im[p] * im[p];
            }
        } else {                          // both rows of a plain transform from one pass
            for (int k = 0; k < half_n; ++k) {
                const int p = perm[k], m = perm[(nfft - k) & (nfft - 1)];
                const floatL rp = re[p], rm = re[m], ip = im[p], imm = im[m];
                const floatL ar = rp + rm, ai = ip - imm, br = ip + imm, bi = rp - rm;
                pw[k] = 0.25f * (ar * ar + ai * ai);
                pw[half_n + k] = 0.25f * (br * br + bi * bi);
            }
        }
        // the transform is no longer needed: re and im hold the CFAR's tables
        for (int r = 0; r < rows; ++r) {
            __local const floatL *p_r = pw + r * half_n;
            int sweep[LANES];
            for (int l = 0; l < LANES; ++l) sweep[l] = first[l] >= 0 && (r == 0 || two[l]) ? first[l] + r : -1;
            if (keep_power) {
                for (int l = 0; l < LANES; ++l) {
                    if (sweep[l] < 0) continue;
                    __global float *out = power + (size_t)(scatter ? index[sweep[l]] : sweep[l]) * half_n;
                    for (int k = 0; k < half_n; ++k) out[k] = lane(p_r, k, l);
                }
            }
            // each lane's row's own band where the search has one (a pair's along its object)
            int lo_l[LANES], hi_l[LANES];
            for (int l = 0; l < LANES; ++l) {
                const int row = sweep[l] < 0 ? -1 : (indexed ? index[first[l]] : first[l]) + r;
                lo_l[l] = banded && row >= 0 ? band[2 * row] : lo;
                hi_l[l] = banded && row >= 0 ? band[2 * row + 1] : hi;
            }
            lanes_peak(p_r, half_n, lo_l, hi_l, guard, sweep, bin, snr);
            if (echoes) {
                lanes_cfar(p_r, half_n, lo, cfar_guard, train, scale, max_echoes, re, im, sweep,
                           echo_bin, echo_snr, echo_count);
            }
        }
    }
}
