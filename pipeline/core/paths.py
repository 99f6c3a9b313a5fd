"""Where everything lives, relative to the project root (the folder holding params.yaml)."""

from pathlib import Path

SOURCES = Path("manifests/sources.csv")
TRACK_MANIFESTS = Path("manifests/tracks")
ANNOTATIONS = Path("annotations/segments.csv")
CATALOG = Path("data/catalog")
RAW = Path("data/raw")
SEGMENT_PROPOSALS = Path("data/segment_proposals")
SEGMENTS = Path("data/segments")
POSE2D = Path("data/pose2d")
TRACKS = Path("data/tracks")
QC = Path("data/qc")
CLEAN = Path("data/clean")
METRICS = Path("metrics")   # headline figures (dvc metrics show)
REPORTS = Path("reports")   # the breakdowns beside them (pipeline/core/metrics.py)
POSE3D = Path("data/pose3d")
SMOOTH = Path("data/smooth")
MOTION24 = Path("data/motion24")
WORLD = Path("data/world")
LIFTER = Path("models/lifter.onnx")
CONTACT_MODEL = Path("models/contact.onnx")
AUDIO = Path("data/audio")
AUDIO_FEATURES = Path("data/audio_features")
CORPUS = Path("data/corpus")

# The folder holding each stage's _failures.parquet.
FAILURE_DIRS = {"download": RAW, "propose_segments": SEGMENT_PROPOSALS, "trim": SEGMENTS,
                "pose2d": POSE2D, "track": TRACKS, "clean": CLEAN,
                "lift": POSE3D, "smooth": SMOOTH, "resample": MOTION24, "ground": WORLD,
                "audio": AUDIO_FEATURES}
