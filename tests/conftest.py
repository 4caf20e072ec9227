"""Test-wide settings: Hypothesis without deadlines (the CI machine is shared and noisy), and
derandomised under CI=true so that a CI run is reproducible; locally it keeps exploring."""

import os

from hypothesis import settings

settings.register_profile("dev", deadline=None)
settings.register_profile("ci", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")
