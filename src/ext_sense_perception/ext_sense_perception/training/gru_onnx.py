"""ONNX graph of the GRU(16) + MLP model built from its weights (onnx.helper, no torch).

The trained network is a plain record of NumPy arrays (:class:`GRUNet`, torch's layout), so the
graph can be built, tested and deployed without torch. One builder (:func:`emit_gru_net`) writes
the nodes through two callbacks; :func:`to_onnx_model` uses it for a standalone model and
:mod:`ext_sense_perception.onnx_export` for the skl2onnx converter that chains it after the
feature pipeline and the scaler.

Mapping torch -> ONNX (``GRU``, opset 14+):

- gates: torch stacks the rows of ``weight_ih`` / ``weight_hh`` / biases as (r, z, n); ONNX
  expects (z, r, h), so the first two blocks swap;
- torch applies the reset gate after the recurrent matmul,
  ``n = tanh(W_in x + b_in + r * (W_hn h + b_hn))``, which is ONNX's ``linear_before_reset=1``;
- ``B`` is ``[Wb_z, Wb_r, Wb_h, Rb_z, Rb_r, Rb_h]`` (torch's ``bias_ih`` then ``bias_hh``);
- the input ``(n, n_channels * n_steps)`` is channel-major (the feature step's flattening), so
  it is reshaped to ``(n, n_channels, n_steps)`` and transposed to ONNX's
  ``(n_steps, n, n_channels)``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError

GRU_OPSET = 17
FEATURES_INPUT = "features"

Emit = Callable[[str, list[str], list[str], dict], None]
Const = Callable[[str, np.ndarray], str]


class GRUNet(NamedTuple):
    """A trained GRU + MLP head, everything inference needs (float32, torch's layout).

    Attributes:
        w_ih: ``(3 * hidden, n_channels)``, row blocks (r, z, n).
        w_hh: ``(3 * hidden, hidden)``, row blocks (r, z, n).
        b_ih: ``(3 * hidden,)``.
        b_hh: ``(3 * hidden,)``.
        layers: MLP layers ``(weight (out, in), bias (out,))``; ReLU between them, none after
            the last.
        n_channels: GRU inputs per step (channels of the flattened features).
        n_steps: Time steps.
        y_mean: Regression target mean (outputs are ``raw * y_scale + y_mean``).
        y_scale: Regression target scale.
        classes: Class labels (classification) or ``None`` (regression).
        reverse: The GRU reads the steps last to first (ONNX ``direction="reverse"``).
    """

    w_ih: np.ndarray
    w_hh: np.ndarray
    b_ih: np.ndarray
    b_hh: np.ndarray
    layers: tuple[tuple[np.ndarray, np.ndarray], ...]
    n_channels: int
    n_steps: int
    y_mean: float = 0.0
    y_scale: float = 1.0
    classes: np.ndarray | None = None
    reverse: bool = False

    @property
    def hidden(self) -> int:
        """GRU cells."""
        return int(self.w_hh.shape[1])

    def check(self) -> None:
        """Validate shapes.

        Raises:
            PerceptionError: when an array has the wrong shape.
        """
        h, c = self.hidden, self.n_channels
        want = {
            "w_ih": (3 * h, c),
            "w_hh": (3 * h, h),
            "b_ih": (3 * h,),
            "b_hh": (3 * h,),
        }
        for name, shape in want.items():
            got = tuple(np.shape(getattr(self, name)))
            if got != shape:
                raise PerceptionError(
                    f"The GRU weight {name!r} must have shape {shape}. Got {got} instead."
                )
        n_in = h
        for i, (w, b) in enumerate(self.layers):
            if np.ndim(w) != 2 or np.shape(w)[1] != n_in or np.shape(b) != (np.shape(w)[0],):
                raise PerceptionError(
                    f"MLP layer {i} must be (out, {n_in}) with bias (out,). Got "
                    f"{np.shape(w)} and {np.shape(b)} instead."
                )
            n_in = np.shape(w)[0]
        if not self.layers:
            raise PerceptionError("The 'layers' of a GRUNet must hold at least one layer.")
        if self.classes is not None and len(self.classes) != n_in:
            raise PerceptionError(
                f"The last layer must have one output per class ({len(self.classes)}). "
                f"Got {n_in} instead."
            )


def onnx_gate_order(a: np.ndarray, hidden: int) -> np.ndarray:
    """Rows (r, z, n) -> (z, r, n) along the first axis (torch -> ONNX gate order)."""
    r, z, n = a[:hidden], a[hidden : 2 * hidden], a[2 * hidden :]
    return np.concatenate([z, r, n], axis=0)


def emit_gru_net(
    net: GRUNet,
    inp: str,
    outputs: list[str],
    emit: Emit,
    const: Const,
    fresh: Callable[[str], str] | None = None,
) -> None:
    """Write the nodes of ``features -> GRU -> MLP -> output`` through callbacks.

    Args:
        net: The weights.
        inp: Name of the ``(n, n_channels * n_steps)`` float32 input.
        outputs: ``[variable]`` (regression, ``(n, 1)``) or ``[label, probabilities]``.
        emit: ``emit(op_type, inputs, outputs, attrs)`` adds one node; output names passed to
            it are unique.
        const: ``const(hint, array) -> name`` adds a constant and returns its unique name.
        fresh: ``fresh(hint) -> name``, a unique name for an intermediate result (default:
            derived from the first output's name).
    """
    net.check()
    h, c, t = net.hidden, int(net.n_channels), int(net.n_steps)
    f32 = np.float32
    names = iter(range(1_000_000))

    def tmp(hint: str) -> str:
        if fresh is not None:
            return fresh(hint)
        return f"{outputs[0]}_gru_{hint}_{next(names)}"

    x = tmp("x3")
    emit("Reshape", [inp, const("shape_nct", np.array([-1, c, t], np.int64))], [x], {})
    xt = tmp("xt")
    emit("Transpose", [x], [xt], {"perm": [2, 0, 1]})
    w = onnx_gate_order(np.asarray(net.w_ih, f32), h)[None]
    r = onnx_gate_order(np.asarray(net.w_hh, f32), h)[None]
    b = np.concatenate(
        [
            onnx_gate_order(np.asarray(net.b_ih, f32), h),
            onnx_gate_order(np.asarray(net.b_hh, f32), h),
        ]
    )[None]
    yh = tmp("yh")
    emit(
        "GRU",
        [xt, const("W", w), const("R", r), const("B", b)],
        ["", yh],
        {
            "hidden_size": h,
            "linear_before_reset": 1,
            "direction": "reverse" if net.reverse else "forward",
        },
    )
    y = tmp("h")
    emit("Reshape", [yh, const("shape_nh", np.array([-1, h], np.int64))], [y], {})
    for i, (wl, bl) in enumerate(net.layers):
        z = tmp(f"fc{i}")
        emit(
            "Gemm",
            [y, const(f"fc{i}_w", np.asarray(wl, f32)), const(f"fc{i}_b", np.asarray(bl, f32))],
            [z],
            {"transB": 1},
        )
        y = z
        if i < len(net.layers) - 1:
            a = tmp(f"relu{i}")
            emit("Relu", [y], [a], {})
            y = a
    if net.classes is None:
        scaled = tmp("scaled")
        emit("Mul", [y, const("y_scale", np.array([net.y_scale], f32))], [scaled], {})
        emit("Add", [scaled, const("y_mean", np.array([net.y_mean], f32))], [outputs[0]], {})
        return
    label, proba = outputs
    emit("Softmax", [y], [proba], {"axis": 1})
    idx = tmp("argmax")
    emit("ArgMax", [y], [idx], {"axis": 1, "keepdims": 0})
    classes = np.asarray(net.classes)
    if classes.dtype.kind in "iub":
        classes = classes.astype(np.int64)
    emit("Gather", [const("classes", classes), idx], [label], {"axis": 0})


def to_onnx_model(net: GRUNet, opset: int = GRU_OPSET):
    """A standalone ONNX model of the network.

    Args:
        net: The weights.
        opset: ONNX opset (at least 14).

    Returns:
        ``onnx.ModelProto`` with input ``features`` ``(n, n_channels * n_steps)`` float32 and
        output ``variable`` ``(n, 1)`` (regression) or ``label`` ``(n,)`` and
        ``probabilities`` ``(n, n_classes)``.
    """
    from onnx import TensorProto, helper, numpy_helper

    nodes, inits = [], []
    used: set[str] = set()

    def emit(op: str, ins: list[str], outs: list[str], attrs: dict) -> None:
        nodes.append(helper.make_node(op, ins, outs, name=f"{op}_{len(nodes)}", **attrs))

    def const(hint: str, arr: np.ndarray) -> str:
        name = hint
        while name in used:
            name = f"{hint}_{len(used)}"
        used.add(name)
        if arr.dtype.kind in "US":
            inits.append(
                helper.make_tensor(
                    name, TensorProto.STRING, arr.shape, [str(v).encode() for v in arr.ravel()]
                )
            )
        else:
            inits.append(numpy_helper.from_array(arr, name))
        return name

    n_in = int(net.n_channels) * int(net.n_steps)
    inp = helper.make_tensor_value_info(FEATURES_INPUT, TensorProto.FLOAT, [None, n_in])
    if net.classes is None:
        outs = [helper.make_tensor_value_info("variable", TensorProto.FLOAT, [None, 1])]
    else:
        label_type = (
            TensorProto.STRING if np.asarray(net.classes).dtype.kind in "US" else TensorProto.INT64
        )
        outs = [
            helper.make_tensor_value_info("label", label_type, [None]),
            helper.make_tensor_value_info(
                "probabilities", TensorProto.FLOAT, [None, len(net.classes)]
            ),
        ]
    emit_gru_net(net, FEATURES_INPUT, [o.name for o in outs], emit, const)
    graph = helper.make_graph(nodes, "ext_sense_gru", [inp], outs, initializer=inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)])
    model.ir_version = min(model.ir_version, 9)
    return model
