"""Identify a cylinder FMU's linear model (plant_models.linear_cylinder) by a short open-loop test.

Why: the servo needs x/u = K_v w_h^2 / (s (s^2 + 2 zeta w_h s + w_h^2)); an FMU that is not
our HydraulicCylinder does not tell it. So the FMU alone is driven, unloaded (F_ext = 0: the
only load every FMU agrees on), with a constant spool command from rest, at operating points

    stroke 25, 50 and 75 % x command +-0.1 and +-0.3 (extending and retracting)

Each run starts half a travel before the operating stroke and stops after a travel of 10 % of
the stroke (or 4000 samples), so it is centred on its operating stroke and far from the end
stops; samples are taken every step_s / 10. From each run:

- K_v,i: the mean velocity over the run's second half (stroke travelled / time, which
  averages the oscillation out) per unit command;
- w_i, zeta_i: the velocity fitted with v(t) = c0 + e^{-sigma t}(c1 cos w_d t + c2 sin w_d t)
  + c3 e^{-a t} (scipy least_squares on sigma, w_d, a; the c's by linear least squares): the
  step response of the hydraulic pole pair plus the real pole of the chambers' pressure level,
  which the valve's flow-pressure coefficient couples in (a second-order fit alone biases w by
  up to 10 %). w_i = |pole| = hypot(sigma, w_d), zeta_i = sigma / w_i. A response without a
  visible oscillation (an overdamped or first-order plant such as a velocity-servoed actuator)
  is fitted as a second-order step with zeta >= 1 instead.

The returned model is the small-signal one: from the +-0.1 runs (a critical-centre valve's
damping grows with the opening, so the smallest opening is the least damped and the closest to
the closed-valve linearisation), K_v the mean of extending and retracting, w_h and zeta the
lowest. Every run's fit is kept: the servo's margins must hold at each (design_linear_servo).
"""

from __future__ import annotations

import hashlib
import math
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plant_models.linear_cylinder import LinearCylinderModel
from plant_models.port_units import PortMap

STROKE_FRACTIONS: tuple[float, ...] = (0.25, 0.5, 0.75)
OPENINGS: tuple[float, ...] = (0.1, 0.3)
TRAVEL_FRACTION = 0.1  # of the stroke per run: w_h changes with the oil volumes along it
MAX_SAMPLES = 4000
SAMPLES_PER_STEP = 10
_FIT_SAMPLES = 1500  # the fit decimates to this many samples (accuracy is set by the span)
_MIN_OSCILLATION = 0.02  # oscillation amplitude / steady velocity below which: overdamped


@dataclass(frozen=True)
class OperatingPointFit:
    """One open-loop run: operating stroke_m (m, mean over the run), spool command (-1..1),
    the fitted model of that point, residual_rms (RMS fit error / steady velocity)."""

    stroke_m: float
    command: float
    model: LinearCylinderModel
    residual_rms: float


@dataclass(frozen=True)
class CylinderIdentification:
    """model: the small-signal linear model (see the module docstring); fits: every run."""

    model: LinearCylinderModel
    fits: tuple[OperatingPointFit, ...]

    def describe(self) -> str:
        """One line for a person."""
        return f"identified {self.model.describe()} from {len(self.fits)} open-loop runs"


_CACHE: dict[tuple, CylinderIdentification] = {}


def identify_cylinder(fmu_path: str | Path, ports: Mapping[str, str],
                      parameters: Mapping[str, float | int | bool], stroke_m: float,
                      step_s: float, openings: Sequence[float] = OPENINGS,
                      stroke_fractions: Sequence[float] = STROKE_FRACTIONS,
                      conversions: Mapping[str, PortMap] | None = None,
                      sample_s: float | None = None) -> CylinderIdentification:
    """Identify the linear model of the cylinder FMU at fmu_path (see the module docstring).

    ports: role -> FMU variable (roles u, F_ext, x, v, x0; missing roles are their own name);
    parameters: start values (SI); stroke_m (m): the usable stroke; step_s (s): the servo's
    communication step (samples every step_s / 10); conversions: role -> PortMap of ports whose
    FMU values are not SI (orchestrator.plants.master.port_conversions); sample_s (s): the runs'
    step, default step_s / 10 (an FMU that takes only its own fixed step is run at it). Cached
    by the FMU's
    sha256, parameters, ports, conversions and settings. ValueError naming the FMU and variable
    when it does not move, gives NaN or fails.
    """
    path = Path(fmu_path)
    if not (math.isfinite(stroke_m) and stroke_m > 0.0):
        raise ValueError(f"{path.name}: stroke_m must be > 0 m, got {stroke_m!r}")
    if not (math.isfinite(step_s) and step_s > 0.0):
        raise ValueError(f"{path.name}: step_s must be > 0 s, got {step_s!r}")
    content = path.read_bytes()  # once: a rebuild of the file meanwhile must not mix versions
    digest = hashlib.sha256(content).hexdigest()
    conversions = dict(conversions or {})
    key = (digest, tuple(sorted(parameters.items())), tuple(sorted(ports.items())),
           tuple(sorted(conversions.items())), float(stroke_m), float(step_s), tuple(openings),
           tuple(stroke_fractions), sample_s)
    if key not in _CACHE:
        _CACHE[key] = _identify(path, content, ports, parameters, stroke_m,
                                sample_s or step_s / SAMPLES_PER_STEP, openings,
                                stroke_fractions, conversions)
    return _CACHE[key]


