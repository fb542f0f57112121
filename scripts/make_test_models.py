#!/usr/bin/python3
"""Writes the tiny ONNX models that test our ONNX decoders (testdata/onnx/).

They have the input and output signatures of the real networks but a few hand-set weights, so
their outputs are known exactly and a test can tell a right decoder from a wrong one:

  yolov8_tiny.onnx     detector, images 1x3x64x64 -> 1x84x3. Box values are constants in input
                       pixels; the 'person' score of anchors 0 and 1 is the image's mean red, the
                       'car' score of anchor 2 its mean blue (so RGB order, the 1/255 scale, the
                       letterbox padding and NMS all show in the result).
  yolov8_dynamic_tiny.onnx  the same with symbolic height and width, and its weights listed
                       among the inputs as in exports before IR version 4.
  yoloseg_tiny.onnx    Fast-SAM-like segmenter, images 1x3x64x64 -> detections 1x7x2
                       (box, 1 score, 2 mask coefficients) and prototypes 1x2x16x16. Prototype 0
                       is positive on red pixels, prototype 1 on green ones; instance 0 (box over
                       the left half) takes prototype 0, instance 1 (right half) prototype 1.
  flow_stacked_tiny.onnx  flow, 1x6x48x64 (previous RGB, current RGB) -> 1x2x48x64 with
                       u = 10 (R_current - R_previous), v = 10 (G_current - G_previous).
  flow_pair_tiny.onnx  the same flow from two named inputs 'previous' and 'current' 1x3x48x64.

Run at development time with Debian's python3-onnx (apt-get install python3-onnx); the outputs
are committed (a few KB), so neither the build nor the tests need Python.
"""
import os
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

OPSET = 11  # what OpenCV 4.6's ONNX importer reads without surprises
SIZE = 64   # detector / segmenter input side


def tensor(name, array):
    return numpy_helper.from_array(np.asarray(array, dtype=np.float32), name)


def int_tensor(name, values):
    return numpy_helper.from_array(np.asarray(values, dtype=np.int64), name)


def save(graph, path):
    model = helper.make_model(graph, producer_name="sdoslam make_test_models.py",
                              opset_imports=[helper.make_opsetid("", OPSET)])
    model.ir_version = 7
    onnx.checker.check_model(model)
    onnx.save(model, path)


def image_means():
    """Nodes turning 'images' (1x3xHxW) into 'means' (1x3): mean R, G, B."""
    return [helper.make_node("GlobalAveragePool", ["images"], ["pooled"]),
            helper.make_node("Flatten", ["pooled"], ["means"], axis=1)]


def yolov8(path, dynamic=False):
    rows, anchors = 84, 3
    weight = np.zeros((3, rows * anchors), np.float32)
    bias = np.zeros(rows * anchors, np.float32)

    def at(row, anchor):
        return row * anchors + anchor

    boxes = [(20, 26, 16, 20), (21, 26, 16, 20), (16, 40, 8, 8)]  # cx, cy, w, h (input px)
    for anchor, box in enumerate(boxes):
        for row, value in enumerate(box):
            bias[at(row, anchor)] = value
    weight[0, at(4 + 0, 0)] = 1.0   # person <- mean R
    weight[0, at(4 + 0, 1)] = 0.9   # a weaker duplicate NMS must remove
    weight[2, at(4 + 2, 2)] = 1.0   # car <- mean B
    nodes = image_means() + [
        helper.make_node("Gemm", ["means", "weight", "bias"], ["flat"], transB=1),
        helper.make_node("Reshape", ["flat", "shape"], ["output0"]),
    ]
    initializers = [tensor("weight", weight.T), tensor("bias", bias),
                    int_tensor("shape", [1, rows, anchors])]
    inputs = [helper.make_tensor_value_info(
        "images", TensorProto.FLOAT, [1, 3, "height", "width"] if dynamic else [1, 3, SIZE, SIZE])]
    if dynamic:  # as exports before IR version 4 do, list the weights among the inputs too
        inputs += [helper.make_tensor_value_info(t.name, t.data_type, list(t.dims))
                   for t in initializers]
    graph = helper.make_graph(
        nodes, "yolov8_tiny", inputs,
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, rows, anchors])],
        initializers)
    save(graph, path)


