"""Quantizing a network for the simulated AI deck (docs/NN_ONNX.md).

``cosim nn import`` takes an int8 ONNX file in the form onnxruntime's
static quantizer writes: QDQ nodes, per-channel int8 weights, uint8 or
int8 activations. :func:`quantize_for_deck` calls that quantizer with
those options, so a float model (an ONNX file, or a PyTorch model exported
to one with ``torch.onnx.export`` first) becomes a file the deck takes::

    from crazyflie_cosim.deck import quantize_for_deck
    quantize_for_deck("net.onnx", "net.q.onnx", calibration_images)

Needs ``onnx`` and ``onnxruntime`` (``pip install onnx onnxruntime``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Literal

import numpy as np


def quantize_for_deck(
    model: str | Path,
    output: str | Path,
    calibration: Iterable[np.ndarray],
    *,
    activations: Literal["uint8", "int8"] = "uint8",
) -> Path:
    """Quantizes the float ONNX ``model`` into ``output`` for the deck.

    ``calibration``: float32 inputs of the model's input shape (a few dozen
    representative ones: camera frames for a gate network); the quantizer
    sets every activation's scale and zero point from the ranges they
    produce. ``activations``: uint8 (onnxruntime's default, asymmetric) or
    int8. Weights are int8 per output channel, the form the cluster's
    kernels requantize per channel. Returns ``output``.
    """
    import onnx
    from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static

    graph = onnx.load(str(model)).graph
    initializers = {t.name for t in graph.initializer}
    inputs = [i.name for i in graph.input if i.name not in initializers]
    if len(inputs) != 1:
        raise ValueError(f"{model}: the deck takes a model with one input, this one has {inputs}")
    name = inputs[0]

    class Reader(CalibrationDataReader):
        def __init__(self):
            self.batches = iter(calibration)

        def get_next(self):
            x = next(self.batches, None)
            return None if x is None else {name: np.asarray(x, dtype=np.float32)}

    quantize_static(
        str(model),
        str(output),
        Reader(),
        quant_format=QuantFormat.QDQ,
        per_channel=True,
        weight_type=QuantType.QInt8,
        activation_type=QuantType.QUInt8 if activations == "uint8" else QuantType.QInt8,
    )
    return Path(output)
