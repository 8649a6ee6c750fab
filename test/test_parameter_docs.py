"""docs/parameters.md is what the nodes really declare (regenerated from the nodes)."""

from __future__ import annotations

from pathlib import Path

import pytest

from ext_sense.parameter_docs import describe, graph_nodes, render

pytestmark = [pytest.mark.ros, pytest.mark.slow]

DOC = Path(__file__).resolve().parents[1] / "docs" / "parameters.md"


def test_every_node_starts_and_the_parameter_doc_is_current():
    rows = [(spec, describe(spec)) for spec in graph_nodes()]
    for spec, params in rows:
        assert params, f"{spec.name} declares no parameters"
        for p in params:
            assert p["description"].strip(), f"{spec.name}.{p['name']} has no description"
    assert DOC.read_text() == render(rows), (
        "docs/parameters.md is stale: run `python -m ext_sense.parameter_docs --out "
        "docs/parameters.md`"
    )
