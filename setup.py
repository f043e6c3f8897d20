"""Build hook of the setuptools backend (metadata: pyproject.toml): compile the FMUs and the
native libraries when the package is built, so that an installed package runs without a
compiler.

`build_native` (a sub-command of `build`) runs fmus.prebuild from this tree: into the wheel's
fmus/_built/ for `pip install .` and `pip wheel .`, into this tree's fmus/_built/ for `pip
install -e .` (setuptools' editable_wheel runs every `build` sub-command with editable_mode set;
a failure stops the install). The wheel carries native code for one platform, loaded with
ctypes, not a CPython extension: a platform wheel (everything in its platlib root) tagged
py3-none-<platform>.
"""

from __future__ import annotations

import sys
from pathlib import Path

from setuptools import Command, Distribution, setup
from setuptools.command.bdist_wheel import bdist_wheel
from setuptools.command.build import build

ROOT = Path(__file__).resolve().parent


class build_native(Command):  # noqa: N801 (setuptools names commands so)
    """Compile every FMU (FMI 2.0 and 3.0) and native library into fmus/_built/."""

    description = "compile the FMUs and the native libraries (fmus.prebuild)"
    user_options: list = []

    def initialize_options(self) -> None:
        self.build_lib: str | None = None
        self.editable_mode = False  # set by editable_wheel: build in this tree
        self._outputs: list[str] = []

    def finalize_options(self) -> None:
        self.set_undefined_options("build_py", ("build_lib", "build_lib"))

    def run(self) -> None:
        sys.path.insert(0, str(ROOT))  # this tree's builder, whatever is installed
        try:
            from fmus.prebuild import prebuild
        finally:
            sys.path.remove(str(ROOT))
        root = ROOT if self.editable_mode else Path(self.build_lib).absolute()
        written = prebuild(root / "fmus" / "_built", self.announce_info)
        self._outputs = [] if self.editable_mode else [str(path) for path in written]

    def announce_info(self, message: str) -> None:
        self.announce(message, level=2)  # INFO

    def get_outputs(self) -> list[str]:
        return self._outputs


class build_with_native(build):  # noqa: N801
    """`build`, then `build_native`."""

    sub_commands = [*build.sub_commands, ("build_native", None)]


class NativeDistribution(Distribution):
    """A distribution with native code: installed as platform-specific (platlib)."""

    def has_ext_modules(self) -> bool:
        return True


class platform_wheel(bdist_wheel):  # noqa: N801
    """A wheel for this platform (its binaries), for any Python 3: no CPython ABI."""

    def get_tag(self) -> tuple[str, str, str]:
        return self.python_tag, "none", super().get_tag()[2]


setup(distclass=NativeDistribution,
      cmdclass={"build": build_with_native, "build_native": build_native,
                "bdist_wheel": platform_wheel})
