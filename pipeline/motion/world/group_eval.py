"""``dance3d eval group``: synthetic dance groups from motion capture, through the corpus's path.

Protocol:

- a group is 2-6 sequences of different takes (the train_lifter split's held-out ones), each cut to
  ``seconds`` at ``VIDEO_FPS`` and centred, then placed on one floor in a formation: spots at
  least ``MIN_GAP`` (0.8 m) apart, each within ``MAX_GAP`` (2 m) of another, in up to three rows,
  so that some dancers stand behind others (each take's own travel comes on top);
- each group is filmed by one camera, a landscape phone at 1.2 m or a landscape camera on a 2 m
  stand (a portrait frame does not hold a line of six), pitched -20 to +20 degrees (> 0 looks
  down), facing the group, its nearest spot 3-4.5 m away; the takes' own travel comes on top, so
  a dancer's root ranges from about 1 to 10 m from the camera over the runs (``nearest_m``,
  ``farthest_m`` per run);
- the 2D of each dancer is noisy (a pose model of expected OKS 0.80, 2 % of joints missing, as
  ``dance3d eval world``), and a joint that falls inside the body of a dancer nearer the camera is
  hidden: confidence 0, so the lift stage fills it;
- each dancer then takes the corpus's path (lift with the contact model, HP filter, 24 fps), and
  the group is grounded in one scene (``scene.ground_scene``); the baseline grounds each dancer
  alone (``grounding.ground_clip``) and places them by their own camera-frame root path.

Real groups beside them: takes captured together in one room (CMU's salsa, both partners of the
held-out takes), each kept in its real place and filmed by ``groups`` cameras drawn as above; they
are summarised apart ("real"), not in "all".

Metrics, per run, then medians per group size and over all:

- position (m): every dancer's root at every frame after one similarity transform of the whole
  group (all dancers at once) onto the truth, camera frame: where the dancers stand relative to
  each other, whatever the group's scale;
- order: the share of pairs whose front-to-back order (mean distance from the camera) is right,
  over the pairs whose true distances differ by at least ``ORDER_GAP`` (0.5 m; closer pairs stand
  side by side);
- floor angle (degrees): between the scene's up and the truth (the baseline: the median over its
  dancers of each one's own).

The truth's up is the capture's y axis; a take whose floor is not level in its own capture (a
plane through its planted points tilts 0.2-4 degrees on most takes, up to 8 on one CMU take)
adds that tilt to the floor angle of every method alike.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.motion.lifting.evaluate import add_pose_noise
from pipeline.motion.lifting.geometry import look_at, project, to_camera
from pipeline.motion.lifting.infer import LiftModels, LiftOptions, lift_clips
from pipeline.motion.mocap.sources import MocapSequence, first_seconds, resample
from pipeline.motion.resample import interpolate_linear
from pipeline.motion.world.contact import ContactRules, standing_level
from pipeline.motion.world.evaluate import CORPUS_FPS, VIDEO_FPS, at_corpus_rate, path_options, similarity
from pipeline.motion.world.gravity import up_error_deg
from pipeline.motion.world.grounding import ground_motion
from pipeline.motion.world.scene import ground_scene
from pipeline.motion.world.trajectory import assumed_focal

SIZES = (2, 3, 4, 5, 6)
PITCHES = (-20.0, -10.0, 0.0, 10.0, 20.0)
SETUPS = (("phone", 1.2), ("stand", 2.0))  # landscape, 1920 x 1080, a phone's 26 mm-equivalent lens
WIDTH, HEIGHT = 1920, 1080
MIN_GAP, MAX_GAP = 0.8, 2.0
NEAREST = (3.0, 4.5)   # the nearest spot's distance from the camera (m); each take's travel comes on top
ORDER_GAP = 0.5


@dataclass(frozen=True)
class GroupCamera:
    setup: str
    height_m: float
    pitch_deg: float   # > 0: looks down
    distance_m: float  # from the nearest spot

    def pose(self, spots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World-to-camera rotation and position facing the formation (``spots``: N x 2, x and z)
        along -z, ``distance_m`` in front of its nearest spot."""
        position = np.array([float(spots[:, 0].mean()), self.height_m, float(spots[:, 1].max()) + self.distance_m])
        target = position + np.array([0.0, -np.tan(np.radians(self.pitch_deg)), -1.0])
        return look_at(position, target), position


