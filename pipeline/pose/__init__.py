"""2D: the ONNX models, streamed detection and top-down pose, tracking, QC videos."""
