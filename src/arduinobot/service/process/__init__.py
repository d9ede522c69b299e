"""The service's processes: the worker pool and what a worker holds.

- ``pool``: the pool of worker processes, deadlines and counters.
- ``worker``: a worker's loop (decode, plan, encode).
- ``zygote``: the pre-loaded parent workers fork from.
- ``slot``: one worker slot (its pipes, its deadline, its restart).
- ``job``: a job handed to a worker.
- ``memtrace``: memory tracing of the workers (``ARDUINOBOT_MEMTRACE``).
- ``heap_trim``: freed heap given back (``malloc_trim``), the serving process's and each worker's.
- ``disk_cache``: the artifact cache (collision geometry built once per model).
- ``warmup``: compile the kernels and fill the cache at set-up.
"""
