"""Test-wide settings: Hypothesis without deadlines (the CI machine is shared and noisy), and
derandomised under CI=true so that a CI run is reproducible; locally it keeps exploring."""

import os

from hypothesis import settings

settings.register_profile("dev", deadline=None)
settings.register_profile("ci", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


import pytest  # noqa: E402
import signal  # noqa: E402

if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    # A test run started in the background by a script (`make test &`) inherits SIGINT ignored, and so
    # would every process a test starts: the Ctrl-C tests would see their Ctrl-C ignored (this used to
    # fail three of them in such a run). A handler, unlike SIG_IGN, is not inherited across exec.
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(autouse=True, scope="session")
def _private_state_dir(tmp_path_factory):
    """Robot processes keep their boot counter under $XDG_STATE_HOME (runtime/onboard/boot_counter.py): every
    test, and every process a test starts, gets a fresh folder of its own, never the user's."""
    old = os.environ.get("XDG_STATE_HOME")
    os.environ["XDG_STATE_HOME"] = str(tmp_path_factory.mktemp("xdg-state"))
    yield
    if old is None:
        os.environ.pop("XDG_STATE_HOME", None)
    else:
        os.environ["XDG_STATE_HOME"] = old
