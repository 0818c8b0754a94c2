// `real`: double where the device has it (cl_khr_fp64), else float; for sums and
// roundings that want numpy's double precision and can live with float's elsewhere.
// In front of the programs that use it (kernels/__init__.py).
#if defined(cl_khr_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double real;
#else
typedef float real;
#endif
