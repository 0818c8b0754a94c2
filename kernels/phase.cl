// Stage 6b: the beat's phase at each half-sweep's peak (twin: fmcw_cl.stages.phase.phasors).
// One work-group per row and direction (get_group_id(1): 0 rising, 1 falling): the row
// de-chirped at its pair's velocity and summed at its peak's fractional bin, referred to
// its centre point (N - 1) / 2, reduced in local memory. The cycles are taken modulo one
// before the sine: a peak at bin 1000 of 2048 turns 250 cycles over a row, and float32
// keeps them to 1e-5 cycle. Their sine and cosine are cycles.cl's polynomials: with
// PoCL's builtins this pass took 2.5 times the rest of a rail's conversion on two CPU
// cores. `peak_phasor_state` reads the velocities and peaks where the tracker's passes
// left them on the device (kernels/track.cl, double precision), so that the phasors
// come down with the tracker's state.

SINCOS_CYCLES(sincos_cycles, float)

// the row's sum at `f` cycles a point, de-chirped at `v`, into out[0..1] (work-item 0);
// the cycles in REAL (float, or double where the passes left double velocities: a
// pair's velocity times the Doppler basis stays exact at any speed)
#define PHASOR_OF(NAME, REAL)                                                                    \
    void NAME(__global const float *row, __global const float *bt, const REAL f, const REAL v,  \
              const int points, __local float *scratch, __global float *out)                    \
    {                                                                                            \
        const int lid = get_local_id(0);                                                         \
        const int lsz = get_local_size(0);                                                       \
        const REAL centre = (REAL)0.5 * (REAL)(points - 1);                                      \
        float re = 0.0f, im = 0.0f;                                                              \
        for (int j = lid; j < points; j += lsz) {                                                \
            REAL c = f * ((REAL)j - centre) + v * (REAL)bt[j];                                   \
            float s, co;                                                                         \
            sincos_cycles((float)(c - rint(c)), &s, &co);                                        \
            const float y = row[j];                                                              \
            re += y * co;                                                                        \
            im -= y * s;                                                                         \
        }                                                                                        \
        scratch[2 * lid] = re;                                                                   \
        scratch[2 * lid + 1] = im;                                                               \
        barrier(CLK_LOCAL_MEM_FENCE);                                                            \
        for (int s = lsz / 2; s > 0; s >>= 1) {                                                  \
            if (lid < s) {                                                                       \
                scratch[2 * lid] += scratch[2 * (lid + s)];                                      \
                scratch[2 * lid + 1] += scratch[2 * (lid + s) + 1];                              \
            }                                                                                    \
            barrier(CLK_LOCAL_MEM_FENCE);                                                        \
        }                                                                                        \
        if (lid == 0) {                                                                          \
            out[0] = scratch[0];                                                                 \
            out[1] = scratch[1];                                                                 \
        }                                                                                        \
    }

PHASOR_OF(phasor_of, float)

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
    phasor_of((job ? x_b : x) + (size_t)i * points, job ? beta_b : beta, bins[job * rows + i] * inv_nfft,
              dechirp ? v[i] : 0.0f, points, scratch, out + 2 * (job * rows + i));
}

#if defined(cl_khr_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

PHASOR_OF(phasor_of_double, double)

__kernel void peak_phasor_state(__global const float *x,        // (rows, points) rising
                                __global const float *x_b,      // (rows, points) falling
                                __global const float *beta,     // (points,) cycles per m/s, rising
                                __global const float *beta_b,   // falling
                                __global const double *vel,     // (rows,) the pairs' velocities (m/s)
                                __global const double *d_r,     // (rows,) final apparent distances (m)
                                __global const double *d_f,
                                const double metres_per_bin,
                                const int rows,
                                const int points,
                                const float inv_nfft,
                                __global float *out,            // (2 rows, 2) real, imaginary
                                __local float *scratch)         // 2 per work-item
{
    const int i = get_group_id(0);
    const int job = get_group_id(1);
    const double d = job ? d_f[i] : d_r[i];
    const double v = vel[i];
    // NaN (a pair never measured) reads as 0, as numpy's nan_to_num
    const double f = isnan(d) ? 0.0 : d / metres_per_bin * (double)inv_nfft;
    phasor_of_double((job ? x_b : x) + (size_t)i * points, job ? beta_b : beta, f, isnan(v) ? 0.0 : v, points,
                     scratch, out + 2 * (job * rows + i));
}
#endif
