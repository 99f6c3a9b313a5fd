"""propose_segments stage: data/raw -> data/segment_proposals/<video_id>.parquet + segments.csv.

Where each downloaded video seems to hold dance (pipeline/pose/propose.py): shots, music,
people moving. Proposals never touch annotations/segments.csv: the trim stage takes them for
videos without human rows when ``trim.unannotated: proposals``, and the review page's trim
mode shows them to the annotator.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from pipeline.core.deferred import Deferred
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import RAW, SEGMENT_PROPOSALS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files
from pipeline.ingest.catalog import read_ledger
from pipeline.pose.models.loading import model_hashes, model_names
from pipeline.pose.propose import SUMMARY, ProposeOptions, propose_video, write_summary
from pipeline.pose.proposed import SCHEMA_VERSION

log = logging.getLogger("dance3d.propose_segments")
CODE = code_fingerprint("pipeline.pose.propose", "pipeline.ingest.shots",  # the cues, the cuts
                        "pipeline.pose.pose2d", "pipeline.pose.models.pose", "pipeline.pose.boxes",  # people
                        "pipeline.ingest.segmentvideo", "pipeline.ingest.media", "pipeline.ingest.trim")  # frames


def run(root: Path) -> None:
    all_params = load_params(root / "params.yaml")
    params = stage_params(all_params, "propose_segments")
    pose_params = stage_params(all_params, "pose2d")
    # The body model is enough to see who moves; pose2d's detector and people rules say who is a person.
    pose_params = {**pose_params, "pose_model": model_names(pose_params.get("pose_model", ""))[0]}
    hashes = model_hashes(root, pose_params)
    opts = ProposeOptions.from_params(params)
    pose_opts = Deferred("dataclasses:replace", (Deferred("pipeline.pose.pose2d:Pose2dOptions.from_params",
                                                          (pose_params,)),), {"confirm_score": 0.0})
    rules = {k: pose_params.get(k) for k in ("detector", "pose_model", "det_score", "min_joints", "dark_mean")}
    items = []
    for row in read_ledger(root / RAW).values():
        if row["status"] != "ok":
            continue
        out = root / SEGMENT_PROPOSALS / f"{row['video_id']}.parquet"
        fp = fingerprint(SCHEMA_VERSION, row["sha256"], hashes, params, rules, CODE)
        job = Deferred("pipeline.pose.propose:ProposeJob",
                       (row["video_id"], root / RAW / row["path"], out, opts, pose_opts, params, fp))
        items.append(WorkItem(row["video_id"], fp, (out,), job, size=float(row.get("duration") or 0.0)))

    def summary(report) -> None:
        path = write_summary(root / SEGMENT_PROPOSALS, item_files(root / SEGMENT_PROPOSALS))
        for video_id, r in sorted(report.done.items()):
            log.info("%s: %d proposed segments, %.1f of %.1f s", video_id, r["segments"], r["seconds"], r["duration"])
        log.info("proposals of every video: %s", path.relative_to(root))

    files = Deferred("pipeline.pose.models.loading:worker_files", (root, pose_params))  # only for work
    run_item_stage("propose_segments", items, propose_video, out_dirs=[root / SEGMENT_PROPOSALS], params=params,
                   setup="pipeline.pose.models.loading:load_pose_models", setup_args=(files,), unit="video",
                   keep_files=frozenset({SUMMARY}), finish=summary)


def main() -> int:
    setup_logging()
    return run_stage("propose_segments", run)


if __name__ == "__main__":
    sys.exit(main())
