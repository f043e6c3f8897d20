"""Our FMI 2.0 Co-Simulation FMUs: C sources per model, the shared FMI layer and the builder.

    fmus.MODELS            names of the model folders, e.g. ("HydraulicCylinder", ...)
    fmus.build(name)       -> Path of the .fmu built with the package (fmus.packaged; no
                              compiler needed), or built with gcc (cached) after an edit
    fmus.build_all()       -> {name: Path}
    fmus.build_model(dir)  -> Path, for a model folder outside the package (same rules)
    fmus.demo()            -> short text summary of a brief simulation of every FMU
    fmus.BuildError        raised with one clear message when a build fails
    fmus.content_hash(fmu) -> sha256 of what an FMU is (model description, binaries, sources)
    fmus.UnsafeArchive     an archive from outside that is not opened (fmus.identity)
"""

from fmus.builder import (
    BuildError,
    build,
    build_all,
    build_model,
    cached_content_hashes,
    fmu_dir,
    local_content_hashes,
    model_names,
)
from fmus.demo import demo
from fmus.identity import UnsafeArchive, check_archive, content_hash

MODELS: tuple[str, ...] = tuple(model_names())

__all__ = [
    "MODELS", "BuildError", "UnsafeArchive", "build", "build_all", "build_model", "check_archive",
    "cached_content_hashes", "content_hash", "demo", "fmu_dir", "local_content_hashes",
    "model_names",
]
