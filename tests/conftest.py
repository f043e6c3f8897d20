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


# The slow set (pytest -m slow; `make test` leaves it out, `make test-all` and CI run it): what
# took most of the suite's time, measured with `pytest --durations=250` on 2 cores, seconds in
# brackets. Whole modules, or (module, test name prefix).
SLOW_MODULES = {
    "test_lab_faults.py",        # real-time faults on the CAN link (50)
    "test_lab_hil.py",           # the emulated lab run in real time (about 40, shared)
    "test_lab_log_tools.py",     # its log (the same run)
    "test_lab_cli.py",           # a master and the standalone emulator (10)
    "test_readme.py",            # every README block, campaigns included (49)
    "test_cylinder_reference.py",  # the cylinder against scipy's Radau (45)
    "test_sweep.py",             # sweeps on local pools and Dask (43)
    "test_packaged_build.py",    # wheels and fresh venvs (19)
    "test_run_isolation.py",     # crashing FMUs in supervised children (12)
    "test_examples.py",          # every numbered example (11)
    "test_scenario_mutations.py",  # generated scenarios, each dug (11)
    "test_run_log_damage.py",    # decompression bombs and damaged chunks in every command (11)
    "test_log_record_mutations.py",  # 300 edited logs, each through five commands (90)
}
SLOW_TESTS = {
    ("test_foxglove_layout.py", "test_each_machines_"): "lab (emulated",  # the lab run (40)
    ("test_log_records.py", "test_a_bad_period_record_is_one_line_in_every_command"): "",  # (30)
    ("test_cli_conventions.py", "test_ctrl_c_"): "",  # runs signalled in children (15 in all)
    ("test_cli_conventions.py", "test_sigterm_"): "",
    ("test_cli_conventions.py", "test_two_runs_started_together"): "",
    ("test_resume.py", "test_a_run_killed_with_sigkill"): "",  # (6)
    ("test_fmu_conformance.py", "test_no_call_sequence_crashes"): "",  # (10)
    # The fast set's own slowest, to keep it under 3 minutes (measured on the fast set):
    ("test_stop_signals.py", "test_a_stop_at_any_moment"): "",  # ten runs signalled (19)
    ("test_full_scale.py", "test_the_payload_reaches_the_arm"): "",  # (5.6)
    ("test_calibrate.py", "test_the_same_command_continues"): "",  # (3.1)
    ("test_calibrate.py", "test_the_paper_benchs_figure_9"): "",  # (2.9)
    ("test_sweep_designs.py", "test_bad_input_exits_2"): "",  # (3.2)
    ("test_step_watchdog.py", "test_a_step_that_never_returns"): "",  # (3.6)
    ("test_live.py", "test_"): "",  # a real client, paced runs (4.7)
    ("test_native_coupling.py", "test_the_arms_equation_of_motion"): "",  # (2.8)
    ("test_docs.py", "test_the_site_builds_strict"): "",  # (2.5)
    ("test_resume.py", "test_a_terrain_run_resumes"): "",  # (2.5)
    ("test_cylinder_regeneration.py", "test_regeneration_under_radau"): "",  # (2.2)
    ("test_nonsense_inputs.py", "test_review_and_compare_options"): "",  # (2.1)
    ("test_design_cache.py", "test_a_run_with_remembered_designs"): "",  # (2.1)
    ("test_lab_time_scale.py", "test_a_fast_emulated_run"): "",  # (2.0)
}


def pytest_collection_modifyitems(items):
    slow = pytest.mark.slow
    for item in items:
        module = item.path.name
        if module in SLOW_MODULES or any(
                module == name and item.name.startswith(prefix) and marker in item.name
                for (name, prefix), marker in SLOW_TESTS.items()):
            item.add_marker(slow)
