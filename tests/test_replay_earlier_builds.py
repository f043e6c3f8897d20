"""A run log of an earlier version made on this machine replays without --trust: its FMUs are
in the build cache (fmus.cached_content_hashes), and they stop counting as ours once the cache
forgets them or when a cache entry is not what it says (a record without its FMU, or one that
others may write)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from test_replay import _assert_repeats, _boom_run

import fmus
from orchestrator.review.replay import ReplayRefused, replay_run


@pytest.fixture()
def runs(tmp_path) -> Path:
    return tmp_path


def test_a_log_of_an_earlier_version_made_here_replays_without_trust(runs):
    """The cylinder built here from other sources (an earlier version's, as far as this tree
    knows: a changed comment gives another content hash) is in the build cache: its log
    replays without --trust, as "earlier local build"; once the cache forgets the build, the
    FMU is native code of unknown origin again."""
    model = Path(shutil.copytree(fmus.builder.MODELS_DIR / "HydraulicCylinder",
                                 runs / "earlier" / "HydraulicCylinder"))
    source = model / "model.c"
    source.write_text(source.read_text() + "/* an earlier version's sources */\n")
    built = fmus.build_model(model)
    try:  # nothing else may count this build as ours
        assert fmus.content_hash(built) not in fmus.local_content_hashes()
        assert fmus.cached_content_hashes()[fmus.content_hash(built)] == "HydraulicCylinder"
        path, records = _boom_run(runs, Path(shutil.copyfile(built, runs / "earlier.fmu")),
                                  "earlier")
        report = replay_run(path)
        _assert_repeats(report, records)
        assert report.fmus["boom"].trusted_by == "earlier local build"
        assert report.fmus["stick"].trusted_by == "local build"
    finally:
        shutil.rmtree(built.parent)
    with pytest.raises(ReplayRefused, match="not an FMU built from this version's sources"):
        replay_run(path)


def test_a_planted_record_makes_nothing_ours(tmp_path, monkeypatch):
    """A content.sha256 without its FMU, or with an FMU that does not hash to it, or in a folder
    that others may write, is no build of this machine's."""
    monkeypatch.setenv("EXCOSIM_FMU_DIR", str(tmp_path))
    planted = "ab" * 32
    alone = tmp_path / "HydraulicCylinder-000000000000"
    alone.mkdir()
    (alone / "content.sha256").write_text(planted + "\n")
    assert fmus.cached_content_hashes() == {}
    copied = tmp_path / "HydraulicCylinder-111111111111"
    copied.mkdir()
    monkeypatch.delenv("EXCOSIM_FMU_DIR")
    built = fmus.build("HydraulicCylinder")
    monkeypatch.setenv("EXCOSIM_FMU_DIR", str(tmp_path))
    shutil.copyfile(built, copied / "HydraulicCylinder.fmu")
    (copied / "content.sha256").write_text(planted + "\n")  # not the FMU's hash
    assert fmus.cached_content_hashes() == {}
    (copied / "content.sha256").write_text(fmus.content_hash(built) + "\n")
    assert fmus.cached_content_hashes() == {fmus.content_hash(built): "HydraulicCylinder"}
    os.chmod(copied, 0o777)  # anyone may replace what is in it
    assert fmus.cached_content_hashes() == {}
