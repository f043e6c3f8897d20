"""Our FMI 2.0 Co-Simulation FMUs: C sources per model, the shared FMI layer and the builder.

    fmus.MODELS            names of the model folders, e.g. ("HydraulicCylinder", ...)
    fmus.build(name)       -> Path of the built (or cached) .fmu
    fmus.build_all()       -> {name: Path}
    fmus.build_model(dir)  -> Path, for a model folder outside the package (same rules)
    fmus.demo()            -> short text summary of a brief simulation of every FMU
    fmus.BuildError        raised with one clear message when a build fails
"""

from fmus.builder import BuildError, build, build_all, build_model, fmu_dir, model_names
from fmus.demo import demo

MODELS: tuple[str, ...] = tuple(model_names())

__all__ = [
    "MODELS", "BuildError", "build", "build_all", "build_model", "demo", "fmu_dir", "model_names",
]
