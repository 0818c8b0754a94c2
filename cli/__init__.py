"""The `fmcw-cl` command line (click): one module per command."""