def yoloseg(path):
    masks, anchors = 2, 2
    rows = 4 + 1 + masks
    weight = np.zeros((3, rows * anchors), np.float32)
    bias = np.zeros(rows * anchors, np.float32)
    half = SIZE // 2
    content_height = SIZE * 3 // 4  # a 4:3 image letterboxed into the square
    instances = [  # box (input px), score, coefficients
        ((half / 2, content_height / 2, half, content_height), 0.9, (1.0, 0.0)),
        ((half + half / 2, content_height / 2, half, content_height), 0.8, (0.0, 1.0)),
    ]
    for anchor, (box, score, coefficients) in enumerate(instances):
        values = list(box) + [score] + list(coefficients)
        for row, value in enumerate(values):
            bias[row * anchors + anchor] = value
    # Prototypes at 1/4 of the input, as in YOLOv8-seg: 20 R - 10 G - 10 B - 10 is +10 on pure
    # red and -10 on black, green, blue, white or the grey padding.
    proto_weight = np.array([[20, -10, -10], [-10, 20, -10]], np.float32).reshape(2, 3, 1, 1)
    proto_bias = np.array([-10, -10], np.float32)
    nodes = image_means() + [
        helper.make_node("Gemm", ["means", "weight", "bias"], ["flat"], transB=1),
        helper.make_node("Reshape", ["flat", "shape"], ["output0"]),
        helper.make_node("AveragePool", ["images"], ["small"], kernel_shape=[4, 4],
                         strides=[4, 4]),
        helper.make_node("Conv", ["small", "proto_weight", "proto_bias"], ["output1"],
                         kernel_shape=[1, 1]),
    ]
    graph = helper.make_graph(
        nodes, "yoloseg_tiny",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, SIZE, SIZE])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, rows, anchors]),
         helper.make_tensor_value_info("output1", TensorProto.FLOAT,
                                       [1, masks, SIZE // 4, SIZE // 4])],
        [tensor("weight", weight.T), tensor("bias", bias), int_tensor("shape", [1, rows, anchors]),
         tensor("proto_weight", proto_weight), tensor("proto_bias", proto_bias)])
    save(graph, path)


FLOW_H, FLOW_W = 48, 64


def flow_stacked(path):
    # Channels: previous R, G, B, current R, G, B.
    weight = np.zeros((2, 6, 1, 1), np.float32)
    weight[0, 0], weight[0, 3] = -10, 10
    weight[1, 1], weight[1, 4] = -10, 10
    graph = helper.make_graph(
        [helper.make_node("Conv", ["pair", "weight"], ["flow"], kernel_shape=[1, 1])], "flow_stacked_tiny",
        [helper.make_tensor_value_info("pair", TensorProto.FLOAT, [1, 6, FLOW_H, FLOW_W])],
        [helper.make_tensor_value_info("flow", TensorProto.FLOAT, [1, 2, FLOW_H, FLOW_W])],
        [tensor("weight", weight)])
    save(graph, path)


def flow_pair(path):
    weight = np.zeros((2, 3, 1, 1), np.float32)
    weight[0, 0] = 10
    weight[1, 1] = 10
    graph = helper.make_graph(
        [helper.make_node("Sub", ["current", "previous"], ["change"]),
         helper.make_node("Conv", ["change", "weight"], ["flow"], kernel_shape=[1, 1])], "flow_pair_tiny",
        [helper.make_tensor_value_info("previous", TensorProto.FLOAT, [1, 3, FLOW_H, FLOW_W]),
         helper.make_tensor_value_info("current", TensorProto.FLOAT, [1, 3, FLOW_H, FLOW_W])],
        [helper.make_tensor_value_info("flow", TensorProto.FLOAT, [1, 2, FLOW_H, FLOW_W])],
        [tensor("weight", weight)])
    save(graph, path)


def main():
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "testdata", "onnx")
    out = sys.argv[1] if len(sys.argv) > 1 else root
    os.makedirs(out, exist_ok=True)
    yolov8(os.path.join(out, "yolov8_tiny.onnx"))
    yolov8(os.path.join(out, "yolov8_dynamic_tiny.onnx"), dynamic=True)
    yoloseg(os.path.join(out, "yoloseg_tiny.onnx"))
    flow_stacked(os.path.join(out, "flow_stacked_tiny.onnx"))
    flow_pair(os.path.join(out, "flow_pair_tiny.onnx"))
    for name in sorted(os.listdir(out)):
        print(f"{os.path.join(out, name)}: {os.path.getsize(os.path.join(out, name))} bytes")


if __name__ == "__main__":
    main()
