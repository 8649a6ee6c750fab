"""docs/parameters.md is the rendering of the nodes' parameter schemas (no node started)."""

from __future__ import annotations

from pathlib import Path

from ext_sense.parameter_docs import graph_nodes, render, schema_of

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
