// Stage 5c: every echo of one power spectrum held in local memory, by a cell-averaging
// CFAR detector. Bin k of [lo, hi) is an echo when it is the largest of k - guard ..
// k + guard (ties: the lowest) and stands above scale[n] times the mean of its n
// training cells (train bins a side beyond the guard, never below lo). Called by the
// whole work-group (fft.cl's spectrum_peak) on a plain spectrum; writes the first
// max_echoes echoes in bin order: the group flags the bins, each work-item counts the
// flags of its own contiguous span, an exclusive scan of the counts gives each its
// first slot, so the list is in bin order without a serial pass over the spectrum.
// Twin: fmcw_cl.stages.cfar.detect.

// p / (training mean) of bin k when it is an echo, else 0.
float cfar_ratio(__local const float *pw, const int half_n, const int lo, const int k,
                 const int guard, const int train, __global const float *scale)
{
    const float p = pw[k];
    for (int d = 1; d <= guard; ++d) {
        if (k - d >= 0 && !(p > pw[k - d])) return 0.0f;
        if (k + d < half_n && !(p >= pw[k + d])) return 0.0f;
    }
    float sum = 0.0f;
    const int a0 = max(k - guard - train, lo), a1 = max(k - guard, lo);
    const int b0 = min(k + guard + 1, half_n), b1 = min(k + guard + train + 1, half_n);
    for (int j = a0; j < a1; ++j) sum += pw[j];
    for (int j = b0; j < b1; ++j) sum += pw[j];
    const int n = (a1 - a0) + (b1 - b0);
    const float mean = sum / (float)max(n, 1);
    return p > scale[n] * mean ? p / mean : 0.0f;
}

void local_cfar(__local const float *pw,   // power of bins 0 .. half_n - 1
                const int half_n,
                const int lo,
                const int hi,
                const int guard,
                const int train,
                __global const float *scale,   // threshold factor per count of training cells
                const int max_echoes,
                __local uchar *flag,           // scratch, half_n
                __local int *counts,           // scratch, one per work-item
                __global float *echo_bin,      // out: max_echoes fractional bins
                __global float *echo_snr,      // out: max_echoes dB over the training mean
                __global int *echo_count)      // out: echoes written
{
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    for (int k = lo + lid; k < hi; k += lsz) flag[k] = cfar_ratio(pw, half_n, lo, k, guard, train, scale) > 0.0f;
    barrier(CLK_LOCAL_MEM_FENCE);
    const int span = (hi - lo + lsz - 1) / lsz;
    const int a = min(lo + lid * span, hi), b = min(a + span, hi);
    int mine = 0;
    for (int k = a; k < b; ++k) mine += flag[k];
    counts[lid] = mine;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) {                    // exclusive scan of lsz counts (<= 256)
        int total = 0;
        for (int i = 0; i < lsz; ++i) {
            const int c = counts[i];
            counts[i] = total;
            total += c;
        }
        const int kept = min(total, max_echoes);
        *echo_count = kept;
        for (int i = kept; i < max_echoes; ++i) {
            echo_bin[i] = NAN;
            echo_snr[i] = NAN;
        }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    int slot = counts[lid];
    for (int k = a; k < b && slot < max_echoes; ++k) {
        if (!flag[k]) continue;
        echo_bin[slot] = peak_position(pw, half_n, k);
        echo_snr[slot] = 10.0f * log10(cfar_ratio(pw, half_n, lo, k, guard, train, scale));
        ++slot;
    }
    barrier(CLK_LOCAL_MEM_FENCE);      // the counts share local_peak's scratch
}
