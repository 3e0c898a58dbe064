"""Import first in a benchmark to run numba, OpenMP and BLAS on one thread (set before numpy is imported).

One core per method compares the algorithms, not the thread pools, and stays meaningful when other jobs share
the machine.
"""

import os

for _name in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
