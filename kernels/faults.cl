// Stage 6 (fault checks): which blocks of `block` beat codes hold a clipped code (at
// or below `lo`, at or above `hi`). One work-item a block, sixteen codes a load; the
// host finds each pair's clipped samples from the flags (fmcw_cl.stages.faults).
// Twin: fmcw_cl.stages.faults.clip_flags.

__kernel void clip_blocks(__global const short *x,
                          const int n,
                          const short lo,
                          const short hi,
                          const int block,
                          __global uchar *flag)
{
    const int b = get_global_id(0);
    const int a = b * block;
    if (a >= n) return;
    const int e = a + block < n ? a + block : n;
    int hit = 0;
    int i = a;
    for (; i + 16 <= e; i += 16) {
        const short16 v = vload16(0, x + i);
        hit |= any((v <= lo) | (v >= hi));
    }
    for (; i < e; ++i) hit |= x[i] <= lo || x[i] >= hi;
    flag[b] = (uchar)hit;
}
