"""Identifiers, times, human-edited CSV files and the executor."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from pipeline.core.errors import InputError
from pipeline.core.ids import check_id, id_path, segment_id, slug_id
from pipeline.core.tables import neutralise_cell, read_csv, write_csv
from pipeline.core.timecode import format_time, parse_time


@pytest.mark.parametrize("bad", ["../x", "/abs", "a b", "a\x00b", "", "x" * 101, "é", "a.b"])
def test_unsafe_ids_are_refused(bad: str) -> None:
    with pytest.raises(ValueError, match="not a safe identifier"):
        check_id(bad)
    with pytest.raises(ValueError):
        id_path(Path("data"), bad, ".mp4")


def test_safe_ids_and_derived_names() -> None:
    assert check_id("Ab_9-z") == "Ab_9-z"
    assert segment_id("vid", 7) == "vid_007"
    assert slug_id("my video (1).mp4") == "my_video_1_mp4"
    assert slug_id("../..") == "video"


@pytest.mark.parametrize("text, seconds", [
    ("12.5", 12.5), ("0", 0.0), ("01:02.250", 62.25), ("00:01:02.250", 62.25), ("1:00:00", 3600.0),
])
def test_times_parse_from_seconds_or_clock(text: str, seconds: float) -> None:
    assert parse_time(text) == pytest.approx(seconds)


@pytest.mark.parametrize("text", ["abc", "-1", "00:61:00", "1:2:3:4", "nan", "inf", ""])
def test_bad_times_say_why(text: str) -> None:
    with pytest.raises(ValueError):
        parse_time(text)


def test_format_time_is_the_qc_timecode() -> None:
    assert format_time(3723.0456) == "01:02:03.046"


def test_read_csv_reports_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "x.csv"
    path.write_text("# comment\n\na,b\n1,2\n3\n")
    with pytest.raises(InputError) as err:
        read_csv(path, ["a", "b"])
    assert str(err.value) == f"{path}:5: expected 2 fields, found 1"


def test_read_csv_header_problems(tmp_path: Path) -> None:
    path = tmp_path / "x.csv"
    path.write_text("a,c\n1,2\n")
    with pytest.raises(InputError, match=r"x\.csv:1: missing column\(s\) b"):
        read_csv(path, ["a", "b"], ["c"])
    path.write_text("a,b,zzz\n1,2,3\n")
    with pytest.raises(InputError, match=r"x\.csv:1: unknown column\(s\) zzz"):
        read_csv(path, ["a", "b"])


def test_formula_cells_are_neutralised_on_write(tmp_path: Path) -> None:
    assert neutralise_cell("=HYPERLINK(1)") == "'=HYPERLINK(1)"
    assert neutralise_cell("-1.5") == "-1.5"
    assert neutralise_cell("@x") == "'@x"
    path = tmp_path / "out.csv"
    write_csv(path, ["a", "note"], [[1, "+cmd"], [2, "fine"]])
    assert path.read_text() == "a,note\n1,'+cmd\n2,fine\n"


def _crash_on_three(x: int) -> int:
    if x == 3:
        os._exit(1)  # a segfault or the OOM killer, as far as the pool can tell
    return x * 10


def test_a_crashing_worker_fails_only_its_own_item() -> None:
    from pipeline.core.executor import run_items

    outcomes = {o.item: o for o in run_items(_crash_on_three, [1, 2, 3, 4, 5], workers=2)}
    assert {i: o.value for i, o in outcomes.items() if o.ok} == {1: 10, 2: 20, 4: 40, 5: 50}
    assert outcomes[3].error_class == "WorkerCrashed"


def _segfault_on_b(x: str) -> str:
    if x == "b":
        os.kill(os.getpid(), signal.SIGSEGV)  # what a native library fault does to the worker
    return x


def test_a_crashed_worker_names_its_item_the_signal_and_the_retry_command(tmp_path: Path, caplog) -> None:
    from pipeline.core.itemstage import WorkItem, run_item_stage

    out = tmp_path / "out"
    items = [WorkItem(i, "fp", (out / f"{i}.parquet",), i) for i in "abc"]
    with caplog.at_level("WARNING"):
        report = run_item_stage("demo", items, _segfault_on_b, out_dirs=[out],
                                params={"workers": 2, "max_failure_ratio": 1.0})
    assert sorted(report.done) == ["a", "c"]
    (failure,) = report.failures
    assert failure.item == "b" and failure.error_class == "WorkerCrashed"
    assert "SIGSEGV" in failure.message and "also when run alone" in failure.message
    assert "`dance3d retry demo`" in failure.message
    assert "worker crashed: b" in caplog.text


def _pid(x: int) -> int:
    return os.getpid()


def _pid_after_a_while(x: int) -> int:
    time.sleep(0.3)
    return os.getpid()


def test_quick_items_of_a_light_stage_run_in_its_own_process() -> None:
    from pipeline.core.executor import run_items

    outcomes = list(run_items(_pid, [1, 2, 3, 4], workers=2, inline_seconds=60))
    assert [o.item for o in outcomes] == [1, 2, 3, 4] and {o.value for o in outcomes} == {os.getpid()}


def test_what_is_left_after_the_inline_seconds_goes_to_the_workers() -> None:
    from pipeline.core.executor import run_items

    pids = {o.item: o.value for o in run_items(_pid_after_a_while, list(range(6)), workers=2, inline_seconds=0.45)}
    inline = [i for i in range(6) if pids[i] == os.getpid()]
    assert sorted(pids) == list(range(6))
    assert inline and inline == list(range(len(inline))) and len(inline) <= 2  # the first items, 0.3 s each
    assert len({pids[i] for i in range(len(inline), 6)} - {os.getpid()}) >= 1  # the rest: worker processes
    assert all(pids[i] != os.getpid() for i in range(len(inline), 6))


def test_a_light_stage_does_its_few_quick_items_itself_and_a_heavy_one_uses_workers(tmp_path: Path) -> None:
    from pipeline.core.itemstage import WorkItem, run_item_stage

    def items(folder: str) -> list:
        return [WorkItem(i, "fp", (tmp_path / folder / f"{i}.parquet",), i) for i in "abc"]

    params = {"workers": 2}
    light = run_item_stage("light", items("light"), _pid, out_dirs=[tmp_path / "light"], params=params, light=True)
    heavy = run_item_stage("heavy", items("heavy"), _pid, out_dirs=[tmp_path / "heavy"], params=params)
    assert set(light.done.values()) == {os.getpid()}
    assert os.getpid() not in set(heavy.done.values()) and len(heavy.done) == 3


def _started_at(seconds: float) -> float:
    start = time.time()
    time.sleep(seconds)
    return start


def test_the_largest_items_start_first_so_no_worker_waits_on_a_long_one_started_last(tmp_path: Path) -> None:
    """Three short videos and a long one on two workers: the long one starts at once."""
    from pipeline.core.itemstage import WorkItem, run_item_stage

    out = tmp_path / "out"
    seconds = {"a": 0.2, "b": 0.2, "c": 1.0, "d": 0.2}
    items = [WorkItem(i, "fp", (out / f"{i}.parquet",), s, size=s) for i, s in seconds.items()]
    started = run_item_stage("demo", items, _started_at, out_dirs=[out], params={"workers": 2}).done
    assert started["c"] <= min(started["a"], started["b"], started["d"]) + 0.05


def test_float_columns_are_stored_byte_stream_split_and_read_back_exactly(tmp_path: Path) -> None:
    """Motion is smooth, so the bytes of neighbouring floats' exponents repeat: split by byte they
    compress about a third smaller under zstd (the demo's intermediates: 5.3 -> 3.4 MiB), losslessly."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from pipeline.core.storage import write_parquet

    walk = np.cumsum(np.random.default_rng(0).normal(0, 0.01, (2000, 51)), 0).astype(np.float32)
    table = pa.table({"clip_id": pa.array(["a"] * 2000),
                      "joints": pa.FixedSizeListArray.from_arrays(pa.array(walk.ravel()), 51),
                      "time": pa.array(np.arange(2000) / 24.0)})
    write_parquet(table, tmp_path / "motion.parquet", schema_version=1)
    meta = pq.read_metadata(tmp_path / "motion.parquet").row_group(0)
    encodings = {meta.column(i).path_in_schema: meta.column(i).encodings for i in range(meta.num_columns)}
    assert "BYTE_STREAM_SPLIT" in encodings["joints.list.element"] and "BYTE_STREAM_SPLIT" in encodings["time"]
    assert "BYTE_STREAM_SPLIT" not in encodings["clip_id"]  # strings keep their dictionary
    back = pq.read_table(tmp_path / "motion.parquet")
    assert back.drop_columns([]).equals(table.replace_schema_metadata(back.schema.metadata))
    pq.write_table(table, tmp_path / "plain.parquet", compression="zstd")
    assert (tmp_path / "motion.parquet").stat().st_size < 0.8 * (tmp_path / "plain.parquet").stat().st_size


@pytest.mark.parametrize("values", [np.arange(7, dtype=np.int32), np.arange(7, dtype=np.uint8),
                                    np.linspace(0, 1, 7, dtype=np.float32), np.linspace(0, 1, 7),
                                    np.arange(7) % 3 == 0, np.zeros(0, np.int64)])
def test_an_arrow_column_reads_into_numpy_as_pyarrow_reads_it_at_any_offset(values: np.ndarray) -> None:
    import pyarrow as pa

    from pipeline.core.storage import to_numpy

    whole = pa.array(values)
    for array in (whole, whole.slice(2), whole.slice(3, 2)):
        mine = to_numpy(array)
        assert mine.dtype == array.to_numpy(zero_copy_only=False).dtype
        assert np.array_equal(mine, array.to_numpy(zero_copy_only=False))
    with_nulls = pa.array([1.0, None, 3.0])
    assert np.isnan(to_numpy(with_nulls)[1])


CODE = '''"""A module."""

import math  # why

TAG = "#1 of 2"  # a hash inside a string is code


def area(r):
    """The area."""
    # pi r squared
    return math.pi * r * r  # exact enough
'''


@pytest.mark.parametrize("edited,same", [
    (CODE.replace('"""The area."""', '"""The area of a disc of radius ``r`` — any unit."""'), True),
    (CODE.replace("# pi r squared", "# pi r squared, as Archimedes knew\n    # (a second line)"), True),
    (CODE.replace('"""A module."""', '"""A module,\nnow in two lines."""') + "\n\n", True),
    (CODE.replace("r * r", "r ** 2"), False),
    (CODE.replace("import math  # why", "import math  # why\nTAU = 2 * math.pi"), False),
    (CODE.replace("    return", "    '''not a docstring: a statement'''\n    return"), False),
    (CODE.replace('"#1 of 2"', '"#2 of 2"'), False),
    (CODE.replace('"""The area."""', '"""The area."""; r = abs(r)'), False),
    (CODE.replace('"#1 of 2"  #', '"#1 of 2"  ## '), True),
])
def test_a_code_fingerprint_is_the_code_not_its_comments_docstrings_or_blank_lines(
        edited: str, same: bool, tmp_path: Path, monkeypatch) -> None:
    """Editing what a module says about itself redoes no stage's items; editing what it does does."""
    from pipeline.core.storage import code_fingerprint

    (tmp_path / "before_edit.py").write_text(CODE)
    (tmp_path / "after_edit.py").write_text(edited)
    monkeypatch.syspath_prepend(str(tmp_path))
    assert (code_fingerprint("before_edit") == code_fingerprint("after_edit")) is same
