"""A published model without the outputs nothing here reads, and the nodes only they needed.

ONNX Runtime runs every node of a graph whatever outputs a call asks for, so an unused head
costs its full price: BlazePose's segmentation mask (a decoder up to 256 x 256) is half of
that model's time. Removing the output lets the nodes that fed only it go too; every kept
output is computed by the same nodes and weights as before (tested bit for bit).
"""

from __future__ import annotations

from typing import Callable


def without_outputs(model: bytes, unused: Callable[[str, tuple], bool]) -> bytes:
    """The serialised ``model`` without the outputs for which ``unused(name, shape)`` is true
    (``shape``: each dimension's size, or its name when symbolic) and the nodes left unused."""
    import onnx

    proto = onnx.load_from_string(model)
    graph = proto.graph
    kept = [o for o in graph.output if not unused(o.name, _shape(o))]
    if len(kept) == len(graph.output):
        return model
    del graph.output[:]
    graph.output.extend(kept)
    needed = {o.name for o in kept}
    nodes = []
    for node in reversed(graph.node):  # the graph is topologically sorted: walk back from the outputs
        if any(name in needed for name in node.output):
            nodes.append(node)
            needed.update(name for name in node.input if name)
    del graph.node[:]
    graph.node.extend(reversed(nodes))
    initializers = [i for i in graph.initializer if i.name in needed]
    del graph.initializer[:]
    graph.initializer.extend(initializers)
    values = [v for v in graph.value_info if v.name in needed]
    del graph.value_info[:]
    graph.value_info.extend(values)
    return proto.SerializeToString()


def _shape(value) -> tuple:
    return tuple(d.dim_value if d.HasField("dim_value") else d.dim_param for d in value.type.tensor_type.shape.dim)
