"""A node's parameters from one schema: declared with descriptors, validated, typed."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from ext_sense_runtime.parameters import build, declare_all, param, specs


def _not_zero(value: int) -> str | None:
    return "must not be 0" if value == 0 else None


@dataclass(frozen=True)
class Schema:
    port: int = param(8765, "TCP port.", low=0, high=65535, read_only=True, check=_not_zero)
    rate_hz: float = param(10.0, "Rate, 1/s.", low=1.0, high=100.0)
    sensor: str = param("nuskin", "Sensor drawn.", choices=("nuskin", "biotac"))
    topics: tuple[str, ...] = param(("a", "b"), "Topics.")
    gains: tuple[float, ...] = param((), "Gains, 1.")
    state_topic: str = param("/state", "State topic.", name="arm.state_topic")
    low_hz: float = param(1.0, "Lower rate, 1/s.", low=0.0, high=100.0)

    def __post_init__(self) -> None:
        if self.low_hz > self.rate_hz:
            raise ValueError(f"low_hz {self.low_hz} is above rate_hz {self.rate_hz}")


def test_specs_list_every_field_with_its_type_and_name():
    by_name = {s.name: s for s in specs(Schema)}
    assert by_name["port"].type_name == "int"
    assert by_name["rate_hz"].type_name == "double"
    assert by_name["topics"].type_name == "string[]"
    assert by_name["gains"].type_name == "double[]"
    assert by_name["arm.state_topic"].field == "state_topic"


def test_an_int_default_for_a_double_is_refused_when_the_schema_is_read():
    @dataclass(frozen=True)
    class Bad:
        rate_hz: float = param(1, "Rate, 1/s.", low=0.0, high=2.0)

    with pytest.raises(TypeError, match=r"Bad\.rate_hz: default 1 is not a float"):
        specs(Bad)


def test_build_names_the_parameter_that_is_refused():
    assert build(Schema, {"sensor": "biotac", "topics": ["x"]}) == Schema(
        sensor="biotac", topics=("x",)
    )
    with pytest.raises(
        ValueError,
        match=r"The 'sensor' parameter must be one of \['nuskin', 'biotac'\]\. Got 'camera'",
    ):
        build(Schema, {"sensor": "camera"})
    with pytest.raises(ValueError, match=r"The 'rate_hz' parameter must be in \[1.0, 100.0\]"):
        build(Schema, {"rate_hz": 0.5})
    with pytest.raises(ValueError, match=r"The 'port' parameter must not be 0\. Got 0 instead\."):
        build(Schema, {"port": 0})
    with pytest.raises(ValueError, match=r"low_hz 5\.0 is above rate_hz 2\.0"):
        build(Schema, {"rate_hz": 2.0, "low_hz": 5.0})


@pytest.fixture
def context():
    import rclpy
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx, args=[])
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.mark.ros
def test_a_node_declares_validates_and_hands_over_its_config(context):
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    node = Node(
        "schema_test",
        context=context,
        parameter_overrides=[Parameter("rate_hz", value=20.0), Parameter("gains", value=[0.5])],
    )
    seen: list[Schema] = []

    def on_change(config: Schema) -> str | None:
        seen.append(config)
        return "not now" if config.rate_hz == 99.0 else None

    try:
        config = declare_all(node, Schema, on_change)
        assert config == Schema(rate_hz=20.0, gains=(0.5,))
        (port,) = node.describe_parameters(["port"])
        assert port.read_only
        assert port.description == "TCP port."
        assert (port.integer_range[0].from_value, port.integer_range[0].to_value) == (0, 65535)
        (rate,) = node.describe_parameters(["rate_hz"])
        assert rate.floating_point_range[0].to_value == 100.0
        assert node.get_parameter("arm.state_topic").value == "/state"

        ok = node.set_parameters([Parameter("sensor", value="biotac")])[0]
        assert ok.successful
        assert seen[-1].sensor == "biotac"
        bad = node.set_parameters([Parameter("sensor", value="camera")])[0]
        assert not bad.successful
        assert "The 'sensor' parameter must be one of" in bad.reason
        cross = node.set_parameters([Parameter("low_hz", value=50.0)])[0]
        assert not cross.successful
        assert "above rate_hz" in cross.reason
        refused = node.set_parameters([Parameter("rate_hz", value=99.0)])[0]
        assert not refused.successful
        assert refused.reason == "not now"
        assert node.get_parameter("rate_hz").value == 20.0
        assert not node.set_parameters([Parameter("port", value=1)])[0].successful
        # the config the callback kept is the accepted one: a later change builds on it
        assert node.set_parameters([Parameter("rate_hz", value=30.0)])[0].successful
        assert seen[-1] == Schema(rate_hz=30.0, sensor="biotac", gains=(0.5,))
    finally:
        node.destroy_node()


@pytest.mark.ros
def test_a_bad_value_at_start_up_is_one_line_naming_the_parameter(context):
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    node = Node(
        "schema_test_bad",
        context=context,
        parameter_overrides=[Parameter("sensor", value="camera")],
    )
    try:
        with pytest.raises(ValueError, match="The 'sensor' parameter must be one of"):
            declare_all(node, Schema)
    finally:
        node.destroy_node()