def _identify(path: Path, content: bytes, ports, parameters, stroke_m: float, dt: float,
              openings, stroke_fractions, conversions) -> CylinderIdentification:
    from fmpy import extract

    names = {role: ports.get(role, role) for role in ("u", "F_ext", "x", "v", "x0")}
    folder = Path(tempfile.mkdtemp(prefix="excosim-identify-"))
    try:
        copy = folder / path.name
        copy.write_bytes(content)
        unzip = extract(str(copy), unzipdir=str(folder / "unzipped"))
        fits = []
        for opening in openings:
            for fraction in stroke_fractions:
                for command in (opening, -opening):
                    fits.append(_one_run(path, unzip, names, parameters, stroke_m, dt,
                                         fraction * stroke_m, command, conversions))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    smallest = min(abs(c) for c in openings)
    small = [f for f in fits if math.isclose(abs(f.command), smallest)]
    gains = [f.model.velocity_gain_m_s for f in small]
    extend = [g for g, f in zip(gains, small, strict=True) if f.command > 0.0]
    retract = [g for g, f in zip(gains, small, strict=True) if f.command < 0.0]
    model = LinearCylinderModel(
        velocity_gain_m_s=0.5 * (float(np.mean(extend)) + float(np.mean(retract))),
        natural_frequency_rad_s=min(f.model.natural_frequency_rad_s for f in small),
        damping=min(f.model.damping for f in small), stroke_m=float(stroke_m))
    return CylinderIdentification(model=model, fits=tuple(fits))


def _one_run(path: Path, unzip: str, names: Mapping[str, str], parameters, stroke_m: float,
             dt: float, operating_stroke: float, command: float,
             conversions: Mapping[str, PortMap]) -> OperatingPointFit:
    """Drive the FMU from rest with `command` held; fit the velocity (see the module doc)."""
    from fmus.runs import FastSlave

    identity = PortMap("")

    def fmu_value(role: str, si: float) -> float:
        return conversions.get(role, identity).from_si(si)

    x_map, v_map = conversions.get("x", identity), conversions.get("v", identity)

    travel = TRAVEL_FRACTION * stroke_m
    start = operating_stroke - math.copysign(0.5 * travel, command)
    where = f"{path.name} ({names['u']} = {command:+g} at {names['x']} = {start:.4g} m)"
    u_fmu, load_fmu = fmu_value("u", command), fmu_value("F_ext", 0.0)
    start_values = {**parameters, names["x0"]: fmu_value("x0", start), names["u"]: u_fmu,
                    names["F_ext"]: load_fmu}
    rows = np.empty((MAX_SAMPLES + 1, 2))
    try:
        with FastSlave(unzip, [names["u"], names["F_ext"]], [names["x"], names["v"]],
                       start_values, "identify", unzip) as slave:
            slave.inputs[:] = (u_fmu, load_fmu)
            scale = np.array([x_map.scale, v_map.scale])  # to SI: scale * fmu + offset
            offset = np.array([x_map.offset, v_map.offset])
            rows[0] = scale * slave.outputs() + offset
            count = MAX_SAMPLES
            for k in range(MAX_SAMPLES):
                rows[k + 1] = scale * slave.step(k * dt, dt) + offset
                if not np.all(np.isfinite(rows[k + 1])):
                    bad = names["x"] if not math.isfinite(rows[k + 1, 0]) else names["v"]
                    raise ValueError(f"{where}: output {bad} is {rows[k + 1].tolist()} at "
                                     f"t = {(k + 1) * dt:.4g} s")
                if abs(rows[k + 1, 0] - start) >= travel:
                    count = k + 1
                    break
    except ValueError:
        raise
    except Exception as error:  # fmpy / the FMU: many kinds
        raise ValueError(f"{where}: the open-loop test failed: {error}") from None
    rows = rows[:count + 1]
    t = np.arange(count + 1) * dt
    half = count // 2
    mean_velocity = (rows[-1, 0] - rows[half, 0]) / (t[-1] - t[half])
    if not abs(mean_velocity) > 1e-6 * stroke_m / dt / MAX_SAMPLES:
        raise ValueError(f"{where}: {names['x']} did not move ({rows[-1, 0] - start:.3g} m in "
                         f"{t[-1]:.3g} s); is {names['u']} the spool command?")
    gain = mean_velocity / command
    if gain <= 0.0:
        raise ValueError(f"{where}: {names['x']} moves against the command (velocity "
                         f"{mean_velocity:.3g} m/s): u must extend the cylinder when positive")
    omega, damping, residual = _fit_velocity(t, rows[:, 1], dt)
    model = LinearCylinderModel(velocity_gain_m_s=float(gain), natural_frequency_rad_s=omega,
                                damping=damping, stroke_m=float(stroke_m))
    return OperatingPointFit(stroke_m=float(np.mean(rows[:, 0])), command=float(command),
                             model=model, residual_rms=residual / abs(mean_velocity))


