"""Co-simulation master: FMI 2.0 and 3.0 co-simulation FMUs, each playing a role through its port
map.

A component is one FMU instance with a role ("cylinder", "pile"; plant_models.model_spec) and an
FmuSpec whose port map names the FMU variable of every role port, and of the parameter roles in
PARAMETER_ROLES (a cylinder's initial stroke `x0`, which the simulated excavator sets). The
master checks every component before anything is instantiated (each port an FMU variable of
type Real, FMI 3.0 a scalar Float64, with the right causality, each parameter a variable that
can be set before initialization), extracts each FMU file once, instantiates and initialises
every component, and frees all of them in `close()`, on error too.

Value exchange per step goes through fmus.runs.FastSlave: pre-allocated numpy buffers and the
FMU's own fmi2SetReal / fmi2DoStep / fmi2GetReal (FMI 3.0: fmi3SetFloat64 / fmi3DoStep /
fmi3GetFloat64) entry points with pre-converted arguments.
A component's `inputs` buffer holds the role's inputs in role order (`input_index`), `outputs`
the role's outputs in role order (`output_index`); the caller writes inputs, calls
`step(t, h)` and reads outputs. The coupling itself (who feeds whom, in which order) belongs
to the caller: for the excavator, orchestrator.plants.simulated_excavator.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from fmus.descriptions import model_description
from fmus.runs import REAL_TYPES, FastSlave, NativeStep, fmi_major
from orchestrator.plants.derived import DerivedOutput, derive_outputs
from orchestrator.plants.fmu_support import not_co_simulation
from plant_models.model_spec import (
    CYLINDER_INPUTS,
    DERIVABLE_OUTPUTS,
    DERIVATION_PARAMETERS,
    OPTIONAL_PORTS,
    PILE_INPUTS,
    ROLES,
    SUPPLY_INPUTS,
    FmuSpec,
)
from plant_models.port_units import PortMap, unit_conversion

_ROLE_INPUTS = {"cylinder": CYLINDER_INPUTS, "pile": PILE_INPUTS}
# Parameter roles: parameters the plant sets itself, mapped like ports (x0: initial stroke, m).
PARAMETER_ROLES = {"cylinder": ("x0",), "pile": ()}
_SETTABLE = ("parameter", "input")  # causalities whose start values may be set before init


def fmu_path(spec: FmuSpec, component: str) -> Path:
    """The .fmu file of `spec`: one of our models, built on demand, or an existing path."""
    import fmus

    if spec.fmu in fmus.MODELS:
        try:
            return fmus.build(spec.fmu)
        except fmus.BuildError as error:
            raise ValueError(f"{component}: cannot build FMU {spec.fmu!r}: {error}") from None
    path = Path(spec.fmu).expanduser()
    try:
        found = path.is_file()
    except OSError:  # a name longer than the file system takes, and the like
        found = False
    if path.suffix != ".fmu" or not found:
        raise ValueError(f"{component}: FMU {spec.fmu!r} is neither one of our models "
                         f"({', '.join(fmus.MODELS)}) nor an existing .fmu file")
    return path


def check_component(component: str, role: str, spec: FmuSpec, description) -> dict[str, str]:
    """Check `spec`'s port map and parameters against an FMU's model description.

    Returns {port role: FMU variable name} for the role's ports and parameter roles; an
    optional port (OPTIONAL_PORTS) that the FMU lacks and the port map does not name is left
    out, and so is a derivable output (DERIVABLE_OUTPUTS) that the master can derive
    (orchestrator.plants.derived). Raises ValueError naming the component, the role and the
    variable.
    """
    if role not in ROLES:
        raise ValueError(f"{component}: unknown role {role!r}; roles: {', '.join(ROLES)}")
    refusal = not_co_simulation(description)
    if refusal:
        raise ValueError(f"{component}: {refusal}")
    real = "Real" if fmi_major(description) == 2 else "Float64"
    variables = {v.name: v for v in description.modelVariables}
    known = ROLES[role] + PARAMETER_ROLES[role] + DERIVATION_PARAMETERS[role]
    unknown = sorted(set(spec.ports) - set(known))
    if unknown:
        raise ValueError(f"{component}: port map names unknown role {unknown[0]!r}; "
                         f"{role} roles: {', '.join(known)}")
    ports = {}
    for port in ROLES[role]:
        name = spec.variable(port)
        wanted = "input" if port in _ROLE_INPUTS[role] else "output"
        variable = variables.get(name)
        if variable is None and port not in spec.ports and (
                port in OPTIONAL_PORTS[role] or port in DERIVABLE_OUTPUTS[role]):
            continue  # a derivable output is checked below, once the ports are known
        if port in SUPPLY_INPUTS and port not in spec.ports and variable.causality != "input":
            continue  # a parameter of that name is the FMU's own supply, not the pump's port
        if variable is None:
            raise ValueError(f"{component}: role {port!r} maps to variable {name!r}, which "
                             f"{description.modelName} does not have")
        if variable.causality != wanted or variable.type not in REAL_TYPES \
                or getattr(variable, "dimensions", None):
            shape = "array " if getattr(variable, "dimensions", None) else ""
            raise ValueError(f"{component}: role {port!r} needs a {real} {wanted}, but variable "
                             f"{name!r} of {description.modelName} is a {shape}"
                             f"{variable.type} {variable.causality}")
        ports[port] = name
    for port in PARAMETER_ROLES[role]:
        ports[port] = spec.variable(port)
        _check_settable(component, description, variables, ports[port], port)
    for name, value in spec.parameters.items():
        _check_settable(component, description, variables, name, None)
        _check_shape(component, description, variables[name], value)
    port_conversions(component, spec, description, ports)
    derive_outputs(component, role, spec, description, ports)
    return ports


def derivation_notes(component: str, role: str, spec: FmuSpec) -> dict[str, str]:
    """output role -> how the master derives it for `spec` in `role` (DerivedOutput.note), {}
    when the FMU has every output; for the run log. ValueError as check_component."""
    description = model_description(fmu_path(spec, component))
    ports = check_component(component, role, spec, description)
    return {output: derived.note() for output, derived in
            derive_outputs(component, role, spec, description, ports).items()}


def port_conversions(component: str, spec: FmuSpec, description,
                     ports: Mapping[str, str]) -> dict[str, PortMap]:
    """role -> PortMap for every port whose FMU value is not already the role's SI value: the
    scenario's explicit scale and offset, else the FMU's declared unit converted
    (plant_models.port_units). ValueError naming the component, role and variable."""
    variables = {v.name: v for v in description.modelVariables}
    definitions = {u.name: u for u in getattr(description, "unitDefinitions", [])}
    out = {}
    for role, name in ports.items():
        if role in spec.port_maps:
            if not spec.port_maps[role].identity:
                out[role] = spec.port_maps[role]
            continue
        try:
            conversion = unit_conversion(role, variables[name], definitions)
        except ValueError as error:
            raise ValueError(f"{component}: {error}") from None
        if conversion is not None:
            out[role] = conversion
    return out


def _closest(name: str, candidates: list[str]) -> str:
    """' (closest: a, b, c)': the candidates nearest to a misspelt name, for the message."""
    import difflib

    near = difflib.get_close_matches(name, candidates, n=3, cutoff=0.5)
    if not near:  # nothing alike: the lower-case containment catches 'Density' vs 'rho_density'
        near = [c for c in candidates if name.lower() in c.lower() or c.lower() in name.lower()]
    return f" (closest: {', '.join(near[:3])})" if near else ""


def _check_settable(component, description, variables, name, port) -> None:
    what = f"role {port!r} maps to variable {name!r}" if port else f"parameter {name!r}"
    variable = variables.get(name)
    if variable is None:
        hint = _closest(name, [v.name for v in variables.values()
                               if v.causality in _SETTABLE and v.variability != "constant"])
        raise ValueError(f"{component}: {what}, which {description.modelName} does not have"
                         f"{hint}" if port else
                         f"{component}: {description.modelName} has no {what}{hint}")
    if variable.causality not in _SETTABLE or variable.variability == "constant":
        raise ValueError(f"{component}: {what} has causality {variable.causality} in "
                         f"{description.modelName}; only parameters and inputs can be set")


def _check_shape(component, description, variable, value) -> None:
    """An array parameter (FMI 3.0 dimensions) takes a list, a scalar one a number."""
    dimensions = getattr(variable, "dimensions", None) or []
    is_list = isinstance(value, list | tuple)
    if dimensions and not is_list:
        sizes = [getattr(d, "start", None) for d in dimensions]
        size = " x ".join(str(n) for n in sizes) if all(sizes) else "several"
        raise ValueError(f"{component}: parameter {variable.name!r} of "
                         f"{description.modelName} is an array ({size} values); give it a list, "
                         f"not {value!r}")
    if is_list and not dimensions:
        raise ValueError(f"{component}: parameter {variable.name!r} of "
                         f"{description.modelName} is a scalar; give it one value, not a list")


def _affine(roles: Sequence[str], conversions: Mapping[str, PortMap]):
    """(scale, offset) arrays of `roles` in order (1, 0 where not converted)."""
    scale = np.array([conversions[r].scale if r in conversions else 1.0 for r in roles])
    offset = np.array([conversions[r].offset if r in conversions else 0.0 for r in roles])
    return scale, offset


class Component:
    """One initialised FMU instance (see the module docstring)."""

    def __init__(self, name: str, role: str, spec: FmuSpec, path: Path, description,
                 ports: Mapping[str, str], unzip_dir: str,
                 start_values: Mapping[str, float],
                 conversions: Mapping[str, PortMap] | None = None,
                 derived: Mapping[str, DerivedOutput] | None = None) -> None:
        self.name, self.role, self.spec, self.path = name, role, spec, path
        self.description = description
        input_roles = _ROLE_INPUTS[role]
        output_roles = tuple(p for p in ROLES[role] if p not in input_roles)
        self.input_index = {port: i for i, port in enumerate(input_roles)}
        self.output_index = {port: i for i, port in enumerate(output_roles)}
        present = [p for p in output_roles if p in ports]
        present_inputs = [p for p in input_roles if p in ports]
        self.derived: dict[str, DerivedOutput] = dict(derived or {})
        """Output roles the FMU lacks that the master computes (orchestrator.plants.derived)."""
        self.missing_outputs: tuple[str, ...] = tuple(
            p for p in output_roles if p not in ports and p not in self.derived)
        """Optional output roles the FMU does not have (their `outputs` slots hold NaN)."""
        self.missing_inputs: tuple[str, ...] = tuple(p for p in input_roles if p not in ports)
        """Optional input roles the FMU does not have (what is written to their slots is unused)."""
        try:
            self._slave = FastSlave(path, [ports[p] for p in present_inputs],
                                    [ports[p] for p in present], start_values,
                                    instance_name=name, unzip_dir=unzip_dir)
        except ValueError as error:
            raise ValueError(f"{name}: {error}") from None
        except Exception as error:  # fmpy raises plain Exceptions for FMI status errors
            raise ValueError(f"{name}: {description.modelName} did not initialise with its "
                             f"start values ({error})") from None
        try:  # the FMU's piston areas, as initialised (a calculated parameter has no start)
            terms = {o: d.coefficients(self._slave.read, name) for o, d in self.derived.items()}
        except Exception:
            self._slave.close()
            raise
        self.derived_notes = {o: d.note(terms[o]) for o, d in self.derived.items()}
        """output role -> how the master derives it, with the values it uses."""
        self.inputs: np.ndarray = self._slave.inputs
        """(n_inputs,) buffer, role input order: write here, then step()."""
        self.conversions = dict(conversions or {})
        """role -> PortMap of the ports converted between the FMU's units and SI."""
        self._refresh = self._slave.outputs  # refills `outputs` from the FMU
        self.native_step: NativeStep | None = None
        if not (self.missing_outputs or self.missing_inputs or self.conversions or self.derived):
            self.outputs: np.ndarray = self._slave.outputs()
            """(n_outputs,) buffer, role output order, refreshed by every step()."""
            self.step = self._slave.step
            """step(t_s, h_s): set the inputs, step from t_s by h_s, refresh `outputs`."""
            self.native_step = self._slave.native_step
            """The same step for a loop in C (fmus.runs.NativeStep), None where there is
            none (no fmus.fast_step; a component converting ports steps through Python)."""
        else:  # copies in role layout and SI units: only for FMUs that need them
            self.inputs = np.zeros(len(input_roles))
            self.outputs = np.full(len(output_roles), np.nan)
            slots = np.array([output_roles.index(p) for p in present], dtype=int)
            in_slots = np.array([input_roles.index(p) for p in present_inputs], dtype=int)
            # si = scale * fmu + offset, per slot (identity where a port is not converted).
            in_scale, in_offset = _affine(tuple(present_inputs), self.conversions)
            out_scale, out_offset = _affine(tuple(present), self.conversions)
            slave_step, slave_in = self._slave.step, self._slave.inputs
            slave_out, outputs, inputs = self._slave.outputs(), self.outputs, self.inputs
            # output slot -> ((term slot, coefficient), ...): each derived output, in SI.
            rules = [(output_roles.index(o), tuple((output_roles.index(t), c) for t, c in
                                                   terms[o])) for o in self.derived]

            def refresh() -> None:
                outputs[slots] = out_scale * slave_out + out_offset
                for slot, sums in rules:
                    value = 0.0
                    for term, coefficient in sums:
                        value += outputs[term] * coefficient
                    outputs[slot] = value

            inputs[in_slots] = in_scale * slave_in + in_offset  # the start values, in SI
            refresh()
            self._refresh = refresh

            def step(t_s: float, h_s: float) -> None:
                slave_in[:] = (inputs[in_slots] - in_offset) / in_scale
                slave_step(t_s, h_s)
                refresh()

            self.step = step

    def read(self, names: Sequence[str]) -> np.ndarray:
        """Current values (n,) of any Real variables of the FMU, by FMU variable name."""
        if self._slave.slave is None:
            raise RuntimeError(f"{self.name}: the FMU instance is closed")
        return self._slave.read(names)

    @property
    def rollback(self) -> tuple[int, int, int] | None:
        """(save, restore, bound state) addresses of the FMU's state rollback for a loop in C
        (fmus/fast_step/rollback.c), None where the FMU cannot get and set its state."""
        step = self._slave.native_step
        if step is None or step.rollback_address is None:
            return None
        return step.save_address, step.restore_address, step.rollback_address

    @property
    def can_save_state(self) -> bool:
        """Whether the FMU can serialize its state (save_state, restore_state)."""
        return self._slave.can_serialize_state

    def save_state(self) -> bytes:
        """The FMU instance's state, serialized by the FMU (fmus.runs.FastSlave)."""
        return self._slave.serialize_state()

    def restore_state(self, data: bytes) -> None:
        """Put the instance into a state from save_state and refill `outputs` from it (as the
        step that reached the state left them). The FMU validates the bytes; fmpy's
        exception when it refuses them."""
        self._slave.restore_state(data)
        self._refresh()

    def close(self) -> str | None:
        """Terminate and free the instance; safe twice (stepping afterwards is a RuntimeError,
        not a call into freed memory). What failed in its terminate, if anything (FastSlave)."""
        failure, self.step, self.native_step = self._slave.close(), self._closed, None
        return failure

    def _closed(self, *args) -> None:
        raise RuntimeError(f"{self.name}: the FMU instance is closed")


