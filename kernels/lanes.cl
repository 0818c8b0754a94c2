// Device functions and types of the kernels that work in vector lanes (lpf.cl,
// resample.cl, fft_lanes.cl, integrate_lanes.cl; built in front of them).

// LANES (a build option, Runtime.width): the lanes of fft_lanes.cl's transforms and of
// resample.cl's resample_rows, which are independent: 16 where the device's preferred
// float vector is 16 wide (AVX-512: one zmm register a value), else 8. Each lane's arithmetic is the same at either width.
// (integrate_lanes.cl at 16 lanes: no faster, its loads bound it; it stays at float8.)
#ifndef LANES
#define LANES 8
#endif
#if LANES == 16
typedef float16 floatL;
typedef int16 intL;
#define VSTOREL vstore16
#define VLOADL vload16
#else
typedef float8 floatL;
typedef int8 intL;
#define VSTOREL vstore8
#define VLOADL vload8
#endif

// The sum of a float8's lanes, pairwise, through private memory: Oclgrind's checks
// crash on v.s0 + v.s1 + ...
float sum8(const float8 v)
{
    float l[8];
    vstore8(v, 0, l);
    return ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]));
}
