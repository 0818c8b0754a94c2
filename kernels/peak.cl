// Stage 5b: the peak of one power spectrum held in local memory, bins [lo, hi):
// arg-max (ties: the lowest bin), Gaussian (log-parabola) interpolation, and the SNR
// over the mean power of the band outside +-guard bins of the peak. Called by the
// whole work-group (fft.cl's spectrum_peak); only the peak leaves the device.
// Twin: fmcw_cl.stages.spectrum.find_peaks.

// Fractional position of the peak at bin kk (clipped to the inner bins) of a power
// spectrum whose bins lie `stride` floats apart (1; 8 for one lane of fft_lanes.cl's
// float8 bins): a parabola through the log power of three bins (Gaussian interpolation).
float peak_position_strided(__local const float *pw, const int stride, const int half_n, int kk)
{
    kk = kk < 1 ? 1 : (kk > half_n - 2 ? half_n - 2 : kk);
    const float tiny = 1.0e-30f;
    const float a = log(pw[stride * (kk - 1)] + tiny);
    const float b = log(pw[stride * kk] + tiny);
    const float c = log(pw[stride * (kk + 1)] + tiny);
    const float den = a - 2.0f * b + c;
    float delta = den < 0.0f ? 0.5f * (a - c) / den : 0.0f;
    delta = delta < -0.5f ? -0.5f : (delta > 0.5f ? 0.5f : delta);
    return (float)kk + delta;
}

float peak_position(__local const float *pw, const int half_n, const int kk)
{
    return peak_position_strided(pw, 1, half_n, kk);
}

// Bins k0, k0 + step, ... below k1 of a power spectrum into the running arg-max (`best`
// at `arg`, ties: the bin seen first) and sum.
void scan_bins(__local const float *pw, const int k0, const int k1, const int step, float *best, int *arg,
               float *sum)
{
    for (int k = k0; k < k1; k += step) {
        const float p = pw[k];
        *sum += p;
        if (p > *best) { *best = p; *arg = k; }
    }
}

// The peak at bin `arg` of a band [lo, hi) whose power sums to `sum`: its fractional
// position and its SNR over the mean of the band outside +-guard bins of it.
void band_peak(__local const float *pw, const int half_n, const int lo, const int hi, const int guard,
               const int arg, const float sum, __global float *bin, __global float *snr)
{
    const int kk = arg < 1 ? 1 : (arg > half_n - 2 ? half_n - 2 : arg);
    const float tiny = 1.0e-30f;
    const int g0 = kk - guard < lo ? lo : kk - guard;
    const int g1 = kk + guard > hi - 1 ? hi - 1 : kk + guard;
    float inside = 0.0f;
    for (int k = g0; k <= g1; ++k) inside += pw[k];
    const int outside = (hi - lo) - (g1 - g0 + 1);
    // a band narrower than the guard has no outside: use the whole band's mean
    const float floor_level = outside > 0 ? (sum - inside) / (float)outside : sum / (float)(hi - lo);
    *bin = peak_position(pw, half_n, kk);
    *snr = 10.0f * log10(pw[kk] / (floor_level > tiny ? floor_level : tiny));
}

void local_peak(__local const float *pw,   // power of bins 0 .. half_n - 1
                const int half_n,
                const int lo,
                const int hi,
                const int guard,
                __local float *lval,       // scratch, one per work-item
                __local int *lidx,
                __local float *lsum,
                __global float *bin,       // out: fractional bin
                __global float *snr)       // out: dB
{
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    float best = -1.0f;
    int arg = lo;
    float sum = 0.0f;
    scan_bins(pw, lo + lid, hi, lsz, &best, &arg, &sum);
    lval[lid] = best;
    lidx[lid] = arg;
    lsum[lid] = sum;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int w = lsz / 2; w > 0; w >>= 1) {
        if (lid < w) {
            const float o = lval[lid + w];
            const int oi = lidx[lid + w];
            if (o > lval[lid] || (o == lval[lid] && oi < lidx[lid])) {
                lval[lid] = o;
                lidx[lid] = oi;
            }
            lsum[lid] += lsum[lid + w];
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (lid == 0) band_peak(pw, half_n, lo, hi, guard, lidx[0], lsum[0], bin, snr);
}
