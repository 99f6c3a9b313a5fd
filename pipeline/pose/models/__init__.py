"""ONNX models: the registry (where each file comes from), sessions, and model wrappers."""
