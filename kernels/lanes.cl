// Device functions of the kernels that work eight values at a time in float8 lanes
// (lpf.cl, resample.cl; built in front of them).

// The sum of a float8's lanes, pairwise, through private memory: Oclgrind's checks
// crash on v.s0 + v.s1 + ...
float sum8(const float8 v)
{
    float l[8];
    vstore8(v, 0, l);
    return ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]));
}
