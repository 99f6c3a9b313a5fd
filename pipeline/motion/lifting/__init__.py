"""2D -> 3D lifting: the VideoPose3D temporal convolutional model, its training data, export
and conversion (these need the ``train`` extra: torch), and ONNX inference (no torch)."""
