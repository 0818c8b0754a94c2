// Stage 7 (the verification of the assembled track): which valid pairs most of the
// valid pairs within `span` seconds disagree with as one body's motion, a work-item a
// pair (its neighbours up to `reach` pairs away on either side). Each neighbour pair is
// judged in time order, as numpy's twin judges it. The continuity residuals of the same
// fixed point are track.cl's `track_residual`, over one group. Twin:
// fmcw_cl.stages.verification.disagreed, in double precision as numpy's.
#pragma OPENCL FP_CONTRACT OFF
#if defined(cl_khr_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

// verification._agrees of pair a (earlier) and pair b
int agrees(const double ta, const double da, const double va, const double tb, const double db,
           const double vb, const double jump_max, const double accel_max, const double consistent)
{
    const double dt = tb - ta;
    const double pred = da + dt * 0.5 * (va + vb);
    return fabs(db - pred) <= jump_max + accel_max * dt * dt / 8.0
           && fabs(vb - va) <= accel_max * fabs(dt) + consistent;
}

__kernel void kinematic_drop(const int n, const int reach, const double span,
                             const double jump_max, const double accel_max, const double consistent,
                             __global const double *t, __global const double *d,
                             __global const double *v, __global const int *ok,
                             __global int *drop)
{
    const int i = get_global_id(0);
    if (i >= n) return;
    int agree = 0, near = 0;
    if (ok[i]) {
        const int far = min(reach, n - 1);
        for (int k = 1; k <= far; ++k) {
            const int a = i - k, b = i + k;
            if (a >= 0 && ok[a] && t[i] - t[a] <= span) {
                ++near;
                agree += agrees(t[a], d[a], v[a], t[i], d[i], v[i], jump_max, accel_max, consistent);
            }
            if (b < n && ok[b] && t[b] - t[i] <= span) {
                ++near;
                agree += agrees(t[i], d[i], v[i], t[b], d[b], v[b], jump_max, accel_max, consistent);
            }
        }
    }
    drop[i] = ok[i] && 2 * agree < near;
}
#endif
