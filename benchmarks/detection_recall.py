"""Who the 2D stage finds on a composite clip: two dancers above three seated musicians.

The clip (710x840, 10 s at 25 fps, the issue's layout) is built from the shared media: the
solo dancer and her mirror image side by side on top, the raga trio scaled into the bottom
third (the right musician is cut by the frame's edge). Every 5th frame, for the previous
default (RTMDet-nano at 0.5, MoveNet) and the configured models and people rules
(params.yaml), it reports per frame: dancers found (of 2), musicians found in each of the
three seats, and extra boxes beyond 2 on top and 3 below (false or duplicate people); and
people found per frame on a synthetic test pattern with no one in it.

Usage: DANCE3D_MODELS=../shared/models DANCE3D_MEDIA=../shared/media python benchmarks/detection_recall.py
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.pose2d import configured, five_people, load_models  # noqa: E402
from pipeline.ingest.media import ffmpeg_exe, iter_frames  # noqa: E402
from pipeline.pose.pose2d import find_people, lift_dark  # noqa: E402

PREVIOUS = {"detector": "rtmdet-nano-person", "pose_model": "movenet-lightning", "det_score": 0.5,
            "confirm_score": 0, "dark_mean": 0, "min_joints": 0}
SEATS = ((168, 335), (335, 500), (500, 542))  # x ranges of the three musicians in the bottom third
TOP = 560  # the dancers' rows end here


def count(frames: list[np.ndarray], models, opts) -> list:
    return [find_people(image, models.detector.detect(image), models.pose, opts)[0]
            for image in (lift_dark(f, opts.dark_mean) for f in frames)]


def composite_scores(people: list) -> dict:
    dancers, extra, seats = [], [], np.zeros(len(SEATS))
    for found in people:
        centre = (found.boxes[:, :2] + found.boxes[:, 2:]) / 2
        top = centre[:, 1] < TOP
        dancers.append(min(int(top.sum()), 2))
        extra.append(max(int(top.sum()) - 2, 0) + max(int((~top).sum()) - 3, 0))
        xs = centre[~top, 0]
        seats += [bool(((xs >= lo) & (xs < hi)).any()) for lo, hi in SEATS]
    n = len(people)
    return {"frames": n, "dancers_found_per_frame": round(float(np.mean(dancers)), 2),
            "musicians_found_share_of_frames": [round(float(s / n), 2) for s in seats],
            "extra_boxes_per_frame": round(float(np.mean(extra)), 2)}


def main() -> None:
    media = Path(os.environ["DANCE3D_MEDIA"])
    with tempfile.TemporaryDirectory() as tmp:
        clip = five_people(media, Path(tmp) / "composite.mp4")
        pattern = Path(tmp) / "pattern.mp4"
        subprocess.run([ffmpeg_exe(), "-loglevel", "error", "-y", "-f", "lavfi", "-i",
                        "testsrc=duration=4:size=640x360:rate=25", "-c:v", "libx264", "-preset", "ultrafast",
                        "-pix_fmt", "yuv420p", str(pattern)], check=True)
        frames = [f.image for i, f in enumerate(iter_frames(clip)) if i % 5 == 0]
        empty = [f.image for f in iter_frames(pattern)]
    report = {}
    for name, overrides in (("previous default", PREVIOUS), ("configured", {})):
        params, opts = configured(overrides)
        models = load_models(params)
        report[name] = {"detector": params["detector"], "pose_model": params["pose_model"],
                        **composite_scores(count(frames, models, opts)),
                        "test_pattern_people_per_frame": round(float(np.mean([len(p) for p in
                                                                              count(empty, models, opts)])), 3)}
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
