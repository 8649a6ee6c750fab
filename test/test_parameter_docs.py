"""docs/parameters.md renders the nodes' parameter schemas, and the nodes declare exactly those."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from ext_sense.parameter_docs import graph_nodes, render, schema_of
from ext_sense_runtime.parameters import build, specs

DOC = Path(__file__).resolve().parents[1] / "docs" / "parameters.md"


def test_the_parameter_doc_is_current():
    assert DOC.read_text() == render(graph_nodes()), (
        "docs/parameters.md is stale: run `python -m ext_sense.parameter_docs --out "
        "docs/parameters.md`"
    )


def test_every_parameter_is_described_and_the_graphs_give_only_declared_ones():
    for spec, given in graph_nodes():
        declared = {p.name for p in schema_of(spec)}
        assert declared, f"{spec.name} declares no parameters"
        for p in schema_of(spec):
            assert p.description.strip(), f"{spec.name}.{p.name} has no description"
        undeclared = sorted(set(given) - declared)
        assert not undeclared, f"graphs give {spec.name} undeclared parameters {undeclared}"


TYPES = {"bool": bool, "int": int, "double": float, "string": str}


def test_the_shipped_parameter_files_name_only_declared_parameters_of_their_type():
    schemas = {spec.executable: spec.node_class().PARAMETERS for spec, _ in graph_nodes()}
    files = sorted((DOC.parents[1] / "src").glob("*/config/*.yaml"))
    assert files
    for path in files:
        for node, body in yaml.safe_load(path.read_text()).items():
            values = body["ros__parameters"]
            declared = {p.name: p for p in specs(schemas[node])}
            assert set(values) <= set(declared), (
                f"{path.name}: {node} has {set(values) - set(declared)}"
            )
            for name, value in values.items():
                wanted = TYPES.get(declared[name].type_name, list)
                assert type(value) is wanted, f"{path.name}: {node}.{name} is not a {wanted}"
            build(schemas[node], values)  # in range, accepted together


@pytest.mark.ros
def test_every_node_declares_its_schema_and_nothing_else():
    """Each graph node, started with its graph's parameters, declares exactly its schema."""
    import rclpy
    from rclpy.context import Context

    from ext_sense.runner import _node_kwargs

    for spec, _ in graph_nodes():
        context = Context()
        rclpy.init(context=context, args=[])
        try:
            node = spec.node_class()(**_node_kwargs(spec, False, context))
            try:
                hidden = {"use_sim_time", "start_type_description_service"}
                names = sorted(set(node._parameters) - hidden)
                expected = sorted(p.name for p in schema_of(spec))
                assert names == expected, spec.executable
                described = node.describe_parameters(expected)
                for p, d in zip(
                    sorted(schema_of(spec), key=lambda p: p.name), described, strict=True
                ):
                    assert (d.description, d.read_only) == (p.description, p.read_only)
            finally:
                node.destroy_node()
        finally:
            rclpy.try_shutdown(context=context)
