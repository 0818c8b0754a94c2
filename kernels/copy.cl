// A step's small results copied on the device into another step's download (a rider,
// fmcw_cl.opencl.buffers.Packed.rider): 16 bytes a work-item. A kernel, not
// clEnqueueCopyBuffer: Oclgrind's uninitialised-value check, after such a copy into a
// buffer, reported values of other buffers that the next kernel read as uninitialised
// (the values were right); a kernel's loads and stores it follows exactly.

__kernel void copy_words(__global const uint4 *src,
                         const int n,                   // 16-byte words
                         __global uint4 *dst)
{
    const int i = get_global_id(0);
    if (i < n) dst[i] = src[i];
}
