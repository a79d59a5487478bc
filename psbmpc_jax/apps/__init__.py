"""The applications built on the library: the ``psbmpc-jax`` command line (:mod:`.cli`), the runtime benchmark
sweeps (:mod:`.bench` and its ``bench_*`` modules) and the benchmark report (:mod:`.report`).

Nothing in the library imports this package; it imports the library."""
