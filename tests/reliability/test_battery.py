"""A battery of bad and hostile inputs across stages. Each gives one clear message naming the
file and the reason, and never costs the work already done for the good items."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from pipeline.annotate.clipfile import read_clean
from pipeline.annotate.manifests import Span, write_manifest
from pipeline.core.errors import InputError, InputErrors, ModelMissingError
from pipeline.core.params import load_params
from pipeline.ingest.catalog import read_index, read_ledger
from pipeline.ingest.sources import read_sources
from pipeline.pose.pose2dfile import read_pose2d
from tests.annotate.test_annotation import HEADER as MANIFEST_HEADER
from tests.annotate.test_annotation import write_tracks
from tests.conftest import PROJECT, ffmpeg, make_test_video, run_stages, set_params
from tests.ingest.test_download import _Server

GOOD = "dance_solo_384x496_30fps.mp4"


def project_with(root: Path, media_dir: Path, bad_url: str) -> Path:
    """A project with one good video and one bad source; failures never stop the stage here."""
    (root / "manifests").mkdir(parents=True)
    (root / "annotations").mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    (root / "manifests/sources.csv").write_text(f"video_id,url\ngood,{media_dir / 'videos' / GOOD}\nbad,{bad_url}\n")
    (root / "annotations/segments.csv").write_text("video_id,start,end\ngood,0,4\n")
    set_params(root, "download", max_failure_ratio=1.0, retries=1)
    set_params(root, "trim", unannotated="whole", max_failure_ratio=1.0)
    return root


def bad_file(tmp_path: Path, media_dir: Path, kind: str) -> Path:
    path = tmp_path / f"bad_{kind}.mp4"
    if kind == "zero_byte":
        path.write_bytes(b"")
    elif kind == "truncated":
        path.write_bytes((media_dir / "videos/dance_single_music_musepose.mp4").read_bytes()[:1_500_000])
    elif kind == "wrong_container":
        path.write_text("<html>this is a web page, not a video</html>\n" * 50)
    elif kind == "audio_only":
        path = tmp_path / "bad_audio_only.ogg"
        shutil.copy(media_dir / "music/music_brahms_hungarian_dance_5.ogg", path)
    elif kind == "no_video_stream":
        path = tmp_path / "bad_no_video.m4a"
        ffmpeg("-f", "lavfi", "-i", "sine=frequency=440:duration=2", "-c:a", "aac", str(path))
    return path


@pytest.mark.parametrize("kind, reason", [
    ("zero_byte", "is empty (0 bytes)"),
    ("truncated", "not a readable media file"),
    ("wrong_container", "not a readable media file"),
    ("audio_only", "no video stream (audio-only file)"),
    ("no_video_stream", "no video stream (audio-only file)"),
])
def test_unusable_videos_are_failed_ledger_rows(tmp_path: Path, media_dir: Path, kind: str, reason: str) -> None:
    src = bad_file(tmp_path, media_dir, kind)
    root = project_with(tmp_path / "p", media_dir, str(src))
    run_stages(root, "download", "trim")
    ledger = {r["video_id"]: r for r in read_ledger(root / "data/raw").values()}
    bad = next(r for r in ledger.values() if r["url"].endswith(src.name))
    assert bad["status"] == "failed" and reason in bad["error_message"], bad["error_message"]
    assert ledger["good"]["status"] == "ok"
    assert "good_000" in read_index(root / "data/segments")  # the good video went on


def test_missing_local_file(tmp_path: Path, media_dir: Path) -> None:
    root = project_with(tmp_path / "p", media_dir, str(tmp_path / "gone.mp4"))
    run_stages(root, "download", "trim")
    bad = list(read_ledger(root / "data/raw").values())[1]
    assert bad["error_class"] == "not_found" and "gone.mp4" in bad["error_message"]
    assert "good_000" in read_index(root / "data/segments")


def test_failing_download_http_404(tmp_path: Path, media_dir: Path) -> None:
    server = _Server(b"", [404] * 10)
    try:
        root = project_with(tmp_path / "p", media_dir, f"{server.url}/deleted-video.mp4")
        run_stages(root, "download", "trim")
    finally:
        server.httpd.shutdown()
    bad = list(read_ledger(root / "data/raw").values())[1]
    assert bad["status"] == "failed" and bad["error_class"] == "not_found" and "404" in bad["error_message"]
    assert "good_000" in read_index(root / "data/segments")


@pytest.mark.parametrize("kind", ["huge_resolution", "rotated_phone", "variable_frame_rate"])
def test_awkward_but_valid_videos_are_handled(tmp_path: Path, media_dir: Path, kind: str) -> None:
    from pipeline.ingest.media import probe
    from pipeline.ingest.segmentvideo import SegmentVideo

    src = tmp_path / f"{kind}.mp4"
    if kind == "huge_resolution":
        make_test_video(src, seconds=1, size="4096x2160")
    elif kind == "rotated_phone":
        plain = make_test_video(tmp_path / "plain.mp4", seconds=1, size="640x360")
        ffmpeg("-display_rotation", "90", "-i", str(plain), "-c", "copy", str(src))
    else:
        plain = make_test_video(tmp_path / "plain.mp4", seconds=2, fps="30", audio=False)
        ffmpeg("-i", str(plain), "-vf", "select='lt(mod(n\\,5)\\,2)'", "-fps_mode", "vfr", "-c:v", "libx264",
               "-preset", "ultrafast", str(src))
    root = project_with(tmp_path / "p", media_dir, str(src))
    run_stages(root, "download", "trim")
    row = read_index(root / "data/segments")["bad_000"]
    frames = list(SegmentVideo.from_index(root / "data/raw", row).iter_frames())
    assert len(frames) == row["frames"] and {f.image.shape for f in frames} == {(row["height"], row["width"], 3)}
    if kind == "huge_resolution":
        assert max(row["width"], row["height"]) == 1280
    elif kind == "rotated_phone":
        assert (row["width"], row["height"]) == (360, 640)
    else:
        info = probe(src)
        assert row["frames"] == round(info.duration * info.fps)  # constant rate, every slot filled


def test_segment_with_no_people(tmp_path: Path, media_dir: Path, models_dir: Path, monkeypatch) -> None:
    monkeypatch.setenv("DANCE3D_MODELS", str(models_dir))
    root = project_with(tmp_path / "p", media_dir, str(make_test_video(tmp_path / "empty_room.mp4", seconds=1)))
    run_stages(root, "download", "trim", "pose2d", "track", "clean")
    assert len(read_pose2d(root / "data/pose2d/bad_000.parquet").poses) == 0
    assert not read_clean(root / "data/clean/bad_000.parquet").clips
    assert read_clean(root / "data/clean/good_000.parquet").clips


SOURCES_HEADER = "video_id,url,channel,style,licence,note\n"


@pytest.mark.parametrize("body, expected", [
    ("x,a.mp4,,,,\nx,b.mp4,,,,\n", "sources.csv:3: duplicate video_id 'x'"),
    ("../x,a.mp4,,,,\n", "sources.csv:2: video_id '../x' is not a safe identifier"),
    ("/etc/passwd,a.mp4,,,,\n", "sources.csv:2: video_id '/etc/passwd' is not a safe identifier"),
    ("a\x00b,a.mp4,,,,\n", "sources.csv:2: video_id 'a\\x00b' is not a safe identifier"),
    ("x" * 300 + ",a.mp4,,,,\n", "sources.csv:2: video_id 'xxxxxxxx"),
    ("my video,a.mp4,,,,\n", "sources.csv:2: video_id 'my video' is not a safe identifier"),
    ("a,b,c\n", "sources.csv:2: expected 6 fields, found 3"),
])
def test_hostile_or_malformed_sources_are_refused_with_file_and_line(tmp_path: Path, body: str, expected: str) -> None:
    path = tmp_path / "sources.csv"
    path.write_text(SOURCES_HEADER + body)
    with pytest.raises(InputError) as err:
        read_sources(path, base_dir=tmp_path)
    assert expected in str(err.value) and str(err.value).startswith(str(tmp_path))


def test_missing_url_column(tmp_path: Path) -> None:
    path = tmp_path / "sources.csv"
    path.write_text("video_id,channel\nx,y\n")
    with pytest.raises(InputError, match=r"sources\.csv:1: missing column\(s\) url"):
        read_sources(path, base_dir=tmp_path)


@pytest.mark.parametrize("url, reason", [
    ("javascript:alert(1)", "unsupported scheme 'javascript'"),
    ("ftp://example.org/v.mp4", "unsupported scheme 'ftp'"),
    ("data:video/mp4;base64,AAAA", "unsupported scheme 'data'"),
    ("https://exa mple.org/v", "contains whitespace or NUL"),
])
def test_hostile_urls_become_failed_rows(tmp_path: Path, url: str, reason: str) -> None:
    path = tmp_path / "sources.csv"
    path.write_text(SOURCES_HEADER + f'a,"{url}",,,,\n')
    (source,) = read_sources(path, base_dir=tmp_path)
    assert source.url_error.startswith(f"{path}:2: ") and reason in source.url_error


def test_local_files_refused_when_disabled(tmp_path: Path) -> None:
    path = tmp_path / "sources.csv"
    path.write_text(SOURCES_HEADER + "a,file:///etc/passwd,,,,\n")
    (source,) = read_sources(path, base_dir=tmp_path, allow_file_urls=False)
    assert "allow_file_urls is false" in source.url_error


def test_non_utf8_and_empty_csv(tmp_path: Path) -> None:
    path = tmp_path / "sources.csv"
    path.write_bytes(SOURCES_HEADER.encode() + b"a,\xff\xfe.mp4,,,,\n")
    with pytest.raises(InputError, match=r"sources\.csv: not UTF-8 text"):
        read_sources(path, base_dir=tmp_path)
    path.write_text("# only a comment\n")
    with pytest.raises(InputError, match=r"sources\.csv: empty file"):
        read_sources(path, base_dir=tmp_path)


@pytest.mark.parametrize("body, expected", [
    ("ghost,0,1\n", ":2: unknown video 'ghost'"),
    ("good,3,1\n", ":2: end 1.000 s is not after start 3.000 s"),
    ("good,0,5\ngood,4,8\n", ":3: segment 4.000-8.000 s overlaps line 2"),
    ("good,0,99\n", ":2: segment 0.000-99.000 s passes the end of good"),
    ("good,0,1:7x\n", ":2: cannot read time '1:7x'"),
    ("../good,0,1\n", ":2: video_id '../good' is not a safe identifier"),
])
def test_bad_segment_annotations_stop_trim_naming_the_line(tmp_path: Path, media_dir: Path, body: str,
                                                           expected: str) -> None:
    root = project_with(tmp_path / "p", media_dir, str(tmp_path / "missing.mp4"))
    run_stages(root, "download")
    (root / "annotations/segments.csv").write_text("video_id,start,end\n" + body)
    with pytest.raises(InputErrors) as err:
        run_stages(root, "trim")
    assert f"{root / 'annotations/segments.csv'}{expected}" in str(err.value)


@pytest.mark.parametrize("body, expected", [
    ("9,0,1,yes,,,,,,\n", ":2: unknown track id 9"),
    ("1,0,9,maybe,,,,,,\n", ":2: keep must be yes or no, not 'maybe'"),
    ("1,0,9,yes,=cmd|' /C calc'!A0,,,,,\n1,0,9,yes,,,,,,\n", ":3: duplicate of line 2"),
])
def test_bad_manifests_stop_clean_naming_the_line(tmp_path: Path, body: str, expected: str) -> None:
    root = tmp_path / "p"
    root.mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    write_tracks(root, "vid_000", {1: list(range(240))})
    before = sorted((root / "data/tracks").iterdir())
    path = root / "manifests/tracks/vid_000.csv"
    path.parent.mkdir(parents=True)
    path.write_text(MANIFEST_HEADER + body)
    with pytest.raises(InputErrors) as err:
        run_stages(root, "clean")
    assert f"{path}{expected}" in str(err.value)
    assert sorted((root / "data/tracks").iterdir()) == before


def test_manifest_for_an_unknown_segment_and_formula_cells(tmp_path: Path) -> None:
    root = tmp_path / "p"
    root.mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    write_tracks(root, "vid_000", {1: list(range(240))})
    path = root / "manifests/tracks/ghost_000.csv"
    write_manifest(path, [Span(1, 0.0, 5.0, True, note="=HYPERLINK(\"http://evil\")")])
    assert "'=HYPERLINK" in path.read_text()  # neutralised for spreadsheets
    with pytest.raises(InputErrors, match=r"ghost_000\.csv: manifest for an unknown segment"):
        run_stages(root, "clean")


def test_missing_model_is_one_line(tmp_path: Path) -> None:
    root = tmp_path / "p"
    root.mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    with pytest.raises(ModelMissingError) as err:
        run_stages(root, "lift")
    assert "\n" not in str(err.value) and "lifter.onnx not found: run the train_lifter stage" in str(err.value)


def test_unknown_model_name_in_params(tmp_path: Path, monkeypatch) -> None:
    root = tmp_path / "p"
    root.mkdir()
    shutil.copy(PROJECT / "params.yaml", root / "params.yaml")
    set_params(root, "pose2d", pose_model="openpose-9000")
    with pytest.raises(ModelMissingError, match="unknown model 'openpose-9000'; registered: .*movenet-lightning"):
        run_stages(root, "pose2d")


def test_malformed_params_file_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "params.yaml"
    path.write_text("trim:\n  fps: [unclosed\n")
    with pytest.raises(InputError) as err:
        load_params(path)
    assert str(err.value).startswith(f"{path}:") and "invalid YAML" in str(err.value)