def formation(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` spots (x, z metres, centred) on the floor, at least ``MIN_GAP`` apart and each within
    ``MAX_GAP`` of another, in one to three rows 1-1.5 m apart (z: toward the camera)."""
    rows = int(rng.integers(1, min(3, n) + 1))
    width = 1.3 * np.ceil(n / rows)
    for _ in range(10000):
        spots = np.column_stack([rng.uniform(-width / 2, width / 2, n),
                                 -rng.integers(0, rows, n) * rng.uniform(1.0, 1.5) + rng.normal(0, 0.15, n)])
        gaps = np.linalg.norm(spots[:, None] - spots[None], axis=-1) + np.eye(n) * 1e9
        if gaps.min() >= MIN_GAP and (gaps.min(1) <= MAX_GAP).all():
            return spots - spots.mean(0)
    raise RuntimeError(f"no formation of {n} dancers found")


@dataclass(frozen=True)
class Placed:
    body: np.ndarray   # T x 21 x 3 world H36M-17 then heels and toe tips, on the group's floor (y = 0)
    coco: np.ndarray   # T x 21 x 3 world COCO-17 then heels and toe tips


def _shifted(seq: MocapSequence, shift: np.ndarray) -> Placed:
    return Placed(np.concatenate([seq.h36m, seq.feet], 1) - shift, np.concatenate([seq.coco, seq.feet], 1) - shift)


def place(seq: MocapSequence, spot: np.ndarray) -> Placed:
    """A take centred on ``spot`` (its mean root path there), its standing level on y = 0."""
    shift = np.array([0.0, standing_level(seq.feet, seq.fps), 0.0])
    shift[[0, 2]] = seq.h36m[:, 0, [0, 2]].mean(0) - spot
    return _shifted(seq, shift)


def place_together(takes: list[MocapSequence]) -> tuple[list[Placed], np.ndarray]:
    """Takes captured together in one room (a real duet): one shift for all, so each keeps its real
    place; the group's centre at the origin, its lowest standing level on y = 0. Returns the placed
    takes and their spots (N x 2, their mean root on the floor)."""
    level = min(standing_level(t.feet, t.fps) for t in takes)
    centre = np.concatenate([t.h36m[:, 0] for t in takes]).mean(0)
    shift = np.array([centre[0], level, centre[2]])
    placed = [_shifted(t, shift) for t in takes]
    return placed, np.array([p.body[:, 0, [0, 2]].mean(0) for p in placed])


def captured_together(sequences: list[MocapSequence]) -> list[list[MocapSequence]]:
    """The real groups among ``sequences``: CMU's salsa takes ``60_NN`` (lead) and ``61_NN`` (follow)
    are the two partners of one take, in one room frame (MOCAP.md §13)."""
    takes: dict[str, list[MocapSequence]] = {}
    for seq in sequences:
        if seq.source == "cmu_salsa_60_61":
            takes.setdefault(seq.name.split("/")[1].split("_")[1], []).append(seq)
    return [sorted(pair, key=lambda s: s.name) for _, pair in sorted(takes.items()) if len(pair) == 2]


def film(dancers: list[Placed], camera: GroupCamera, spots: np.ndarray,
         rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray, np.ndarray]:
    """Per dancer: noisy 2D (T x 21 x 3: pixels and confidence, 0 where hidden behind a nearer
    dancer) and the true camera-frame root path (T x 3); and the camera's rotation and position."""
    rotation, position = camera.pose(spots)
    focal = assumed_focal(WIDTH, HEIGHT)
    cams = [to_camera(d.coco, rotation, position) for d in dancers]
    pixels = [project(c, focal, WIDTH, HEIGHT) for c in cams]
    depth = np.stack([c[:, :17, 2].mean(1) for c in cams])                  # N x T
    lo = np.stack([p[:, :17].min(1) for p in pixels])                       # N x T x 2
    hi = np.stack([p[:, :17].max(1) for p in pixels])
    inset = (hi - lo) * 0.1  # a body's box less its edges, where limbs leave gaps
    out = []
    for i, xy in enumerate(pixels):
        hidden = np.zeros(xy.shape[:2], bool)
        for j in range(len(dancers)):
            nearer = depth[j] < depth[i] - 0.2
            inside = ((xy >= (lo[j] + inset[j])[:, None]) & (xy <= (hi[j] - inset[j])[:, None])).all(-1)
            hidden |= inside & nearer[:, None]
        noisy = add_pose_noise(xy, rng)
        out.append(np.concatenate([noisy, (~hidden)[..., None].astype(float)], -1))
    roots = [to_camera(d.body[:, 0], rotation, position) for d in dancers]
    return out, roots, rotation, position


def group_scores(estimate: list[np.ndarray], truth: list[np.ndarray]) -> dict:
    """Position error (m) after one similarity transform of the group, and the front-to-back order."""
    est, true = np.stack(estimate), np.stack(truth)
    s, r, t = similarity(est.reshape(-1, 3), true.reshape(-1, 3))
    error = float(np.linalg.norm(s * est @ r.T + t - true, axis=-1).mean())
    far_est, far_true = np.linalg.norm(est, axis=-1).mean(1), np.linalg.norm(true, axis=-1).mean(1)
    right = total = 0
    for i in range(len(est)):
        for j in range(i + 1, len(est)):
            if abs(far_true[i] - far_true[j]) >= ORDER_GAP:
                total += 1
                right += int(np.sign(far_est[i] - far_est[j]) == np.sign(far_true[i] - far_true[j]))
    return {"position_m": error, "order_right": right, "order_pairs": total}


def run_group(models: LiftModels, takes: list[MocapSequence], camera: GroupCamera, rng: np.random.Generator,
              lamb: float = 1.0, together: bool = False, lift: LiftOptions = LiftOptions(),
              rules: ContactRules = ContactRules()) -> dict[str, dict]:
    """One group filmed by one camera, through the corpus's path: the scene and the baseline.
    ``together``: the takes were captured together and keep their real places (no formation)."""
    frames = min(t.frames for t in takes)
    cut = [first_seconds(t, frames / t.fps) for t in takes]
    if together:
        dancers, spots = place_together(cut)
    else:
        spots = formation(len(takes), rng)
        dancers = [place(t, spot) for t, spot in zip(cut, spots)]
    seen, roots, rotation, _ = film(dancers, camera, spots, rng)
    lifted = lift_clips(models, [k[:, :17] for k in seen], [k[:, 17:] for k in seen], WIDTH, HEIGHT, VIDEO_FPS,
                        lift)
    clips = [at_corpus_rate(lc, lamb, f"group_{k}", k) for k, lc in enumerate(lifted)]
    truth = [interpolate_linear(c.time, np.arange(len(root)) / VIDEO_FPS, root) for c, root in zip(clips, roots)]
    true_up = rotation @ np.array([0.0, 1.0, 0.0])
    scene = ground_scene(clips, CORPUS_FPS, rules)
    alone = [ground_motion(c, CORPUS_FPS, rules) for c in clips]
    hidden = float(np.mean([(k[..., 2] == 0).mean() for k in seen]))
    common = {"dancers": len(takes), "pitch": camera.pitch_deg, "setup": camera.setup, "hidden_share": hidden,
              "nearest_m": float(min(np.linalg.norm(r, axis=-1).min() for r in roots)),
              "farthest_m": float(max(np.linalg.norm(r, axis=-1).max() for r in roots))}
    return {"scene": {**common, **group_scores([g.root_camera for g in scene.clips], truth),
                      "floor_deg": up_error_deg(scene.frame.camera, true_up)},
            "baseline": {**common, **group_scores([g.root_camera for g in alone], truth),
                         "floor_deg": float(np.median([up_error_deg(g.camera, true_up) for g in alone]))}}


def random_camera(rng: np.random.Generator) -> GroupCamera:
    """A camera drawn as the protocol says: a set-up, a pitch and the nearest spot's distance."""
    setup, height = SETUPS[int(rng.integers(len(SETUPS)))]
    return GroupCamera(setup, height, float(rng.choice(PITCHES)), float(rng.uniform(*NEAREST)))


def evaluate_groups(models: LiftModels, sequences: list[MocapSequence], *, groups: int = 8, seconds: float = 15.0,
                    sizes: tuple[int, ...] = SIZES, seed: int = 0, progress=None,
                    real: list[list[MocapSequence]] = (), lift: LiftOptions = LiftOptions(),
                    rules: ContactRules = ContactRules()) -> dict:
    """``groups`` groups of each size in ``sizes``; medians per size and over all, per method.
    ``real``: groups captured together (``captured_together``), each filmed by ``groups`` cameras
    and summarised apart ("real")."""
    rng = np.random.default_rng(seed)
    takes = [first_seconds(resample(s, VIDEO_FPS), seconds) for s in sequences if s.feet is not None]
    takes = [t for t in takes if t.frames >= 0.8 * seconds * VIDEO_FPS]
    if len(takes) < max(sizes):
        raise ValueError(f"{len(takes)} sequences of at least {0.8 * seconds:g} s with feet; groups of "
                         f"{max(sizes)} need as many")
    runs: list[dict] = []
    for size in sizes:
        for _ in range(groups):
            chosen = [takes[i] for i in rng.choice(len(takes), size, replace=False)]
            for method, row in run_group(models, chosen, random_camera(rng), rng, lift=lift, rules=rules).items():
                runs.append({"method": method, "sequences": [t.name for t in chosen], **row})
            if progress:
                progress()
    real_runs: list[dict] = []
    for group in real:
        cut = [first_seconds(resample(s, VIDEO_FPS), seconds) for s in group]
        for _ in range(groups):
            for method, row in run_group(models, cut, random_camera(rng), rng, together=True, lift=lift,
                                         rules=rules).items():
                real_runs.append({"method": method, "sequences": [t.name for t in group], **row})
            if progress:
                progress()

    def summary(rows: list[dict]) -> dict:
        pairs = sum(r["order_pairs"] for r in rows)
        return {"runs": len(rows),
                "position_m": round(float(np.median([r["position_m"] for r in rows])), 3),
                "order_right": round(sum(r["order_right"] for r in rows) / pairs, 3) if pairs else float("nan"),
                "order_pairs": pairs,
                "floor_deg": round(float(np.median([r["floor_deg"] for r in rows])), 2),
                "hidden_share": round(float(np.mean([r["hidden_share"] for r in rows])), 3)}

    result: dict = {"protocol": {"groups_per_size": groups, "sizes": list(sizes), "seconds_each": seconds,
                                 "takes": len(takes), "video_fps": VIDEO_FPS, "corpus_fps": CORPUS_FPS,
                                 **path_options(lift, rules)}}
    for method in ("scene", "baseline"):
        rows = [r for r in runs if r["method"] == method]
        result[method] = {"all": summary(rows),
                          **{str(size): summary([r for r in rows if r["dancers"] == size]) for size in sizes}}
        if real_runs:
            result[method]["real"] = summary([r for r in real_runs if r["method"] == method])
    if real_runs:
        result["protocol"]["real_groups"] = [[t.name for t in g] for g in real]
    result["runs"] = runs + [{**r, "real": True} for r in real_runs]
    return result


def evaluate_group_folder(lifter, contact, mocap, *, heldout_only: bool = True, groups: int = 8,
                          seconds: float = 15.0, threads: int = 2, progress=None,
                          lift: LiftOptions = LiftOptions(), rules: ContactRules = ContactRules()) -> dict:
    """``dance3d eval group`` on a folder ``load_folder`` reads (held-out sequences of the known
    sources; a folder of your own capture is used whole)."""
    from pipeline.core.errors import InputError
    from pipeline.motion.lifting.evaluate import held_out_later, split
    from pipeline.motion.lifting.infer import load_models
    from pipeline.motion.mocap.sources import load_folder

    everything = load_folder(Path(mocap))
    held = split(everything)[1] if heldout_only else []
    sequences = held or everything
    # Real duets: the held-out salsa takes (a folder of one's own capture: every pair in it).
    real = captured_together(held_out_later(everything) if heldout_only and held else everything)
    for path in (lifter, contact):
        if path is not None and not Path(path).is_file():
            raise InputError(path, "no such model")
    models = load_models(str(lifter), str(contact) if contact else "", threads)
    try:
        result = evaluate_groups(models, sequences, groups=groups, seconds=seconds, progress=progress, real=real,
                                 lift=lift, rules=rules)
    except ValueError as exc:
        raise InputError(mocap, str(exc)) from exc
    result["protocol"].update(lifter=str(lifter), contact_model=str(contact) if contact else "none",
                              mocap=str(mocap), split="held-out sequences of the train_lifter split" if held
                              else "every sequence")
    return result


def format_report(result: dict) -> str:
    """One line per group size and method."""
    lines = [f"{'dancers':8s} {'method':9s} {'position m':>11s} {'order right':>12s} {'pairs':>6s} "
             f"{'floor deg':>10s} {'hidden':>7s} {'runs':>5s}"]
    sizes = ["all", *map(str, result["protocol"]["sizes"]), *(["real"] if "real" in result["scene"] else [])]
    for size in sizes:
        for method in ("scene", "baseline"):
            row = result[method][size]
            lines.append(f"{size:8s} {method:9s} {row['position_m']:11.3f} {row['order_right']:12.3f} "
                         f"{row['order_pairs']:6d} {row['floor_deg']:10.2f} {row['hidden_share']:7.3f} "
                         f"{row['runs']:5d}")
    if "real" in result["scene"]:
        lines.append("real: groups captured together, in their real places (" + "; ".join(
            " + ".join(name.split("/")[-1] for name in g) for g in result["protocol"]["real_groups"]) + ")")
    return "\n".join(lines)


def sync_pairs(path: Path) -> dict:
    """``dance3d eval sync``: ``quality.sync_ratio`` for every pair of a world file's clips that
    share 4 s or more (real group video, no ground truth)."""
    from pipeline.core.errors import InputError
    from pipeline.core.storage import read_meta
    from pipeline.motion.quality import sync_ratio
    from pipeline.motion.world.worldfile import read_world

    if not Path(path).is_file():
        raise InputError(path, "no such world file")
    fps = float(read_meta(path).get("fps", 24.0))
    pairs = []
    for a, b in itertools.combinations(read_world(path), 2):
        common = np.intersect1d(a.frame, b.frame)
        if len(common) < 4 * fps:
            continue
        ratio = sync_ratio(a.joints[np.searchsorted(a.frame, common)], b.joints[np.searchsorted(b.frame, common)], fps)
        pairs.append({"a": a.clip_id, "b": b.clip_id, "seconds": round(len(common) / fps, 2),
                      **{k: round(v, 4) for k, v in ratio.items()}})
    return {"world": str(path), "pairs": pairs}


def format_sync(result: dict) -> str:
    lines = [f"{'clip a':24s} {'clip b':24s} {'seconds':>8s} {'same m':>8s} {'shifted m':>10s} {'ratio':>7s}"]
    for p in result["pairs"]:
        lines.append(f"{p['a']:24s} {p['b']:24s} {p['seconds']:8.1f} {p['same_instant_m']:8.3f} {p['shifted_m']:10.3f} "
                     f"{p['ratio']:7.3f}")
    if not result["pairs"]:
        lines.append("(no two clips share 4 s)")
    return "\n".join(lines)
