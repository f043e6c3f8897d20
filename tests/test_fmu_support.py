"""What the master refuses to run, in one line naming the FMU and what to do, read from the model
description: an FMU for model exchange or for scheduled execution only, one with input clocks
(the master never ticks them), and one that takes only its own fixed step when the
communication step is another (FMI 2.0 canHandleVariableCommunicationStepSize false with a
default experiment stepSize). The descriptions are fmpy's, read from our FMUs and then changed
as another tool would have exported them."""

import copy
from types import SimpleNamespace

import pytest
from fmpy import read_model_description

import fmus
from orchestrator.plants.fmu_support import check_fixed_step, fixed_step_s, not_co_simulation


@pytest.fixture(scope="module")
def ours():
    return read_model_description(str(fmus.build("HydraulicCylinder")))


def test_ours_run(ours):
    assert not_co_simulation(ours) is None
    assert ours.coSimulation.canHandleVariableCommunicationStepSize
    assert fixed_step_s(ours) is None and check_fixed_step("boom", ours, 0.01) is None


def test_model_exchange_and_scheduled_execution_are_named_as_what_they_are(ours):
    exchange = copy.copy(ours)
    exchange.coSimulation = None
    assert "for model exchange only" in not_co_simulation(exchange)
    scheduled = copy.copy(exchange)
    scheduled.scheduledExecution = SimpleNamespace(modelIdentifier="HydraulicCylinder")
    assert "for scheduled execution only" in not_co_simulation(scheduled)


def test_input_clocks_are_refused(ours):
    clocked = copy.copy(ours)
    clocked.modelVariables = [*ours.modelVariables,
                              SimpleNamespace(name="tick", type="Clock", causality="input")]
    assert not_co_simulation(clocked) == (
        "HydraulicCylinder has input clocks (tick), which the master never ticks: it runs "
        "co-simulation FMUs without clocks (export it without them)")


def test_a_fixed_step_fmu_runs_only_at_its_step(ours):
    fixed = copy.copy(ours)
    fixed.coSimulation = copy.copy(ours.coSimulation)
    fixed.coSimulation.canHandleVariableCommunicationStepSize = False
    fixed.defaultExperiment = SimpleNamespace(stepSize="0.001")
    assert fixed_step_s(fixed) == 0.001
    assert check_fixed_step("bucket", fixed, 0.001) == 0.001
    with pytest.raises(ValueError, match=r"^bucket: HydraulicCylinder steps only at its fixed "
                       r"step 0\.001 s .* not at the communication step 0\.01 s: set "
                       r"plant\.communication_step_s = 0\.001"):
        check_fixed_step("bucket", fixed, 0.01)
    fixed.coSimulation.canHandleVariableCommunicationStepSize = True  # any step then
    assert fixed_step_s(fixed) is None


def test_a_parameter_of_the_wrong_shape_is_named(ours):
    """A number for an array parameter (FMI 3.0 dimensions), or a list for a scalar one: the
    refusal names the parameter and its shape, before any FMU runs."""
    from orchestrator.plants.master import check_component
    from plant_models.model_spec import FmuSpec

    arrayed = copy.copy(ours)
    arrayed.modelVariables = [copy.copy(v) for v in ours.modelVariables]
    bore = next(v for v in arrayed.modelVariables if v.name == "bore")
    bore.dimensions = [SimpleNamespace(start=3)]
    with pytest.raises(ValueError, match=r"^boom: parameter 'bore' of HydraulicCylinder is an "
                       r"array \(3 values\); give it a list, not 0\.12$"):
        check_component("boom", "cylinder", FmuSpec("HydraulicCylinder", {"bore": 0.12}),
                        arrayed)
    with pytest.raises(ValueError, match=r"^boom: parameter 'rod' of HydraulicCylinder is a "
                       r"scalar; give it one value, not a list$"):
        check_component("boom", "cylinder", FmuSpec("HydraulicCylinder", {"rod": [0.1, 0.2]}),
                        ours)
