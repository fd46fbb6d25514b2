"""Tiny ONNX models built in the tests: a fixed YOLO-layout output, whatever the image."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper


def constant_yolo_model(
    path: Path,
    output: np.ndarray,
    input_hw: tuple[int | str, int | str] = (64, 64),
    names: str | None = None,
) -> Path:
    """Write a model whose output is always ``output`` (plus 0 x the image mean) to ``path``."""
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["mean"], keepdims=0),
        helper.make_node("Constant", [], ["zero"], value=numpy_helper.from_array(np.float32(0.0))),
        helper.make_node("Mul", ["mean", "zero"], ["nothing"]),
        helper.make_node(
            "Constant", [], ["fixed"], value=numpy_helper.from_array(output.astype(np.float32))
        ),
        helper.make_node("Add", ["fixed", "nothing"], ["output0"]),
    ]
    graph = helper.make_graph(
        nodes,
        "constant_yolo",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, *input_hw])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, list(output.shape))],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    if names is not None:
        helper.set_model_props(model, {"names": names})
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def yolo_output(rows: list[tuple[float, float, float, float, list[float]]], num_classes: int) -> np.ndarray:
    """Build a ``[1, 4 + classes, N]`` array from (cx, cy, w, h, class scores) rows."""
    out = np.zeros((1, 4 + num_classes, len(rows)), dtype=np.float32)
    for i, (cx, cy, w, h, scores) in enumerate(rows):
        out[0, :4, i] = (cx, cy, w, h)
        out[0, 4:, i] = scores
    return out
