"""The shard stage rebuilds the corpus only when what it is made from changed (pipeline/corpus/inputs.py):
`dance3d run` and `dvc repro -f` run every stage, and DVC re-runs it when any dependency moves."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq

from pipeline.core.storage import read_meta


def _shard(root: Path) -> str:
    from tests.conftest import tool_environment

    done = subprocess.run([sys.executable, "-m", "stages.shard"], cwd=root, env=tool_environment(),
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stderr


def _built(root: Path) -> int:
    return (root / "data/corpus/README.md").stat().st_mtime_ns


def test_the_corpus_is_rebuilt_when_and_only_when_what_it_is_made_from_changed(built_demo: Path,
                                                                             tmp_path: Path) -> None:
    from pipeline.core.storage import write_parquet
    from tests.conftest import demo_copy, set_params

    root = demo_copy(built_demo, tmp_path / "demo")
    first = _built(root)
    assert "up to date" in _shard(root) and _built(root) == first  # built by dvc repro, nothing changed

    (root / "metrics/durations.csv").unlink()  # an output gone: built again
    assert "up to date" not in _shard(root) and (root / "metrics/durations.csv").is_file()
    assert "up to date" in _shard(root)

    motion = sorted((root / "data/motion24").glob("[!_]*.parquet"))[0]  # an item made again, differently
    meta = read_meta(motion)
    write_parquet(pq.read_table(motion), motion, schema_version=meta["schema_version"], params=meta.get("params", {}),
                  inputs=meta.get("inputs", {}), extra={**{k: v for k, v in meta.items()
                                                          if k not in ("schema_version", "params", "inputs")},
                                                       "fingerprint": "changed"})
    before = _built(root)
    assert "up to date" not in _shard(root) and _built(root) != before

    windows = json.loads((root / "metrics/corpus.json").read_text())["corpus_windows"]
    set_params(root, "shard", hop_seconds=2)  # a param (the demo hops 4 s): built again, with more windows
    assert "up to date" not in _shard(root)
    assert json.loads((root / "metrics/corpus.json").read_text())["corpus_windows"] > windows


def test_a_rebuild_stopped_half_way_leaves_no_stamp(built_demo: Path, tmp_path: Path) -> None:
    from pipeline.corpus.inputs import STAMP, corpus_fingerprint, corpus_up_to_date, forget_built
    from tests.conftest import demo_copy

    root = demo_copy(built_demo, tmp_path / "demo")
    stamp = (root / STAMP).read_text().strip()
    assert corpus_up_to_date(root, stamp) and not corpus_up_to_date(root, "another")
    forget_built(root)  # what the stage does first when it rebuilds; a stop after it leaves no stamp
    assert not corpus_up_to_date(root, stamp)
    assert corpus_fingerprint(root, {"window_seconds": 20}) != corpus_fingerprint(root, {"window_seconds": 10})
