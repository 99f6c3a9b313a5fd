"""Run the demo pipeline at two git revisions and compare every output they produce.

    python scripts/compare_outputs.py run REV OUT     # the demo pipeline at REV, in the folder OUT
    python scripts/compare_outputs.py diff A B        # every file under A/data and B/data, and metrics/

For refactors that must not change behaviour. Files are compared byte for byte, except
Parquet files, whose tables must be equal and whose metadata must be equal once the
provenance that names the *code* is set aside: per-item fingerprints hash the producing
modules' source, so a moved or edited module changes them by design (``fingerprint`` and
the upstream fingerprints in ``inputs``, and the segment index's ``fingerprint`` column).
Clock readings are set aside too: yt-dlp's ``epoch`` in ``.info.json`` and ``wall_seconds``
in metrics. Torch checkpoints are compared by their loaded contents (the zip container
is not byte-stable). Needs DANCE3D_MEDIA, DANCE3D_MODELS and
DANCE3D_MOCAP (as the tests do). The lifter and the TSMT are trained briefly, as in the
end-to-end test.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import pyarrow.parquet as pq
import yaml

STAGES = ("download", "trim", "pose2d", "track", "clean", "train_lifter", "lift", "smooth", "resample", "audio",
          "shard", "train")
CODE_PROVENANCE = ("fingerprint", "inputs")
CLOCK_KEYS = ("epoch", "wall_seconds")


def run(rev: str, out: Path) -> None:
    repo = Path(__file__).resolve().parents[1]
    out.mkdir(parents=True, exist_ok=False)
    with tempfile.NamedTemporaryFile(suffix=".tar") as archive:
        subprocess.run(["git", "archive", "-o", archive.name, rev], cwd=repo, check=True)
        with tarfile.open(archive.name) as tar:
            tar.extractall(out, filter="data")
    params = yaml.safe_load((out / "params.yaml").read_text())
    params["train_lifter"].update(steps=150, channels=64)
    params["train"].update(steps=40)
    (out / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    if (out / "demo").exists() and not (out / "manifests/sources.csv").read_text().count("https://"):
        (out / "demo/media").symlink_to(Path(os.environ["DANCE3D_MEDIA"]) / "videos")
    env = {**os.environ, "PYTHONPATH": str(out)}
    for stage in STAGES:
        print(f"{rev}: {stage}", flush=True)
        subprocess.run([sys.executable, "-m", f"stages.{stage}"], cwd=out, env=env, check=True)


def _meta(path: Path) -> dict:
    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(b"dance3d")
    info = json.loads(raw) if raw else {}
    return {k: v for k, v in info.items() if k not in CODE_PROVENANCE}


def _without_clock(value):
    if isinstance(value, dict):
        return {k: _without_clock(v) for k, v in value.items() if k not in CLOCK_KEYS}
    if isinstance(value, list):
        return [_without_clock(v) for v in value]
    return value


def _same_checkpoint(a: Path, b: Path) -> bool:
    import torch

    def flat(x, prefix=""):
        if isinstance(x, dict):
            return {k2: v2 for k, v in x.items() for k2, v2 in flat(v, f"{prefix}{k}/").items()}
        return {prefix: x}

    fa, fb = flat(torch.load(a, weights_only=False)), flat(torch.load(b, weights_only=False))
    return fa.keys() == fb.keys() and all(
        torch.equal(fa[k], fb[k]) if isinstance(fa[k], torch.Tensor) else fa[k] == fb[k] for k in fa)


def _same(a: Path, b: Path) -> str:
    if a.suffix == ".json":
        ja, jb = json.loads(a.read_text()), json.loads(b.read_text())
        return "" if _without_clock(ja) == _without_clock(jb) else "JSON differs (beyond clock readings)"
    if a.suffix == ".pt":
        return "" if _same_checkpoint(a, b) else "checkpoint contents differ"
    if a.suffix == ".parquet":
        ta, tb = pq.read_table(a), pq.read_table(b)
        if a.name == "index.parquet":
            ta, tb = ta.drop_columns(["fingerprint"]), tb.drop_columns(["fingerprint"])
        if not ta.schema.remove_metadata().equals(tb.schema.remove_metadata()):
            return "schemas differ"
        if not ta.equals(tb):
            return "tables differ"
        if _meta(a) != _meta(b):
            return "metadata differs (beyond code fingerprints)"
        return ""
    return "" if a.read_bytes() == b.read_bytes() else "bytes differ"


def diff(a: Path, b: Path) -> int:
    def files(root: Path) -> set[str]:
        found = set()
        for folder in ("data", "metrics", "models"):
            found |= {str(p.relative_to(root)) for p in (root / folder).rglob("*")
                      if p.is_file() and "/." not in str(p.relative_to(root))}
        return found

    names_a, names_b = files(a), files(b)
    problems = [f"only in {a}: {n}" for n in sorted(names_a - names_b)]
    problems += [f"only in {b}: {n}" for n in sorted(names_b - names_a)]
    same = 0
    for name in sorted(names_a & names_b):
        why = _same(a / name, b / name)
        if why:
            problems.append(f"{name}: {why}")
        else:
            same += 1
    for line in problems:
        print(line)
    print(f"{same} files identical, {len(problems)} differences")
    return 1 if problems else 0


def main(argv: list[str]) -> int:
    if len(argv) == 3 and argv[0] == "run":
        run(argv[1], Path(argv[2]))
        return 0
    if len(argv) == 3 and argv[0] == "diff":
        return diff(Path(argv[1]), Path(argv[2]))
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
