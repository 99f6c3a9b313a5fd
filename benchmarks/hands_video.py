"""Hands on dance video: how many hands the hand model is sure of, on the wrist it was looked for, and
what it costs, for each way pose2d can look for them (issue: hands).

There is no hand annotation of dance video here, so the figure is a count: on every keyframe's
posed person, the hands looked at (wrist and elbow confident, hand large enough, on the picture),
the hands the model is sure of (presence 0.5, MediaPipe's threshold), and of those the ones whose
wrist lies within half a forearm of the body's wrist (a hand farther away belongs to another wrist).
pose2d runs as the stage does (params.yaml's pose2d section, hands on), each variant in turn on the
same clip, the wall time of the whole 2D beside it:

- ``forearm``: the landmark model in the forearm's square (``hand_recrop: false``);
- ``recrop``: Holistic's re-crop model in a wider square first, as shipped (``hand_recrop: true``);
- ``forearm-1pass`` and ``recrop-1pass``: the same with one landmark pass (``hand_passes: 1``).

The clips (``--clips``, default): the MusePose solo, the duet and the office trio of ``../shared/media``.

Usage: DANCE3D_MODELS=../shared/models DANCE3D_MEDIA=../shared/media \\
       python -m benchmarks.hands_video [--variants forearm,recrop] [--models DIR] [--out r.json]
(``--models``: a folder holding the fetched hand models, `dance3d models fetch hand-landmark-full hand-recrop`.)
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from pipeline.core.params import load_params, stage_params
from pipeline.core.storage import write_json
from pipeline.ingest.media import probe
from pipeline.pose.hands import MAX_WRIST_OFFSET, HandModels
from pipeline.pose.models.loading import load_pose_models, worker_files
from pipeline.pose.pose2d import Pose2dOptions, collect_poses, estimate_segment
from pipeline.pose.pose2dfile import MIN_PRESENCE

CLIPS = ("dance_single_music_musepose.mp4", "group_duet_music.mp4", "group_trio_office_music.mp4")
VARIANTS = {"forearm": {"hand_recrop": False}, "recrop": {"hand_recrop": True},
            "forearm-1pass": {"hand_recrop": False, "hand_passes": 1},
            "recrop-1pass": {"hand_recrop": True, "hand_passes": 1}}


def count_hands(poses) -> dict:
    """Hands looked at, sure, and sure on their own wrist, over the posed (not interpolated) rows."""
    posed = ~poses.interpolated_mask()
    hands, body = poses.hands[posed], poses.keypoints[posed]
    presence = hands[:, :, 0, 2]
    forearm = np.linalg.norm(body[:, [9, 10], :2] - body[:, [7, 8], :2], axis=-1)
    offset = np.linalg.norm(hands[:, :, 0, :2] - body[:, [9, 10], :2], axis=-1)
    sure = presence >= MIN_PRESENCE
    return {"person_keyframes": int(posed.sum()), "looked_at": int((presence > 0).sum()), "sure": int(sure.sum()),
            "sure_on_wrist": int((sure & (offset <= MAX_WRIST_OFFSET * forearm)).sum())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--clips", default=",".join(CLIPS), help="clip names in $DANCE3D_MEDIA/videos")
    parser.add_argument("--variants", default="forearm,recrop")
    parser.add_argument("--models", type=Path, default=Path("."),
                        help="the project root whose models/ holds the hand models (default: here)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/hands_video.json"))
    args = parser.parse_args()

    params = {**stage_params(load_params(Path("params.yaml")), "pose2d"), "hands": True, "hand_recrop": True}
    models = load_pose_models(worker_files(args.models, params))
    media = Path(os.environ.get("DANCE3D_MEDIA", "../shared/media")) / "videos"
    results: dict = {"protocol": __doc__.split("\n\n")[1].replace("\n", " "), "clips": {}}
    for clip in args.clips.split(","):
        fps = probe(media / clip).fps
        results["clips"][clip] = {}
        for name in args.variants.split(","):
            opts = Pose2dOptions.from_params({**params, **VARIANTS[name]})
            hands = models.hands if opts.hand_recrop else HandModels(models.hands.landmarks)
            started = time.monotonic()
            poses, _ = collect_poses(estimate_segment(media / clip, fps, models.detector, models.pose, opts,
                                                      None, hands))
            row = {**count_hands(poses), "pose2d_seconds": round(time.monotonic() - started, 1)}
            results["clips"][clip][name] = row
            print(f"{clip:36s} {name:14s} " + "  ".join(f"{k} {v}" for k, v in row.items()), flush=True)
    write_json(args.out, results)


if __name__ == "__main__":
    main()
