// Stage 5d on CPU devices: what integrate.cl's integrate_peak computes, one work-item a
// row, eight bins of the window's mean at a time in a float8. The displacement of row j
// relative to row i is the same for every bin, so row j is read at b + s with one
// interpolation weight f for the whole row: a block of eight bins is two unaligned
// vector loads. PoCL runs integrate_peak's per-bin loop over the window as scalar code
// (the kernel has loops of its own). Twin: fmcw_cl.stages.integrate.peaks.

// local_peak (peak.cl) of one spectrum held as float8 blocks, by one work-item: the
// band's arg-max (ties: the lowest bin) and sum eight bins a step, the band's unaligned
// ends a bin at a time, the lanes' sums added pairwise (`sum8`). local_peak's one
// work-item adds the bins one after another: a chain of dependent additions that cost a
// window of two spectra twice its integration (PoCL, 2-core Skylake-SP); the order
// differs, within float rounding.
void row_peak(__local const float8 *pw8, const int half_n, const int lo, const int hi, const int guard,
              __global float *bin, __global float *snr)
{
    __local const float *pw = (__local const float *)pw8;
    int a = (lo + 7) & ~7, b = hi & ~7;          // the whole blocks [a, b)
    if (a >= b) a = b = hi;
    float best = -1.0f, sum = 0.0f;
    int arg = lo;
    scan_bins(pw, lo, a, 1, &best, &arg, &sum);
    float8 vbest = -1.0f, vsum = 0.0f;
    int8 varg = (int8)a;
    const int8 lane = (int8)(0, 1, 2, 3, 4, 5, 6, 7);
    for (int q = a / 8; q < b / 8; ++q) {
        const float8 p = pw8[q];
        const int8 gt = p > vbest;
        vbest = gt ? p : vbest;
        varg = gt ? (int8)(8 * q) + lane : varg;
        vsum += p;
    }
    float lb[8];
    int la[8];
    vstore8(vbest, 0, lb);
    vstore8(varg, 0, la);
    for (int l = 0; l < 8; ++l) {                // the bins before a block's come first
        if (lb[l] > best || (lb[l] == best && la[l] < arg)) { best = lb[l]; arg = la[l]; }
    }
    sum += sum8(vsum);
    scan_bins(pw, b, hi, 1, &best, &arg, &sum);
    band_peak(pw, half_n, lo, hi, guard, arg, sum, bin, snr);
}

__kernel void integrate_lanes(INTEGRATE_PARAMS,        // half_n % 8 == 0
                              __local float8 *acc)      // half_n / 8
{
    if (state[1]) return;
    TO_SECOND_JOB
    const int i = get_group_id(0);
    const int blocks = half_n / 8;
    const int j0 = i - before < bounds[i] ? bounds[i] : i - before;
    const int j1 = i + after > bounds[rows + i] ? bounds[rows + i] : i + after;
    const float d0 = disp[i];
    for (int q = 0; q < blocks; ++q) acc[q] = (float8)0.0f;
    for (int j = j0; j <= j1; ++j) {
        const float delta = disp[j] - d0;
        const float fl = floor(delta);
        const int s = (int)fl;
        const float f = delta - fl;
        __global const float *row = power + (size_t)j * half_n;
        for (int q = 0; q < blocks; ++q) {
            const int k0 = 8 * q + s;
            if (k0 >= 0 && k0 + 8 <= half_n - 1) {
                const float8 a = vload8(0, row + k0);
                acc[q] += a + f * (vload8(0, row + k0 + 1) - a);
            } else {        // a block reaching past an end: each bin clipped as integrate_peak does
                float l[8];
                for (int t = 0; t < 8; ++t) {
                    int k = k0 + t;
                    float w = f;
                    if (k < 0) { k = 0; w = 0.0f; }
                    if (k > half_n - 2) { k = half_n - 2; w = 1.0f; }
                    l[t] = row[k] + w * (row[k + 1] - row[k]);
                }
                acc[q] += vload8(0, l);
            }
        }
    }
    const float inv = 1.0f / (float)(j1 - j0 + 1);
    for (int q = 0; q < blocks; ++q) acc[q] *= inv;
    row_peak(acc, half_n, banded ? band[2 * i] : lo, banded ? band[2 * i + 1] : hi, guard, bin + i, snr + i);
    count[i] = j1 - j0 + 1;
}
