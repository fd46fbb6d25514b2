"""Perception: detectors, depth and lidar geometry, colour naming of image regions.

Import what you need from the submodules, e.g. :mod:`.detectors` (the Detector protocol and the
YOLO-layout ONNX detector), :mod:`.oracle` (the simulation-only ground-truth detector),
:mod:`.colour` and :mod:`.providers` (the factories registered with the plugin manager).
"""
