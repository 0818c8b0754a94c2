// Stage 6 (fault checks): how many of each block of `block` beat codes are clipped (at
// or below `lo`, at or above `hi`). One work-item a block, a code at a time (a short16
// count through convert_int16 crashed Oclgrind; PoCL vectorises across work-items); the
// host finds each pair's clipped share from the counts (fmcw_cl.stages.faults).
// Twin: fmcw_cl.stages.faults.clip_counts.

__kernel void clip_blocks(__global const short *x,
                          const int n,
                          const short lo,
                          const short hi,
                          const int block,
                          __global ushort *count)
{
    const int b = get_global_id(0);
    const int a = b * block;
    if (a >= n) return;
    const int e = a + block < n ? a + block : n;
    int hits = 0;
    int i = a;
    for (; i < e; ++i) hits += x[i] <= lo || x[i] >= hi;
    count[b] = (ushort)hits;
}
