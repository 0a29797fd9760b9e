"""Policies as ONNX files: one input ``[batch, obs_dim]`` -> one output ``[batch, act_dim]``.

Ours (``robogym-ray export CHECKPOINT OUT.onnx``: input ``obs``, output ``actions`` in [-1, 1],
any batch size) and Isaac Lab's (rsl_rl ``play.py``'s ``policy.onnx``: batch fixed at 1, raw
actions). A robot PC runs either with ``onnxruntime`` alone, without torch or this project:

    import numpy as np, onnxruntime as ort
    session = ort.InferenceSession("policy.onnx")
    action = session.run(None, {"obs": obs.reshape(1, -1).astype(np.float32)})[0][0]

Reading and writing them here needs the ``onnx`` extra (``pip install -e ".[onnx]"``:
onnxruntime, and onnx for torch's exporter).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from robogym_ray.errors import ConfigError
from robogym_ray.text import reason

OPSET = 17
"""ONNX opset of our exports: what onnxruntime has run for years (Isaac Lab writes 11)."""


class OnnxPolicy:
    """An ONNX policy file run by onnxruntime: ``policy(batch) -> actions`` (float32 arrays)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            import onnxruntime as ort
        except ImportError:
            raise ConfigError(
                f"{self.path}: running an ONNX policy needs onnxruntime: pip install -e '.[onnx]'"
            ) from None
        try:
            self.session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own, unexported exception classes
            why = reason(str(exc)) or type(exc).__name__
            raise ConfigError(
                f"{self.path}: not an ONNX model onnxruntime can load ({why})"
            ) from None
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if len(inputs) != 1 or not outputs:
            raise ConfigError(
                f"{self.path}: expected one input (observations) and an output (actions); it has "
                f"{[i.name for i in inputs]} -> {[o.name for o in outputs]} (a recurrent policy?)"
            )
        self.input, self.output = inputs[0].name, outputs[0].name
        self.obs_dim = _size(inputs[0].shape, self.path)
        self.act_dim = _size(outputs[0].shape, self.path)

    def __call__(self, batch: np.ndarray) -> np.ndarray:
        feed = {self.input: np.asarray(batch, dtype=np.float32)}
        return np.asarray(self.session.run([self.output], feed)[0])


def _size(shape: list[Any], path: Path) -> int:
    if len(shape) != 2 or not isinstance(shape[-1], int):
        raise ConfigError(f"{path}: expected [batch, size] input and output, got {shape}")
    return int(shape[-1])


def write_onnx(
    module: Any,
    obs_dim: int,
    dest: str | Path | BinaryIO,
    any_batch: bool = True,
    opset: int = OPSET,
) -> None:
    """Write a torch policy (``[batch, obs_dim] -> [batch, act_dim]``) as ONNX to a file name or
    a binary stream (``export`` writes it to memory first): any batch size, or a batch of 1 as
    Isaac Lab's ``play.py`` writes it (``any_batch=False``; it writes ``opset`` 11).

    TorchScript-based export (``dynamo=False``): exact for a fixed MLP; it needs the ``onnx``
    package (the ``onnx`` extra), not ``onnxscript``.
    """
    import inspect
    import warnings

    import torch

    # torch < 2.5 has only the TorchScript exporter, and no ``dynamo`` argument to ask for it.
    which = {"dynamo": False} if "dynamo" in inspect.signature(torch.onnx.export).parameters else {}
    batch_axes = {"obs": {0: "batch"}, "actions": {0: "batch"}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation notice
        torch.onnx.export(
            module, (torch.zeros(1, obs_dim),), dest if hasattr(dest, "write") else str(dest),
            input_names=["obs"],
            output_names=["actions"], dynamic_axes=batch_axes if any_batch else {},
            opset_version=opset, **which,
        )  # fmt: skip
