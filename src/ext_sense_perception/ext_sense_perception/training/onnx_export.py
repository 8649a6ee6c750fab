"""ONNX export of whole models: feature pipeline plus estimator, from the raw window.

The feature families' converter is ``Reshape`` -> ``Gather`` (channels) -> ``MatMul`` (their
constant time maps) -> element-wise ops. The scaler and estimators use skl2onnx's converters,
except the SVR and the taxel stack (plain MatMul/Exp, faster) and the GRU (torch's export,
spliced in). The graph takes ``window`` ``(n, n_channels * n_samples)`` float32, as
:func:`~ext_sense_perception.features.as_model_input` makes it.
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.pipeline import Pipeline

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.maps import FFT_SCALE_IN, FFT_SCALE_OUT, FeatureKind
from ext_sense_perception.features.transformer import FAMILIES, WindowFeatures
from ext_sense_perception.training.gru import GRUEstimator
from ext_sense_perception.training.taxel_stack import TaxelStackSVR

TARGET_OPSET = {"": 17, "ai.onnx.ml": 3}
INPUT_NAME = "window"
_registered = False


def _ints(*values: int) -> np.ndarray:
    """An int64 constant: a shape, axes or slice bounds."""
    return np.array(values, np.int64)


def _shape_calculator(operator) -> None:
    from skl2onnx.common.data_types import FloatTensorType

    op = operator.raw_operator
    operator.outputs[0].type = FloatTensorType([None, int(op.n_features_out_)])


def _converter(scope, operator, container) -> None:
    from skl2onnx.algebra import onnx_ops as ops

    op: WindowFeatures = operator.raw_operator
    v = container.target_opset
    f32 = np.float32
    x = ops.OnnxReshape(operator.inputs[0], _ints(-1, op.n_channels, op.n_samples), op_version=v)
    if len(op.channel_index_) != op.n_channels or np.any(
        op.channel_index_ != np.arange(op.n_channels)
    ):
        x = ops.OnnxGather(x, op.channel_index_.astype(np.int64), axis=1, op_version=v)
    n_sel = len(op.channel_index_)
    kind = op.kind_
    maps = [m.astype(f32) for m in op.time_maps_]
    if kind in (FeatureKind.BASELINE, FeatureKind.EST):
        y = ops.OnnxMatMul(x, maps[0], op_version=v)
        y = ops.OnnxReshape(y, _ints(-1, n_sel * maps[0].shape[1]), op_version=v)
    elif kind in (FeatureKind.FFT, FeatureKind.AUTOENCODER):
        re = ops.OnnxMatMul(x, maps[0], op_version=v)
        im = ops.OnnxMatMul(x, maps[1], op_version=v)
        power = ops.OnnxAdd(
            ops.OnnxMul(re, re, op_version=v), ops.OnnxMul(im, im, op_version=v), op_version=v
        )
        y = ops.OnnxMul(
            ops.OnnxSqrt(power, op_version=v),
            np.array([FFT_SCALE_IN * FFT_SCALE_OUT], f32),
            op_version=v,
        )
        y = ops.OnnxReshape(y, _ints(-1, n_sel * maps[0].shape[1]), op_version=v)
        if kind is FeatureKind.AUTOENCODER:
            y = ops.OnnxMul(
                ops.OnnxSub(y, op.ae_mean_.astype(f32), op_version=v),
                (1.0 / op.ae_scale_).astype(f32),
                op_version=v,
            )
            for w, b in op.ae_layers_:
                y = ops.OnnxRelu(
                    ops.OnnxAdd(
                        ops.OnnxMatMul(y, w.astype(f32), op_version=v), b.astype(f32), op_version=v
                    ),
                    op_version=v,
                )
    else:  # ACTIVITY
        nb = op.activity_bins_
        n_seg = maps[0].shape[1] - nb
        a = ops.OnnxMatMul(ops.OnnxAbs(x, op_version=v), maps[0], op_version=v)
        one = np.array([1.0], f32)
        over = ops.OnnxSlice(a, _ints(0), _ints(nb), _ints(2), op_version=v)
        over = ops.OnnxReduceSum(over, _ints(1), keepdims=0, op_version=v)
        over = ops.OnnxLog(ops.OnnxAdd(over, one, op_version=v), op_version=v)
        seg = ops.OnnxSlice(a, _ints(nb), _ints(nb + n_seg), _ints(2), op_version=v)
        seg = ops.OnnxLog(ops.OnnxAdd(seg, one, op_version=v), op_version=v)
        seg = ops.OnnxReshape(seg, _ints(-1, n_sel * n_seg), op_version=v)
        y = ops.OnnxConcat(over, seg, axis=1, op_version=v)
    final = ops.OnnxIdentity(y, op_version=v, output_names=operator.outputs[:1])
    final.add_to(scope, container)


def _svr_shape_calculator(operator) -> None:
    from skl2onnx.common.data_types import FloatTensorType

    operator.outputs[0].type = FloatTensorType([None, 1])


def _svr_converter(scope, operator, container) -> None:
    """SVR with plain MatMul/Exp ops (ONNX Runtime's SVMRegressor measured 25x slower).

    RBF distances are expanded on inputs centred on the support vectors' mean (less float32
    cancellation) and clipped at 0.
    """
    from skl2onnx.algebra import onnx_ops as ops

    op = operator.raw_operator
    v = container.target_opset
    f32 = np.float32
    sv = np.asarray(op.support_vectors_, dtype=np.float64)
    coef = np.asarray(op.dual_coef_, dtype=np.float64).T  # (n_sv, 1)
    b = np.asarray(op.intercept_, dtype=f32).reshape(1, 1)
    x = operator.inputs[0]
    out = operator.outputs[:1]
    if op.kernel == "linear":
        w = (sv.T @ coef).astype(f32)
        y = ops.OnnxAdd(ops.OnnxMatMul(x, w, op_version=v), b, op_version=v, output_names=out)
    elif op.kernel == "rbf":
        centre = sv.mean(axis=0)
        svc = sv - centre
        xc = ops.OnnxSub(x, centre.astype(f32)[None, :], op_version=v)
        axes = _ints(1)
        xx = ops.OnnxReduceSum(ops.OnnxMul(xc, xc, op_version=v), axes, keepdims=1, op_version=v)
        cross = ops.OnnxMatMul(xc, (-2.0 * svc.T).astype(f32), op_version=v)
        ss = (svc * svc).sum(axis=1).astype(f32)[None, :]
        d2 = ops.OnnxAdd(ops.OnnxAdd(cross, xx, op_version=v), ss, op_version=v)
        d2 = ops.OnnxMax(d2, np.array([0.0], f32), op_version=v)
        gamma = np.array([-float(op._gamma)], f32)
        k = ops.OnnxExp(ops.OnnxMul(d2, gamma, op_version=v), op_version=v)
        y = ops.OnnxAdd(
            ops.OnnxMatMul(k, coef.astype(f32), op_version=v), b, op_version=v, output_names=out
        )
    else:
        raise PerceptionError(f"SVR kernel {op.kernel!r} has no ONNX export here (linear, rbf).")
    y.add_to(scope, container)


def _taxel_stack_converter(scope, operator, container) -> None:
    """Per-channel RBF SVRs and their ridge combination as one batched ``MatMul`` graph.

    Uses :meth:`TaxelStackSVR.onnx_arrays`; distances as in :func:`_svr_converter`.
    """
    from skl2onnx.algebra import onnx_ops as ops

    op = operator.raw_operator
    v = container.target_opset
    f32 = np.float32
    arr = op.onnx_arrays()
    n_ch, _, d = arr["sv"].shape
    x = ops.OnnxReshape(operator.inputs[0], _ints(-1, n_ch, d), op_version=v)
    xc = ops.OnnxSub(x, arr["centre"].astype(f32)[None, :, :], op_version=v)
    xc = ops.OnnxTranspose(xc, perm=[1, 0, 2], op_version=v)  # (n_ch, n, d)
    xx = ops.OnnxReduceSum(ops.OnnxMul(xc, xc, op_version=v), _ints(2), keepdims=1, op_version=v)
    cross = ops.OnnxMatMul(xc, (-2.0 * arr["sv"].transpose(0, 2, 1)).astype(f32), op_version=v)
    ss = (arr["sv"] ** 2).sum(axis=2)[:, None, :].astype(f32)  # (n_ch, 1, n_sv)
    d2 = ops.OnnxAdd(ops.OnnxAdd(cross, xx, op_version=v), ss, op_version=v)
    d2 = ops.OnnxMax(d2, np.array([0.0], f32), op_version=v)
    k = ops.OnnxExp(
        ops.OnnxMul(d2, (-arr["gamma"]).astype(f32)[:, None, None], op_version=v), op_version=v
    )
    per_channel = ops.OnnxMatMul(
        k, arr["coef"].astype(f32)[:, :, None], op_version=v
    )  # (n_ch, n, 1)
    total = ops.OnnxReduceSum(per_channel, _ints(0), keepdims=0, op_version=v)
    y = ops.OnnxAdd(
        total, np.array([[arr["intercept"]]], f32), op_version=v, output_names=operator.outputs[:1]
    )
    y.add_to(scope, container)


def _gru_parser(scope, model, inputs, custom_parsers=None):
    """Outputs of the GRU: ``variable`` (regression) or ``label`` + ``probabilities``."""
    from skl2onnx.common.data_types import FloatTensorType, Int64TensorType, StringTensorType

    op = scope.declare_local_operator("ExtSenseGRU", model)
    op.inputs = inputs
    if model.net_.classes is None:
        op.outputs.append(scope.declare_local_variable("variable", FloatTensorType([None, 1])))
        return op.outputs
    kind = np.asarray(model.net_.classes).dtype.kind
    label = StringTensorType([None]) if kind in "US" else Int64TensorType([None])
    n_classes = len(model.net_.classes)
    op.outputs.append(scope.declare_local_variable("label", label))
    op.outputs.append(
        scope.declare_local_variable("probabilities", FloatTensorType([None, n_classes]))
    )
    return op.outputs


def _gru_shape_calculator(operator) -> None:
    """Output types are fixed by :func:`_gru_parser`."""


def _gru_converter(scope, operator, container) -> None:
    """The GRU's graph as torch exported it at training (``GRUEstimator.onnx_``), spliced in.

    Names are made unique; a classifier's label is ``Gather`` of the ``ArgMax`` probability.
    """
    from onnx import TensorProto, helper, load_from_string, numpy_helper

    est = operator.raw_operator
    if not isinstance(getattr(est, "onnx_", None), bytes):
        raise PerceptionError(
            "This GRU was fitted before its ONNX graph was kept with it: fit it again to export."
        )
    graph = load_from_string(est.onnx_).graph
    outs = [o.full_name for o in operator.outputs]
    names = {graph.input[0].name: operator.inputs[0].full_name, graph.output[0].name: outs[-1]}

    def name(old: str) -> str:
        if old and old not in names:
            names[old] = scope.get_unique_variable_name(f"gru_{old}")
        return names.get(old, old)

    def node(op: str, ins: list[str], out: list[str], **attrs) -> None:
        name_ = scope.get_unique_operator_name(op)
        container.add_node(op, ins, out, name=name_, op_version=container.target_opset, **attrs)

    # skl2onnx cannot order nodes around an empty input name: the GRU's inputs end before its
    # empty sequence_lens, so its initial state is ONNX's default zeros (torch's too), and the
    # nodes that only made the zeros are left out with what else the output does not need
    steps, used = [], {graph.output[0].name}
    for n in reversed(graph.node):
        ins = list(n.input)
        if n.op_type == "GRU" and "" in ins:
            ins = ins[: ins.index("")]
        if used.intersection(n.output):
            used.update(ins)
            steps.append((n, ins))
    for t in graph.initializer:
        if t.name in used:
            tensor = numpy_helper.from_array(numpy_helper.to_array(t), name(t.name))
            container.add_initializer(name(t.name), None, None, tensor)
    for n, ins in reversed(steps):
        attrs = {a.name: helper.get_attribute_value(a) for a in n.attribute}
        node(n.op_type, [name(i) for i in ins], [name(o) for o in n.output], **attrs)
    if est.net_.classes is None:
        return
    classes = np.asarray(est.net_.classes)
    table = scope.get_unique_variable_name("gru_classes")
    if classes.dtype.kind in "US":
        strings = [str(v) for v in classes]
        container.add_initializer(table, TensorProto.STRING, [len(strings)], strings)
    else:
        values = classes.astype(np.int64)
        container.add_initializer(table, None, None, numpy_helper.from_array(values, table))
    best = scope.get_unique_variable_name("gru_argmax")
    node("ArgMax", [outs[1]], [best], axis=1, keepdims=0)
    node("Gather", [table, best], [outs[0]], axis=0)


def register_converters() -> None:
    """Teach skl2onnx (once) the feature families, a faster SVR, the taxel stack and the GRU."""
    global _registered
    if _registered:
        return
    from skl2onnx import update_registered_converter
    from sklearn.svm import SVR

    for family in FAMILIES.values():
        update_registered_converter(
            family, f"ExtSense{family.__name__}", _shape_calculator, _converter
        )
    update_registered_converter(SVR, "ExtSenseSVR", _svr_shape_calculator, _svr_converter)
    update_registered_converter(
        TaxelStackSVR, "ExtSenseTaxelStackSVR", _svr_shape_calculator, _taxel_stack_converter
    )
    update_registered_converter(
        GRUEstimator,
        "ExtSenseGRU",
        _gru_shape_calculator,
        _gru_converter,
        parser=_gru_parser,
        options={"zipmap": [False]},  # probabilities stay a tensor, as for the other models
    )
    _registered = True


def to_onnx_bytes(pipeline: Pipeline, n_inputs: int) -> bytes:
    """Serialized ONNX model of a fitted pipeline that starts with :class:`WindowFeatures`.

    Classifiers output ``label`` and ``probabilities`` (no ZipMap); regressors ``variable``.
    PerceptionError: skl2onnx cannot convert the model.
    """
    register_converters()
    from skl2onnx import convert_sklearn
    from skl2onnx.common.data_types import FloatTensorType

    final = pipeline.steps[-1][1]
    options = {id(final): {"zipmap": False}} if hasattr(final, "classes_") else None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter(
                "ignore", FutureWarning
            )  # skl2onnx reads SVC attributes sklearn 1.9 deprecates
            onx = convert_sklearn(
                pipeline,
                initial_types=[(INPUT_NAME, FloatTensorType([None, int(n_inputs)]))],
                target_opset=TARGET_OPSET,
                options=options,
            )
    except Exception as err:  # skl2onnx raises many types for unsupported models
        raise PerceptionError(f"Cannot export {type(final).__name__} to ONNX: {err}") from err
    return onx.SerializeToString()
