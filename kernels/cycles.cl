// Device functions shared by the spectra (fft.cl, fft_lanes.cl) and the phase (phase.cl).

// sin and cos of 2 pi p (p in cycles): reduced to half an angle in [-pi/2, pi/2],
// Taylor polynomials there (error < 1e-7), then the double-angle formulas. PoCL's
// sin/cos builtins cost more than the whole transform.
#define SINCOS_CYCLES(NAME, T)                                                                   \
void NAME(const T p, T *s, T *c)                                                                 \
{                                                                                                \
    const T r = p - floor(p + 0.5f);               /* [-0.5, 0.5) cycles */                      \
    const T h = 3.14159265358979f * r;             /* half the angle */                          \
    const T h2 = h * h;                                                                          \
    const T sh = h * (1.0f + h2 * (-1.6666667e-1f + h2 * (8.3333333e-3f + h2 * (-1.9841270e-4f   \
               + h2 * (2.7557319e-6f + h2 * -2.5052108e-8f)))));                                 \
    const T ch = 1.0f + h2 * (-0.5f + h2 * (4.1666667e-2f + h2 * (-1.3888889e-3f                 \
               + h2 * (2.4801587e-5f + h2 * (-2.7557319e-7f + h2 * 2.0876757e-9f)))));           \
    *s = 2.0f * sh * ch;                                                                         \
    *c = ch * ch - sh * sh;                                                                      \
}
