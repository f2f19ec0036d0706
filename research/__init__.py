"""Research code, not part of the installed package: the thesis experiments and their published-table
constants, the baselines they compare against, an independent lumped-mass reference model, and where the
external validation datasets live. The benchmarks (which print its tables) and the tests (which assert them)
import it as `research.<module>` with the repository root on sys.path: benchmarks/_repository.py for the
benchmark scripts, tests/conftest.py for the tests."""
