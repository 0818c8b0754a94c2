// Device functions and types of the kernels that work in vector lanes (lpf.cl,
// resample.cl, fft_lanes.cl, integrate_lanes.cl, survey.cl; built in front of them).

// LANES (a build option, Runtime.width): the lanes of fft_lanes.cl's transforms, of
// resample.cl's resample_rows and of survey.cl's hidden_lanes, which are independent:
// 16 where the device's preferred float vector is 16 wide (AVX-512: one zmm register a
// value), else 8; fft_lanes.cl's also 4 where a transform of 8 lanes does not fit the
// local memory (Intel's CPU runtime: 256 KiB, the 4096-point range check needs 384 KiB
// at 8). Each lane's arithmetic is the same at any width. (integrate_lanes.cl at 16
// lanes: no faster, its loads bound it; it stays at float8.) LO_HALF and HI_HALF
// interleave the lower and the upper halves of two vectors.
#ifndef LANES
#define LANES 8
#endif
// Integer bounds without PoCL's min/max builtins, which are calls (shared notes: its
// clamp and select were slow; vector conditionals are used for select here too).
#define IMAX(a, b) ((a) > (b) ? (a) : (b))
#define IMIN(a, b) ((a) < (b) ? (a) : (b))
// SHUFFLES (Runtime.shuffles): whether vectors may be built from other vectors' lanes
// (any_lanes, transpose_lanes); not on a simulator, whose uninitialised-value check
// reports every such vector and crashes (Oclgrind 21.10)
#ifndef SHUFFLES
#define SHUFFLES 1
#endif
#if LANES == 16
typedef float16 floatL;
typedef int16 intL;
#define VSTOREL vstore16
#define VLOADL vload16
#define VLOADSL vload16
#define CONVERT_FLOATL convert_float16
#define CONVERT_INTL convert_int16
#define AS_INTL as_int16
#define AS_FLOATL as_float16
#define LO_HALF(a, b) (floatL)(a.s0, b.s0, a.s1, b.s1, a.s2, b.s2, a.s3, b.s3, \
                               a.s4, b.s4, a.s5, b.s5, a.s6, b.s6, a.s7, b.s7)
#define HI_HALF(a, b) (floatL)(a.s8, b.s8, a.s9, b.s9, a.sa, b.sa, a.sb, b.sb, \
                               a.sc, b.sc, a.sd, b.sd, a.se, b.se, a.sf, b.sf)
#define LOG2_LANES 4
#elif LANES == 4
typedef float4 floatL;
typedef int4 intL;
#define VSTOREL vstore4
#define VLOADL vload4
#define VLOADSL vload4
#define CONVERT_FLOATL convert_float4
#define CONVERT_INTL convert_int4
#define AS_INTL as_int4
#define AS_FLOATL as_float4
#define LO_HALF(a, b) (floatL)(a.s0, b.s0, a.s1, b.s1)
#define HI_HALF(a, b) (floatL)(a.s2, b.s2, a.s3, b.s3)
#define LOG2_LANES 2
#else
typedef float8 floatL;
typedef int8 intL;
#define VSTOREL vstore8
#define VLOADL vload8
#define VLOADSL vload8
#define CONVERT_FLOATL convert_float8
#define CONVERT_INTL convert_int8
#define AS_INTL as_int8
#define AS_FLOATL as_float8
#define LO_HALF(a, b) (floatL)(a.s0, b.s0, a.s1, b.s1, a.s2, b.s2, a.s3, b.s3)
#define HI_HALF(a, b) (floatL)(a.s4, b.s4, a.s5, b.s5, a.s6, b.s6, a.s7, b.s7)
#define LOG2_LANES 3
#endif

// The sum of a float8's lanes, pairwise, through private memory: Oclgrind's checks
// crash on v.s0 + v.s1 + ...
float sum8(const float8 v)
{
    float l[8];
    vstore8(v, 0, l);
    return ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]));
}

// Whether any lane is set, by halving swizzles (PoCL's any() tests lane after lane).
inline int any_lanes(const intL v)
{
#if !SHUFFLES
    return any(v);
#else
#if LANES == 16
    const int8 a = v.lo | v.hi;
    const int4 b = a.lo | a.hi;
#elif LANES == 4
    const int4 b = v;
#else
    const int4 b = v.lo | v.hi;
#endif
    const int2 c = b.lo | b.hi;
    return (c.x | c.y) < 0;
#endif
}

// Transpose LANES x LANES values in place: lane c of v[r] <-> lane r of v[c]. A round
// interleaves v[i] with v[i + LANES / 2] (which rotates the bits of (vector, lane) by
// one); LOG2_LANES rounds transpose. Unrolled, the interleaves are register shuffles
// (PoCL otherwise moves the lanes through memory one at a time).
inline void transpose_lanes(floatL *v)
{
    floatL w[LANES];
#pragma unroll
    for (int round = 0; round < LOG2_LANES; ++round) {
#pragma unroll
        for (int i = 0; i < LANES / 2; ++i) {
            const floatL a = v[i], b = v[i + LANES / 2];
            w[2 * i] = LO_HALF(a, b);
            w[2 * i + 1] = HI_HALF(a, b);
        }
#pragma unroll
        for (int i = 0; i < LANES; ++i) v[i] = w[i];
    }
}
