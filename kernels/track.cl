// Stage 6: the tracker's regularisation between its de-chirp passes, so that the passes
// follow each other on the device and the host reads the tracker's state once. One launch
// a pass, one work-group (the work is a few operations a pair; a launch costs more): each
// pair's new measurements into the state and its velocity, the continuity median and the
// trusted pairs, the velocities interpolated over the trusted pairs, and the pairs whose
// de-chirp velocity moved, listed in order for the next measurement (their count in
// state[0], which the measurement reads). After the last pass, the verdict: which pairs
// are valid and their continuity residuals (the host takes the tolerance). Pairs in groups
// tracked apart (the delay's trial stretches) are nobody's neighbours across their group's
// ends. With integration (stages.integrate), every pair is measured again each pass on
// its K-window integrated spectra, read at the target's displacement (`displace`),
// and a peak is heard over the floor of its count of spectra. Twins:
// fmcw_cl.stages.pairing.passes and .verdict, in double precision as numpy's (a device
// without it runs the passes on the host).
#pragma OPENCL FP_CONTRACT OFF
#if defined(cl_khr_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#define REACH_MAX 16        // the median's half-width, at most (groups.NEIGHBOURS: 8)

// numpy's order: NaN above every number, equal to itself
int before(const double a, const double b) { return !isnan(a) && (isnan(b) || a < b); }
int same(const double a, const double b) { return a == b || (isnan(a) && isnan(b)); }

// x into the sorted w[0..n), one place up from where it goes
void insert(double *w, const int n, const double x)
{
    int j = n;
    while (j > 0 && before(x, w[j - 1])) {
        w[j] = w[j - 1];
        --j;
    }
    w[j] = x;
}

// one value equal to x out of the sorted w[0..n)
void remove(double *w, const int n, const double x)
{
    int j = 0;
    while (j < n - 1 && !same(w[j], x)) ++j;
    for (; j < n - 1; ++j) w[j] = w[j + 1];
}

// np.interp(t[i], t[trusted], med[trusted]) over its group for a pair between the
// group's trusted pairs p <= i < n (either absent: -1; both: 0), numpy's arithmetic and
// its fallbacks where it makes a NaN.
double interpolated(__global const double *t, __global const double *med, const int i,
                    const int p, const int n)
{
    if (p == i) return med[i];
    if (p < 0) return n < 0 ? 0.0 : med[n];
    if (n < 0) return med[p];
    const double slope = (med[n] - med[p]) / (t[n] - t[p]);
    double r = slope * (t[i] - t[p]) + med[p];
    if (isnan(r)) {
        r = slope * (t[i] - t[n]) + med[n];
        if (isnan(r) && med[p] == med[n]) r = med[p];
    }
    return r;
}

// Whether both peaks of pair i are heard: at least snr_min, or, integrated (`counted`),
// at least the floor of its count of spectra (floors[count]: integrate.threshold_db),
// compared in double as numpy compares float32 SNRs with float64 floors.
int heard(const int i, __global const float *s_r, __global const float *s_f, const float snr_min,
          __global const int *count, __global const double *floors, const int counted)
{
    if (!counted) return s_r[i] >= snr_min && s_f[i] >= snr_min;
    const double f = floors[count[i]];
    return (double)s_r[i] >= f && (double)s_f[i] >= f;
}

// The target's move (m) from pair i - 1 to pair i: the trapezoid rule over the pairs'
// centres t at the de-chirp velocities vd (numeric.steps).
double step_m(__global const double *t, __global const double *vd, const int i)
{
    return 0.5 * (vd[i] + vd[i - 1]) * (t[i] - t[i - 1]);
}

// The sum over this work-item's pairs a..b of the target's steps (`step_m`) since the
// last start of a group among them, and whether one started there: what `displace`
// carries over.
void runs_since_restart(__global const double *t, __global const int *bounds, __global const double *vd,
                        const int a, const int b, __local double *sums, __local int *restarted)
{
    const int lid = get_local_id(0);
    double run = 0.0;
    int cut = 0;
    for (int i = a; i < b; ++i) {
        if (i == bounds[i]) {
            run = 0.0;
            cut = 1;
        } else {
            run += step_m(t, vd, i);
        }
    }
    sums[lid] = run;
    restarted[lid] = cut;
}

// The target's displacement (bins, from its group's first pair) at the pairs a..b, in
// the order numpy's cumsum adds, carried over from the runs before this work-item's in
// its group (`runs_since_restart` of every work-item, after a barrier). Twin:
// numeric.travelled, each group apart.
void displace(__global const double *t, __global const int *bounds, const double metres_per_bin,
              __global const double *vd, __global float *disp, const int a, const int b,
              __local const double *sums, __local const int *restarted)
{
    double d = 0.0;                            // at the end of the runs before this one
    for (int k = 0; k < (int)get_local_id(0); ++k) d = restarted[k] ? sums[k] : d + sums[k];
    for (int i = a; i < b; ++i) {
        d = i == bounds[i] ? 0.0 : d + step_m(t, vd, i);
        disp[i] = (float)(d / metres_per_bin);
    }
}

