"""Benchmark scripts (``python -m benchmarks.<name>`` from the repo root).

Importing the package limits BLAS/OpenMP to one thread before numpy is loaded, so every
script measures one core unless the caller set these variables explicitly.
"""

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
