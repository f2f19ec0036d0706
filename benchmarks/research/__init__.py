"""Research code beside the benchmarks, not part of the installed package: the thesis experiments
and their published-table constants, the baselines they compare against, an independent
lumped-mass reference model, and where the external validation datasets live. Benchmarks and
tests import it as `research.<module>` (benchmarks/ on sys.path: the benchmark scripts' own
folder; tests/conftest.py adds it for the tests)."""
