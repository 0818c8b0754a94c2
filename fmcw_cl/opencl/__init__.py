"""OpenCL backend: context and program cache, one launcher per kernel."""
