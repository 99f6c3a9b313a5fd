"""Where everything lives, relative to the project root (the folder holding params.yaml)."""

from pathlib import Path

SOURCES = Path("manifests/sources.csv")
TRACK_MANIFESTS = Path("manifests/tracks")
ANNOTATIONS = Path("annotations/segments.csv")
RAW = Path("data/raw")
SEGMENTS = Path("data/segments")
POSE2D = Path("data/pose2d")
TRACKS = Path("data/tracks")
QC = Path("data/qc")
CLEAN = Path("data/clean")
METRICS = Path("metrics")
