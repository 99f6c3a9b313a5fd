"""Headline metrics for `dvc metrics show`, the breakdowns in reports beside them."""

from __future__ import annotations

import json
from pathlib import Path

from pipeline.core.failures import Failure, failure_totals, write_failures
from pipeline.core.metrics import HEADLINES, headline, headline_figures, write_metrics


def test_every_headline_is_flat_named_to_read_alone_and_few() -> None:
    names = [name for fields in HEADLINES.values() for name in fields]
    assert len(names) == len(set(names)) <= 25
    # One column each in dvc's table: with the path column it must fit a terminal.
    assert 20 + sum(max(len(n), 6) + 4 for n in names) < 250


def test_a_stage_writes_its_report_whole_and_its_headline_beside_it(tmp_path: Path) -> None:
    report = {"val_mpjpe_mm": 91.8, "val_p_mpjpe_mm": 54.1, "heldout": {"sources": {"perfume": {"mpjpe_mm": 80.0}}}}
    write_metrics(tmp_path, "lifter", report)
    assert json.loads((tmp_path / "reports/lifter.json").read_text()) == report
    assert json.loads((tmp_path / "metrics/lifter.json").read_text()) == {"lifter_mpjpe_mm": 91.8,
                                                                          "lifter_p_mpjpe_mm": 54.1}
    write_metrics(tmp_path, "smooth", {"mean_acc_before": 2.4})  # no headline: the report alone
    assert (tmp_path / "reports/smooth.json").exists() and not (tmp_path / "metrics/smooth.json").exists()
    assert headline_figures(tmp_path) == {"lifter_mpjpe_mm": 91.8, "lifter_p_mpjpe_mm": 54.1}


def test_a_figure_the_report_lacks_is_left_out_not_invented() -> None:
    assert headline("corpus", {"videos": 3, "windows_train": 4}) == {"corpus_videos": 3}


def test_the_corpus_sums_every_stages_failures(tmp_path: Path) -> None:
    for stage, failed, total in (("pose2d", 1, 10), ("audio", 0, 10)):
        folder = tmp_path / "data" / stage
        folder.mkdir(parents=True)
        write_failures(folder, stage, [Failure(f"seg{k}", stage, "ValueError", "bad", "now") for k in range(failed)],
                       total=total)
    assert failure_totals(tmp_path) == {"items": 20, "failed": 1, "failed_share": 0.05,
                                        "stages_with_failures": {"pose2d": 1}}
    assert headline("corpus", {"failures": failure_totals(tmp_path)}) == {"failed_share": 0.05}
