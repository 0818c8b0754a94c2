// Device functions shared by the kernels that keep eight values in the lanes of a
// vector (built into the programs that use them: kernels/__init__.py).

// The sum of a float8's lanes, pairwise, through memory: Oclgrind's uninitialised-value
// check crashes on a sum of its components (v.s0 + v.s1 + ...).
float sum8(const float8 v)
{
    float l[8];
    vstore8(v, 0, l);
    return ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]));
}