def _basis(t: np.ndarray, sigma: float, omega: float, rate: float) -> np.ndarray:
    decay = np.exp(-sigma * t)
    return np.column_stack([np.ones_like(t), decay * np.cos(omega * t),
                            decay * np.sin(omega * t), np.exp(-rate * t)])


def _fit_velocity(t: np.ndarray, v: np.ndarray, dt: float) -> tuple[float, float, float]:
    """(w rad/s, zeta, RMS residual m/s) of the velocity step response v(t)."""
    from scipy.optimize import least_squares

    stride = max(1, len(t) // _FIT_SAMPLES)
    t, v = t[::stride], v[::stride]
    top = math.pi / (dt * stride)  # Nyquist of the decimated record

    def residual(p):
        basis = _basis(t, *p)
        coefficients = np.linalg.lstsq(basis, v, rcond=None)[0]
        return basis @ coefficients - v

    # The oscillation's frequency from the acceleration's spectrum (the step itself would
    # dominate the velocity's); the decay rates from a few multiples of it.
    window = np.diff(v) * np.hanning(len(v) - 1)
    spectrum = np.abs(np.fft.rfft(window, 8 * len(window)))
    frequencies = 2.0 * math.pi * np.fft.rfftfreq(8 * len(window), t[1] - t[0])
    guess = float(frequencies[1 + int(np.argmax(spectrum[1:]))])
    best = None
    for sigma in (0.05, 0.3):
        for rate in (0.3, 3.0):
            start = np.clip([sigma * guess, guess, rate * guess], 1e-6, 0.99 * top)
            fit = least_squares(residual, start, bounds=([0.0, 0.0, 0.0], [top, top, top]),
                                x_scale=[guess] * 3)
            if best is None or fit.cost < best.cost:
                best = fit
    sigma, omega_d, rate = best.x
    coefficients = np.linalg.lstsq(_basis(t, *best.x), v, rcond=None)[0]
    # The non-oscillating part at the record's end: a slow drift (the hydraulic mode moving
    # with the stroke) fits as c0 + c3 e^{-rate t} with rate -> 0 and c0 = -c3 huge, so c0
    # alone is no measure of the steady velocity.
    steady = abs(coefficients[0] + coefficients[3] * math.exp(-rate * t[-1])) or 1.0
    rms = float(np.sqrt(np.mean(best.fun ** 2)))
    if math.hypot(coefficients[1], coefficients[2]) / steady >= _MIN_OSCILLATION \
            and omega_d > 0.0:
        omega = math.hypot(sigma, omega_d)
        return omega, sigma / omega, rms
    return _fit_overdamped(t, v, top)


def _fit_overdamped(t: np.ndarray, v: np.ndarray, top: float) -> tuple[float, float, float]:
    """Second-order step K (1 - (p2 e^{p1 t} - p1 e^{p2 t}) / (p2 - p1)), zeta in [1, 20]."""
    from scipy.optimize import least_squares

    def step(p):
        omega, zeta = p
        root = math.sqrt(max(zeta * zeta - 1.0, 1e-12))
        p1, p2 = omega * (-zeta + root), omega * (-zeta - root)
        return 1.0 - (p2 * np.exp(p1 * t) - p1 * np.exp(p2 * t)) / (p2 - p1)

    def residual(p):
        shape = step(p)
        return shape * (shape @ v) / (shape @ shape) - v

    rise = t[int(np.argmax(np.abs(v) >= 0.63 * np.abs(v[-1])))] or t[1]
    fit = least_squares(residual, [min(2.0 / rise, 0.5 * top), 1.5],
                        bounds=([1e-6, 1.0], [top, 20.0]))
    return float(fit.x[0]), float(fit.x[1]), float(np.sqrt(np.mean(fit.fun ** 2)))
