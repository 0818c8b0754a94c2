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
SINCOS_CYCLES(sincos_cycles8, float8)

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

// The cycles of a point, m = 2 j - (points - 1), with Doppler basis b, in float exact
// where they are large: f = F / 4096 + fl with F whole (F m / 8192 is exact for
// |m| < 8192) and v = vh + vl; F m / 8192 and vh b reduced modulo one apart, vh b's
// rounding by fma, then the small terms.
#define SPLIT_CYCLES(NAME, T)                                                                    \
    T NAME(const T m, const T b, const float F, const float fl, const float vh, const float vl)  \
    {                                                                                            \
        T a = F * m * (1.0f / 8192.0f), p = vh * b;                                              \
        const T e = fma((T)vh, b, -p);                                                           \
        a -= rint(a);                                                                            \
        p -= rint(p);                                                                            \
        return a + p + (0.5f * fl * m + (e + vl * b));                                           \
    }

SPLIT_CYCLES(split_cycles, float)
SPLIT_CYCLES(split_cycles8, float8)

// The same sum by one work-item, eight points a step in float8 (CPU devices,
// Runtime.lanes). PoCL runs the work-group version's loop one work-item at a time,
// unvectorised: on two cores of a Zen 4 it took 0.37 s of a 1 s rail's 0.9. The cycles
// in float (`split_cycles`). (No double8: pip's PoCL, built for AVX2, built a program
// with one into no kernels where Intel's runtime was loaded too.)
#define PHASOR_LANES(NAME, REAL)                                                                 \
    void NAME(__global const float *row, __global const float *bt, const REAL f, const REAL v,  \
              const int points, __global float *out)                                            \
    {                                                                                            \
        const REAL whole = rint(f * (REAL)4096);                                                 \
        const float F = (float)whole, fl = (float)(f - whole / (REAL)4096);                      \
        const float vh = (float)v, vl = (float)(v - (REAL)vh);                                   \
        const float8 k = (float8)(0.0f, 2.0f, 4.0f, 6.0f, 8.0f, 10.0f, 12.0f, 14.0f);            \
        float8 re8 = 0.0f, im8 = 0.0f;                                                           \
        int j = 0;                                                                               \
        for (; j + 8 <= points; j += 8) {                                                        \
            const float8 m = k + (float)(2 * j - (points - 1));                                  \
            float8 s, co;                                                                        \
            sincos_cycles8(split_cycles8(m, vload8(0, bt + j), F, fl, vh, vl), &s, &co);         \
            const float8 y = vload8(0, row + j);                                                 \
            re8 += y * co;                                                                       \
            im8 -= y * s;                                                                        \
        }                                                                                        \
        float re = sum8(re8), im = sum8(im8);                                                    \
        for (; j < points; j++) {                                                                \
            const float m = (float)(2 * j - (points - 1));                                       \
            float s, co;                                                                         \
            sincos_cycles(split_cycles(m, bt[j], F, fl, vh, vl), &s, &co);                       \
            re += row[j] * co;                                                                   \
            im -= row[j] * s;                                                                    \
        }                                                                                        \
        out[0] = re;                                                                             \
        out[1] = im;                                                                             \
    }

PHASOR_OF(phasor_of, float)
PHASOR_LANES(phasor_lanes, float)


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
                          const int lanes,                // a work-item a row (else a work-group)
                          __global float *out,            // (2 rows, 2) real, imaginary
                          __local float *scratch)         // 2 per work-item
{
    const int i = lanes ? get_global_id(0) : get_group_id(0);
    const int job = get_group_id(1);
    if (i >= rows)
        return;                                           // lanes: the items past the rows
    __global const float *row = (job ? x_b : x) + (size_t)i * points;
    const float f = bins[job * rows + i] * inv_nfft, vi = dechirp ? v[i] : 0.0f;
    if (lanes)
        phasor_lanes(row, job ? beta_b : beta, f, vi, points, out + 2 * (job * rows + i));
    else
        phasor_of(row, job ? beta_b : beta, f, vi, points, scratch, out + 2 * (job * rows + i));
}

#if defined(cl_khr_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

PHASOR_OF(phasor_of_double, double)
PHASOR_LANES(phasor_lanes_double, double)

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
                                const int lanes,                // a work-item a row (else a work-group)
                                __global float *out,            // (2 rows, 2) real, imaginary
                                __local float *scratch)         // 2 per work-item
{
    const int i = lanes ? get_global_id(0) : get_group_id(0);
    const int job = get_group_id(1);
    if (i >= rows)
        return;                                                 // lanes: the items past the rows
    const double d = job ? d_f[i] : d_r[i];
    const double v = isnan(vel[i]) ? 0.0 : vel[i];
    // NaN (a pair never measured) reads as 0, as numpy's nan_to_num
    const double f = isnan(d) ? 0.0 : d / metres_per_bin * (double)inv_nfft;
    __global const float *row = (job ? x_b : x) + (size_t)i * points;
    if (lanes)
        phasor_lanes_double(row, job ? beta_b : beta, f, v, points, out + 2 * (job * rows + i));
    else
        phasor_of_double(row, job ? beta_b : beta, f, v, points, scratch, out + 2 * (job * rows + i));
}
#endif
