"""Numpy references of the compiled kernels, for the equivalence tests only.

The monitor and the simulator run one implementation of each algorithm, its numba kernel
(``gcs_monitor.core.kernels``). The equivalence tests compare each kernel with an independent
plain numpy / plain float version of the same equations, written here, beside the tests,
equation by equation with the papers' numbering. Nothing under ``gcs_monitor`` or
``sim_vehicle`` imports this package.
"""