// One pass (`first`: the plain pass's, vd = 0, or the pass `seeded` at the velocities
// `seed`, vd = seed; `last`: only the measurements into the
// state and the velocities' running median, for the verdict). A pair's measurement is
// row `slot[i]` of the last one (the pairs listed), or row i on the first pass and with
// `every` (integration: every pair measured each pass, read at the displacement `disp`
// this pass writes from the new velocities). Each work-item takes a run of consecutive
// pairs. Nothing is done once the passes have stopped (state[1], from the
// first pass on: a pass moved no pair).
__kernel void track_pass(const int pairs, const int first, const int last, const int every,
                         __global const float *bin_r, __global const float *snr_r,
                         __global const float *bin_f, __global const float *snr_f,
                         __global int *slot,                  // each pair's place in the list, -1: none
                         const double metres_per_bin,
                         __global const double *t,            // s, the pairs' centres
                         __global const double *half_gap,     // s, half the sweeps' spacing
                         __global const int *bounds,          // each pair's group: first pair, then
                                                              // `pairs` on, its last
                         const double k_rise, const double k_fall,
                         __global double *d_r, __global double *d_f,     // m
                         __global float *s_r, __global float *s_f,       // dB
                         __global double *vd,                 // m/s: each pair's de-chirp velocity
                         __global const float *seed,          // m/s: the first pass's, where `seeded`
                         const int seeded,
                         const int reach,                     // the median's half-width (pairs)
                         const float snr_min,
                         __global const int *count, __global const double *floors, const int counted,
                         const double consistent,
                         const double share,                  // of |median| added to `consistent`
                         const double stop,                   // m/s: a pair moved
                         __global double *vel, __global double *med, __global double *next,
                         __global int *trusted, __global int *prev,
                         __global int *rows, __global float *v32,   // the list: pairs, their velocity
                         __global int *state,
                         __global float *disp,                // with `every`: bins (`displace`)
                         __local int *ends,                   // 4 per work-item
                         __local double *sums)                // 1 per work-item
{
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    const int per = (pairs + lsz - 1) / lsz;
    const int a = min(lid * per, pairs), b = min(a + per, pairs);
    if (first || !state[1]) {                         // uniform in the group: barriers are safe
        // the new measurements (doppler.solve_pair)
        for (int i = a; i < b; ++i) {
            const int g = first || every ? i : slot[i];
            if (first) vd[i] = seeded ? (double)seed[i] : 0.0;
            if (g >= 0) {
                d_r[i] = (double)bin_r[g] * metres_per_bin;
                d_f[i] = (double)bin_f[g] * metres_per_bin;
                s_r[i] = snr_r[g];
                s_f[i] = snr_f[g];
            }
            const double hg = half_gap[i];
            const double dv = (d_f[i] - d_r[i] - 2.0 * vd[i] * hg) / (2.0 * hg + k_fall - k_rise);
            vel[i] = vd[i] + dv;
        }
        barrier(CLK_GLOBAL_MEM_FENCE);
        // the running median (a group's ends extended; the last pass's for the
        // verdict) and the trusted pairs
        double w[2 * REACH_MAX + 1];
        const int size = 2 * reach + 1;
        int l = -1, f = -1;                       // the run's last and first trusted pair
        for (int i = a; i < b; ++i) {
            const int lo = bounds[i], hi = bounds[pairs + i];
            if (i == a || lo != bounds[i - 1]) {
                for (int k = 0; k < size; ++k) insert(w, k, vel[clamp(i - reach + k, lo, hi)]);
            } else {
                remove(w, size, vel[clamp(i - 1 - reach, lo, hi)]);
                insert(w, size - 1, vel[clamp(i + reach, lo, hi)]);
            }
            const double m = w[reach];
            med[i] = m;
            const double tol = consistent + (share > 0.0 ? share * fabs(m) : 0.0);
            const int ok = heard(i, s_r, s_f, snr_min, count, floors, counted) && fabs(vel[i] - m) < tol;
            trusted[i] = ok;
            if (ok) {
                l = i;
                if (f < 0) f = i;
            }
        }
        if (last) return;                         // uniform in the group
        ends[3 * lid] = l;
        ends[3 * lid + 1] = f;
        barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);
        // the next velocity of each pair (groups.regularise) and whether it moved
        int p = -1, n = -1;
        for (int k = 0; k < lsz; ++k) {
            const int lk = ends[3 * k], fk = ends[3 * k + 1];
            if (k < lid && lk >= 0) p = lk;
            if (k > lid && fk >= 0 && n < 0) n = fk;
        }
        for (int i = a; i < b; ++i) {             // the trusted pair at or before each
            if (trusted[i]) p = i;
            prev[i] = p;
        }
        int moved = 0;
        for (int i = b - 1; i >= a; --i) {        // ... and after, both in its group
            if (trusted[i]) n = i;
            const int pg = prev[i] >= bounds[i] ? prev[i] : -1;
            const int ng = n >= 0 && n <= bounds[pairs + i] ? n : -1;
            const double v = interpolated(t, med, i, pg, ng);
            next[i] = v;
            moved += fabs(v - vd[i]) >= stop;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        ends[3 * lid + 2] = moved;
        barrier(CLK_LOCAL_MEM_FENCE);
        // the moved pairs, listed in order
        int at = 0, total = 0;
        for (int k = 0; k < lsz; ++k) {
            at += k < lid ? ends[3 * k + 2] : 0;
            total += ends[3 * k + 2];
        }
        for (int i = a; i < b; ++i) {
            const double v = next[i];
            if (fabs(v - vd[i]) >= stop) {
                vd[i] = v;
                rows[at] = i;
                v32[at] = (float)v;
                slot[i] = at++;
            } else {
                slot[i] = -1;
            }
        }
        barrier(CLK_GLOBAL_MEM_FENCE);
        if (lid == 0) {
            state[0] = total;
            state[1] = total == 0;
        }
        // integrated: the displacement of the new velocities (`displace`; the barrier
        // outside the tests: inside, PoCL 3.1's work-group variant crashed)
        __local int *restarted = ends + 3 * lsz;
        if (every) runs_since_restart(t, bounds, vd, a, b, sums, restarted);
        barrier(CLK_LOCAL_MEM_FENCE);
        if (every) displace(t, bounds, metres_per_bin, vd, disp, a, b, sums, restarted);
    }
}

