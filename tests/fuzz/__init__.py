"""Fuzzing of the public entry points: the harness (`harness.py`) and its long run (`long_run.py`)."""
