"""Studies built on the run loop and the results: why and how two engines differ, and what it costs.

``sweep`` (parameter sweeps and convergence orders), ``tasks`` (one run of a
sweep as plain data), ``executors`` (the process pool and the Dask cluster
every parallel run uses, ``legbench run --jobs`` included), ``horizon``
(short-horizon replay), ``verify`` (closed-form verification cases),
``calibrate_contact`` (measured contact stiffness, damping and creep),
``bench`` (harness overhead) and ``doctor`` (parity pre-flight).
"""
