"""Numbers from the equations: numeric models, tapes and C code, the integrator driver and its compiled loops,
the exact solution of linear models, work–precision benchmarks.
"""
