"""A crop model exported for one image at a time, made to take a batch: one call per frame.

PP-TinyPose and BlazePose are published with a fixed batch of 1, so a frame with five dancers
takes five ONNX Runtime calls per model. On a GPU the stage edits them (``loading.batch_crops``;
on the CPU one crop per call is faster). The graph edit frees the batch dimension: the inputs'
and outputs' first dimension becomes symbolic, a ``Reshape`` whose constant target starts with
the batch (1) copies it instead (-1), and a ``Resize`` to constant ``sizes`` (batch 1 included)
resizes by the equivalent ``scales`` (1 on the batch). Every other shape annotation is dropped
and inferred again by the runtime. The weights are untouched: a batch gives what the crops give
one by one (tested on the golden images).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def any_batch(path: Path) -> bytes:
    """The serialised model at ``path`` with a free batch dimension (see the module docstring)."""
    import onnx
    from onnx import numpy_helper, shape_inference

    model = onnx.load(str(path))
    inferred = shape_inference.infer_shapes(model)
    shapes = {v.name: [d.dim_value for d in v.type.tensor_type.shape.dim]
              for v in [*inferred.graph.value_info, *inferred.graph.input, *inferred.graph.output]}
    constants = {i.name: i for i in model.graph.initializer}
    added = []
    for node in model.graph.node:
        if node.op_type == "Reshape" and node.input[1] in constants:
            target = numpy_helper.to_array(constants[node.input[1]])
            if target.size and target[0] == 1:
                target = target.copy()
                target[0] = -1
                added.append(numpy_helper.from_array(target, node.input[1] + "/any_batch"))
                node.input[1] = added[-1].name
        elif node.op_type == "Resize" and len(node.input) == 4 and node.input[3] in constants:
            sizes = numpy_helper.to_array(constants[node.input[3]]).astype(np.float64)
            source = shapes.get(node.input[0])
            if not source or len(source) != len(sizes) or not all(source) or sizes[0] != source[0]:
                raise ValueError(f"{path}: Resize {node.name!r} to {sizes.tolist()} from an unknown or batch-changing "
                                 f"shape {source}; cannot free its batch")
            added.append(numpy_helper.from_array((sizes / np.array(source)).astype(np.float32),
                                                 node.input[3] + "/as_scales"))
            node.input[2], node.input[3] = added[-1].name, ""
    model.graph.initializer.extend(added)
    used = {name for node in model.graph.node for name in node.input}
    keep = [i for i in model.graph.initializer if i.name in used]
    del model.graph.initializer[:]
    model.graph.initializer.extend(keep)
    for value in [*model.graph.input, *model.graph.output]:
        value.type.tensor_type.shape.dim[0].dim_param = "batch"
    del model.graph.value_info[:]
    return model.SerializeToString()


def fixed_batch_of_one(session) -> bool:
    """Whether the session's first input takes exactly one image."""
    return session.get_inputs()[0].shape[0] == 1


def run_batched(session, outputs, input_name: str, tensors: np.ndarray):
    """``session.run`` on a batch of crops: one call when the session takes a batch, one per crop
    (concatenated) when its model is fixed at one. ``outputs`` is one output name or a list."""
    names = [outputs] if isinstance(outputs, str) else list(outputs)
    if len(tensors) == 1 or not fixed_batch_of_one(session):
        results = session.run(names, {input_name: tensors})
    else:
        parts = [session.run(names, {input_name: tensors[i:i + 1]}) for i in range(len(tensors))]
        results = [np.concatenate([p[k] for p in parts]) for k in range(len(names))]
    return results[0] if isinstance(outputs, str) else results
