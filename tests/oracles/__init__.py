"""Reference implementations (oracles) of the package's compiled kernels: the plain Python each
kernel replaced, kept here only to check the kernels against (tests/*/test_*_oracle.py)."""
