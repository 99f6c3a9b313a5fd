"""shard stage: data/motion24 + data/audio_features -> data/corpus/{train,val}/shard-NNNNN.parquet,
data/corpus/groups/{train,val}/ (windows of two or more dancers in one scene),
data/corpus/README.md (the dataset card with Hugging Face metadata; + durations.png, alignment.png),
metrics/corpus.json (headline), reports/corpus.json, metrics/durations.csv; rebuilt only when what it is
made from changed (pipeline/corpus/inputs.py)."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from pipeline.core.params import corpus_fps, load_params, stage_params
from pipeline.core.stage import run_stage, setup_logging
from pipeline.corpus.inputs import corpus_fingerprint, corpus_up_to_date, forget_built, mark_built

log = logging.getLogger("dance3d.shard")


def run(root: Path) -> None:
    all_params = load_params(root / "params.yaml")
    fps = corpus_fps(all_params)
    params = {**stage_params(all_params, "shard"), "fps": fps}
    fingerprint = corpus_fingerprint(root, params, Path(__file__))
    if corpus_up_to_date(root, fingerprint):
        log.info("the corpus is up to date (what it is made from, its params and code are unchanged)")
        return
    forget_built(root)
    from pipeline.corpus.build import (
        collect_group_windows,
        collect_windows,
        write_card_and_metrics,
        write_group_shards,
        write_shards,
    )
    from pipeline.corpus.groups import link_solo_windows

    window = int(round(float(params.get("window_seconds", 20)) * fps))
    hop = int(round(float(params.get("hop_seconds", 10)) * fps))
    windows, counts = collect_windows(root, window, hop, float(params.get("val_fraction", 0.2)), fps)
    groups = collect_group_windows(root, window, hop, float(params.get("val_fraction", 0.2)), fps)
    link_solo_windows(windows, groups, window)
    write_group_shards(root, groups, window, int(params.get("windows_per_shard", 256)),
                       int(params.get("row_group_windows", 32)), params, fps)
    written = write_shards(root, windows, window, int(params.get("windows_per_shard", 256)),
                           int(params.get("row_group_windows", 32)), params, fps)
    log.info("%d windows: %d train, %d val (%d clips, %d without audio, %d shorter than a window)", len(windows),
             written["train"], written["val"], counts["clips"], counts["clips_without_audio"],
             counts["clips_too_short"])
    log.info("%d group windows (two or more dancers in one scene)", len(groups))
    write_card_and_metrics(root, windows, counts, params, window, hop, fps, groups)
    mark_built(root, fingerprint)


def main() -> int:
    setup_logging()
    return run_stage("shard", run)


if __name__ == "__main__":
    sys.exit(main())
