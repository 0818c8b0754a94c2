// Stage 6b: the beat's phase at each half-sweep's peak (twin: fmcw_cl.stages.phase.phasors).
// One work-group per row and direction (get_group_id(1): 0 rising, 1 falling): the row
// de-chirped at its pair's velocity and summed at its peak's fractional bin, referred to
// its centre point (N - 1) / 2, reduced in local memory. The cycles are taken modulo one
// before the sine: a peak at bin 1000 of 2048 turns 250 cycles over a row, and float32
// keeps them to 1e-5 cycle.

__kernel void peak_phasor(__global const float *x,        // (rows, points) rising
                          __global const float *x_b,      // (rows, points) falling
                          __global const float *beta,     // (points,) cycles per m/s, rising
                          __global const float *beta_b,   // falling
                          __global const float *v,        // (rows,) de-chirp velocity (m/s)
                          __global const float *bins,     // (2 rows,) peak bins, rising then falling
                          const int rows,
                          const int points,
                          const float inv_nfft,
                          const int dechirp,
                          __global float *out,            // (2 rows, 2) real, imaginary
                          __local float *scratch)         // 2 per work-item
{
    const int i = get_group_id(0);
    const int job = get_group_id(1);
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    __global const float *row = (job ? x_b : x) + (size_t)i * points;
    __global const float *bt = job ? beta_b : beta;
    const float f = bins[job * rows + i] * inv_nfft;
    const float vi = dechirp ? v[i] : 0.0f;
    const float centre = 0.5f * (float)(points - 1);
    float re = 0.0f, im = 0.0f;
    for (int j = lid; j < points; j += lsz) {
        float c = f * ((float)j - centre) + vi * bt[j];
        c = c - rint(c);
        const float a = 6.283185307179586f * c;
        const float y = row[j];
        re += y * cos(a);
        im -= y * sin(a);
    }
    scratch[2 * lid] = re;
    scratch[2 * lid + 1] = im;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int s = lsz / 2; s > 0; s >>= 1) {
        if (lid < s) {
            scratch[2 * lid] += scratch[2 * (lid + s)];
            scratch[2 * lid + 1] += scratch[2 * (lid + s) + 1];
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (lid == 0) {
        out[2 * (job * rows + i)] = scratch[0];
        out[2 * (job * rows + i) + 1] = scratch[1];
    }
}
