// Stage 4b: the still echoes taken out of the resampled half-sweeps: each row less the
// mean of its direction's rows within `reach` of it (fewer at the ends). A work-item a
// column (point), its running sum in double precision, in the order of the numpy twin
// fmcw_cl.stages.clutter.without_still (a device without doubles runs the twin).
#pragma OPENCL FP_CONTRACT OFF
#if defined(cl_khr_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

__kernel void without_still(__global const float *x,
                            const int rows,
                            const int points,
                            const int reach,
                            __global float *y)
{
    const int j = get_global_id(0);
    if (j >= points)
        return;
    double s = 0.0;
    int hi = min(reach + 1, rows);
    for (int r = 0; r < hi; r++)
        s += (double)x[(size_t)r * points + j];
    int lo = 0;
    for (int i = 0; i < rows; i++) {
        const size_t at = (size_t)i * points + j;
        y[at] = x[at] - (float)(s / (double)(hi - lo));
        if (hi < rows) {
            s += (double)x[(size_t)hi * points + j];
            hi++;
        }
        if (i - reach >= 0) {
            s -= (double)x[(size_t)(i - reach) * points + j];
            lo++;
        }
    }
}
#endif
