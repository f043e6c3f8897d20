"""The terrain strategy's C slump kernel (orchestrator.campaign.native_slump) against the numpy
oracle (tests/slump_reference.py): the same bits on any surface, the same campaign, mass kept
and every step within the repose; the library comes with the package (no gcc needed), builds
byte-reproducibly, and one that cannot be had is a clear error."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from slump_reference import relax_steps

import orchestrator.campaign.native_slump as native_slump
import orchestrator.campaign.strategy as strategy
from fmus import packaged
from fmus.builder import BuildError
from fmus.shared_library import compile_library, library_sources
from fmus.toolchain import gcc
from orchestrator.campaign import run_campaign
from orchestrator.scenario import load_scenario
from planner.surface_estimate import RELAX_TOLERANCE_M

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
C_RELAX = native_slump.native_relax()


@st.composite
def surfaces(draw):
    """Ground with trenches, heaps and steps as the planner's estimate holds them (240 cells of
    5 cm on the paper arm, trenches under a metre): (heights (n,) m, allowed step m)."""
    n = draw(st.integers(2, 240))
    z = np.zeros(n)
    for _ in range(draw(st.integers(0, 4))):
        a = draw(st.integers(0, n - 1))
        b = draw(st.integers(a + 1, n))
        z[a:b] += draw(st.floats(-0.8, 0.8, allow_nan=False))
    noise = draw(st.floats(0.0, 0.05))
    z += noise * np.random.default_rng(draw(st.integers(0, 2**32 - 1))).standard_normal(n)
    cell = draw(st.sampled_from([0.05, 0.1, 0.2]))
    return z, cell * math.tan(math.radians(draw(st.floats(25.0, 75.0))))


TRENCH = np.where((np.arange(240) >= 60) & (np.arange(240) < 80), -0.5, 0.0)  # 1 m x 0.5 m


@settings(max_examples=80, deadline=None)
@given(surfaces())
@example((TRENCH, 0.05 * math.tan(math.radians(40.4))))
def test_the_c_kernel_gives_the_numpy_kernels_bits(case):
    z, allowed = case
    by_numpy, by_c = z.copy(), z.copy()
    relax_steps(by_numpy, allowed)
    C_RELAX(by_c, allowed)
    assert by_c.tobytes() == by_numpy.tobytes()
    # What makes either right: the slump keeps the material (round-off of the transfers) and
    # leaves no step steeper than the repose (the stopping rule).
    assert abs(by_c.sum() - z.sum()) <= 1e-12 * max(1.0, np.abs(z).sum())
    assert np.abs(np.diff(by_c)).max(initial=0.0) <= allowed + RELAX_TOLERANCE_M


def terrain_campaign(monkeypatch, relax_factory) -> list[dict]:
    monkeypatch.setattr(strategy, "native_relax", relax_factory)
    scenario = load_scenario(PAPER, ["periods=5", 'adaptation.strategy="terrain"',
                                     "adaptation.assumed_repose_angle_deg=40.4"])
    result = run_campaign(scenario)
    assert result.termination == "periods", result.message
    return result.records


def test_a_terrain_campaign_decides_the_same_with_either_kernel(monkeypatch):
    calls = []

    def counting():
        kernel = native_slump.native_relax()

        def relax(z, allowed):
            calls.append(len(z))
            kernel(z, allowed)
        return relax

    with_c = terrain_campaign(monkeypatch, counting)
    with_numpy = terrain_campaign(monkeypatch, lambda: relax_steps)
    assert calls  # the C kernel did the slumping
    for a, b in zip(with_c, with_numpy, strict=True):
        keys = ("deepest_point_m", "mass_kg", "predicted_mass_kg", "mass_per_area_kg_m2")
        assert [a.get(key) for key in keys] == [b.get(key) for key in keys]
    assert with_c[-1].get("predicted_mass_kg") is not None


def test_the_kernel_comes_with_the_package_and_needs_no_gcc(monkeypatch, tmp_path):
    monkeypatch.setenv("PATH", str(tmp_path))  # a folder without gcc
    monkeypatch.setenv("EXCOSIM_FMU_DIR", str(tmp_path / "empty-cache"))
    native_slump._library.cache_clear()
    try:
        z = TRENCH.copy()
        native_slump.native_relax()(z, 0.05)
        assert np.abs(np.diff(z)).max() <= 0.05 + RELAX_TOLERANCE_M
        assert native_slump._library()._name == str(packaged.library_target(packaged.BUILT_DIR,
                                                                             "slump"))
    finally:
        native_slump._library.cache_clear()
    assert not (tmp_path / "empty-cache").exists()


def test_a_library_that_cannot_be_had_is_a_clear_error(monkeypatch):
    """slump.c edited on a machine without gcc, say: the strategy cannot be made (no numpy
    kernel to fall back on), with the builder's message."""
    def no_gcc(*args, **kwargs):
        raise BuildError("gcc not found on PATH: install a C compiler")

    native_slump._library.cache_clear()
    monkeypatch.setattr("fmus.shared_library.build_library", no_gcc)
    try:
        with pytest.raises(BuildError, match="gcc not found"):
            native_slump.native_relax()
    finally:
        native_slump._library.cache_clear()


def test_the_kernel_refuses_an_array_it_would_misread():
    with pytest.raises(ValueError, match="contiguous"):
        C_RELAX(np.zeros(10)[::2], 0.01)
    with pytest.raises(ValueError, match="float64"):
        C_RELAX(np.zeros(10, dtype=np.float32), 0.01)


def test_the_library_builds_byte_reproducibly(tmp_path):
    """Built twice into other folders: the bytes of the library built with the package."""
    source_dir, c_files = library_sources("slump")
    digests = []
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        compile_library("slump", source_dir, c_files, tmp_path / folder / "slump.so", gcc())
        digests.append(hashlib.sha256((tmp_path / folder / "slump.so").read_bytes()).hexdigest())
    packaged_library = packaged.library_target(packaged.BUILT_DIR, "slump")
    assert digests[0] == digests[1] == packaged.file_sha256(packaged_library)