class Master:
    """FMUs of one run: checked, instantiated once, freed by close() (also a context manager).

    components: name -> (role, FmuSpec). step_s: the communication step (s).
    start_values: name -> {input role or parameter role (e.g. "tip_y", "x0"): value}, set
    before initialization on top of the spec's parameters.
    """

    def __init__(self, components: Mapping[str, tuple[str, FmuSpec]], step_s: float,
                 start_values: Mapping[str, Mapping[str, float]] | None = None) -> None:
        if not step_s > 0.0:
            raise ValueError(f"communication step must be > 0 s, got {step_s!r}")
        from fmpy import extract

        self.step_s = float(step_s)
        self.components: dict[str, Component] = {}
        self._unzip_dirs: dict[Path, str] = {}
        start_values = start_values or {}
        checked = []
        for name, (role, spec) in components.items():
            path = fmu_path(spec, name)
            try:
                description = model_description(path)
            except Exception as error:
                raise ValueError(f"{name}: cannot read {path.name}: {error}") from None
            ports = check_component(name, role, spec, description)
            conversions = port_conversions(name, spec, description, ports)
            derived = derive_outputs(name, role, spec, description, ports)
            values = dict(spec.parameters)
            for key, value in start_values.get(name, {}).items():
                if key not in _ROLE_INPUTS[role] + PARAMETER_ROLES[role]:
                    raise ValueError(f"{name}: start values are set by input or parameter "
                                     f"role, got {key!r}")
                if key not in ports:  # an optional input the FMU does not have
                    continue
                # Start values come in the role's SI units: into the FMU's.
                values[ports[key]] = conversions[key].from_si(value) if key in conversions \
                    else value
            checked.append((name, role, spec, path, description, ports, values, conversions,
                            derived))
        try:
            for name, role, spec, path, description, ports, values, conversions, derived \
                    in checked:
                if path not in self._unzip_dirs:
                    self._unzip_dirs[path] = extract(
                        str(path), unzipdir=tempfile.mkdtemp(prefix="excosim-fmu-"))
                self.components[name] = Component(name, role, spec, path, description, ports,
                                                  self._unzip_dirs[path], values, conversions,
                                                  derived)
        except BaseException:
            self.close()
            raise

    def __getitem__(self, name: str) -> Component:
        return self.components[name]

    def close(self) -> None:
        """Free every instance and remove the extracted FMUs; safe twice. Then RuntimeError
        naming each FMU whose terminate failed without an earlier error (FastSlave.close)."""
        failures = [f for f in (c.close() for c in self.components.values()) if f]
        for folder in self._unzip_dirs.values():
            shutil.rmtree(folder, ignore_errors=True)
        self._unzip_dirs.clear()
        if failures:
            raise RuntimeError("; ".join(failures))

    def __enter__(self) -> Master:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
