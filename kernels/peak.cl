// Stage 5b: the peak of each power spectrum in bins [lo, hi): arg-max (ties: the
// lowest bin), Gaussian (log-parabola) interpolation, and the SNR over the mean
// power of the band outside +-guard bins of the peak. One work-group per spectrum;
// only the peaks leave the device.

__kernel void peak(__global const float *power,
                   const int half_n,
                   const int lo,
                   const int hi,
                   const int guard,
                   __global float *bin,
                   __global float *snr,
                   __local float *lval,
                   __local int *lidx,
                   __local float *lsum)
{
    const int s = get_group_id(0);
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    __global const float *row = power + (size_t)s * half_n;
    float best = -1.0f;
    int arg = lo;
    float sum = 0.0f;
    for (int k = lo + lid; k < hi; k += lsz) {
        const float p = row[k];
        sum += p;
        if (p > best) { best = p; arg = k; }
    }
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
    if (lid == 0) {
        int kk = lidx[0];
        kk = kk < 1 ? 1 : (kk > half_n - 2 ? half_n - 2 : kk);
        const float tiny = 1.0e-30f;
        const float a = log(row[kk - 1] + tiny);
        const float b = log(row[kk] + tiny);
        const float c = log(row[kk + 1] + tiny);
        const float den = a - 2.0f * b + c;
        float delta = den < 0.0f ? 0.5f * (a - c) / den : 0.0f;
        delta = delta < -0.5f ? -0.5f : (delta > 0.5f ? 0.5f : delta);
        const int g0 = kk - guard < lo ? lo : kk - guard;
        const int g1 = kk + guard > hi - 1 ? hi - 1 : kk + guard;
        float inside = 0.0f;
        for (int k = g0; k <= g1; ++k) inside += row[k];
        const int outside = (hi - lo) - (g1 - g0 + 1);
        // a band narrower than the guard has no outside: use the whole band's mean
        const float floor_level = outside > 0 ? (lsum[0] - inside) / (float)outside
                                              : lsum[0] / (float)(hi - lo);
        bin[s] = (float)kk + delta;
        snr[s] = 10.0f * log10(row[kk] / (floor_level > tiny ? floor_level : tiny));
    }
}
