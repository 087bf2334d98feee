"""Test-suite settings: reproducible property tests and a headless matplotlib."""

import os

import matplotlib
from hypothesis import HealthCheck, settings

matplotlib.use("Agg")

# Property tests draw their examples from a fixed seed, so a run is reproducible (conventions:
# seeded randomness); set OPTIK_HYPOTHESIS=explore to search with fresh randomness locally.
settings.register_profile("ci", derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("explore", deadline=None)
settings.load_profile(os.environ.get("OPTIK_HYPOTHESIS", "ci"))
