import os

# Small dense algebra runs in loops, where multithreaded BLAS is slower; set before numpy loads.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import pytest  # noqa: E402


@pytest.fixture(scope="session")
def lab_simulated_run(tmp_path_factory):
    """(CampaignResult, log path): scenarios/lab.toml on the simulated plant (lab_runs.py)."""
    from lab_runs import simulated_lab_run

    return simulated_lab_run(tmp_path_factory.mktemp("lab-sim") / "sim.mcap")


@pytest.fixture(scope="session")
def lab_hil_run(tmp_path_factory):
    """(CliRunner result, log path): the emulated lab run in real time that the tests share
    (lab_runs.py; about a minute)."""
    from lab_runs import emulated_lab_run

    return emulated_lab_run(tmp_path_factory.mktemp("lab-hil") / "lab.mcap")
