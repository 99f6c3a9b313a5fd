"""The foot template, checked where heels are captured.

Usage: python -m benchmarks.foot_template [--mocap DIR] [--out benchmarks/results/foot_template.json]

BVH rigs have no heel, so dance3d places one with a foot template (pipeline/motion/mocap/
skeleton.py, ``FOOT_TEMPLATE``). Two sources capture heels: Tang's joint data (points 10 and 19)
and ChoreoNet's heel markers. For each of their sequences and feet, the template's heel is
placed from the knee, the ankle and the captured toe point (read as the ball of the foot, as
the loaders do) and compared with the captured heel: the median distance per foot, then the
median over feet, beside the baseline of putting the heel at the ankle.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

from pipeline.motion.mocap.markers import h36m_from_markers, read_c3d
from pipeline.motion.mocap.skeleton import foot_points, leg_stature
from pipeline.motion.mocap.sources import load_tang


def _distance(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.median(np.linalg.norm(a - b, axis=-1)))


def tang(folder: Path) -> list[tuple[float, float]]:
    rows = []
    for path in sorted(folder.glob("*.npz")):
        if "_W_" in path.name:  # the subsampled waltz files, as the loader leaves them out
            continue
        data = np.load(path)
        points = (data["skeletons"] + data["center"][:, None]).astype(np.float64) * 0.01
        points[..., 2] *= -1
        size = leg_stature(load_tang(path).h36m)
        for knee, ankle, heel, toe in ((8, 9, 10, 11), (17, 18, 19, 20)):
            placed = foot_points(points[:, knee], points[:, ankle], points[:, toe], "ball", size)["heel"]
            rows.append((_distance(placed, points[:, heel]), _distance(points[:, ankle], points[:, heel])))
    return rows


def choreonet(folder: Path) -> list[tuple[float, float]]:
    rows = []
    for path in sorted(folder.glob("*.c3d")):
        markers, _ = read_c3d(path)
        h36m = h36m_from_markers(markers)
        size = leg_stature(h36m)
        for side, knee, ankle in (("L", 5, 6), ("R", 2, 3)):
            placed = foot_points(h36m[:, knee], h36m[:, ankle], markers[f"{side}TOE"], "ball", size)["heel"]
            rows.append((_distance(placed, markers[f"{side}HEE"]), _distance(h36m[:, ankle], markers[f"{side}HEE"])))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mocap", type=Path, default=Path(os.environ.get("DANCE3D_MOCAP", "../shared/mocap")))
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/foot_template.json"))
    args = parser.parse_args()
    results = {}
    for name, rows in (("tang2018_ballroom", tang(args.mocap / "tang2018_ballroom")),
                       ("choreonet_c3d", choreonet(args.mocap / "choreonet_c3d"))):
        arr = 1000 * np.array(rows)
        results[name] = {"feet": len(rows), "template_heel_mm": round(float(np.median(arr[:, 0])), 1),
                         "heel_at_ankle_mm": round(float(np.median(arr[:, 1])), 1)}
        print(f"{name:20s} {len(rows):3d} feet: template heel {results[name]['template_heel_mm']:5.1f} mm from the "
              f"captured heel (heel at the ankle: {results[name]['heel_at_ankle_mm']:5.1f} mm)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"results": results, "protocol": __doc__}, indent=1))


if __name__ == "__main__":
    main()
