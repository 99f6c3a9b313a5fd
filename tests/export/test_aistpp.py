"""The AIST++ export's pieces: names Bailando can split, and a frame-rate change that keeps the motion."""

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.export.aistpp import resample, sequence_name


def test_sequence_names_are_aist_names_stable_and_distinct():
    name, music = sequence_name("solo_dance_000_1_0")
    genre, situation, camera, dancer, music_tag, choreo = name.split("_")
    assert (genre[0], situation[0], camera, dancer[0], choreo[:2]) == ("g", "s", "cAll", "d", "ch")
    assert music_tag == music and sequence_name("solo_dance_000_1_0") == (name, music)
    assert sequence_name("solo_dance_000_2_0")[0] != name


def test_24_to_60_fps_keeps_every_source_frame_and_slerps_between():
    frames = 25  # one second at 24 fps
    angles = np.linspace(0, np.pi / 2, frames)
    poses = np.zeros((frames, 72))
    poses[:, 3 * 4] = angles  # the left knee turns steadily about x
    trans = np.stack([np.linspace(0, 1, frames), np.ones(frames), np.zeros(frames)], 1)
    out, path = resample(poses, trans, 24.0, 60.0)
    assert len(out) == 61 and len(path) == 61  # 0 .. 1 s at 60 fps
    assert np.allclose(out[::5][:, 12], angles[::2], atol=1e-9)  # 60 fps frame 5k is 24 fps frame 2k
    assert np.allclose(out[:, 12], np.linspace(0, np.pi / 2, 61), atol=1e-9)  # constant speed between
    assert np.allclose(path[:, 0], np.linspace(0, 1, 61))
    knee = Rotation.from_rotvec(out[:, 12:15]).magnitude()
    assert np.all(np.diff(knee) > 0)


def test_a_world_file_of_an_older_schema_gets_one_line_naming_it_and_the_fix(tmp_path, capsys):
    import shutil

    import pyarrow as pa

    from pipeline.cli import main
    from pipeline.core.storage import write_parquet
    from pipeline.ingest.catalog import INDEX_SCHEMA, write_index
    from pipeline.motion.world.worldfile import SCHEMA_VERSION

    row = {f.name: None for f in INDEX_SCHEMA}
    row.update(segment_id="vid_000", video_id="vid", start=0.0, end=2.0, fps=24.0, frames=48)
    write_index(tmp_path / "data/segments", [row], params={})
    (tmp_path / "data/audio").mkdir(parents=True)
    (tmp_path / "data/audio/vid_000.flac").write_bytes(b"")
    write_parquet(pa.table({"clip_id": pa.array([], pa.string())}), tmp_path / "data/world/vid_000.parquet",
                  schema_version=2, params={})
    shutil.copy("params.yaml", tmp_path / "params.yaml")
    assert main(["--root", str(tmp_path), "export", "aistpp", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"dance3d: {tmp_path / 'data/world/vid_000.parquet'}: world file schema 2, this dance3d reads "
                   f"schema {SCHEMA_VERSION}: re-run the ground stage"]
