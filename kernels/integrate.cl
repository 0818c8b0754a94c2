// Stage 5d: incoherent integration of the power spectra of K consecutive half-sweeps of
// one direction, aligned along the track, then the peak of the sum (peak.cl, built into
// the same program). One work-group per output row: for each bin b of row i, the mean
// over rows j = i - before .. i + after (cut at the array's ends) of row j read at
// b + disp[j] - disp[i] by linear interpolation (ends held), then local_peak on it;
// the window is cut at the ends of row i's group too (rows converted together but apart:
// `bounds` holds each row's group's first row, then each one's last).
// The spectra stay on the device from spectrum_peak (fft.cl, keep_power); only the
// peaks come back. A launch integrates one or two jobs (a pair's two directions), a job
// a row of work-groups. Twin: fmcw_cl.stages.integrate.peaks.

// The parameters both variants (integrate_lanes.cl: CPU devices) begin with, in launch
// order; each declares its local buffers with their own types (a buffer read as float8
// is declared float8, so that the device aligns it for that).
#define INTEGRATE_PARAMS                                                                         \
    __global const float *power,   /* (rows, half_n) */                                          \
    const int rows,                                                                              \
    const int half_n,                                                                            \
    __global const float *disp,    /* (rows,) target displacement, bins */                       \
    __global const int *bounds,    /* (2 rows,) each row's group's first row, then last row */   \
    const int before,                                                                            \
    const int after,                                                                             \
    const int lo,                                                                                \
    const int hi,                                                                                \
    __global const int *band,      /* banded: [lo, hi) of each row */                            \
    const int banded,                                                                            \
    const int guard,                                                                             \
    __global float *bin,           /* (rows,) */                                                 \
    __global float *snr,           /* (rows,) */                                                 \
    __global int *count,           /* (rows,) */                                                 \
    __global const int *state,     /* state[1] set: the tracker's passes stopped, nothing to do */ \
    /* the second job (get_group_id(1) = 1: the pair's other direction), the same rows */        \
    __global const float *power_b, __global const int *band_b, __global float *bin_b,           \
    __global float *snr_b, __global int *count_b

// The second job's buffers for the work-groups of row 1 of the launch.
#define TO_SECOND_JOB      \
    if (get_group_id(1)) { \
        power = power_b;   \
        band = band_b;     \
        bin = bin_b;       \
        snr = snr_b;       \
        count = count_b;   \
    }

__kernel void integrate_peak(INTEGRATE_PARAMS,
                             __local float *pw,             // half_n
                             __local float *scratch)        // 3 per work-item
{
    if (state[1]) return;                  // the same in the whole group
    TO_SECOND_JOB
    const int i = get_group_id(0);
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    const int j0 = i - before < bounds[i] ? bounds[i] : i - before;
    const int j1 = i + after > bounds[rows + i] ? bounds[rows + i] : i + after;
    const float inv = 1.0f / (float)(j1 - j0 + 1);
    const float d0 = disp[i];
    for (int b = lid; b < half_n; b += lsz) {
        float acc = 0.0f;
        for (int j = j0; j <= j1; ++j) {
            const float y = (float)b + (disp[j] - d0);
            const float fl = floor(y);
            int k = (int)fl;
            float f = y - fl;
            if (k < 0) { k = 0; f = 0.0f; }
            if (k > half_n - 2) { k = half_n - 2; f = 1.0f; }
            __global const float *row = power + (size_t)j * half_n;
            acc += row[k] + f * (row[k + 1] - row[k]);
        }
        pw[b] = acc * inv;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    local_peak(pw, half_n, banded ? band[2 * i] : lo, banded ? band[2 * i + 1] : hi, guard, scratch,
               (__local int *)(scratch + lsz), scratch + 2 * lsz, bin + i, snr + i);
    if (lid == 0) count[i] = j1 - j0 + 1;
}
