// Stage 5d on CPU devices: what integrate.cl's integrate_peak computes, one work-item a
// row, eight bins of the window's mean at a time in a float8. The displacement of row j
// relative to row i is the same for every bin, so row j is read at b + s with one
// interpolation weight f for the whole row: a block of eight bins is two unaligned
// vector loads. PoCL runs integrate_peak's per-bin loop over the window as scalar code
// (the kernel has loops of its own). Twin: fmcw_cl.stages.integrate.peaks.

__kernel void integrate_lanes(INTEGRATE_PARAMS,        // half_n % 8 == 0
                              __local float8 *acc,      // half_n / 8
                              __local float *scratch)   // 3
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
    local_peak((__local const float *)acc, half_n, lo, hi, guard, scratch, (__local int *)(scratch + 1),
               scratch + 2, bin + i, snr + i);
    count[i] = j1 - j0 + 1;
}
