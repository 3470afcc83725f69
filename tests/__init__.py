"""The test suite. Under pytest-xdist (`make test`), each worker gets one core: its linear algebra
runs on one thread (set here, before numpy loads). Threaded BLAS in two workers on two cores
oversubscribes them: tests/modal took 89-97 s on two workers against 17 s with one thread each
(and 25 s in one process)."""

import os

if os.environ.get("PYTEST_XDIST_WORKER"):
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")
