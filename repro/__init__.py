"""Entry points of the harness: figures, render, evaluate, estimate, magnify, report, bench, sweep.

Importing ``repro`` (every ``python -m repro.X`` and the ``defocus-repro`` console script do) sets the
OpenMP wait policy of numba's "omp" threading layer to PASSIVE unless the environment already sets
one, before any parallel region starts the OpenMP runtime. By default its worker threads busy-wait
after every parallel region; the propagation's refinement runs ~3 regions per CG iteration with the
serial coarse V-cycle in between, during which a spinning thread takes the second core from the main
thread and from other jobs. Measured on this 2-core machine at load ≈ 3.8 (1024², paper preset's
measures): propagation 5.5 s wall / 5.4 s CPU with the default policy, 4.0 / 3.8 s with PASSIVE;
bit-identical results (the kernels' results do not depend on scheduling). ``method`` itself, a pure
numerics library, does not touch the process environment.
"""

import os

#: The policy in effect for this process (the environment's own setting wins).
OMP_WAIT_POLICY = os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
