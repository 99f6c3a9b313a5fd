"""The docs' reference pages come from the code: every params.yaml key and every command has words,
and the pages name them all."""

from __future__ import annotations

from pathlib import Path

from pipeline.cli import build_parser
from pipeline.reference import commands, param_docs, undocumented_commands, undocumented_params, write_reference

ROOT = Path(__file__).resolve().parents[1]


def test_every_params_key_says_what_it_means() -> None:
    assert undocumented_params(ROOT / "params.yaml") == []


def test_every_command_and_option_has_help() -> None:
    assert undocumented_commands(build_parser()) == []


def test_a_key_without_a_comment_is_caught(tmp_path: Path) -> None:
    (tmp_path / "params.yaml").write_text("stage:            # a stage\n  known: 1   # one\n  bare: 2\n"
                                          "  profiles:\n    a:\n      known: 3\n      other: 4\n")
    assert undocumented_params(tmp_path / "params.yaml") == ["stage.bare", "stage.profiles.a.other"]


def test_the_generated_pages_name_every_key_command_and_stage(tmp_path: Path) -> None:
    import yaml

    pages = {p.name: p.read_text() for p in write_reference(ROOT, tmp_path)}
    assert all(f"`{d.path}`" in pages["params.md"] for d in param_docs(ROOT / "params.yaml") if "." in d.path)
    assert all(f"## {line}" in pages["cli.md"] for line, _ in commands(build_parser()))
    assert all(f"## {name}" in pages["stages.md"] for name in yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"])
    assert "`smpl_poses`" in pages["schemas.md"] and "`beat_phase`" in pages["schemas.md"]


def test_stage_modules_only_wire() -> None:
    """A stage module reads params, builds jobs and hands them to its package: 90 lines at most."""
    long = {p.name: n for p in (ROOT / "stages").glob("*.py") if (n := len(p.read_text().splitlines())) > 90}
    assert long == {}


def test_pipeline_pages_explain_and_reports_measure() -> None:
    """A pipeline page says how a stage works (150 lines at most); its measurement logs live in a
    dated report under docs/reports/ that the page links to."""
    pages = sorted((ROOT / "docs" / "pipeline").glob("*.md"))
    assert {p.name: n for p in pages if (n := len(p.read_text().splitlines())) > 150} == {}
    reports = {p.name for p in (ROOT / "docs" / "reports").glob("*.md")}
    assert {"lifter.md", "world.md", "pose2d.md", "proposals.md", "music.md", "throughput.md"} <= reports
    for name in reports:
        assert "## 20" in (ROOT / "docs" / "reports" / name).read_text(), f"{name} has no dated entry"