// The pairs' verdict after the last pass, one work-item a pair (twin: pairing.verdict):
// each pair's distance (m) and whether it is valid: both peaks heard, its last velocity
// correction below `converged` and its velocity within `consistent` of its running median
// (`vel`, `med`: the last pass's).
__kernel void track_valid(const int pairs,
                          __global const double *d_r, __global const double *d_f,
                          __global const float *s_r, __global const float *s_f,
                          __global const double *vd, __global const double *half_gap,
                          __global const double *vel, __global const double *med,
                          const double k_rise, const double k_fall, const float snr_min,
                          __global const int *count, __global const double *floors, const int counted,
                          const double converged, const double consistent,
                          __global double *dist, __global int *valid)
{
    const int i = get_global_id(0);
    if (i >= pairs) return;
    const double hg = half_gap[i];
    const double dv = (d_f[i] - d_r[i] - 2.0 * vd[i] * hg) / (2.0 * hg + k_fall - k_rise);
    dist[i] = 0.5 * (d_r[i] + d_f[i]) - 0.5 * dv * (k_rise + k_fall);
    valid[i] = heard(i, s_r, s_f, snr_min, count, floors, counted) && fabs(dv) < converged
               && fabs(vel[i] - med[i]) < consistent;
}

// Each pair's continuity residual (m; twin: verification._residuals): |its distance - the
// median of what its valid neighbours within `reach` in its group predict|, infinite
// with fewer than `support` of them, and how many there are (`vouched`).
__kernel void track_residual(const int pairs, const int reach, const int support,
                             __global const double *t, __global const int *bounds,
                             __global const double *dist, __global const double *vel,
                             __global const int *valid, __global double *resid,
                             __global int *vouched)
{
    const int i = get_global_id(0);
    if (i >= pairs) return;
    double w[2 * REACH_MAX];
    int n = 0, vouch = 0;
    const int lo = max(bounds[i], i - reach), hi = min(bounds[pairs + i], i + reach);
    for (int j = lo; j <= hi; ++j) {
        if (j == i || !valid[j]) continue;
        ++vouch;
        const double p = dist[j] + (t[i] - t[j]) * 0.5 * (vel[i] + vel[j]);
        if (!isnan(p)) insert(w, n++, p);
    }
    // numpy's median of no number: the last of the sorted NaNs
    const double m = n > 0 ? 0.5 * (w[(n - 1) / 2] + w[n / 2]) : NAN;
    resid[i] = vouch >= support ? fabs(dist[i] - m) : INFINITY;
    vouched[i] = vouch;
}

// Before the integrated passes (`every`): the de-chirp velocities and the displacement
// zero, the passes not stopped. One work-item a pair.
__kernel void track_start(const int pairs, __global double *vd, __global float *disp, __global int *state)
{
    const int i = get_global_id(0);
    if (i == 0) state[0] = state[1] = 0;
    if (i >= pairs) return;
    vd[i] = 0.0;
    disp[i] = 0.0f;
}
#endif
