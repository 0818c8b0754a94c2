// Stage 5a: de-chirp, zero-pad and FFT each half-sweep; write the power of the
// non-negative frequencies 0 .. nfft/2 - 1. One work-group per half-sweep; the
// transform runs in local memory (radix-2, decimation in time, bit-reversed load).
// De-chirp: x_j * exp(-2 pi i v beta_j), the phase reduced modulo one cycle first so
// that float32 keeps its precision; v = 0 gives the plain spectrum of the real sweep.

__kernel void dechirp_fft_power(__global const float *x,
                                const int points,
                                __global const float *beta,      // cycles per m/s, (points,)
                                __global const float *velocity,  // m/s, one per sweep
                                __global const int *bitrev,      // (nfft,)
                                __global const float *tw_re,     // exp(-2 pi i m / nfft), m < nfft/2
                                __global const float *tw_im,
                                const int nfft,
                                __global float *power,           // (sweeps, nfft/2)
                                __local float *re,
                                __local float *im)
{
    const int s = get_group_id(0);
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    const float v = velocity[s];
    __global const float *row = x + (size_t)s * points;
    for (int i = lid; i < nfft; i += lsz) {
        float a = 0.0f;
        float b = 0.0f;
        if (i < points) {
            float ph = v * beta[i];
            ph = ph - floor(ph);
            const float ang = 6.2831853071795865f * ph;
            const float xr = row[i];
            a = xr * cos(ang);
            b = -xr * sin(ang);
        }
        const int r = bitrev[i];
        re[r] = a;
        im[r] = b;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    const int half_n = nfft >> 1;
    int stride = half_n;
    for (int len = 2; len <= nfft; len <<= 1) {
        const int span = len >> 1;
        for (int bf = lid; bf < half_n; bf += lsz) {
            const int k = bf & (span - 1);
            const int i = ((bf - k) << 1) + k;
            const int j = i + span;
            const float wr = tw_re[k * stride];
            const float wi = tw_im[k * stride];
            const float tr = wr * re[j] - wi * im[j];
            const float ti = wr * im[j] + wi * re[j];
            const float ur = re[i];
            const float ui = im[i];
            re[i] = ur + tr;
            im[i] = ui + ti;
            re[j] = ur - tr;
            im[j] = ui - ti;
        }
        stride >>= 1;
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    __global float *out = power + (size_t)s * half_n;
    for (int i = lid; i < half_n; i += lsz) out[i] = re[i] * re[i] + im[i] * im[i];
}
