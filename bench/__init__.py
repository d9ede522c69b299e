"""The benchmarks: entry scripts at this level, shared pieces in ``bench/_lib``.

Run one from the repository root as ``./dev bench NAME [ARGS]`` or ``python -m
bench.NAME [ARGS]``; ``./dev bench`` lists them. Each prints its figures, then, as its last
line, one line of JSON that names it: ``{"bench": "NAME", ...}``. A bench that starts
`arduinobot serve` or a router does it through the tests' launcher
(tests/helpers/serve.py, tests/helpers/zrouter.py), so both wait for a ready line alike.
"""
