"""The shipped simulator detector's tools: labelled data from the simulator and CPU training.

- :mod:`tools.detector.data`: generated worlds and labelled camera views (training and scoring).
- :mod:`tools.detector.network`: the network, widening, loading a ``.pt`` or ``.onnx``, export.
- :mod:`tools.detector.train`: the training command (needs the ``train`` extra's CPU torch).
"""
